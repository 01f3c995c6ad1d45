# SPDX-License-Identifier: Apache-2.0
"""The H4 for MuJoCo (``mujoco`` extra): an MJCF built with ``mujoco.MjSpec``, loops closed by
8 ``connect`` equalities, 4 motors, a floor, a light and a camera.

MuJoCo reads h4pin's URDF but drops its ``<constraint>`` elements (``neq = 0``): the legs then
hang loose. :func:`spec` builds the robot with MuJoCo's own model-editing API instead, from the
robot's URDF (:attr:`H4.urdf <h4pin.H4>`) and its Pinocchio model; MuJoCo compiles and writes it
(:func:`to_mjcf`). What the file holds (``docs/mujoco.md``):

- one body per URDF link, named after it, in the URDF's tree under ``base_link``: a single tree,
  which Pinocchio's MJCF reader needs (it reads only the world's first body);
- every URDF joint as a MuJoCo joint of the same name: revolute -> ``hinge`` whose ``range`` is
  the URDF limits (``model.lowerPositionLimit``/``upperPositionLimit``; a joint without finite
  limits, e.g. ``continuous``, stays unlimited). The plate's floating joint becomes three
  ``slide`` joints ``plate_x``, ``plate_y``, ``plate_z`` and a ``ball`` joint ``plate`` in
  ``central_bar`` (MuJoCo allows a ``free`` joint only in a body of the world, which would split
  the tree). MuJoCo's ``qpos`` is then Pinocchio's ``q`` with each quaternion written w first
  (:func:`qpos`), joint by joint in the same order;
- inertias: each link's ``<inertial>`` of the URDF (mass, centre of mass, full inertia tensor in
  the link frame). Massless links (the named frames ``P_i``, ``A_ij``, ``B_ij``, ``D``,
  ``bar_ij_end``, ...) are jointless bodies without inertia, welded to their parent: MuJoCo
  needs mass only in bodies that move on their own joints. Each also carries a site of its name
  at its origin, for sensors;
- bodies placed as in the URDF (every joint at zero, MuJoCo's ``qpos0``), which does not close
  the loops: the closed configuration is the keyframe :data:`KEYFRAME` (``q0``, actuators at
  45 deg), to start from with ``mj_resetDataKeyframe``. No joint has a ``ref``, so the file means
  the same to any MJCF reader (Pinocchio's ``buildModelFromMJCF`` gives the URDF's model);
- each ``<constraint>`` of the URDF as ``connect`` between two sites, ``<closure>_parent`` on the
  ``<parent>`` link (at ``parent_origin``) and ``<closure>_child`` on the ``<child>`` link, named
  after the closure; stiff constraint parameters (:data:`SOLREF`, :data:`SOLIMP`) and a
  :data:`TIMESTEP` of 0.1 ms keep the loops closed;
- a ``motor`` (torque, N.m, gear 1) on each actuated joint, in leg order, ``ctrlrange`` = the
  URDF effort limit (``model.effortLimit``);
- the URDF's visual primitives (box, cylinder, sphere, capsule; meshes are left out) as geoms
  that collide with nothing (``contype = conaffinity = 0``) and weigh nothing (density 0);
- a floor plane below every pose the legs can reach, a light above the robot and a camera
  :data:`CAMERA` looking at it.

:func:`elastic_spec` (``to_mjcf(h4, elastic=True)``, ``h4pin export --mjcf PATH --elastic``) builds the
elastic robot of :func:`h4pin.elastic.elastic_model` with the same builder: every virtual elastic
joint a ``hinge`` or ``slide`` with its ``stiffness``, ``springref`` 0 and a small
stiffness-proportional damping (:data:`DAMPING`), the actuators locked (their joints removed), and
closures stiff enough for the springs (:data:`ELASTIC_SOLREF`, :data:`ELASTIC_SOLIMP` at
:data:`ELASTIC_TIMESTEP`): its static deflection and first frequency in MuJoCo equal
:func:`h4pin.compliance` and :func:`h4pin.elastic.modes` (``tests/test_mjcf_elastic.py``).

The lowest MuJoCo this works with is :data:`MIN_MUJOCO` (the first whose ``MjSpec`` has a usable
``option`` and site ``connect``). ``h4pin export --mjcf PATH`` writes the file; the shipped
``mjcf/h4_<variant>.xml`` (:func:`mjcf_path`) are written by ``scripts/generate_urdf.py``.
"""

from __future__ import annotations

import dataclasses
import os
import re
import xml.etree.ElementTree as ET
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.errors import ParameterError
from h4pin.files import write_text
from h4pin.mechanism import mjcf_writer as mw
from h4pin.mechanism.mjcf_writer import (
    ARMATURE_STEPS,
    CHAIN_MASS,
    DAMPING,
    ELASTIC_SOLIMP,
    ELASTIC_SOLREF,
    ELASTIC_TIMESTEP,
    KEYFRAME,
    MIN_MUJOCO_ELASTIC,
    require_mujoco,
    set_spring,
)

