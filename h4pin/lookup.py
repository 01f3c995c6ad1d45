# SPDX-License-Identifier: Apache-2.0
"""Looking things up in a Pinocchio model, checked: a frame by name or id, a configuration.

One place for what the H4's kinematics and the generic closed-loop engine both need, so that a
frame is found the same way everywhere (:func:`frame_id`) and a configuration is refused with the
same message (:func:`finite_configuration`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.inputs import real_array

#: When several frames share a name, the one of the first of these types that has it.
FRAME_TYPES = ("OP_FRAME", "BODY", "FIXED_JOINT", "JOINT", "SENSOR")


def frame_id(model: pin.Model, frame: str | int, kind: Any = None, what: str = "frame") -> int:
    """The id of ``frame`` in ``model``: a name (of type ``kind`` if given; when several frames
    share the name, the first of :data:`FRAME_TYPES` that has it), or an id.

    Raises:
        ParameterError: no such frame (naming ``what``), an id out of range.
    """
    if isinstance(frame, str):
        if kind is not None:
            if not model.existFrame(frame, kind):
                raise ParameterError(f"{what}: the model has no frame named {frame!r} of type {kind}")
            return int(model.getFrameId(frame, kind))
        if not model.existFrame(frame):
            raise ParameterError(f"{what}: the model has no frame named {frame!r}")
        for t in FRAME_TYPES:
            ft = getattr(pin.FrameType, t)
            if model.existFrame(frame, ft):
                return int(model.getFrameId(frame, ft))
        return int(model.getFrameId(frame))
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise ParameterError(f"{what}: a frame name or id, got {frame!r}")
    fid = int(frame)
    if not 0 <= fid < model.nframes:
        raise ParameterError(f"{what}: id {fid} out of range (the model has {model.nframes} frames)")
    return fid


def finite_configuration(q: Any, nq: int, what: str = "q") -> np.ndarray:
    """``q`` as a finite float vector (nq,) (a copy), or a :class:`ParameterError` naming
    ``what``: not real numbers (complex, bools, text), the shape it has, or the first coordinate
    that is not finite."""
    qv = np.array(real_array(q, what, ParameterError, f"a configuration of {nq} real numbers"))
    if qv.shape != (nq,):
        raise ParameterError(f"{what} must be a configuration of shape ({nq},), got shape {qv.shape}")
    bad = np.flatnonzero(~np.isfinite(qv))
    if bad.size:
        raise ParameterError(f"{what}[{bad[0]}] is {qv[bad[0]]}: a configuration must be finite")
    return qv


def model_configuration(model: pin.Model, q: Any, what: str = "q") -> np.ndarray:
    """``q`` as a finite configuration (nq,) of ``model`` (a copy), or a :class:`ParameterError`
    naming ``what``."""
    return finite_configuration(q, model.nq, what)


__all__ = ["FRAME_TYPES", "finite_configuration", "frame_id", "model_configuration"]
