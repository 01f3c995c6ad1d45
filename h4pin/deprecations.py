# SPDX-License-Identifier: Apache-2.0
"""Every deprecated name of h4pin, in one table, with the release that removes it.

A name listed here still resolves, with a :class:`DeprecationWarning` that says where it went and
when it goes; ``CHANGELOG.md`` lists the same names. A module whose names moved hands its
``__getattr__`` to :func:`module_getattr`.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import Any

#: ``{module: {old name: (new dotted path, release that removes the old name)}}``.
MOVED: dict[str, dict[str, tuple[str, str]]] = {
    "h4pin.elastic": {name: (f"h4pin.mechanism.{name}", "0.3.0") for name in (
        "Beam", "FrameOutput", "Insertion", "JointCoupling", "JointOutput", "Mechanism", "Modes", "Payload",
        "UnassembledError", "UnrestrainedMotionError", "VirtualJoint", "compliance_matrix", "insert_joints")},
    "h4pin.io.viewer": {
        "show_mechanism": ("h4pin.mechanism.scene.show", "0.3.0"),
        "draw_mechanism": ("h4pin.mechanism.scene.draw_sticks", "0.3.0"),
        "ellipsoid_axes": ("h4pin.mechanism.scene.ellipsoid_axes", "0.3.0"),
        "draw_ellipsoid": ("h4pin.mechanism.scene.draw_ellipsoid", "0.3.0"),
        "screenshot": ("h4pin.mechanism.scene.screenshot", "0.3.0"),
        "nice": ("h4pin.mechanism.scene.nice", "0.3.0"),
    },
}


def resolve(path: str) -> Any:
    """The object at a dotted path (``package.module.name``)."""
    module, _, name = path.rpartition(".")
    return getattr(importlib.import_module(module), name)


def module_getattr(module: str) -> Callable[[str], Any]:
    """A module ``__getattr__`` that resolves the module's moved names of :data:`MOVED`, warning."""
    table = MOVED[module]

    def __getattr__(name: str) -> Any:
        if name in table:
            new, removed = table[name]
            warnings.warn(f"{module}.{name} is now {new}; the old name is removed in h4pin {removed}",
                          DeprecationWarning, stacklevel=2)
            return resolve(new)
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
