# SPDX-License-Identifier: Apache-2.0
"""Natural frequencies and modes of the elastic H4 (``h4pin.modes``): the compiled twin
(:mod:`h4pin.stiffness.frequencies`) for robots whose parallelograms are exact, once compiled, or
the Pinocchio route (:func:`h4pin.elastic.modal.modes`, ``crba`` on the elastic model) for any
robot and for the mode shapes. The two agree to round-off (``tests/test_frequencies.py``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import limits, verdicts
from h4pin.elastic.h4 import ElasticH4, elastic_model
from h4pin.elastic.modal import modes as pinocchio_modes
from h4pin.errors import ParameterError
from h4pin.inputs import check_choice, check_flag, describe, is_mechanism, real_array
from h4pin.kinematics.closed_form import as_poses
from h4pin.mechanism.engine import Modes
from h4pin.mechanism.payload import Payload
from h4pin.robot import H4
from h4pin.stiffness import kernel
from h4pin.stiffness.frequencies import FREQUENCIES, frequencies


def _robot(robot: Any):
    """The :class:`h4pin.H4` of ``robot`` (an H4 or its :class:`~h4pin.elastic.h4.ElasticH4`)."""
    if isinstance(robot, ElasticH4):
        return robot.robot
    if isinstance(robot, H4):
        return robot
    if is_mechanism(robot):
        raise ParameterError("h4pin.modes computes the H4's natural modes and takes an h4pin.H4 or an "
                             "h4pin.ElasticH4, got a Mechanism: for any closed-loop robot call its own method, "
                             "Mechanism.modes(q, springs, locked) (docs/mechanisms.md)")
    raise ParameterError(f"robot must be an h4pin.H4 or an h4pin.ElasticH4, got {describe(robot)}")


METHODS = ("auto", "compiled", "pinocchio")


def modes(robot: Any, pose: np.ndarray, payload: Any = None, *, method: str = "auto", link_inertias: bool = True,
          data: Any = None):
    """Natural frequencies (and mode shapes) of the elastic H4 at a pose or at many.

    The elastic H4 of :func:`h4pin.elastic_model` (every compliance a spring, the robot's own
    elements; actuators locked; the URDF's link inertias; an optional rigid payload on the
    central bar; massless motions condensed): :mod:`h4pin.stiffness.frequencies` (compiled,
    its module docstring) or :func:`h4pin.elastic.modal.modes` (Pinocchio's ``crba`` on the
    elastic model), which agree to round-off (``tests/test_frequencies.py``).

    Args:
        robot: an :class:`h4pin.H4` or its :class:`h4pin.ElasticH4`.
        pose: (4,) [x, y, z, theta] (m, rad), or (N, 4).
        payload: an :class:`h4pin.Payload` on the central bar, or None.
        method: ``"auto"`` (the compiled twin once compiled, for a robot whose parallelograms are
            exact; else Pinocchio), ``"compiled"`` or ``"pinocchio"``.
        link_inertias: the URDF's link inertias (True) or massless links (only the payload has mass).
        data: a ``pin.Data`` of the elastic model for the Pinocchio route.

    Returns:
        :class:`h4pin.Modes`, the same fields for one pose or many: one pose, frequencies (m,)
        (its shapes computed by the Pinocchio route on first access when the twin gave the
        frequencies); (N, 4), frequencies (N, m) (refused poses NaN, with their status).

    Raises:
        PoseError: ``pose`` is not real numbers of shape (4,) or (N, 4) (bools, text, ``None``,
            complex numbers and masked arrays are refused) or not finite.
        UnreachablePoseError (and subclasses), UnrestrainedMotionError: one pose the robot cannot
            take or that is singular (a batch gives NaN and the status instead).
        ParameterError: a bad robot, method, payload, link_inertias (not a bool) or data (not a
            ``pin.Data`` of the elastic model), each named.
    """
    h4 = _robot(robot)  # the door (issue 30): every argument's type before any work
    method = check_choice(method, METHODS, "method")
    link_inertias = check_flag(link_inertias, "link_inertias")
    if payload is not None and not isinstance(payload, Payload):
        raise ParameterError(f"payload must be an h4pin.Payload or None, got {describe(payload)}")
    if payload is not None:  # an H4's plate weighs about 1 kg: a 1e12 kg payload is a typo
        limits.check_range("payload mass", payload.mass, "payload")
    shape = np.shape(pose) if isinstance(pose, np.ndarray) else ()
    n = int(np.prod(shape[:-1])) if len(shape) > 1 else 1  # before any pass over the values (a broadcast view)
    limits.check_size(f"modes: {n:,} poses", n * (limits.MODES_BYTES_PER_POSE + 32), n / limits.MODES_POSES_PER_S,
                      "split the poses into chunks")
    x = as_poses(real_array(pose, "pose")).copy()
    x.setflags(write=False)
    if data is not None:
        if not isinstance(data, pin.Data):
            raise ParameterError(f"data must be a pinocchio.Data of the elastic model or None, got {describe(data)}")
        robot = robot if isinstance(robot, ElasticH4) else elastic_model(robot)  # built once, not per pose
        if len(data.oMi) != robot.model.njoints:
            raise ParameterError(f"data must be a pinocchio.Data of the elastic model ({robot.model.njoints} joints), "
                                 f"got one of {len(data.oMi)} joints")
    compiled = h4.geometry.ideal and method != "pinocchio" and (
        method == "compiled" or (FREQUENCIES.ready and kernel.ONE.ready and kernel.BATCH.ready))
    if method == "compiled" and not h4.geometry.ideal:
        raise ParameterError("the compiled twin takes robots whose parallelograms are exact; use method='pinocchio'")
    if x.ndim == 1:
        if compiled:
            freq, counts, status = frequencies(h4, x, payload, link_inertias=link_inertias)
            if status[0] == verdicts.OK:
                m = int(counts[0, 0])
                f = freq[0, :m].copy()
                f.setflags(write=False)
                return Modes(f, m, 0, payload, x, lambda: pinocchio_modes(
                    robot, x, payload, link_inertias=link_inertias, data=data)._shapes(), int(counts[0, 1]) - m)
        return pinocchio_modes(robot, x, payload, link_inertias=link_inertias, data=data)  # its typed error
    if compiled:
        freq, counts, status = frequencies(h4, x, payload, link_inertias=link_inertias)
        return Modes(freq, counts[:, 0].copy(), status, payload, x)
    from h4pin.stiffness.api import compliance

    status = compliance(h4, x, "consistent", on_error="nan").status.astype(np.int8)
    rows = [pinocchio_modes(robot, xk, payload, link_inertias=link_inertias, data=data).frequencies if s == 0
            else np.zeros(0) for xk, s in zip(x, status, strict=True)]
    width = max([len(r) for r in rows] + [1])
    freq = np.full((len(x), width), np.nan)
    for k, r in enumerate(rows):
        freq[k, :len(r)] = r
    return Modes(freq, np.array([len(r) for r in rows]), status, payload, x)




__all__ = ["METHODS", "modes"]
