# SPDX-License-Identifier: Apache-2.0
"""Independent validation routes: Newton-Euler statics, the non-linear deformed robot, the
tool point, and finite differences of the deformed robot for the optional elements.

Statics, the deformed robot and the tool point share only the closed-form geometry with the
stiffness model; the elements' finite-difference route reuses the elements' beam model
(:mod:`h4pin.stiffness.elements`) but not their unit loads (``docs/architecture.md``).
"""
