# SPDX-License-Identifier: Apache-2.0
"""The H4 for Gepetto's closed-loop tools: Extended-URDF sidecar, the toolbox's own objects, workarounds.

Gepetto's ``toolbox-parallel-robots`` (PyPI) works on a Pinocchio model, its data, a list of
``RigidConstraintModel`` closures with their datas, and an *actuation model* (which joints are
motors). Its loader (``example_parallel_robots.loader_tools.completeRobotLoader``) reads a URDF tree
plus an Extended-URDF sidecar ``robot.yaml`` (Batto, de Matteis, Mansard) with the keys
``closed_loop`` (pairs of frame names joined by a closure), ``type`` (``3D`` or ``6D`` per pair),
``name_mot`` (actuated joints), ``joint_name`` / ``joint_type`` (joints to replace, none here).

- :func:`extended_urdf_yaml`: the sidecar of an H4, from the ``<constraint>`` elements of its URDF
  (shipped as ``urdf/h4_<variant>.yaml``, written by ``scripts/generate_urdf.py``).
- :func:`toolbox`: the toolbox package with its numpy/SciPy modules imported, on pip's Pinocchio
  (no casadi bindings); raises :class:`h4pin.extras.MissingExtraError` without it.
- :func:`closed_loop`: everything the toolbox's functions take, for an :class:`h4pin.H4`: with the
  toolbox installed, its own ``ActuationModel`` and ``ActuationData`` classes, completed so that
  every function of version 1.2.0 accepts them; without it, h4pin's look-alikes
  (:class:`ActuationModel`, :class:`ActuationData`). :func:`closed_loop_from_sidecar` builds the
  same from a URDF and its sidecar, the way the toolbox's loader does.
- :func:`prime`, :func:`local_to_world`, :func:`seed`, :func:`closed_configuration`: the
  workarounds of the toolbox's bugs listed in ``docs/interop.md``.
- :func:`closed_loop_frame_jacobian`: the closed-loop Jacobian of a frame, world-aligned by default
  (the toolbox's is in the LOCAL frame, and needs forward kinematics and each ``calc`` first).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import threading
import types
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin._compat import constraint_calc
from h4pin.description.urdf import closures_from_urdf
from h4pin.errors import ConvergenceError, MalformedURDFError, ParameterError, SingularPoseError
from h4pin.extras import require
from h4pin.kinematics.pinocchio import frame_id
from h4pin.verdicts import CLOSURE_SINGULAR_COND

if TYPE_CHECKING:
    from h4pin.robot import H4

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

    h4pin's stand-in, used by :func:`closed_loop` when the toolbox is not installed (with it,
    :func:`closed_loop` gives the toolbox's own class, completed the same way).

    Attributes:
        mot_joints_names, mot_joints_ids: the actuated joints (names as given, ids in the model).
        mot_ids_q, mot_ids_v: their configuration and velocity indices (sorted arrays).
        free_ids_q, free_ids_v: the other indices (lists, as the toolbox has them).
        nv_mot, nv_free: their counts (read by the toolbox's ``ActuationData``, absent from its
            ``ActuationModel`` in version 1.2.0).
        dq, dq_no: (nv, nv_mot) set by :func:`closed_loop` to its actuation data's arrays (the
            toolbox's 1.2.0 functions read and write them on the model).
    """

    def __init__(self, model: pin.Model, names: list[str] | tuple[str, ...]):
        _check_motor_names(model, names)
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