#: MuJoCo time step (s).
TIMESTEP = 1e-4
#: Constraint softness of the closures: solref (time constant s, damping ratio) and solimp.
SOLREF = (0.0005, 1.0)
SOLIMP = (0.999, 0.9999, 0.001, 0.5, 2.0)
#: Name of the camera looking at the robot.
CAMERA = "overview"
#: Lowest MuJoCo version :func:`spec` works with (``pyproject.toml``'s ``mujoco`` extra; tested in CI).
MIN_MUJOCO = "3.2.4"
#: Suffixes of the three slide joints that carry a floating joint's translation.
SLIDES = ("_x", "_y", "_z")
_MARGIN = 0.05  # m, floor below the lowest reachable point


def mjcf_dir() -> Path:
    """Folder of the shipped MJCF files (inside the installed package, or the repo's ``mjcf/``)."""
    packaged = Path(str(resources.files("h4pin"))) / "mjcf"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent.parent / "mjcf"


def mjcf_path(variant: str) -> Path:
    """Path of the shipped MJCF of variant ``variant`` (``mjcf/h4_<variant>.xml``).

    Raises:
        ParameterError: unknown variant (the message lists them).
    """
    from h4pin.description.params import VARIANTS

    if variant not in VARIANTS:
        raise ParameterError(f"variant: unknown H4 variant {variant!r}; available: {', '.join(sorted(VARIANTS))}")
    return mjcf_dir() / f"h4_{variant}.xml"


def _mujoco(least: str = MIN_MUJOCO, what: str = "the MuJoCo export (h4pin.io.mjcf)") -> Any:
    """The ``mujoco`` module, at least ``least`` (:data:`MIN_MUJOCO`; :func:`require_mujoco`)."""
    return require_mujoco(least, what)


def writer_version(text: str) -> str | None:
    """The MuJoCo version named in the comment :func:`to_mjcf` writes at the top of a file (None
    if there is none): MuJoCo's XML writer lays files out a little differently across versions."""
    found = re.search(r"written by h4pin\.io\.mjcf through MuJoCo (\S+)'s MjSpec", text[:2000])
    return found.group(1) if found else None


