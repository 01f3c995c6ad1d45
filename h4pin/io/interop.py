# SPDX-License-Identifier: Apache-2.0
"""The H4 for Gepetto's closed-loop tools: Extended-URDF sidecar, actuation model, closed-loop Jacobian.

Gepetto's ``toolbox-parallel-robots`` (PyPI) works on a Pinocchio model, its data, a list of
``RigidConstraintModel`` closures with their datas, and an *actuation model* (which joints are
motors). Its loader (``example_parallel_robots.loader_tools.completeRobotLoader``) reads a URDF tree
plus an Extended-URDF sidecar ``robot.yaml`` (Batto, de Matteis, Mansard) with the keys
``closed_loop`` (pairs of frame names joined by a closure), ``type`` (``3D`` or ``6D`` per pair),
``name_mot`` (actuated joints), ``joint_name`` / ``joint_type`` (joints to replace, none here).

- :func:`extended_urdf_yaml`: the sidecar of an H4, from the ``<constraint>`` elements of its URDF
  (shipped as ``urdf/h4_<variant>.yaml``, written by ``scripts/generate_urdf.py``).
- :class:`ActuationModel`, :class:`ActuationData`: the toolbox's fields, built without importing it
  (version 1.2.0 cannot build its own ``ActuationData`` for a fixed-base robot on Pinocchio 4, see
  ``docs/interop.md``).
- :func:`closed_loop`: everything the toolbox's functions take, for an :class:`h4pin.H4`.
- :func:`closed_loop_frame_jacobian`: the closed-loop Jacobian of a frame, world-aligned by default
  (the toolbox's is in the LOCAL frame, and needs forward kinematics and each ``calc`` first).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin._compat import constraint_calc
from h4pin.description.urdf import closures_from_urdf
from h4pin.errors import MalformedURDFError, ParameterError, SingularPoseError
from h4pin.verdicts import CLOSURE_SINGULAR_COND

if TYPE_CHECKING:
    from h4pin.robot import H4

#: Condition number of the free-joint closure Jacobian above which a configuration is singular.


def _xyz(elem: ET.Element | None) -> np.ndarray:
    if elem is None:
        return np.zeros(3)
    return np.array([float(v) for v in elem.get("xyz", "0 0 0").split()])


def closure_frame_pairs(urdf_text: str, where: str = "URDF") -> list[tuple[str, str]]:
    """For each ``<constraint>`` of the URDF, the names of the two frames it joins.

    A closure joins a point of its parent link to a point of its child link. The Extended URDF
    names frames, so each point must be a link on a fixed joint (no rotation) at that point: the
    H4 URDFs have ``bar_ij_end`` on each bar and ``B_ij`` on the lateral bars.

    Raises:
        MalformedURDFError: a closure point has no such frame (the message names the closure).
    """
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise MalformedURDFError(f"{where}: not well-formed XML ({exc})") from None
    fixed = []  # (parent link, child link, xyz, rpy)
    for j in root.findall("joint"):
        if j.get("type") != "fixed" or j.find("parent") is None or j.find("child") is None:
            continue
        o = j.find("origin")
        rpy = np.array([float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()])
        fixed.append((j.find("parent").get("link"), j.find("child").get("link"), _xyz(o), rpy))
    pairs = []
    for name, plink, pxyz, clink, cxyz in closures_from_urdf(urdf_text, where):
        frames = []
        for side, link, xyz in (("parent", plink, pxyz), ("child", clink, cxyz)):
            hits = [c for p, c, o, r in fixed if p == link and np.allclose(o, xyz, rtol=0, atol=1e-12)
                    and not np.any(r)]
            if not hits:
                raise MalformedURDFError(
                    f"{where}: closure '{name}': no frame on link '{link}' at its {side} point {xyz.tolist()} "
                    "(the Extended URDF joins named frames)")
            frames.append(hits[0])
        pairs.append((frames[0], frames[1]))
    return pairs


def extended_urdf_yaml(h4: H4, urdf_name: str | None = None) -> str:
    """The Extended-URDF sidecar (YAML text) of ``h4``: its 8 closures as 3-D frame pairs, its motors.

    Args:
        h4: the robot; its URDF text gives the closures, ``h4.actuated_joint_names`` the motors.
        urdf_name: file name of the URDF it goes with, for the header comment.
    """
    pairs = closure_frame_pairs(h4.urdf, h4.source)
    lines = [
        "# SPDX-License-Identifier: Apache-2.0",
        f"# Extended-URDF sidecar of {urdf_name or 'the H4 URDF'} (Batto, de Matteis, Mansard): the loop closures",
        "# and actuated joints, for Gepetto's loader (example_parallel_robots completeRobotLoader).",
        "# Generated from the URDF's <constraint> elements by scripts/generate_urdf.py; do not edit.",
        "closed_loop: [" + ", ".join(f"[{a}, {b}]" for a, b in pairs) + "]",
        "type: [" + ", ".join("3D" for _ in pairs) + "]",
        "name_mot: [" + ", ".join(h4.actuated_joint_names) + "]",
        "joint_name: []",
        "joint_type: []",
    ]
    return "\n".join(lines) + "\n"


class ActuationModel:
    """Which joints are motors, with the fields of ``toolbox_parallel_robots.ActuationModel``.

    Attributes:
        mot_joints_names, mot_joints_ids: the actuated joints (names as given, ids in the model).
        mot_ids_q, mot_ids_v: their configuration and velocity indices (sorted arrays).
        free_ids_q, free_ids_v: the other indices (lists, as the toolbox has them).
        nv_mot, nv_free: their counts (read by the toolbox's ``ActuationData``, absent from its
            ``ActuationModel`` in version 1.2.0).
    """

    def __init__(self, model: pin.Model, names: list[str] | tuple[str, ...]):
        known = list(model.names)
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ParameterError(f"names: no joint {', '.join(map(repr, unknown))} in the model")
        self.model = model
        self.mot_joints_names = list(names)
        self.mot_joints_ids = [i for i, n in enumerate(model.names) if n in names]
        joints = [model.joints[i] for i in self.mot_joints_ids]
        self.mot_ids_q = np.unique([j.idx_q + k for j in joints for k in range(j.nq)])
        self.mot_ids_v = np.unique([j.idx_v + k for j in joints for k in range(j.nv)])
        self.free_ids_q = [i for i in range(model.nq) if i not in self.mot_ids_q]
        self.free_ids_v = [i for i in range(model.nv) if i not in self.mot_ids_v]
        self.nv_mot = len(self.mot_ids_v)
        self.nv_free = len(self.free_ids_v)


class ActuationData:
    """Work arrays of the toolbox's closed-loop functions, with the fields of its ``ActuationData``.

    Sized for any robot (the toolbox's 1.2.0 constructor assumes an actuated free-flyer, sizing
    ``vqmot`` as ``nv_mot - 6``, and calls ``RigidConstraintModel.size()``, which Pinocchio 4
    renamed ``residualSize``).
    """

    def __init__(self, model: pin.Model, constraint_models, actuation_model: ActuationModel):
        nv, nm, nf = model.nv, actuation_model.nv_mot, actuation_model.nv_free
        self.constraints_sizes = [_constraint_size(cm) for cm in constraint_models]
        nc = sum(self.constraints_sizes)
        self.Smot = np.zeros((nv, nm))
        self.Smot[actuation_model.mot_ids_v, range(nm)] = 1
        self.Sfree = np.zeros((nv, nf))
        self.Sfree[actuation_model.free_ids_v, range(nf)] = 1
        self.Jmot, self.Jfree = np.zeros((nc, nm)), np.zeros((nc, nf))
        self.pinvJfree = np.zeros((nf, nc))
        self.Mmot = np.zeros((nm, nm))
        self.dq, self.dq_no = np.zeros((nv, nm)), np.zeros((nv, nm))
        self.LJ = [np.zeros((n, nv)) for n in self.constraints_sizes]
        self.Jf_closed = np.zeros((6, nm))
        self.vq, self.vqmot, self.vqfree, self.vqmotfree = np.zeros(nv), np.zeros(nm), np.zeros(nf), np.zeros(nv)


def _constraint_size(cm: pin.RigidConstraintModel) -> int:
    """Rows of a closure: ``residualSize()`` (Pinocchio 4) or ``size()`` (3.x)."""
    return int(cm.residualSize() if hasattr(cm, "residualSize") else cm.size())


class ClosedLoop(NamedTuple):
    """What the toolbox's closed-loop functions take, in their argument order."""

    model: pin.Model
    data: pin.Data
    constraint_models: list
    constraint_datas: list
    actuation_model: ActuationModel
    actuation_data: ActuationData


