# SPDX-License-Identifier: Apache-2.0
"""Compliance of any serial Pinocchio robot with elastic joints: ``C = J K^-1 J^T`` at a frame.

The H4's compliance (:mod:`h4pin.stiffness.api`) comes from its legs' springs through its closures.
For a serial arm whose links are much stiffer than its joints (the usual model of collaborative
arms with strain-wave gears), the joints are torsion springs ``tau_i = k_i dq_i`` and a wrench
``w = [F; T]`` at a frame deflects it by

    dx = J K^-1 J^T w = C w,

with ``J`` the frame's Jacobian in Pinocchio's LOCAL_WORLD_ALIGNED convention (rows v_x, v_y, v_z,
w_x, w_y, w_z at the frame's origin, world axes) and ``K = diag(k_i)``. :func:`serial_compliance`
returns it as a :class:`SerialCompliance` with the same ``matrix`` / ``translational`` /
``deflection`` reading as the H4's result; :func:`h4pin.io.viewer.draw_ellipsoid` draws its
ellipsoid for any model and frame.

Joint stiffness of the UR5 (:data:`UR5_JOINT_STIFFNESS`): see that constant. It is an
*assumption*, not a published identification (see ``docs/interop.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.kinematics.pinocchio import frame_id

#: Joint stiffness (N.m/rad) used for the UR5 of example-robot-data in ``scripts/compare_serial.py``,
#: joints 1-6 (shoulder pan, shoulder lift, elbow, wrist 1-3). ASSUMED values, of the order of
#: strain-wave (harmonic) gear torsional stiffness for the UR5's large (joints 1-3) and small
#: (joints 4-6) drives; no published identification could be checked for this package. Pass
#: measured values to :func:`serial_compliance` for real numbers.
UR5_JOINT_STIFFNESS = np.array([3.0e4, 3.0e4, 3.0e4, 6.0e3, 6.0e3, 6.0e3])


@dataclass(frozen=True)
class SerialCompliance:
    """Compliance of a serial robot at a frame (SI).

    Attributes:
        matrix: (6, 6) ``C = J K^-1 J^T``: twist-like displacement [dp (m), dphi (rad)] of the frame
            (LOCAL_WORLD_ALIGNED) per wrench [F (N), T (N.m)] applied at its origin (world axes).
        jacobian: (6, nv) the frame Jacobian ``J`` (LOCAL_WORLD_ALIGNED).
        joint_stiffness: (nv,) ``k_i`` in N.m/rad (N/m for prismatic joints).
        frame: the frame's name.
        position: (3,) the frame's origin, m.
    """

    matrix: np.ndarray
    jacobian: np.ndarray
    joint_stiffness: np.ndarray
    frame: str
    position: np.ndarray

    @property
    def translational(self) -> np.ndarray:
        """(3, 3) translational block, m/N: dp = C_tt F."""
        return self.matrix[:3, :3]

    @property
    def rotational(self) -> np.ndarray:
        """(3, 3) rotational block, rad/(N.m)."""
        return self.matrix[3:, 3:]

    def deflection(self, force, torque=None) -> np.ndarray:
        """(6,) [dp, dphi] under ``force`` (3,) N and optional ``torque`` (3,) N.m at the frame."""
        f = np.asarray(force, float)
        if f.shape != (3,):
            raise ParameterError(f"force: expected 3 components (N), got shape {f.shape}")
        t = np.zeros(3) if torque is None else np.asarray(torque, float)
        if t.shape != (3,):
            raise ParameterError(f"torque: expected 3 components (N.m), got shape {t.shape}")
        return self.matrix @ np.r_[f, t]


def _stiffness(model: pin.Model, joint_stiffness) -> np.ndarray:
    """(nv,) stiffness from an array (one per velocity) or a {joint name: k} mapping."""
    if isinstance(joint_stiffness, dict):
        k = np.full(model.nv, np.nan)
        for name, value in joint_stiffness.items():
            if not model.existJointName(name):
                raise ParameterError(f"joint_stiffness: no joint {name!r} in the model")
            j = model.joints[model.getJointId(name)]
            k[j.idx_v:j.idx_v + j.nv] = value
        missing = [model.names[i] for i in range(1, model.njoints)
                   if np.isnan(k[model.joints[i].idx_v:model.joints[i].idx_v + model.joints[i].nv]).any()]
        if missing:
            raise ParameterError(f"joint_stiffness: no value for joint(s) {', '.join(missing)}")
    else:
        k = np.asarray(joint_stiffness, float)
        if k.shape != (model.nv,):
            raise ParameterError(f"joint_stiffness: expected {model.nv} values (one per joint velocity), "
                                 f"got shape {k.shape}")
    if not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise ParameterError("joint_stiffness: every value must be finite and > 0 (N.m/rad)")
    return k


def serial_compliance(model: pin.Model, data: pin.Data, q, frame: str | int, joint_stiffness) -> SerialCompliance:
    """Compliance ``C = J K^-1 J^T`` of a serial robot at ``frame``, configuration ``q``.

    Args:
        model, data: a Pinocchio model (a tree: every joint is an elastic joint) and its data.
        q: (nq,) configuration.
        frame: frame name or id (e.g. ``"tool0"`` on the UR5).
        joint_stiffness: (nv,) ``k_i`` (N.m/rad), or a mapping {joint name: k}. Joints the robot
            holds rigidly can be given a very large k; a gripper's finger joints do not move the
            frame and their k does not matter.

    Raises:
        ParameterError: unknown frame, wrong ``q`` size, missing or non-positive stiffness.
    """
    fid = frame_id(model, frame)
    q = np.asarray(q, float)
    if q.shape != (model.nq,):
        raise ParameterError(f"q: expected shape ({model.nq},), got {q.shape}")
    k = _stiffness(model, joint_stiffness)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    c = (jac / k) @ jac.T
    return SerialCompliance(matrix=(c + c.T) / 2, jacobian=jac, joint_stiffness=k,
                            frame=model.frames[fid].name, position=data.oMf[fid].translation.copy())


__all__ = ["UR5_JOINT_STIFFNESS", "SerialCompliance", "serial_compliance"]
