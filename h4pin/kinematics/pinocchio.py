# SPDX-License-Identifier: Apache-2.0
"""Kinematics of a loaded H4 through Pinocchio: free functions over the robot and a ``pin.Data``.

Pinocchio's own style: the robot (:class:`h4pin.H4`, immutable once loaded) holds the shared
``pin.Model``; every function here takes the ``pin.Data`` it works in (``data=``), by default the
calling thread's own (:attr:`h4pin.H4.data`), so that calls from several threads never see each
other's workspace. Nothing here changes the robot or its model.

* :func:`state`, :func:`assemble`, :func:`configuration`: a pose [x, y, z, theta] to the closed
  Pinocchio configuration (actuators from the inverse geometry, each bar's universal joint in
  closed form, the plate's free-flyer and lateral revolutes);
* :func:`kinematics`: one :class:`Kinematics` value per pose (q, points, the Jacobians of the B_ij
  and A_ij points) from which :mod:`h4pin.stiffness.matrices` builds the paper's matrices;
* :func:`passive_map`, :func:`jacobian`: the closed-loop velocity map from the 24x24 closure
  Jacobian, an independent route to J of eq. 8;
* :func:`gravity_torques`, :func:`potential_energy`, :func:`closure_residuals`,
  :func:`frame_position`.
"""

from __future__ import annotations

import weakref
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin import _jit
from h4pin.errors import ParameterError, SingularPoseError
from h4pin.kinematics import _compiled
from h4pin.kinematics import closed_form as cf
from h4pin.kinematics.closed_form import PlateState, Points
from h4pin.lookup import FRAME_TYPES, finite_configuration, frame_id, model_configuration  # noqa: F401  (re-exported)
from h4pin.verdicts import CLOSURE_SINGULAR_COND, raise_for_status

_PACKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: The compiled configuration is cached (else its interpreted twin runs: :mod:`h4pin._jit`).
CONFIGURATION = _jit.Gate("configuration", _compiled.configuration_packed, step="configuration")


class Kinematics(NamedTuple):
    """One pose of an H4, through Pinocchio: everything the stiffness model needs, no hidden state.

    Attributes:
        pose: (4,) [x, y, z, theta].
        state: the assembled :class:`h4pin.kinematics.closed_form.PlateState`.
        configuration: (nq,) Pinocchio configuration, all loops closed.
        points: characteristic points from Pinocchio's frame placements.
        JB: (8, 3, 8) Jacobians of the B_ij w.r.t. dtp = [dD, dOmega, domega_1, domega_2].
        JA: (8, 3, 4) Jacobians of the A_ij w.r.t. the actuator angles.
    """

    pose: np.ndarray
    state: PlateState
    configuration: np.ndarray
    points: Points
    JB: np.ndarray
    JA: np.ndarray


def state(h4, pose: np.ndarray, *, check: bool = True) -> PlateState:
    """The assembled :class:`PlateState` of one pose (raises the typed error of a bad pose:
    unreachable, and with ``check`` joint limits and interfering bars)."""
    sol = cf.solve(h4.geometry, cf.as_pose(pose), check=check)
    raise_for_status(sol.status, sol.detail, batch=False)
    return sol.state


def assemble(h4, st: PlateState) -> np.ndarray:
    """Configuration (nq,) of actuator angles and plate placement; bars aimed at B_ij.

    The closures hold exactly when ``st`` is assembled (e.g. from :func:`state`), and
    approximately for a slightly deformed robot (used to draw deflected shapes). Each universal
    joint is solved in closed form (two rotations about axes through A_ij that take the bar's
    end to the direction of B_ij; the branch closest to the reference).
    """
    q, D, R, omega = (np.ascontiguousarray(a, dtype=float) for a in st)
    floats, ints = configuration_pack(h4)
    fill = _compiled.configuration_packed if CONFIGURATION.ready else _jit.interpreted(_compiled.configuration_packed)
    return fill(h4.index.q_neutral.copy(), q, D, R, omega, floats, ints)


def configuration_pack(h4) -> tuple[np.ndarray, np.ndarray]:
    """The constants of :func:`h4pin.kinematics._compiled.configuration_packed`, packed once per
    robot (a read-only cache keyed by the robot, outside it)."""
    packed = _PACKS.get(h4)
    if packed is None:
        g, ix = h4.geometry, h4.index
        packed = _compiled.pack_configuration(g.P, g.u, g.A0, g.C0, g.b, g.v, ix.e1, ix.e2, ix.p0, ix.lat_sign,
                                              ix.X0R, ix.X0t, ix.D0, g.lat, ix.q_act, ix.q_u, ix.q_plate, ix.q_lat)
        for a in packed:
            a.setflags(write=False)
        _PACKS[h4] = packed
    return packed


