# SPDX-License-Identifier: Apache-2.0
"""The robot description: parameters (a URDF generator), the URDF format, and the loaded robot.

Layer 1 of h4pin (``docs/architecture.md``): :mod:`.params` (H4Params, variants), :mod:`.urdf`
(write and parse), :mod:`.geometry` (the per-leg and per-bar constants, :class:`H4Geometry`),
:mod:`.elements` (the optional compliant elements' data), :mod:`.reader` (a URDF read into a
:class:`~h4pin.description.reader.Description`, from which :func:`h4pin.load` makes the H4).
"""
