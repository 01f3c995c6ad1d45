# SPDX-License-Identifier: Apache-2.0
"""The H4 for MuJoCo (``mujoco`` extra): an MJCF built with ``mujoco.MjSpec``, loops closed by
8 ``connect`` equalities, 4 motors, a floor, a light and a camera.

MuJoCo reads h4pin's URDF but drops its ``<constraint>`` elements (``neq = 0``): the legs then
hang loose. :func:`spec` builds the robot with MuJoCo's own model-editing API instead, from the
robot's URDF (:attr:`h4pin.H4.urdf`) and its Pinocchio model; MuJoCo compiles and writes it
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

The lowest MuJoCo this works with is :data:`MIN_MUJOCO` (the first whose ``MjSpec`` has a usable
``option`` and site ``connect``). ``h4pin export --mjcf PATH`` writes the file; the shipped
``mjcf/h4_<variant>.xml`` (:func:`mjcf_path`) are written by ``scripts/generate_urdf.py``.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.files import write_text

#: MuJoCo time step (s).
TIMESTEP = 1e-4
#: Constraint softness of the closures: solref (time constant s, damping ratio) and solimp.
SOLREF = (0.0005, 1.0)
SOLIMP = (0.999, 0.9999, 0.001, 0.5, 2.0)
#: Name of the keyframe (Pinocchio's reference configuration ``q0``).
KEYFRAME = "q0"
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


def _version(text: str) -> tuple[int, ...]:
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


def _mujoco() -> Any:
    """The ``mujoco`` module, at least :data:`MIN_MUJOCO`.

    Raises:
        MissingExtraError: MuJoCo is not installed, or older than :data:`MIN_MUJOCO`.
    """
    from h4pin.extras import MissingExtraError, require

    require("mujoco", extra="mujoco", what="the MuJoCo export (h4pin.io.mjcf)")
    import mujoco

    if _version(mujoco.__version__) < _version(MIN_MUJOCO):
        raise MissingExtraError(f"the MuJoCo export (h4pin.io.mjcf) needs MuJoCo >= {MIN_MUJOCO}, this is "
                                f"{mujoco.__version__}: pip install 'h4pin[mujoco]'")
    return mujoco


def writer_version(text: str) -> str | None:
    """The MuJoCo version named in the comment :func:`to_mjcf` writes at the top of a file (None
    if there is none): MuJoCo's XML writer lays files out a little differently across versions."""
    found = re.search(r"written by h4pin\.io\.mjcf through MuJoCo (\S+)'s MjSpec", text[:2000])
    return found.group(1) if found else None


@contextlib.contextmanager
def _full_precision(mujoco: Any) -> Iterator[bool]:
    """MuJoCo's XML writer with 17 significant digits (every double written exactly) inside the
    block, then its previous setting (6 by default) again. MuJoCo's Python API has no setting for
    it; its library has one, ``_mjPRIVATE__set_xml_precision`` (what MuJoCo's own tests use),
    reached here through ctypes. Yields False, with a warning, where the library has none (the
    file then carries 6 digits, about 1e-6 relative)."""
    setter = getter = None
    folder = Path(mujoco.__file__).parent
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        for library in sorted(folder.glob(pattern)):
            with contextlib.suppress(OSError, AttributeError):
                lib = ctypes.CDLL(str(library))
                setter, getter = lib._mjPRIVATE__set_xml_precision, lib._mjPRIVATE__get_xml_precision
                break
        if setter is not None:
            break
    if setter is None or getter is None:
        warnings.warn(f"MuJoCo {mujoco.__version__}: its XML writer's precision cannot be set here; the MJCF "
                      "keeps 6 significant digits", RuntimeWarning, stacklevel=3)
        yield False
        return
    getter.restype = ctypes.c_int
    before = getter()
    setter(ctypes.c_int(17))
    try:
        yield True
    finally:
        setter(ctypes.c_int(before))


def _floats(values: Any) -> list[float]:
    return [float(v) for v in np.ravel(values)]


def _quat(rotation: np.ndarray) -> list[float]:
    """Quaternion (w x y z, w >= 0) of a rotation matrix."""
    q = pin.Quaternion(np.asarray(rotation, float))
    q.normalize()
    w = np.array([q.w, q.x, q.y, q.z])
    return _floats(w if w[0] >= 0 else -w)