def _check_motor_names(model: pin.Model, names: list[str] | tuple[str, ...]) -> None:
    known = list(model.names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ParameterError(f"names: no joint {', '.join(map(repr, unknown))} in the model")


class ActuationData:
    """Work arrays of the toolbox's closed-loop functions, with the fields of its ``ActuationData``.

    Sized for any robot (the toolbox's 1.2.0 constructor assumes an actuated free-flyer, sizing
    ``vqmot`` as ``nv_mot - 6``, and calls ``RigidConstraintModel.size()``, which Pinocchio 4
    renamed ``residualSize``). :func:`closed_loop` fills an instance of the toolbox's own class
    the same way when the toolbox is installed.
    """

    def __init__(self, model: pin.Model, constraint_models, actuation_model: ActuationModel):
        _fill_actuation_data(self, model, constraint_models, actuation_model)


def _fill_actuation_data(ad: Any, model: pin.Model, constraint_models, actuation_model: Any) -> None:
    """Set the fields of the toolbox's ``ActuationData`` on ``ad``, sized for any robot."""
    nv = model.nv
    nm, nf = len(actuation_model.mot_ids_v), len(actuation_model.free_ids_v)
    ad.constraints_sizes = [_constraint_size(cm) for cm in constraint_models]
    nc = sum(ad.constraints_sizes)
    ad.Smot = np.zeros((nv, nm))
    ad.Smot[actuation_model.mot_ids_v, range(nm)] = 1
    ad.Sfree = np.zeros((nv, nf))
    ad.Sfree[actuation_model.free_ids_v, range(nf)] = 1
    ad.Jmot, ad.Jfree = np.zeros((nc, nm)), np.zeros((nc, nf))
    ad.pinvJfree = np.zeros((nf, nc))
    ad.Mmot = np.zeros((nm, nm))
    ad.dq, ad.dq_no = np.zeros((nv, nm)), np.zeros((nv, nm))
    ad.LJ = [np.zeros((n, nv)) for n in ad.constraints_sizes]
    ad.Jf_closed = np.zeros((6, nm))
    ad.vq, ad.vqmot, ad.vqfree, ad.vqmotfree = np.zeros(nv), np.zeros(nm), np.zeros(nf), np.zeros(nv)


def _complete_actuation_model(am: Any, ad: Any) -> None:
    """Add what the toolbox's 1.2.0 functions read on an actuation model: ``nv_mot``, ``nv_free``
    (its ``ActuationData`` reads them) and ``dq``, ``dq_no`` (``computeDerivative_dq_dqmot`` and
    ``inverseConstraintKinematicsSpeed`` read or write them on the model where they mean the data's:
    aliased to ``ad``'s arrays, so both read the same numbers)."""
    am.nv_mot, am.nv_free = len(am.mot_ids_v), len(am.free_ids_v)
    am.dq, am.dq_no = ad.dq, ad.dq_no


def _constraint_size(cm: pin.RigidConstraintModel) -> int:
    """Rows of a closure: ``residualSize()`` (Pinocchio 4) or ``size()`` (3.x)."""
    return int(cm.residualSize() if hasattr(cm, "residualSize") else cm.size())


# ----------------------------------------------------------------- the toolbox itself
_PACKAGE = "toolbox_parallel_robots"
#: The toolbox's modules that run on numpy, SciPy and pip's Pinocchio (the others, ``closures``,
#: ``projections`` and ``inverse_dynamics``, need casadi bindings of Pinocchio or qpsolvers).
TOOLBOX_MODULES = ("actuation", "actuation_model", "actuation_data", "jacobian", "freeze_joints", "constraints",
                   "forward_kinematics", "inverse_kinematics", "mounting")
_IMPORT_LOCK = threading.Lock()


class _PinocchioWithoutCasadi(types.ModuleType):
    """Pinocchio as the toolbox's ``actuation`` module sees it when Pinocchio has no casadi bindings:
    every name is Pinocchio's, and ``casadi.Model`` is an empty tuple of types, of which nothing is
    an instance (``mergeq``/``mergev`` test ``isinstance(model, pin.casadi.Model)``)."""

    casadi = types.SimpleNamespace(Model=())

    def __getattr__(self, name: str) -> Any:
        return getattr(pin, name)


def toolbox_installed() -> bool:
    """Whether ``toolbox-parallel-robots`` is installed (without importing it)."""
    if _PACKAGE in sys.modules:
        return sys.modules[_PACKAGE] is not None
    return importlib.util.find_spec(_PACKAGE) is not None


def toolbox() -> types.ModuleType:
    """The ``toolbox_parallel_robots`` package with :data:`TOOLBOX_MODULES` imported, runnable on
    pip's Pinocchio, which has no casadi bindings (the workarounds of ``docs/interop.md``):

    - bug 1: its ``__init__`` imports casadi, qpsolvers and ``pinocchio.casadi``: when that fails
      the package is entered without running it, and its modules are imported one by one;
    - bug 7: its ``constraints`` module imports ``casadi`` at the top but uses it only for casadi
      models: without casadi it is imported with a placeholder ``casadi`` module, removed right
      after (``sys.modules`` is left as it was);
    - bug 8: ``mergeq``/``mergev`` read ``pin.casadi.Model``, absent from pip's Pinocchio: the
      toolbox's ``actuation`` module gets a view of Pinocchio in which nothing is a casadi model.

    Nothing of Pinocchio itself is changed. The toolbox's functions are then called as they are.

    Raises:
        MissingExtraError: the toolbox is not installed (``pip install 'h4pin[interop]'``).
    """
    if not toolbox_installed():
        require(_PACKAGE, extra="interop", what="h4pin.io.interop.toolbox")
    with _IMPORT_LOCK:
        if _PACKAGE not in sys.modules:
            try:
                importlib.import_module(_PACKAGE)
            except ImportError:  # bug 1: enter the package without its __init__
                spec = importlib.util.find_spec(_PACKAGE)
                pkg = types.ModuleType(_PACKAGE)
                pkg.__path__ = list(spec.submodule_search_locations)
                pkg.__spec__ = spec
                pkg.__file__ = spec.origin
                sys.modules[_PACKAGE] = pkg
        pkg = sys.modules[_PACKAGE]
        for name in TOOLBOX_MODULES:
            full = f"{_PACKAGE}.{name}"
            if full not in sys.modules:
                if name == "constraints" and importlib.util.find_spec("casadi") is None:
                    _import_with_placeholder_casadi(full)  # bug 7
                else:
                    importlib.import_module(full)
            setattr(pkg, name, sys.modules[full])  # also those a failed __init__ left behind
        actuation = sys.modules[f"{_PACKAGE}.actuation"]
        if not hasattr(pin, "casadi") and actuation.pin is pin:  # bug 8
            actuation.pin = _PinocchioWithoutCasadi("pinocchio")
    return pkg


def _import_with_placeholder_casadi(full: str) -> None:
    placeholder = types.ModuleType("casadi", "h4pin placeholder: casadi is not installed")
    sys.modules["casadi"] = placeholder
    try:
        importlib.import_module(full)
    finally:
        if sys.modules.get("casadi") is placeholder:
            del sys.modules["casadi"]


# ----------------------------------------------------------------- closed-loop objects
class ClosedLoop(NamedTuple):
    """What the toolbox's closed-loop functions take, in their argument order.

    ``actuation_model`` and ``actuation_data`` are instances of the toolbox's own classes when
    it is installed (else h4pin's :class:`ActuationModel`, :class:`ActuationData`).
    """

    model: pin.Model
    data: pin.Data
    constraint_models: list
    constraint_datas: list
    actuation_model: Any
    actuation_data: Any


def _actuation(model: pin.Model, constraint_models: list, names: list[str],
               use_toolbox: bool | None) -> tuple[Any, Any]:
    _check_motor_names(model, names)
    if use_toolbox is None:
        use_toolbox = toolbox_installed()
    if use_toolbox:
        tb = toolbox()
        am = tb.actuation_model.ActuationModel(model, list(names))
        # The toolbox's ActuationData() cannot be built in 1.2.0 (size(), nv_mot - 6): an instance
        # of its class, with its fields filled as it means them.
        ad = tb.actuation_data.ActuationData.__new__(tb.actuation_data.ActuationData)
    else:
        am = ActuationModel(model, names)
        ad = ActuationData.__new__(ActuationData)
    _fill_actuation_data(ad, model, constraint_models, am)
    _complete_actuation_model(am, ad)
    return am, ad


def closed_loop(h4: H4, *, use_toolbox: bool | None = None) -> ClosedLoop:
    """The H4 as the toolbox takes it: its model, a fresh data, its 8 closures with fresh datas,
    and the actuation model and data of ``h4.actuated_joint_names`` (h4's own data are left alone).

    Args:
        h4: the robot.
        use_toolbox: True for the toolbox's own ``ActuationModel``/``ActuationData`` classes
            (completed so that every function of version 1.2.0 accepts them), False for h4pin's
            look-alikes; None (default) for the toolbox's when it is installed.

    Raises:
        MissingExtraError: ``use_toolbox=True`` and the toolbox is not installed.
    """
    cms = list(h4.constraint_models)
    am, ad = _actuation(h4.model, cms, list(h4.actuated_joint_names), use_toolbox)
    return ClosedLoop(h4.model, h4.model.createData(), cms, [cm.createData() for cm in cms], am, ad)


def closed_loop_from_sidecar(urdf_path: str | Path, sidecar_path: str | Path | None = None, *,
                             use_toolbox: bool | None = None) -> ClosedLoop:
    """A URDF and its Extended-URDF sidecar as the toolbox's loader builds them (``completeRobotLoader``
    of example-parallel-robots, not on PyPI), through h4pin's one sidecar reader
    (:mod:`h4pin.mechanism.sidecar`): Pinocchio's URDF parser (fixed base), the ``joint_name`` /
    ``joint_type`` conversions, each sidecar pair of frames as a ``RigidConstraintModel``
    (``CONTACT_3D`` for ``3D``, ``CONTACT_6D`` for ``6D``) between the frames' parent joints at the
    frames' placements in the LOCAL frame, and the actuation model of ``name_mot``.

    Args:
        urdf_path: the URDF file.
        sidecar_path: its sidecar; default: the same path with the suffix ``.yaml``.
        use_toolbox: as for :func:`closed_loop`.

    Raises:
        MissingExtraError: PyYAML is not installed (the ``interop`` extra).
        MalformedURDFError: as :func:`h4pin.mechanism.sidecar.read` and :func:`~h4pin.mechanism.sidecar.build`.
    """
    from h4pin.mechanism import sidecar

    urdf_path = Path(urdf_path)
    side = sidecar.read(urdf_path.with_suffix(".yaml") if sidecar_path is None else sidecar_path)
    model, cms = sidecar.build(urdf_path, side)
    am, ad = _actuation(model, cms, list(side.motors), use_toolbox)
    return ClosedLoop(model, model.createData(), cms, [cm.createData() for cm in cms], am, ad)


# ----------------------------------------------------------------- workarounds
def _configuration(model: pin.Model, q: Any) -> np.ndarray:
    try:
        q = np.asarray(q, float)
    except (TypeError, ValueError):
        raise ParameterError(f"q: expected {model.nq} numbers, got {q!r}") from None
    if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
        raise ParameterError(f"q: expected a finite configuration of shape ({model.nq},), got shape {q.shape}")
    return q


def prime(loop: ClosedLoop, q: np.ndarray) -> None:
    """Forward kinematics and each closure's ``calc`` at ``q`` (nq,) in ``loop.data``: run it before
    the toolbox's ``computeClosedLoopFrameJacobian`` or ``inverseConstraintKinematicsSpeed``, which
    use the contact placements of whatever configuration was computed last (bug 2).

    Raises:
        ParameterError: ``q`` has the wrong size.
    """
    q = _configuration(loop.model, q)
    pin.forwardKinematics(loop.model, loop.data, q)
    for cm, cd in zip(loop.constraint_models, loop.constraint_datas, strict=True):
        constraint_calc(cm, loop.model, loop.data, cd)


def local_to_world(loop: ClosedLoop, frame: str | int) -> np.ndarray:
    """(6, 6) map of a twist in the frame's LOCAL axes (the toolbox's Jacobians and velocity IK,
    bug 3) to world-aligned axes at the frame's origin: ``blockdiag(R, R)``, R the frame's
    orientation in ``loop.data`` (after :func:`prime`). Its transpose maps back.

    Raises:
        ParameterError: ``frame`` is not a frame of the model.
    """
    rot = pin.updateFramePlacement(loop.model, loop.data, frame_id(loop.model, frame)).rotation
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = rot
    return out


class Seed(np.ndarray):
    """A configuration that the toolbox's ``closedLoopForwardKinematicsScipy`` accepts as ``q_prec``
    on numpy 2 (it tests ``q_prec == []``, which numpy 2 refuses for an array: bug 9). Equal to
    nothing that is an empty list; otherwise a plain array. Make one with :func:`seed`."""

    def __eq__(self, other: object) -> Any:
        if isinstance(other, list) and not other:
            return False
        return super().__eq__(other)

    def __ne__(self, other: object) -> Any:
        if isinstance(other, list) and not other:
            return True
        return super().__ne__(other)

    __hash__ = None


def seed(q: np.ndarray) -> Seed:
    """``q`` (nq,) as a :class:`Seed` for the toolbox's forward kinematics (a copy)."""
    return np.array(q, dtype=float).view(Seed)


def plate_pose(h4: H4, q: np.ndarray) -> np.ndarray:
    """The pose [x, y, z, theta] (m, rad) of a configuration (nq,): D's position and the central
    bar's rotation theta about z, in h4pin's convention ``R = exp(tilt) Rz(theta)`` with the tilt
    normal to z (a tilt arises only with inexact parallelograms). The plate's quaternion is
    normalised first (the toolbox's forward kinematics returns it unnormalised: bug 10).

    Raises:
        ParameterError: ``q`` has the wrong size or is not finite.
    """
    q = pin.normalize(h4.model, _configuration(h4.model, q))
    data = h4.model.createData()
    pin.framesForwardKinematics(h4.model, data, q)
    plate = h4.model.getJointId("plate")
    r = data.oMi[plate].rotation @ h4.model.jointPlacements[plate].rotation.T  # central bar w.r.t. its reference
    # h4pin's convention: r = exp(tilt) Rz(theta), tilt normal to z (the least rotation taking z to r z).
    axis = np.cross([0.0, 0.0, 1.0], r[:, 2])
    sin = np.linalg.norm(axis)
    if sin > 0:
        r = pin.exp3(axis / sin * np.arctan2(sin, r[2, 2])).T @ r
    return np.r_[data.oMf[h4.frames["D"]].translation, np.arctan2(r[1, 0], r[0, 0])]


def closed_configuration(h4: H4, q: np.ndarray) -> np.ndarray:
    """The exactly closed configuration (nq,) with the actuator angles of ``q`` (nq,), on the assembly
    nearest ``q``: h4pin's forward geometry (Newton to 1e-13) from :func:`plate_pose` of ``q`` (or
    from its default guess if Newton fails from there), then ``h4.configuration``. Use it on the
    result of the toolbox's forward kinematics (bug 10).

    Raises:
        ParameterError: ``q`` has the wrong size or is not finite.
        ConvergenceError: Newton did not converge from either guess.
    """
    q = _configuration(h4.model, q)
    q_act = q[[h4.model.joints[h4.model.getJointId(n)].idx_q for n in h4.actuated_joint_names]]
    try:
        pose = h4.forward_geometry(q_act, guess=plate_pose(h4, q))
    except ConvergenceError:  # e.g. the symmetric robot at its centre, a slow Newton from some guesses
        pose = h4.forward_geometry(q_act)
    return h4.configuration(pose, check=False)


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
    fid = frame_id(model, frame)
    q = _configuration(model, q)
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
    "Seed",
    "TOOLBOX_MODULES",
    "closed_configuration",
    "closed_loop",
    "closed_loop_frame_jacobian",
    "closed_loop_from_sidecar",
    "closure_frame_pairs",
    "extended_urdf_yaml",
    "local_to_world",
    "plate_pose",
    "prime",
    "seed",
    "toolbox",
    "toolbox_installed",
]