def _urdf_inertials(urdf_text: str) -> dict[str, tuple[float, np.ndarray, np.ndarray]]:
    """Each URDF link's ``<inertial>``: mass, centre of mass and inertia tensor in the link frame."""

    def vector(elem: ET.Element | None, key: str) -> np.ndarray:
        return np.array([float(v) for v in (elem.get(key, "0 0 0") if elem is not None else "0 0 0").split()])

    out = {}
    for link in ET.fromstring(urdf_text).findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass = inertial.find("mass")
        origin = inertial.find("origin")
        elem = inertial.find("inertia")
        g = {k: float(elem.get(k, "0")) if elem is not None else 0.0
             for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        tensor = np.array([[g["ixx"], g["ixy"], g["ixz"]], [g["ixy"], g["iyy"], g["iyz"]],
                           [g["ixz"], g["iyz"], g["izz"]]])
        rot = pin.rpy.rpyToMatrix(vector(origin, "rpy"))
        out[link.get("name", "")] = (float(mass.get("value", "0")) if mass is not None else 0.0,
                                     vector(origin, "xyz"), rot @ tensor @ rot.T)
    return out


def _links(model: pin.Model) -> tuple[list[int], dict[int, int], dict[int, int]]:
    """URDF links as Pinocchio BODY frames, parents before children and siblings in file order:
    (frame ids, parent link frame of each (0, the universe, for the root), the Pinocchio joint a
    link moves on, for those that have one)."""
    bodies = [i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY]
    parent, own_joint = {}, {}
    for b in bodies:
        up = model.frames[b].parentFrame
        if model.frames[up].type == pin.FrameType.JOINT:
            own_joint[b] = model.frames[up].parentJoint
        while up != 0 and model.frames[up].type != pin.FrameType.BODY:
            up = model.frames[up].parentFrame
        parent[b] = up
    ordered: list[int] = []
    placed = {0}
    while len(ordered) < len(bodies):
        ready = [b for b in bodies if b not in placed and parent[b] in placed]
        if not ready:
            raise ParameterError("h4: the URDF's links do not form a tree")
        ordered += ready
        placed.update(ready)
    return ordered, parent, own_joint


def _geom_shape(mujoco: Any, geom: Any) -> tuple[Any, list[float]] | None:
    kind = type(geom).__name__
    if kind == "Box":
        return mujoco.mjtGeom.mjGEOM_BOX, mw.floats(geom.halfSide)
    if kind == "Cylinder":
        return mujoco.mjtGeom.mjGEOM_CYLINDER, [float(geom.radius), float(geom.halfLength), 0.0]
    if kind == "Capsule":
        return mujoco.mjtGeom.mjGEOM_CAPSULE, [float(geom.radius), float(geom.halfLength), 0.0]
    if kind == "Sphere":
        return mujoco.mjtGeom.mjGEOM_SPHERE, [float(geom.radius), 0.0, 0.0]
    return None


def _look_at(eye: np.ndarray, target: np.ndarray) -> list[float]:
    """Quaternion of a MuJoCo camera at ``eye`` looking at ``target`` (camera -z forward, +y up)."""
    back = (eye - target) / np.linalg.norm(eye - target)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    return mw.quaternion(np.column_stack([right, np.cross(back, right), back]))


def _closed(h4: Any, q: np.ndarray | None) -> np.ndarray:
    model = h4.model
    if q is None:
        if h4.q0 is None:
            raise ParameterError("h4: the robot does not assemble at its centre pose (h4.q0 is None); pass q")
        q = h4.q0
    q = np.asarray(q, float)
    if q.shape != (model.nq,):
        raise ParameterError(f"q: expected shape ({model.nq},), got {q.shape}")
    gap = float(np.max(np.abs(h4.closure_residuals(q)))) if len(h4.constraint_models) else 0.0
    if not gap <= 1e-9:
        raise ParameterError(f"q: does not close the loops (residual {gap:.2e} m)")
    return q


def spec(h4: Any, name: str | None = None, q: np.ndarray | None = None) -> Any:
    """The robot as a ``mujoco.MjSpec`` (not compiled): links, joints with limits, inertias,
    closures, motors, keyframe ``q0``, floor, light and camera (see the module's description).

    Args:
        h4: an :class:`h4pin.H4`.
        name: the model's name (default: the Pinocchio model's, else ``"h4"``).
        q: the closed configuration the keyframe holds (default :attr:`H4.q0 <h4pin.H4>`).

    Raises:
        MissingExtraError: MuJoCo is not installed.
        ParameterError: no closed configuration (``h4.q0`` is None and no ``q``), ``q`` does not
            close the loops (1e-9 m), or the URDF has a joint MuJoCo has no counterpart of here.
    """
    return _build(h4, name, _closed(h4, q), None)


def elastic_spec(h4: Any, name: str | None = None, q: np.ndarray | None = None, *, damping: float = DAMPING,
                 solref: Any = ELASTIC_SOLREF, solimp: Any = ELASTIC_SOLIMP, timestep: float = ELASTIC_TIMESTEP,
                 servo: bool = False, payload: float = 0.0) -> Any:
    """The elastic H4 (:func:`h4pin.elastic.elastic_model`) as a ``mujoco.MjSpec`` (not compiled).

    The robot of :func:`spec`, with every virtual elastic joint of the elastic model as a MuJoCo
    ``hinge`` or ``slide`` joint of the same name carrying its spring: ``stiffness`` (N.m/rad or
    N/m, :attr:`ElasticH4.stiffness <h4pin.elastic.h4.ElasticH4>`), ``springref`` 0 (every virtual
    joint reads 0 at an assembled configuration, so the springs are at rest there) and
    ``damping = damping * stiffness`` (stiffness-proportional damping: a mode of frequency f gets
    the damping ratio ``pi f damping``). The actuators are locked: their joints are removed, each
    forearm welded to the base at its angle in ``q`` (a file holds the robot locked at one
    configuration). Needs MuJoCo >= :data:`MIN_MUJOCO_ELASTIC`. ``actuator_i_elastic``, the
    actuator's servo and forearm bending spring (coaxial with the actuator), is the forearm's own
    joint, so that the forearm turns on it as in
    :func:`h4pin.elastic.modes`; every other virtual joint has a body of its own, named after it
    (mass :data:`CHAIN_MASS`, next to nothing), nested in chain order, the last carrying what the
    chain carries in the elastic model (a forearm's tip, a bar's end and its closure site, ...).
    Slides along one line through one point (a bar's stretch and, with ``ball_radial``, its two
    ball joints) are one slide of their series stiffness, named after the softest
    (``bar_ij_tension``): the same statics, and a chain MuJoCo integrates stably. A
    virtual joint that moves no mass (a bar's stretch) gets the armature
    ``stiffness * (ARMATURE_STEPS * timestep)^2`` (kg or kg.m^2), for a positive-definite
    joint-space inertia and a spring MuJoCo's explicit integration of stiffness keeps stable. No
    motor (nothing is actuated). The 8 closures are ``connect`` equalities with ``solref`` and
    ``solimp``; the defaults add less than 0.1 % to the compliance at the default ``timestep``
    (``docs/mujoco.md``). Gravity is on: the springs sag under the robot's weight.

    Args:
        h4: an :class:`h4pin.H4` (its elements, ``h4.elements``, become joints too).
        name: the model's name (default: the Pinocchio model's, else ``"h4"``).
        q: the robot's closed configuration (Pinocchio's, ``h4.configuration(pose)``): the
            actuators' locked angles, and the keyframe ``q0`` with every virtual joint at 0
            (default :attr:`H4.q0 <h4pin.H4>`).
        damping: stiffness-proportional damping coefficient (s), >= 0.
        solref, solimp: the closures' constraint parameters (MuJoCo's ``solref`` (time constant
            s, damping ratio) and ``solimp``).
        timestep: MuJoCo time step (s), > 0.
        servo: keep the actuators' joints, driven by position servos instead of locked: each
            actuator joint gets a ``position``-type actuator ``<joint>_servo`` (ctrl: the angle,
            rad) of gain the ``actuator_i_elastic`` spring's stiffness (the servo and the
            forearm's bending, which then has no joint of its own), and a ``velocity``-type
            ``<joint>_damper`` (ctrl: the angle's rate, rad/s) of gain ``damping * stiffness``:
            the same spring and damping, on the error to a commanded motion. The keyframe's
            controls hold ``q``. For driving a motion (``h4pin export --elastic --servo``,
            :func:`h4pin.studies.elastic_cycle.mujoco_cycle`).
        payload: kg, a point mass at D (a body ``payload`` on the central bar, no inertia of its
            own), as the studies' ``payload``; 0: none.

    Raises:
        MissingExtraError: MuJoCo is not installed, or older than :data:`MIN_MUJOCO_ELASTIC`.
        ParameterError: as :func:`spec`, or a damping or a time step that is not a real number
            within its plausible range (:func:`h4pin.mechanism.mjcf_writer.check_settings`).
    """
    from h4pin.elastic import elastic_model

    _mujoco(MIN_MUJOCO_ELASTIC, "the elastic MuJoCo export (h4pin.io.mjcf.elastic_spec)")

    damping, timestep = mw.check_settings(damping, timestep)
    payload = float(limits.check_range("payload", payload, "payload"))
    q = _closed(h4, q)
    plan = _plan(h4, elastic_model(h4), q, float(damping), float(timestep), bool(servo))
    s = _build(h4, name, q, plan, (mw.floats(solref), mw.floats(solimp), float(timestep)))
    if payload > 0:
        site = s.site("D")
        body = site.parent.add_body()
        body.name, body.pos, body.mass = "payload", site.pos, payload
        body.inertia, body.explicitinertial = [0.0] * 3, True
    return s


@dataclasses.dataclass
class _Chain:
    """A chain of virtual joints of the elastic model: a MuJoCo body each, nested (``in_link``: in its link's body)."""

    link: int  # rigid model's frame id of the link whose body is this body's parent (or holds the joints)
    joints: list[tuple[str, bool, np.ndarray, np.ndarray]]  # (name, revolute, pos, axis) in the link's frame
    in_link: bool = False  # the joints go into the link's own body (a locked actuator's spring)


@dataclasses.dataclass
class _Plan:
    """How the elastic model differs from the rigid one, in MJCF terms."""

    em: Any
    q_em: np.ndarray  # the elastic model's configuration (virtual joints at 0)
    locked: set[int]  # rigid joint ids removed (actuators)
    chains: dict[int, _Chain]  # elastic joint id of a chain's end -> chain
    moved: dict[int, int]  # link frame id -> the chain (end joint id) whose body is its parent
    sites: dict[str, tuple[int, np.ndarray]]  # closure site -> (chain, position in the chain's frame)
    stiffness: dict[str, float]
    damping: float
    armature: dict[str, float]
    servo: dict[str, float] = dataclasses.field(default_factory=dict)  # actuated joint -> servo stiffness


def _plan(h4: Any, em: Any, q: np.ndarray, damping: float, timestep: float, servo: bool = False) -> _Plan:
    """Where each virtual joint of the elastic model ``em`` goes in the MJCF tree of ``h4``."""
    from h4pin.elastic.modal import mass_model

    rigid, m = h4.model, em.model
    zero = rigid.createData()
    pin.framesForwardKinematics(rigid, zero, pin.neutral(rigid))
    ezero = m.createData()
    q_ref = np.zeros(m.nq)
    q_ref[em.q_index] = pin.neutral(rigid)
    pin.forwardKinematics(m, ezero, q_ref)
    frames, parent, own_joint = _links(rigid)
    virtual = {j for j in range(1, m.njoints) if not rigid.existJointName(m.names[j])}
    link_of = {0: next(f for f in frames if parent[f] == 0)}  # elastic joint -> link whose body it moves
    for f, j in own_joint.items():
        link_of[int(m.getJointId(rigid.names[j]))] = f
    locked = set() if servo else {int(rigid.getJointId(n)) for n in em.locked}
    servos: dict[str, float] = {}
    heavy = mass_model(em)
    mass = {j: sum(heavy.inertias[k].mass for k in m.subtrees[j]) for j in virtual}

    chains: dict[int, _Chain] = {}
    for start in sorted(j for j in virtual if m.parents[j] not in virtual):
        names, j = [], start
        while True:
            names.append(j)
            nxt = [k for k in range(1, m.njoints) if m.parents[k] == j and k in virtual]
            if not nxt:
                break
            j = nxt[0]
        link = link_of[m.parents[start]]
        world = zero.oMf[link]
        joints = []
        for k in names:
            jm, place = m.joints[k], ezero.oMi[k]
            axis = place.rotation @ mw.motion(jm)[3:] if mw.is_revolute(jm) else place.rotation @ mw.motion(jm)[:3]
            joints.append((m.names[k], mw.is_revolute(jm), world.actInv(place.translation), world.rotation.T @ axis))
        up = rigid.names[rigid.frames[link].parentJoint] if link in own_joint else None
        if servo and up in em.locked and joints[0][0] == f"{up}_elastic":
            servos[up] = em.stiffness[joints[0][0]]  # the servo's position gain: the spring itself
            chains[names[-1]] = _Chain(link, joints[1:], in_link=len(joints) == 1)
            continue
        if up is not None and own_joint[link] in locked and joints[0][0] == f"{up}_elastic":
            chains[start] = _Chain(link, joints[:1], in_link=True)  # the forearm turns on it
            if len(joints) == 1:
                continue
            joints = joints[1:]
        chains[names[-1]] = _Chain(link, joints)

    def carrier(f: int) -> int:
        return int(m.frames[m.getFrameId(rigid.frames[f].name, pin.FrameType.BODY)].parentJoint)

    moved = {}
    for f in frames:
        anchor = int(m.parents[carrier(f)]) if f in own_joint else carrier(f)
        if parent[f] != 0 and carrier(parent[f]) != anchor:
            if anchor not in chains:
                raise ParameterError(f"h4: link {rigid.frames[f].name!r} hangs from virtual joint {m.names[anchor]!r}, "
                                     "not the end of a chain")
            moved[f] = anchor
    sites = {}
    for c, cm in zip(_closure_list(h4), em.constraint_models, strict=True):
        for side, link_name, xyz, joint in ((1, c.parent, c.parent_xyz, cm.joint1_id),
                                            (2, c.child, c.child_xyz, cm.joint2_id)):
            if joint in virtual:
                f = int(rigid.getFrameId(link_name, pin.FrameType.BODY))
                here = zero.oMf[f].act(np.asarray(xyz, float))
                sites[f"{c.name}_{'parent' if side == 1 else 'child'}"] = (
                    int(joint), zero.oMf[chains[int(joint)].link].actInv(here))
    stiffness = dict(em.stiffness)
    for chain in chains.values():
        chain.joints = _in_series(chain.joints, stiffness)
    kept = {j[0] for chain in chains.values() for j in chain.joints}
    armature = {m.names[k]: stiffness[m.names[k]] * (ARMATURE_STEPS * timestep) ** 2
                for k in virtual if not mass[k] > 0 and m.names[k] in kept}
    q_em = np.zeros(m.nq)
    q_em[em.q_index] = q
    return _Plan(em, q_em, locked, chains, moved, sites, stiffness, damping, armature, servos)


def _in_series(joints: list[tuple[str, bool, np.ndarray, np.ndarray]], stiffness: dict[str, float]
               ) -> list[tuple[str, bool, np.ndarray, np.ndarray]]:
    """A chain's joints with every run of slides along one line through one point (a bar's two
    ball joints and its stretch) made one slide of their series stiffness, named after its
    softest member (``stiffness`` updated): the same statics, and no stiff massless slide beside a
    soft one, which MuJoCo cannot integrate stably."""
    out: list[tuple[str, bool, np.ndarray, np.ndarray]] = []
    for joint in joints:
        name, revolute, pos, axis = joint
        if out and not revolute and not out[-1][1] and np.allclose(out[-1][2], pos, rtol=0, atol=1e-12) \
                and np.linalg.norm(np.cross(out[-1][3], axis)) < 1e-12 * np.linalg.norm(axis):
            last = out[-1][0]
            series = 1.0 / (1.0 / stiffness[last] + 1.0 / stiffness[name])
            keep = last if stiffness[last] <= stiffness[name] else name
            stiffness[keep] = series
            out[-1] = (keep, False, out[-1][2], out[-1][3] if keep == last else axis)
            continue
        out.append(joint)
    return out


def _spring(mujoco: Any, j: Any, plan: _Plan) -> None:
    """Stiffness, rest position, damping and armature of virtual joint ``j`` (MjsJoint)."""
    k = plan.stiffness[j.name]
    set_spring(mujoco, j, k, plan.damping * k, 0.0, plan.armature.get(j.name, 0.0))


def _build(h4: Any, name: str | None, q: np.ndarray, plan: _Plan | None,
           settings: tuple[list[float], list[float], float] | None = None) -> Any:
    """The MjSpec of :func:`spec` (``plan`` None) or :func:`elastic_spec` (its :class:`_Plan`)."""
    mujoco = _mujoco()
    model = h4.model
    data = model.createData()  # the closed configuration: keyframe, scene
    pin.framesForwardKinematics(model, data, q)
    zero = model.createData()  # the URDF's zero configuration: body placements
    pin.framesForwardKinematics(model, zero, pin.neutral(model))
    lock = zero
    if plan is not None:  # the locked actuators at their angles in q, every other joint at zero
        q_lock = pin.neutral(model)
        for j in plan.locked:
            sl = slice(model.joints[j].idx_q, model.joints[j].idx_q + model.joints[j].nq)
            q_lock[sl] = q[sl]
        lock = model.createData()
        pin.framesForwardKinematics(model, lock, q_lock)
    frames, parent, own_joint = _links(model)
    inertials = _urdf_inertials(h4.urdf)
    solref, solimp, timestep = settings or (list(SOLREF), list(SOLIMP), TIMESTEP)

    s = mujoco.MjSpec()
    s.modelname = name or model.name or "h4"
    compiler = getattr(s, "compiler", s)  # MuJoCo >= 3.2.5 groups these under spec.compiler
    compiler.degree = False
    s.option.timestep = timestep
    s.option.gravity = mw.floats(model.gravity.linear)
    s.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST

    geoms: dict[int, list[Any]] = {}
    for obj in h4.visual_model.geometryObjects:
        geoms.setdefault(obj.parentFrame, []).append(obj)
    closures = _closure_sites(h4)

    bodies: dict[int, Any] = {0: s.worldbody}
    chain_bodies: dict[int, Any] = {}

    def chain_body(end: int) -> Any:
        assert plan is not None
        if plan.chains[end].in_link:
            return bodies[plan.chains[end].link]
        if end not in chain_bodies:
            body = bodies[plan.chains[end].link]
            for jname, revolute, pos, axis in plan.chains[end].joints:  # one body per joint, at the link's frame
                body = body.add_body()
                body.name = jname
                body.mass, body.inertia = CHAIN_MASS[0], [CHAIN_MASS[1]] * 3  # MuJoCo's least for a moving body
                body.ipos = [0.0, 0.0, 0.0]  # (the XML writer leaves out an inertial without it)
                if hasattr(body, "explicitinertial"):
                    body.explicitinertial = True
                j = body.add_joint()
                j.name, j.pos, j.axis = jname, mw.floats(pos), mw.floats(axis)
                j.type = mujoco.mjtJoint.mjJNT_HINGE if revolute else mujoco.mjtJoint.mjJNT_SLIDE
                _spring(mujoco, j, plan)
            chain_bodies[end] = body
        return chain_bodies[end]

    for f in frames:
        frame, up = model.frames[f], parent[f]
        if plan is not None and f in plan.moved:  # on a chain's body, whose frame is its link's
            body, there = chain_body(plan.moved[f]).add_body(), plan.chains[plan.moved[f]].link
        else:
            body, there = bodies[up].add_body(), up
        bodies[f] = body
        body.name = frame.name
        place = lock.oMf[f] if there == 0 else lock.oMf[there].actInv(lock.oMf[f])
        joint_id = own_joint.get(f)
        if plan is not None and joint_id in plan.locked:
            joint_id = None  # locked: the link is welded at its angle
            for chain in plan.chains.values():
                if chain.in_link and chain.link == f:
                    jname, _, pos, axis = chain.joints[0]
                    j = body.add_joint()
                    j.name, j.type, j.pos, j.axis = jname, mujoco.mjtJoint.mjJNT_HINGE, mw.floats(pos), mw.floats(axis)
                    _spring(mujoco, j, plan)
        if joint_id is not None:
            _add_joint(mujoco, body, model, frame, joint_id)
        body.pos, body.quat = mw.floats(place.translation), mw.quaternion(place.rotation)
        mass, com, tensor = inertials.get(frame.name, (0.0, np.zeros(3), np.zeros((3, 3))))
        if mass > 0:
            body.mass, body.ipos = mass, mw.floats(com)
            body.fullinertia = mw.floats([tensor[0, 0], tensor[1, 1], tensor[2, 2],
                                        tensor[0, 1], tensor[0, 2], tensor[1, 2]])
            if hasattr(body, "explicitinertial"):
                body.explicitinertial = True
        elif joint_id is None and up != 0 and not (plan is not None and own_joint.get(f) in plan.locked):
            site = body.add_site()
            site.name, site.size, site.group = frame.name, [0.004, 0.0, 0.0], 2
        for site_name, xyz in closures.get(frame.name, []):
            if plan is not None and site_name in plan.sites:
                end, xyz = plan.sites[site_name]
                site = chain_body(end).add_site()
            else:
                site = body.add_site()
            site.name, site.pos, site.size, site.group = site_name, mw.floats(xyz), [0.003, 0.0, 0.0], 3
        _add_geoms(mujoco, body, frame, geoms.get(f, []))
    if plan is not None:
        for end in plan.chains:
            if not plan.chains[end].in_link:
                chain_body(end)  # a chain that carries nothing still has its springs

    _add_closures(mujoco, s, h4, solref, solimp)
    if plan is None:
        _add_actuators(mujoco, s, h4)
    elif plan.servo:
        _add_servos(mujoco, s, h4, plan)
    _scene(model, s, mujoco, data)
    key = s.add_key()
    key.name = KEYFRAME
    key.qpos = mw.floats(qpos(h4, q)) if plan is None else mw.floats(_named_qpos(s.compile(), plan.em.model, plan.q_em))
    if plan is not None and plan.servo:
        angles = [q[model.joints[model.getJointId(n)].idx_q] for n in h4.actuated_joint_names]
        key.ctrl = mw.floats(angles + [0.0] * len(angles))
    return s


def _add_servos(mujoco: Any, s: Any, h4: Any, plan: _Plan) -> None:
    """A position servo and a velocity damper on each actuated joint (:func:`elastic_spec`, ``servo``)."""
    for kind in ("servo", "damper"):
        for jname in h4.actuated_joint_names:
            kp = plan.servo[jname]
            gain = kp if kind == "servo" else plan.damping * kp
            a = s.add_actuator()
            a.name, a.trntype, a.target = f"{jname}_{kind}", mujoco.mjtTrn.mjTRN_JOINT, jname
            a.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            a.gaintype, a.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
            a.gainprm = [gain] + [0.0] * 9
            a.biasprm = [0.0, -gain, 0.0] + [0.0] * 7 if kind == "servo" else [0.0, 0.0, -gain] + [0.0] * 7
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


def _add_joint(mujoco: Any, body: Any, model: pin.Model, frame: Any, joint_id: int) -> None:
    """The MuJoCo joints of Pinocchio joint ``joint_id`` on ``body`` (its child link's frame):
    a hinge (with its limits) or a floating joint's three slides and ball."""
    joint, jname = model.joints[joint_id], model.names[joint_id]
    if mw.is_free(joint):
        if not frame.placement.isIdentity(1e-12):
            raise ParameterError(f"h4: link '{frame.name}' must sit at the origin of its floating joint")
        for k, suffix in enumerate(SLIDES):
            j = body.add_joint()
            j.name, j.type = jname + suffix, mujoco.mjtJoint.mjJNT_SLIDE
            j.axis = mw.floats(np.eye(3)[k])
            j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        j = body.add_joint()
        j.name, j.type = jname, mujoco.mjtJoint.mjJNT_BALL
        j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    elif mw.is_revolute(joint):
        in_link = frame.placement.inverse()  # the joint frame seen from the link
        j = body.add_joint()
        j.name, j.type = jname, mujoco.mjtJoint.mjJNT_HINGE
        j.pos = mw.floats(in_link.translation)
        j.axis = mw.floats(in_link.rotation @ mw.motion(joint)[3:])
        lo, hi = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
        if joint.nq == 1 and np.isfinite(lo) and np.isfinite(hi):
            j.limited, j.range = mujoco.mjtLimited.mjLIMITED_TRUE, [float(lo), float(hi)]
        else:
            j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    else:
        raise ParameterError(f"h4: joint '{jname}' ({joint.shortname()}) has no MuJoCo counterpart here")


def _add_geoms(mujoco: Any, body: Any, frame: Any, objs: list[Any]) -> None:
    """The visual geometries ``objs`` of a link (frame ``frame``) on its body (no contacts)."""
    for obj in objs:
        shape = _geom_shape(mujoco, obj.geometry)
        if shape is None:
            continue
        local = frame.placement.actInv(obj.placement)
        g = body.add_geom()
        g.name, (g.type, g.size) = obj.name, shape
        g.pos, g.quat = mw.floats(local.translation), mw.quaternion(local.rotation)
        g.rgba = mw.floats(obj.meshColor)
        g.density, g.contype, g.conaffinity, g.group = 0.0, 0, 0, 1


def _add_closures(mujoco: Any, s: Any, h4: Any, solref: list[float], solimp: list[float]) -> None:
    """One connect equality per loop closure, between its two sites."""
    for c in _closure_list(h4):
        e = s.add_equality()
        e.name, e.type = c.name, mujoco.mjtEq.mjEQ_CONNECT
        e.objtype = mujoco.mjtObj.mjOBJ_SITE
        e.name1, e.name2 = f"{c.name}_parent", f"{c.name}_child"
        e.solref, e.solimp = list(solref), list(solimp)


def _add_actuators(mujoco: Any, s: Any, h4: Any) -> None:
    """A motor on each actuated joint, its control range the URDF's effort limit."""
    model = h4.model
    for jname in h4.actuated_joint_names:
        effort = float(model.effortLimit[model.joints[model.getJointId(jname)].idx_v])
        a = s.add_actuator()
        a.name, a.trntype, a.target = jname, mujoco.mjtTrn.mjTRN_JOINT, jname
        a.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        if np.isfinite(effort):
            a.ctrllimited, a.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, [-effort, effort]
        else:
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


def _named_qpos(m: Any, model: pin.Model, q: np.ndarray) -> np.ndarray:
    """MuJoCo ``qpos`` (nq of the compiled ``m``) of the Pinocchio configuration ``q`` of
    ``model``, joint by joint by name (a floating joint as its slides and ball, :func:`qpos`)."""
    import mujoco

    out = np.zeros(m.nq)
    for jid in range(m.njnt):
        name, adr = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, jid), int(m.jnt_qposadr[jid])
        own = name if model.existJointName(name) else name[:-2]
        j = model.joints[model.getJointId(own)]
        v = q[j.idx_q:j.idx_q + j.nq]
        if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL:
            out[adr:adr + 4] = np.r_[v[6], v[3:6]]
        elif own != name:
            out[adr] = v[SLIDES.index(name[-2:])]
        else:
            out[adr] = mw.angle(j, q) if j.nq == 2 else v[0]
    return out


