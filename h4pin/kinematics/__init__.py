# SPDX-License-Identifier: Apache-2.0
"""Kinematics of a loaded H4: closed forms (numpy reference, any batch of robots x poses) and
Pinocchio (one configuration and its Jacobians per pose, each call with its own ``pin.Data``).

Layer 2 of h4pin (``docs/architecture.md``).
"""