def closed_loop(h4: H4) -> ClosedLoop:
    """The H4 as the toolbox takes it: its model, a fresh data, its 8 closures with fresh datas,
    and the actuation model of ``h4.actuated_joint_names`` (h4's own data are left alone)."""
    cms = list(h4.constraint_models)
    am = ActuationModel(h4.model, h4.actuated_joint_names)
    return ClosedLoop(h4.model, h4.model.createData(), cms, [cm.createData() for cm in cms], am,
                      ActuationData(h4.model, cms, am))


def closed_loop_frame_jacobian(loop: ClosedLoop, q: np.ndarray, frame: str | int,
                               reference: pin.ReferenceFrame = pin.LOCAL_WORLD_ALIGNED) -> np.ndarray:
    """Jacobian (6, nv_mot) of a frame's twist with respect to the motor velocities, loops closed.

    Runs forward kinematics, the joint Jacobians and each closure's ``calc`` at ``q`` (the toolbox
    skips the last), then ``dq/dq_mot = [I; -Jc_free^-1 Jc_mot]`` from the closure Jacobians, and
    the frame Jacobian in ``reference`` (world-aligned by default: rows v_x, v_y, v_z, w_x, w_y, w_z
    at the frame's origin; the toolbox's is LOCAL).

    Raises:
        ParameterError: ``frame`` is not a frame of the model, or ``q`` has the wrong size.
        SingularPoseError: the free-joint closure Jacobian has lost rank (cond > 1e10).
    """
    model, data = loop.model, loop.data
    if isinstance(frame, str):
        if not model.existFrame(frame):
            raise ParameterError(f"frame: no frame {frame!r} in the model")
        fid = model.getFrameId(frame)
    else:
        fid = int(frame)
        if not 0 <= fid < model.nframes:
            raise ParameterError(f"frame: id {fid} out of range (the model has {model.nframes} frames)")
    q = np.asarray(q, float)
    if q.shape != (model.nq,):
        raise ParameterError(f"q: expected shape ({model.nq},), got {q.shape}")
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    for cm, cd in zip(loop.constraint_models, loop.constraint_datas, strict=True):
        constraint_calc(cm, model, data, cd)
    jc = np.vstack([pin.getConstraintJacobian(model, data, cm, cd)
                    for cm, cd in zip(loop.constraint_models, loop.constraint_datas, strict=True)])
    am = loop.actuation_model
    jm, jf = jc[:, am.mot_ids_v], jc[:, am.free_ids_v]
    s = np.linalg.svd(jf, compute_uv=False)
    cond = s[0] / s[-1] if s[-1] > 0 else np.inf
    if jf.shape[0] < jf.shape[1] or not cond < CLOSURE_SINGULAR_COND:
        raise SingularPoseError(f"the free-joint closure Jacobian is singular (cond = {cond:.2e})")
    dq = np.zeros((model.nv, am.nv_mot))
    dq[am.mot_ids_v] = np.eye(am.nv_mot)
    dq[am.free_ids_v] = -np.linalg.lstsq(jf, jm, rcond=None)[0]
    return pin.getFrameJacobian(model, data, fid, reference) @ dq


__all__ = [
    "ActuationData",
    "ActuationModel",
    "ClosedLoop",
    "closed_loop",
    "closed_loop_frame_jacobian",
    "closure_frame_pairs",
    "extended_urdf_yaml",
]