def _closure_list(h4: Any) -> list[Any]:
    from h4pin.description.urdf import parse

    return parse(h4.urdf, h4.source).closures


def _closure_sites(h4: Any) -> dict[str, list[tuple[str, np.ndarray]]]:
    """Link name -> the closure sites it carries: (``<closure>_parent`` or ``_child``, point)."""
    out: dict[str, list[tuple[str, np.ndarray]]] = {}
    for c in _closure_list(h4):
        out.setdefault(c.parent, []).append((f"{c.name}_parent", c.parent_xyz))
        out.setdefault(c.child, []).append((f"{c.name}_child", c.child_xyz))
    return out


def _floor_height(model: pin.Model, data: pin.Data) -> float:
    """A height below every pose the legs can reach: for each bar ij, its actuator axis P_i minus
    the forearm length, the bar length and the depth of the plate below B_ij (at ``data``), less
    :data:`_MARGIN`."""

    def at(name: str) -> np.ndarray:
        return data.oMf[model.getFrameId(name)].translation

    plate = set(model.subtrees[model.getJointId("plate")])
    plate_z = min(data.oMf[i].translation[2] for i, f in enumerate(model.frames)
                  if f.type == pin.FrameType.BODY and f.parentJoint in plate)
    lowest = [at(f"P_{i}")[2] - np.linalg.norm(at(f"A_{i}") - at(f"P_{i}"))
              - np.linalg.norm(at(f"bar_{i}{j}_end") - at(f"A_{i}{j}")) - (at(f"B_{i}{j}")[2] - plate_z)
              for i in range(1, 5) for j in (1, 2)]
    return float(min(lowest)) - _MARGIN


