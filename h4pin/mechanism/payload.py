# SPDX-License-Identifier: Apache-2.0
"""A rigid payload (:class:`Payload`): mass, centre of mass and inertia, checked and ranged; what
the natural frequencies of the H4 (:func:`h4pin.modes`) and of any mechanism
(:meth:`h4pin.mechanism.Mechanism.modes`) add at a frame."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError


@dataclasses.dataclass(frozen=True, eq=False)
class Payload:
    """A rigid body fixed to a frame: for the H4, the central bar (the tool and what it carries,
    frame ``D``: the world axes at theta = 0, turned by theta about z); for a
    :class:`~h4pin.mechanism.Mechanism`, the frame its ``modes(payload=(frame, Payload(...)))`` names.

    Attributes:
        mass: kg, >= 0.
        com: (3,) m, its centre of mass from the frame's origin, in the frame's axes.
        inertia: (3, 3) kg.m^2, its inertia tensor about the centre of mass, same axes; symmetric,
            positive semi-definite and obeying the triangle inequalities (0 for a point mass).
    """

    mass: float
    com: Any = (0.0, 0.0, 0.0)
    inertia: Any = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        from h4pin import limits
        from h4pin.inputs import describe, real_array, short

        if isinstance(self.mass, (str, bytes)) or any(isinstance(v, (str, bytes)) for v in
                                                      np.asarray(self.com, dtype=object).reshape(-1)):
            raise ParameterError(f"payload: mass and com must be numbers (kg, m), not text, got {self!r}")
        mass_arr = real_array(self.mass, "payload mass", ParameterError, "a real number (kg)")
        com = real_array(self.com, "payload com", ParameterError, "3 finite numbers (m)").copy()
        inertia = real_array(self.inertia, "payload inertia", ParameterError, "a finite 3x3 matrix (kg.m^2)").copy()
        if mass_arr.shape != ():
            raise ParameterError(f"payload mass must be one number (kg), got {describe(self.mass)}")
        mass = float(mass_arr)
        if not (math.isfinite(mass) and mass >= 0):
            raise ParameterError(f"payload mass must be finite and >= 0 (kg), got {short(self.mass)}")
        if com.shape != (3,) or not np.all(np.isfinite(com)):
            raise ParameterError(f"payload com must be 3 finite numbers (m), got {short(self.com)}")
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ParameterError(f"payload inertia must be a finite 3x3 matrix (kg.m^2), got {short(self.inertia)}")
        scale = max(float(np.abs(inertia).max()), 1e-300)
        if np.abs(inertia - inertia.T).max() > 1e-12 * scale:
            raise ParameterError(f"payload inertia must be symmetric, got {inertia.tolist()}")
        limits.check_range("payload mass", mass, "payload")
        limits.check_range("payload com", com, "com offset")
        principal = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
        limits.check_range("payload inertia (principal moments)", np.clip(principal, 0.0, None), "payload inertia")
        a, b, c = principal
        if principal[0] < -1e-12 * scale or a + b < c - 1e-12 * scale:
            raise ParameterError("payload inertia must be positive semi-definite and obey the triangle inequality "
                                 f"(principal moments {principal.tolist()} kg.m^2)")
        for name, value in (("mass", mass), ("com", com), ("inertia", 0.5 * (inertia + inertia.T))):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    def spatial(self) -> np.ndarray:
        """(6, 6) its spatial inertia in its frame, Pinocchio's order [linear; angular]
        (kg, kg.m, kg.m^2)."""
        return pin.Inertia(self.mass, self.com, self.inertia).matrix()


__all__ = ["Payload"]


def at_frame(model: pin.Model, payload: Any) -> tuple[str, Payload, Any]:
    """``(frame name, Payload, the model's frame)`` of a ``(frame, Payload)`` argument, checked: a
    frame of the model and a :class:`Payload`, else a :class:`ParameterError` naming what is
    expected."""
    try:
        frame, body = payload
    except (TypeError, ValueError):
        raise ParameterError(f"payload: (frame name, h4pin.mechanism.Payload), got {payload!r}") from None
    if not isinstance(body, Payload) or not isinstance(frame, str) or not model.existFrame(frame):
        raise ParameterError(f"payload: (frame name of the model, h4pin.mechanism.Payload), got {payload!r}")
    return frame, body, model.frames[model.getFrameId(frame)]