def configuration(h4, pose: np.ndarray, *, check: bool = True) -> np.ndarray:
    """Full Pinocchio configuration (nq,) of ``pose`` (4,), all 8 closures satisfied."""
    return assemble(h4, state(h4, pose, check=check))


def _cross_columns(r: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``r[n] x cols[n, :, c]`` for every n and column c: (n, 3) x (n, 3, m) -> (n, 3, m)."""
    rx, ry, rz = (r[:, i, None] for i in range(3))
    cx, cy, cz = cols[:, 0], cols[:, 1], cols[:, 2]
    return np.stack([ry * cz - rz * cy, rz * cx - rx * cz, rx * cy - ry * cx], axis=1)


def kinematics(h4, pose: np.ndarray, data: pin.Data | None = None, st: PlateState | None = None) -> Kinematics:
    """Everything about one pose through Pinocchio (:class:`Kinematics`): the assembled
    configuration, the points from Pinocchio's joint placements, and the Jacobians of the B_ij
    and A_ij points from Pinocchio's joint Jacobians.

    ``dB_ij = JB[n] dtp`` with ``dtp = [dD, dOmega, domega_1, domega_2]`` (world-aligned at
    D), and ``dA_ij = JA[n] dq``: the joint Jacobians (LOCAL_WORLD_ALIGNED) of the lateral
    bars and forearms shifted to the points (``v_X = v_joint + w x (X - joint)``); the plate
    columns mapped from the free-flyer's local velocity to dtp with the frame Jacobian of D.
    ``st``: the pose's assembled state when the caller has it (else :func:`state` solves it).

    Raises:
        UnreachablePoseError (and subclasses): the robot cannot take the pose.
    """
    x = cf.as_pose(pose).copy()
    st = state(h4, x) if st is None else st
    q = assemble(h4, st)
    m, d, ix, g = h4.model, h4.data if data is None else data, h4.index, h4.geometry
    pin.computeJointJacobians(m, d, q)
    homog = np.array([d.oMi[j].homogeneous for j in ix.point_joints])
    xyz = np.einsum("nab,nb->na", homog[ix.point_joint_index, :3, :3], ix.point_local) \
        + homog[ix.point_joint_index, :3, 3]
    bij, aij = xyz[3:11], xyz[11:19]
    lwa = pin.LOCAL_WORLD_ALIGNED
    jd = pin.getFrameJacobian(m, d, ix.fid_D, lwa)[:, ix.v_plate]
    to_tp = np.eye(8)
    to_tp[:6, :6] = jd[:, :6]
    jlat = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, ix.v_plate] for j in ix.jid_lat])
    jact = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, h4.v_act] for j in ix.jid_act])
    olat = homog[[ix.point_joints.index(j) for j in ix.jid_lat], :3, 3]
    oact = homog[[ix.point_joints.index(j) for j in ix.jid_act], :3, 3]
    jl, ja = jlat[g.lat], jact[np.arange(8) // 2]
    jb = jl[:, :3] - _cross_columns(bij - olat[g.lat], jl[:, 3:])
    ja = ja[:, :3] - _cross_columns(aij - oact[np.arange(8) // 2], ja[:, 3:])
    v_world = st.R @ g.v.T
    pts = Points(D=xyz[0], C=xyz[1:3], B=bij.reshape(4, 2, 3).mean(axis=1), Bij=bij.reshape(4, 2, 3), P=g.P,
                 A=aij.reshape(4, 2, 3).mean(axis=1), Aij=aij.reshape(4, 2, 3), v=v_world.T)
    return Kinematics(x, st, q, pts, jb @ np.linalg.inv(to_tp), ja)


def as_configuration(h4, q: Any) -> np.ndarray:
    """``q`` as a finite configuration (nq,) of the robot's model, or a :class:`ParameterError`."""
    return model_configuration(h4.model, q)


def closure_residuals(h4, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
    """Position errors of the 8 closures at configuration q, (8, 3) in m, from Pinocchio."""
    q = as_configuration(h4, q)
    d = h4.data if data is None else data
    pin.forwardKinematics(h4.model, d, q)
    out = np.empty((8, 3))
    for n, (cm, cd) in enumerate(zip(h4.constraint_models, h4.constraint_datas, strict=True)):
        cm.calc(h4.model, d, cd)
        out[n] = cd.c1Mc2.translation
    return out


def passive_map(h4, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
    """``S`` (nv, 4) with ``v = S q_dot`` at configuration q: the closed-loop velocity of
    every joint, from Pinocchio's closure Jacobian: ``v_p = -Jc_p^-1 Jc_a q_dot``.

    Raises:
        SingularPoseError: the 24x24 passive closure block is singular (cond >= 1e10).
    """
    m, d = h4.model, h4.data if data is None else data
    pin.computeJointJacobians(m, d, q)
    datas = h4.constraint_datas  # the calling thread's own
    for cm, cd in zip(h4.constraint_models, datas, strict=True):
        cm.calc(m, d, cd)
    jc = pin.getConstraintsJacobian(m, d, h4.constraint_models, datas)
    jp, ja = jc[:, h4.v_pas], jc[:, h4.v_act]
    try:
        inv = np.linalg.inv(jp)
        cond = np.abs(jp).sum(0).max() * np.abs(inv).sum(0).max()  # 1-norm condition number
    except np.linalg.LinAlgError:
        cond = np.inf
    if not cond < CLOSURE_SINGULAR_COND:
        raise SingularPoseError(f"the passive closure Jacobian is singular (cond = {cond:.2e}): "
                                "the plate has an uncontrolled motion at this pose")
    s = np.zeros((m.nv, 4))
    s[h4.v_act] = np.eye(4)
    s[h4.v_pas] = -inv @ ja
    return s


def jacobian(h4, pose: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
    """J (4, 4) with x_dot = J q_dot (eq. 8), from Pinocchio's closure and frame Jacobians.

    The passive velocities come from the 24x24 closure Jacobian (:func:`passive_map`), the
    plate motion from the frame Jacobian of D (LOCAL_WORLD_ALIGNED), rows v_x, v_y, v_z, w_z.
    An independent route to the J that :mod:`h4pin.stiffness` computes from M1 and M3.
    """
    d = h4.data if data is None else data
    s = passive_map(h4, configuration(h4, pose), d)
    jd = pin.getFrameJacobian(h4.model, d, h4.index.fid_D, pin.LOCAL_WORLD_ALIGNED)
    return jd[[0, 1, 2, 5]] @ s


def gravity_torques(h4, pose: np.ndarray, gravity: np.ndarray | None = None,
                    data: pin.Data | None = None) -> np.ndarray:
    """Actuator torques (4,) in N.m that hold the robot still at ``pose`` under gravity.

    The generalized gravity of a uniform field g is ``-m J_com^T g`` (m the total mass, J_com
    Pinocchio's Jacobian of the centre of mass), so any gravity vector is used without touching
    the shared model; with ``v = S q_dot`` (:func:`passive_map`), virtual work gives
    ``tau = S^T g(q)``, the same as eliminating the closure forces from
    ``g = tau_full + Jc^T lambda``.

    Args:
        gravity: (3,) m/s^2, default the model's (0, 0, -9.81).
    """
    if gravity is None:
        gv = h4.model.gravity.linear.copy()
    else:
        gv = np.asarray(gravity, dtype=float) if np.ndim(gravity) else np.array([np.nan])
        if gv.shape != (3,) or not np.all(np.isfinite(gv)):
            raise ParameterError(f"gravity must be a finite vector of 3 numbers (m/s^2), got {gravity!r}")
    d = h4.data if data is None else data
    q = configuration(h4, pose)
    jcom = pin.jacobianCenterOfMass(h4.model, d, q)
    g = -float(d.mass[0]) * (jcom.T @ gv)
    return passive_map(h4, q, d).T @ g


def potential_energy(h4, pose: np.ndarray, data: pin.Data | None = None) -> float:
    """Gravitational potential energy (J) of the assembled robot at ``pose``, from Pinocchio."""
    d = h4.data if data is None else data
    return float(pin.computePotentialEnergy(h4.model, d, configuration(h4, pose)))


def frame_position(h4, name: str, q: np.ndarray | None = None, data: pin.Data | None = None) -> np.ndarray:
    """World position (3,) of a named frame: at configuration ``q`` (forward kinematics on
    ``data``), or, without ``q``, as ``data`` last placed it (``updateFramePlacements``)."""
    if name not in h4.frames:
        raise ParameterError(f"no frame named {name!r}")
    d = h4.data if data is None else data
    if q is not None:
        pin.forwardKinematics(h4.model, d, as_configuration(h4, q))
    pin.updateFramePlacement(h4.model, d, h4.frames[name])
    return d.oMf[h4.frames[name]].translation.copy()


#: The name h4pin.studies.atlas calls it by, until it uses the public one.

__all__ = ["FRAME_TYPES", "Kinematics", "as_configuration", "assemble", "closure_residuals", "configuration",
           "configuration_pack", "frame_id", "frame_position", "gravity_torques", "jacobian", "kinematics",
           "passive_map", "potential_energy", "state"]