def _scene(model: pin.Model, s: Any, mujoco: Any, data: pin.Data) -> None:
    """Floor (below every pose the legs can reach), light and camera, sized from the robot at ``data``."""
    points = np.array([data.oMf[i].translation for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY])
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2
    size = float(np.max(hi - lo))
    floor = s.worldbody.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.pos = [float(centre[0]), float(centre[1]), _floor_height(model, data)]
    floor.size = [size, size, 0.05]
    floor.rgba = [0.82, 0.84, 0.86, 1.0]

    light = s.worldbody.add_light()
    light.name = "top"
    light.pos = [float(centre[0]), float(centre[1]), float(hi[2]) + 1.5 * size]
    light.dir = [0.0, 0.0, -1.0]
    light.cutoff = 60.0
    light.diffuse = [0.8, 0.8, 0.8]

    camera = s.worldbody.add_camera()
    camera.name = CAMERA
    eye = centre + size * np.array([1.1, -1.3, 0.7])
    camera.pos = [float(v) for v in eye]
    camera.quat = _look_at(eye, centre)
    camera.fovy = 45.0


def to_mjcf(h4: Any, name: str | None = None, q: np.ndarray | None = None, *, elastic: bool = False,
            servo: bool = False) -> str:
    """MJCF text of ``h4``: :func:`spec` (``elastic=True``: :func:`elastic_spec` with its default
    settings; ``servo=True`` with it: the actuators kept and driven by position servos, a file that
    can follow a motion) compiled and written by MuJoCo (``MjSpec.to_xml``, every number to 17 significant
    digits), after two comment lines: the licence, and what wrote it (with the MuJoCo version, whose
    writer's layout can differ from another's).

    Raises:
        MissingExtraError: MuJoCo is not installed.
        ParameterError: as :func:`spec`.
    """
    mujoco = _mujoco()
    if servo and not elastic:
        raise ParameterError("servo: only the elastic robot has servos (elastic=True)")
    s = elastic_spec(h4, name, q, servo=servo) if elastic else spec(h4, name, q)
    s.compile()
    with mw.full_precision(mujoco):
        text = s.to_xml()
    head, sep, rest = text.partition("\n")
    held = ("the actuators driven by position servos (<joint>_servo: ctrl the angle in rad, gain the "
            "actuator_i_elastic spring; <joint>_damper: ctrl the rate in rad/s)" if servo else "the actuators locked")
    what = (f"its URDF and h4pin.elastic_model: every compliance a spring joint (stiffness N.m/rad or N/m, "
            f"springref 0, damping {DAMPING:g} s x stiffness), {held}, the closures as connect "
            "equalities, keyframe q0." if elastic else
            "its URDF: one body per link, the closures as connect equalities, torque motors (N.m), keyframe q0.")
    note = ("<!-- SPDX-License-Identifier: Apache-2.0 -->\n"
            f"<!-- The {'elastic ' if elastic else ''}H4 parallel robot '{s.modelname}', written by h4pin.io.mjcf "
            f"through MuJoCo {mujoco.__version__}'s MjSpec from {what} -->\n")
    if head.startswith("<?xml"):
        return head + sep + note + rest
    return note + text