def _neutral(joint: Any) -> np.ndarray:
    q = np.zeros(joint.nq)
    if joint.nq == 2:  # unbounded revolute: (cos, sin)
        q[0] = 1.0
    return q


def _motion(joint: Any) -> np.ndarray:
    """First column of a joint's motion subspace (linear, angular), in its joint frame."""
    jd = joint.createData()
    joint.calc(jd, _neutral(joint))
    s = jd.S
    return np.asarray(s.matrix() if hasattr(s, "matrix") else s, float).reshape(6, -1)[:, 0]


def _is_revolute(joint: Any) -> bool:
    return joint.nv == 1 and joint.nq in (1, 2) and bool(np.allclose(_motion(joint)[:3], 0.0))


def _is_free(joint: Any) -> bool:
    return joint.nq == 7 and joint.nv == 6


def _angle(joint: Any, q: np.ndarray) -> float:
    """The angle of a revolute joint (bounded: q; unbounded: atan2(sin, cos))."""
    v = q[joint.idx_q:joint.idx_q + joint.nq]
    return float(v[0]) if joint.nq == 1 else float(np.arctan2(v[1], v[0]))


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
        return mujoco.mjtGeom.mjGEOM_BOX, _floats(geom.halfSide)
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
    return _quat(np.column_stack([right, np.cross(back, right), back]))


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
        q: the closed configuration the keyframe holds (default :attr:`h4pin.H4.q0`).

    Raises:
        MissingExtraError: MuJoCo is not installed.
        ParameterError: no closed configuration (``h4.q0`` is None and no ``q``), ``q`` does not
            close the loops (1e-9 m), or the URDF has a joint MuJoCo has no counterpart of here.
    """
    mujoco = _mujoco()
    model = h4.model
    q = _closed(h4, q)
    data = model.createData()  # the closed configuration: keyframe, scene
    pin.framesForwardKinematics(model, data, q)
    zero = model.createData()  # the URDF's zero configuration: body placements
    pin.framesForwardKinematics(model, zero, pin.neutral(model))
    frames, parent, own_joint = _links(model)
    inertials = _urdf_inertials(h4.urdf)

    s = mujoco.MjSpec()
    s.modelname = name or model.name or "h4"
    compiler = getattr(s, "compiler", s)  # MuJoCo >= 3.2.5 groups these under spec.compiler
    compiler.degree = False
    s.option.timestep = TIMESTEP
    s.option.gravity = _floats(model.gravity.linear)
    s.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST

    geoms: dict[int, list[Any]] = {}
    for obj in h4.visual_model.geometryObjects:
        geoms.setdefault(obj.parentFrame, []).append(obj)
    closures = _closure_sites(h4)

    bodies: dict[int, Any] = {0: s.worldbody}
    for f in frames:
        frame, up = model.frames[f], parent[f]
        body = bodies[up].add_body()
        bodies[f] = body
        body.name = frame.name
        place = zero.oMf[f] if up == 0 else zero.oMf[up].actInv(zero.oMf[f])
        joint_id = own_joint.get(f)
        if joint_id is not None:
            joint, jname = model.joints[joint_id], model.names[joint_id]
            if _is_free(joint):
                if not frame.placement.isIdentity(1e-12):
                    raise ParameterError(f"h4: link '{frame.name}' must sit at the origin of its floating joint")
                for k, suffix in enumerate(SLIDES):
                    j = body.add_joint()
                    j.name, j.type = jname + suffix, mujoco.mjtJoint.mjJNT_SLIDE
                    j.axis = _floats(np.eye(3)[k])
                    j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
                j = body.add_joint()
                j.name, j.type = jname, mujoco.mjtJoint.mjJNT_BALL
                j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
            elif _is_revolute(joint):
                in_link = frame.placement.inverse()  # the joint frame seen from the link
                j = body.add_joint()
                j.name, j.type = jname, mujoco.mjtJoint.mjJNT_HINGE
                j.pos = _floats(in_link.translation)
                j.axis = _floats(in_link.rotation @ _motion(joint)[3:])
                lo, hi = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
                if joint.nq == 1 and np.isfinite(lo) and np.isfinite(hi):
                    j.limited, j.range = mujoco.mjtLimited.mjLIMITED_TRUE, [float(lo), float(hi)]
                else:
                    j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
            else:
                raise ParameterError(f"h4: joint '{jname}' ({joint.shortname()}) has no MuJoCo counterpart here")
        body.pos, body.quat = _floats(place.translation), _quat(place.rotation)
        mass, com, tensor = inertials.get(frame.name, (0.0, np.zeros(3), np.zeros((3, 3))))
        if mass > 0:
            body.mass, body.ipos = mass, _floats(com)
            body.fullinertia = _floats([tensor[0, 0], tensor[1, 1], tensor[2, 2],
                                        tensor[0, 1], tensor[0, 2], tensor[1, 2]])
            if hasattr(body, "explicitinertial"):
                body.explicitinertial = True
        elif joint_id is None and up != 0:
            site = body.add_site()
            site.name, site.size, site.group = frame.name, [0.004, 0.0, 0.0], 2
        for site_name, xyz in closures.get(frame.name, []):
            site = body.add_site()
            site.name, site.pos, site.size, site.group = site_name, _floats(xyz), [0.003, 0.0, 0.0], 3
        for obj in geoms.get(f, []):
            shape = _geom_shape(mujoco, obj.geometry)
            if shape is None:
                continue
            local = frame.placement.actInv(obj.placement)
            g = body.add_geom()
            g.name, (g.type, g.size) = obj.name, shape
            g.pos, g.quat = _floats(local.translation), _quat(local.rotation)
            g.rgba = _floats(obj.meshColor)
            g.density, g.contype, g.conaffinity, g.group = 0.0, 0, 0, 1

    for c in _closure_list(h4):
        e = s.add_equality()
        e.name, e.type = c.name, mujoco.mjtEq.mjEQ_CONNECT
        e.objtype = mujoco.mjtObj.mjOBJ_SITE
        e.name1, e.name2 = f"{c.name}_parent", f"{c.name}_child"
        e.solref, e.solimp = list(SOLREF), list(SOLIMP)
    for jname in h4.actuated_joint_names:
        effort = float(model.effortLimit[model.joints[model.getJointId(jname)].idx_v])
        a = s.add_actuator()
        a.name, a.trntype, a.target = jname, mujoco.mjtTrn.mjTRN_JOINT, jname
        a.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        if np.isfinite(effort):
            a.ctrllimited, a.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, [-effort, effort]
        else:
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    key = s.add_key()
    key.name, key.qpos = KEYFRAME, _floats(qpos(h4, q))
    _scene(model, s, mujoco, data)
    return s


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


def to_mjcf(h4: Any, name: str | None = None, q: np.ndarray | None = None) -> str:
    """MJCF text of ``h4``: :func:`spec` compiled and written by MuJoCo (``MjSpec.to_xml``, every
    number to 17 significant digits), after two comment lines: the licence, and what wrote it
    (with the MuJoCo version, whose writer's layout can differ from another's).

    Raises:
        MissingExtraError: MuJoCo is not installed.
        ParameterError: as :func:`spec`.
    """
    mujoco = _mujoco()
    s = spec(h4, name, q)
    s.compile()
    with _full_precision(mujoco):
        text = s.to_xml()
    head, sep, rest = text.partition("\n")
    note = ("<!-- SPDX-License-Identifier: Apache-2.0 -->\n"
            f"<!-- The H4 parallel robot '{s.modelname}', written by h4pin.io.mjcf through "
            f"MuJoCo {mujoco.__version__}'s MjSpec from its URDF: one body per link, the closures as connect "
            "equalities, torque motors (N.m), keyframe q0. -->\n")
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
        if _is_free(j):
            out += _floats(np.r_[v[:3], v[6], v[3:6]])
        elif j.nq == 2 and j.nv == 1:
            out.append(_angle(j, q))
        else:
            out += _floats(v)
    return np.asarray(out, float)


def write_mjcf(h4: Any, path: str | os.PathLike[str], name: str | None = None) -> Path:
    """Write :func:`to_mjcf` to ``path`` atomically (a temporary file renamed), mode 0644. The model
    is named ``name``, else after the file (its stem).

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
    return write_text(path, to_mjcf(h4, name or path.stem))


__all__ = ["CAMERA", "KEYFRAME", "MIN_MUJOCO", "SLIDES", "SOLIMP", "SOLREF", "TIMESTEP", "mjcf_dir", "mjcf_path",
           "qpos", "spec", "to_mjcf", "write_mjcf", "writer_version"]