def qpos(h4: Any, q: np.ndarray) -> np.ndarray:
    """MuJoCo ``qpos`` of a Pinocchio configuration ``q`` of ``h4``: joint by joint in Pinocchio's
    order, a floating joint as its three slides and its ball (x y z qw qx qy qz: Pinocchio's
    x y z qx qy qz qw with the quaternion's w first), a revolute joint as its angle (an unbounded
    one's (cos, sin) pair becomes one angle).

    Raises:
        ParameterError: ``q`` has the wrong shape.
    """
    model = h4.model
    q = np.asarray(q, float)
    if q.shape != (model.nq,):
        raise ParameterError(f"q: expected shape ({model.nq},), got {q.shape}")
    out: list[float] = []
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        v = q[j.idx_q:j.idx_q + j.nq]
        if mw.is_free(j):
            out += mw.floats(np.r_[v[:3], v[6], v[3:6]])
        elif j.nq == 2 and j.nv == 1:
            out.append(mw.angle(j, q))
        else:
            out += mw.floats(v)
    return np.asarray(out, float)


def write_mjcf(h4: Any, path: str | os.PathLike[str], name: str | None = None, *, elastic: bool = False,
               servo: bool = False) -> Path:
    """Write :func:`to_mjcf` to ``path`` atomically (a temporary file renamed), mode 0644. The model
    is named ``name``, else after the file (its stem); ``elastic=True`` writes the elastic robot
    (:func:`elastic_spec`), with ``servo=True`` its actuators driven by position servos.

    Raises:
        MissingExtraError: MuJoCo is not installed.
        FileNotFoundError: the folder of ``path`` does not exist.
        IsADirectoryError: ``path`` is a folder.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"path: {path} is a folder")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"path: no folder {path.parent}")
    return write_text(path, to_mjcf(h4, name or path.stem, elastic=elastic, servo=servo))


__all__ = ["ARMATURE_STEPS", "CAMERA", "CHAIN_MASS", "DAMPING", "ELASTIC_SOLIMP", "ELASTIC_SOLREF", "ELASTIC_TIMESTEP",
           "KEYFRAME", "MIN_MUJOCO", "SLIDES", "SOLIMP", "SOLREF", "TIMESTEP", "elastic_spec", "mjcf_dir", "mjcf_path",
           "qpos", "spec", "to_mjcf", "write_mjcf", "writer_version"]
