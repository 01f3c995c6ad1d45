# SPDX-License-Identifier: Apache-2.0
"""An MJCF file read as MuJoCo means it, for :meth:`h4pin.mechanism.Mechanism.from_mjcf`.

Two readers, each for what it does right:

* Pinocchio 4's (``buildModelAndLegacyConstraintsFromMJCF``): the tree and the ``weld``
  equalities as ``RigidConstraintModel`` closures (a ``connect`` is built here from MuJoCo's own
  anchors: the reader puts it elsewhere when a body's joint is off the body's origin). Its
  coordinate of a hinge or slide is MuJoCo's ``qpos``, minus the joint's ``ref`` where the joint
  shares its body with others (its composite joints measure from the pose the file draws); balls
  and free joints are the same numbers with the quaternion reordered (:func:`from_qpos`). It
  merges the joints of one body into one composite joint (``Composite_<first>``): they are split
  back here into the file's joints, one Pinocchio joint each, so that a motor on any of them is a
  joint of its own. It drops a fixed root body's placement on the world (``<body pos quat>``
  without a joint): that placement is put back here, so that the model's world is the file's. It
  reads a geom's mass as density times volume where a default class sets the mass: every body's
  mass, centre of mass and inertia are MuJoCo's compiled ones (``body_mass``, ``body_ipos``,
  ``body_iquat``, ``body_inertia``), summed onto the joint that carries the body. Every file read
  is checked: the two readers' world placements of every body agree at the reference and at
  random configurations, or the bodies that differ are named
  (:class:`~h4pin.errors.UnsupportedFeatureError`; Pinocchio's reader ignores a joint ``pos`` set
  by a default class, for one).
* MuJoCo's compiler (``mujoco.MjModel``): the reference configuration (the first keyframe, else
  ``qpos0``, where each joint's ``ref`` is), the ranges of limited hinges and slides, the joints'
  ``stiffness`` and ``springref`` (all in Pinocchio's coordinates), the masses, the equalities
  and the actuators' transmissions.

Joint couplings (``<equality><joint polycoef>``) become :class:`~h4pin.mechanism.couplings.JointCoupling`
constraints. File values MuJoCo compiles but h4pin would drop are refused by element and attribute
(:class:`~h4pin.errors.MalformedURDFError`): a negative or non-finite joint ``stiffness`` or
``springref``, a ``range`` not finite or with its bounds reversed, a first keyframe whose ``qpos``
has not one value per coordinate (MuJoCo fills the rest), and any position, orientation, axis,
mass, inertia, anchor or keyframe that is not finite (MuJoCo reads ``nan``) or a position beyond
``h4pin.limits.RANGES["robot length"]``. Before either reader opens anything, the file, the files
it includes and the assets it names are checked as regular files of bounded size
(:func:`check_files`: a FIFO named as a mesh would block MuJoCo forever). What neither reader can represent is
refused by name (:class:`~h4pin.errors.UnsupportedFeatureError`): tendon equalities, actuators
that do not drive a joint (unless the motors are given), a second body on the world with joints
(Pinocchio's reader reads the first tree only).
"""

from __future__ import annotations

import dataclasses
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import MalformedURDFError, ParameterError, UnsupportedFeatureError
from h4pin.files import ASSET_BYTES, check_input, read_input
from h4pin.limits import RANGES
from h4pin.mechanism.couplings import JointCoupling


@dataclasses.dataclass(frozen=True)
class MjcfInfo:
    """What MuJoCo's compiler says of the file, in the Pinocchio model's coordinates."""

    name: str
    reference: np.ndarray
    ranges: tuple[np.ndarray, np.ndarray]
    springs: dict[str, float]
    spring_rest: dict[str, float]
    motors: tuple[str, ...]
    refused: tuple[str, ...]  # actuators that drive no joint (tendon, site, body)
    couplings: tuple[JointCoupling, ...]


def _split(model: pin.Model, names_of: dict[str, list[str]]) -> tuple[pin.Model, dict[int, int]]:
    """``model`` with each composite joint split into its components (named from ``names_of``:
    composite name -> the file's joint names, in order); old joint id -> new id of the joint that
    carries the old one's body."""
    composite = [j for j in range(1, model.njoints) if model.joints[j].shortname() == "JointModelComposite"]
    if not composite:
        return model, {j: j for j in range(model.njoints)}
    out = pin.Model()
    out.name, out.gravity = model.name, model.gravity
    ids = {0: 0}
    for j in range(1, model.njoints):
        jm, parent = model.joints[j], ids[model.parents[j]]
        if j in composite:
            comp = jm.extract()
            names = names_of.get(model.names[j])
            if names is None or len(names) != len(comp.joints):
                raise MalformedURDFError(f"composite joint {model.names[j]!r}: cannot match its {len(comp.joints)} "
                                         "parts to the file's joints")
            place = model.jointPlacements[j]
            for k, (part, name) in enumerate(zip(comp.joints, names, strict=True)):
                parent = out.addJoint(parent, part, place * comp.jointPlacements[k] if k == 0 else
                                      comp.jointPlacements[k], name)
            ids[j] = parent
        else:
            ids[j] = out.addJoint(parent, jm, model.jointPlacements[j], model.names[j])
        out.appendBodyToJoint(ids[j], model.inertias[j], pin.SE3.Identity())
    for f in list(model.frames)[1:]:
        out.addFrame(pin.Frame(f.name, ids[f.parentJoint], f.parentFrame, f.placement, f.type, f.inertia), False)
    return out, ids


def _joint_name(mj: Any, i: int) -> str:
    """Joint i's name in Pinocchio's model: the file's, or for an unnamed free joint
    ``<body>_free`` (Pinocchio's reader's name)."""
    import mujoco

    name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, i)
    if name:
        return name
    body = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, mj.jnt_bodyid[i]) or f"body {mj.jnt_bodyid[i]}"
    return f"{body}_free" if int(mj.jnt_type[i]) == int(mujoco.mjtJoint.mjJNT_FREE) else f"an unnamed joint of {body}"


def from_qpos(mj: Any, model: pin.Model, qpos: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration (nq,) of MuJoCo's ``qpos`` (``mj.nq``,), joint by joint by name:
    a hinge's or slide's ``qpos`` (minus its ``ref`` where it shares its body with other joints:
    Pinocchio's composite joints measure from the pose the file draws), a ball's or free joint's
    the same numbers with the quaternion reordered (MuJoCo w x y z, Pinocchio x y z w)."""
    import mujoco

    q = pin.neutral(model)
    for i in range(mj.njnt):
        name = _joint_name(mj, i)
        if not model.existJointName(name):
            raise MalformedURDFError(f"joint {name!r} of the MJCF file is not in Pinocchio's model")
        jm = model.joints[model.getJointId(name)]
        adr, kind = mj.jnt_qposadr[i], int(mj.jnt_type[i])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            x = qpos[adr:adr + 7]
            q[jm.idx_q:jm.idx_q + 7] = [*x[:3], x[4], x[5], x[6], x[3]]
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            x = qpos[adr:adr + 4]
            q[jm.idx_q:jm.idx_q + 4] = [x[1], x[2], x[3], x[0]]
        else:
            q[jm.idx_q] = qpos[adr] - _ref(mj, i)
    return pin.normalize(model, q)


def _ref(mj: Any, i: int) -> float:
    """What Pinocchio 4's reader subtracts from joint i's ``qpos``: its ``ref`` when the joint
    shares its body with others (a composite joint), nothing for a body's only joint (the reader
    puts ``ref`` into the joint's placement)."""
    return float(mj.qpos0[mj.jnt_qposadr[i]]) if mj.body_jntnum[mj.jnt_bodyid[i]] > 1 else 0.0


def _body_name(mj: Any, b: int) -> str:
    import mujoco

    return mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b) or f"body {b}"


def _rotation(quat: np.ndarray) -> np.ndarray:
    """The rotation matrix of MuJoCo's quaternion (w x y z)."""
    import mujoco

    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float))
    return out.reshape(3, 3)


def _check_values(path: Path, mj: Any) -> None:
    """Refuse the file values MuJoCo compiles but h4pin would drop (module docstring)."""
    import mujoco

    for i in range(mj.njnt):
        name, k = _joint_name(mj, i), float(mj.jnt_stiffness[i])
        if not (np.isfinite(k) and k >= 0):
            raise MalformedURDFError(f"{path}: joint {name!r}: stiffness {k:g} is not a finite value >= 0")
        rest = float(mj.qpos_spring[mj.jnt_qposadr[i]])
        if k > 0 and not np.isfinite(rest):
            raise MalformedURDFError(f"{path}: joint {name!r}: springref {rest:g} is not finite")
        lo, hi = (float(x) for x in mj.jnt_range[i])
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise MalformedURDFError(f"{path}: joint {name!r}: range '{lo:g} {hi:g}' is not two finite bounds, "
                                     "the lower first")
    if mj.nkey:  # MuJoCo's compiled key_qpos is always nq long: the values the file gives, from its spec
        key = mujoco.MjSpec.from_file(str(path)).keys[0]
        if len(key.qpos) not in (0, mj.nq):
            raise MalformedURDFError(f"{path}: keyframe {key.name or '0'!r}: qpos has {len(key.qpos)} values, the "
                                     f"model has {mj.nq} coordinates (MuJoCo would fill the rest)")


def _dirs(trees: list[tuple[Path, ET.Element]], main: Path, key: str) -> list[Path]:
    """Where MuJoCo may look for an asset of the compiler folder ``key`` (``meshdir``,
    ``texturedir``): that folder (or ``assetdir``) of any ``<compiler>``, relative to the main
    file's folder or to the folder of the file that states it, and those folders themselves."""
    out = [main]
    for where, root in trees:
        out.append(where.parent)
        for comp in root.iter("compiler"):
            for attr in (key, "assetdir"):
                if comp.get(attr):
                    out += [main / comp.get(attr), where.parent / comp.get(attr)]
    return list(dict.fromkeys(out))


def _existing(name: str, dirs: list[Path]) -> list[Path]:
    """The paths ``name`` may stand for (absolute, or under each of ``dirs``) that exist."""
    paths = [Path(name)] if Path(name).is_absolute() else [d / name for d in dirs]
    return [p for p in dict.fromkeys(paths) if os.path.lexists(p)]


def check_files(path: Path) -> None:
    """Refuse, before MuJoCo or Pinocchio opens anything, an MJCF file, a file it includes
    (``<include file>``, read here as XML too) or an asset it names (every ``file*`` attribute:
    meshes, textures, height fields, skins, models; found as MuJoCo finds them, from the
    ``<compiler>``'s ``meshdir``, ``texturedir`` or ``assetdir``) that is not a regular file of a
    bounded size (:func:`h4pin.files.check_input`: a FIFO would block the reader forever, a device
    never end). A file named but missing is left to MuJoCo's own message.

    Raises:
        InputFileError: naming the file, the element that names it and what it is.
        MalformedURDFError: the file or an included one is not well-formed XML.
    """
    main = path.parent
    trees: list[tuple[Path, ET.Element]] = []
    todo, seen = [path], set()
    while todo:
        where = todo.pop()
        if os.path.abspath(where) in seen:
            continue
        seen.add(os.path.abspath(where))
        data = read_input(where, "MJCF file" if where == path else f"{path}: <include file>")
        try:
            root = ET.fromstring(data)
        except ET.ParseError as exc:
            raise MalformedURDFError(f"{where}: not well-formed XML ({exc})") from None
        trees.append((where, root))
        for inc in root.iter("include"):
            todo += _existing(inc.get("file") or "", [main, where.parent]) if inc.get("file") else []
    for _, root in trees:
        for elem in root.iter():
            for attr, name in elem.attrib.items():
                if not attr.startswith("file") or not name or elem.tag == "include":
                    continue
                dirs = _dirs(trees, main, "meshdir" if elem.tag in ("mesh", "skin") else "texturedir")
                for candidate in _existing(name, dirs):
                    check_input(candidate, f"{path}: <{elem.tag} {attr}>", max_bytes=ASSET_BYTES)


def _finite(path: Path, what: str, attr: str, values: Any, length: bool = False) -> None:
    """Refuse a compiled value that is not finite (or a position beyond the plausible length of
    a robot: :data:`h4pin.limits.RANGES`), naming the element and attribute."""
    v = np.asarray(values, dtype=float).reshape(-1)
    lo, hi, unit, span = RANGES["robot length"]
    if not np.all(np.isfinite(v)):
        raise MalformedURDFError(f"{path}: {what}: {attr} {' '.join(f'{x:g}' for x in v)} is not finite")
    if length and not np.all((v >= lo) & (v <= hi)):
        raise MalformedURDFError(f"{path}: {what}: {attr} {' '.join(f'{x:g}' for x in v)} is outside the plausible "
                                 f"range [{lo:g}, {hi:g}] {unit} of {span} (h4pin.limits.RANGES)")


def _check_numbers(path: Path, mj: Any) -> None:
    """Refuse positions, orientations, axes, masses, inertias, anchors and keyframes that MuJoCo
    compiled from the file but that are not finite (``nan`` is read as a number), or positions
    beyond the plausible length of a robot; each named by element and attribute."""
    import mujoco

    for b in range(1, mj.nbody):
        what = f"body {_body_name(mj, b)!r}"
        for attr, values, length in (("pos", mj.body_pos[b], True), ("quat", mj.body_quat[b], False),
                                     ("inertial pos", mj.body_ipos[b], True),
                                     ("inertial quat", mj.body_iquat[b], False), ("mass", mj.body_mass[b], False),
                                     ("diaginertia", mj.body_inertia[b], False)):
            _finite(path, what, attr, values, length)
    for i in range(mj.njnt):
        _finite(path, f"joint {_joint_name(mj, i)!r}", "pos", mj.jnt_pos[i], True)
        _finite(path, f"joint {_joint_name(mj, i)!r}", "axis", mj.jnt_axis[i])
        if int(mj.jnt_type[i]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            _finite(path, f"joint {_joint_name(mj, i)!r}", "ref", mj.qpos0[mj.jnt_qposadr[i]], True)
    for i in range(mj.nsite):
        what = f"site {mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_SITE, i) or i!r}"
        _finite(path, what, "pos", mj.site_pos[i], True)
        _finite(path, what, "quat", mj.site_quat[i])
    kinds = {int(mujoco.mjtEq.mjEQ_CONNECT): ("connect", "anchor"), int(mujoco.mjtEq.mjEQ_WELD): ("weld", "relpose"),
             int(mujoco.mjtEq.mjEQ_JOINT): ("joint", "polycoef")}
    for i in range(mj.neq):
        kind, attr = kinds.get(int(mj.eq_type[i]), ("other", "data"))
        what = f"equality {mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_EQUALITY, i) or i!r} ({kind})"
        if kind in ("connect", "weld"):
            _finite(path, what, "anchor", mj.eq_data[i, :3], True)
        _finite(path, what, attr, mj.eq_data[i])
    for k in range(mj.nkey):  # positions (m), angles (rad) and quaternions: none beyond 1e3
        _finite(path, f"keyframe {mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_KEY, k) or k!r}", "qpos", mj.key_qpos[k],
                True)


def _check_one_tree(path: Path, mj: Any) -> None:
    """Refuse a second body on the world whose tree has joints: Pinocchio's reader reads the first
    body under ``<worldbody>`` only (a second one without joints is part of the world)."""
    roots = [b for b in range(1, mj.nbody) if mj.body_parentid[b] == 0]
    for b in roots[1:]:
        joints = int(sum(mj.body_jntnum[c] for c in range(mj.nbody) if mj.body_rootid[c] == b))
        if joints:
            raise UnsupportedFeatureError(
                f"{path}: a second root body on the world, {_body_name(mj, b)!r} ({joints} joints), is not supported: "
                f"Pinocchio's MJCF reader reads one tree, the first body {_body_name(mj, roots[0])!r}")


def _bodies(path: Path, mj: Any, model: pin.Model) -> list[tuple[int, int]]:
    """``(MuJoCo body id, Pinocchio BODY frame id)`` of every body of the tree Pinocchio reads (the
    first on the world): both readers number them in the file's order (an unnamed body gets a
    made-up name from Pinocchio's reader)."""
    import mujoco

    frames = [i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY]
    bodies = [b for b in range(1, mj.nbody) if mj.body_rootid[b] == 1]
    if len(frames) != len(bodies):
        raise MalformedURDFError(f"{path}: MuJoCo reads {len(bodies)} bodies in the first tree, Pinocchio's reader "
                                 f"{len(frames)}")
    for b, i in zip(bodies, frames, strict=True):
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b)
        if name and model.frames[i].name != name:
            raise MalformedURDFError(f"{path}: MuJoCo's body {b} is {name!r}, Pinocchio's {model.frames[i].name!r}")
    return list(zip(bodies, frames, strict=True))


def _place_root(mj: Any, model: pin.Model, cms: list[Any]) -> None:
    """A fixed root body (no joint) placed on the world where the file places it: Pinocchio's
    reader puts it at the world's origin; its frames, the joints on it and the closures' ends on
    the world moved by its pose."""
    if mj.nbody < 2 or mj.body_jntnum[1] or not model.existFrame(_body_name(mj, 1), pin.FrameType.BODY):
        return
    root = model.getFrameId(_body_name(mj, 1), pin.FrameType.BODY)
    if model.frames[root].parentJoint != 0:
        return
    move = pin.SE3(_rotation(mj.body_quat[1]), np.array(mj.body_pos[1])) * model.frames[root].placement.inverse()
    moved = {root}
    for i in range(root, len(model.frames)):
        f = model.frames[i]
        if f.parentJoint == 0 and (i == root or f.parentFrame in moved):
            moved.add(i)
            f.placement = move * f.placement
            model.frames[i] = f
    for j in range(1, model.njoints):
        if model.parents[j] == 0:
            model.jointPlacements[j] = move * model.jointPlacements[j]
    for cm in cms:
        if cm.joint1_id == 0:
            cm.joint1_placement = move * cm.joint1_placement
        if cm.joint2_id == 0:
            cm.joint2_placement = move * cm.joint2_placement


def _mujoco_inertias(path: Path, mj: Any, model: pin.Model) -> None:
    """Every body's mass, centre of mass and inertia MuJoCo's compiled ones, each joint's inertia
    the sum of its bodies' (module docstring)."""
    total = [pin.Inertia.Zero() for _ in range(model.njoints)]
    for b, i in _bodies(path, mj, model):
        rot = _rotation(mj.body_iquat[b])
        body = pin.Inertia(float(mj.body_mass[b]), np.array(mj.body_ipos[b]),
                           rot @ np.diag(mj.body_inertia[b]) @ rot.T)
        f = model.frames[i]
        f.inertia = body
        model.frames[i] = f
        total[f.parentJoint] = total[f.parentJoint] + f.placement.act(body)
    for j, inertia in enumerate(total):
        model.inertias[j] = inertia


def _check_kinematics(path: Path, mj: Any, model: pin.Model) -> None:
    """Refuse a file whose two readings place a body differently on the world (module docstring)."""
    import mujoco

    d, pd = mujoco.MjData(mj), model.createData()
    rng = np.random.default_rng(0)
    bodies = _bodies(path, mj, model)
    for trial in range(3):
        qpos = mj.key_qpos[0].copy() if (trial == 0 and mj.nkey) else mj.qpos0.copy()
        if trial:
            for i in range(mj.njnt):
                adr, kind = mj.jnt_qposadr[i], int(mj.jnt_type[i])
                if kind in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                    qpos[adr] += 0.1 * rng.uniform(-1, 1)
        d.qpos[:] = qpos
        mujoco.mj_kinematics(mj, d)
        pin.framesForwardKinematics(model, pd, from_qpos(mj, model, qpos))
        length = max(1e-3, float(np.abs(d.xpos).max()))  # the scale of the positions' round-off
        for b, i in bodies:
            p = pd.oMf[i]
            gap = float(np.linalg.norm(d.xpos[b] - p.translation))
            turn = float(np.linalg.norm(pin.log3(d.xmat[b].reshape(3, 3).T @ p.rotation)))
            if gap > 1e-9 * length or turn > 1e-9:
                raise UnsupportedFeatureError(
                    f"{path}: Pinocchio's MJCF reader places body {_body_name(mj, b)!r} {gap * 1e3:.3g} mm and "
                    f"{turn:.3g} rad away from where MuJoCo does (a joint pos from a default class, or a feature it "
                    "reads otherwise); h4pin would compute another robot")


def _load(path: Path) -> tuple[Any, pin.Model, list[Any], dict[int, int]]:
    """MuJoCo's compiled model (its values checked) and Pinocchio's reading of the file, composites
    split, the root body on the world and the masses MuJoCo's; Pinocchio's closures and the map
    from its joint ids to the split model's."""
    from h4pin.extras import MissingExtraError, require

    check_files(path)  # first: a FIFO or a device is refused whatever is installed
    reader = getattr(pin, "buildModelAndLegacyConstraintsFromMJCF", None)
    if reader is None:
        raise MissingExtraError(f"Mechanism.from_mjcf needs Pinocchio >= 4 (its MJCF reader's closures); "
                                f"this is {pin.__version__}")
    require("mujoco", extra="mujoco", what="Mechanism.from_mjcf")
    import mujoco

    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # MuJoCo's reader raises ValueError with its own message
        raise MalformedURDFError(f"{path}: MuJoCo cannot read it ({' '.join(str(exc).split())})") from None
    _check_numbers(path, mj)
    _check_values(path, mj)
    _check_one_tree(path, mj)
    try:
        model, cms = reader(str(path))
    except Exception as exc:  # Pinocchio's reader: ValueError, RuntimeError, IndexError, ...
        raise MalformedURDFError(f"{path}: Pinocchio's MJCF reader fails ({type(exc).__name__}: {exc})") from None
    names_of: dict[str, list[str]] = {}
    for b in range(mj.nbody):
        joints = list(range(mj.body_jntadr[b], mj.body_jntadr[b] + mj.body_jntnum[b]))
        if len(joints) > 1:
            names_of[f"Composite_{_joint_name(mj, joints[0])}"] = [_joint_name(mj, i) for i in joints]
    model, ids = _split(model, names_of)
    _place_root(mj, model, cms)
    _mujoco_inertias(path, mj, model)
    return mj, model, cms, ids


def _closures(path: Path, mj: Any, model: pin.Model, cms: list[Any], ids: dict[int, int],
              kinds: list[str]) -> list[Any]:
    """The ``connect`` and ``weld`` equalities as closures, in the file's order (module docstring)."""
    import mujoco

    loops = [i for i, k in enumerate(kinds) if k in ("connect", "weld")]
    if len(loops) != len(cms):
        raise MalformedURDFError(f"{path}: MuJoCo reads {len(loops)} connect/weld equalities, Pinocchio's reader "
                                 f"{len(cms)} closures")
    welds = [cm for cm in cms if cm.type == pin.ContactType.CONTACT_6D]
    out_cms = []
    for i in loops:
        if kinds[i] == "weld":  # Pinocchio's reading of a weld, its joints renumbered
            cm = welds.pop(0)
            c = pin.RigidConstraintModel(cm.type, model, ids[cm.joint1_id], cm.joint1_placement, ids[cm.joint2_id],
                                         cm.joint2_placement, cm.reference_frame)
        else:  # a connect from MuJoCo's own anchors (body1's anchor and its image in body2)
            ends = []
            sides = ((mj.eq_obj1id[i], mj.eq_data[i, 0:3]), (mj.eq_obj2id[i], mj.eq_data[i, 3:6]))
            if int(mj.eq_objtype[i]) == int(mujoco.mjtObj.mjOBJ_SITE):  # connect site1 site2: the sites
                sides = tuple((mj.site_bodyid[o], mj.site_pos[o]) for o in (mj.eq_obj1id[i], mj.eq_obj2id[i]))
            for body, anchor in sides:
                bname = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, body)
                if body == 0 or not bname or not model.existFrame(bname, pin.FrameType.BODY):
                    raise MalformedURDFError(f"{path}: connect {i} joins body {bname or body!r}, not a body of "
                                             "Pinocchio's model")
                f = model.frames[model.getFrameId(bname, pin.FrameType.BODY)]
                ends.append((f.parentJoint, f.placement * pin.SE3(np.eye(3), np.array(anchor))))
            c = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, ends[0][0], ends[0][1], ends[1][0],
                                         ends[1][1], pin.ReferenceFrame.LOCAL)
        c.name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_EQUALITY, i) or ""
        out_cms.append(c)
    return out_cms


def read(path: str | Path) -> tuple[pin.Model, list[Any], MjcfInfo]:
    """The Pinocchio model (composites split), its closures and :class:`MjcfInfo` of an MJCF file
    (module docstring).

    Raises:
        as :meth:`h4pin.mechanism.Mechanism.from_mjcf`.
    """
    path = Path(path)
    mj, model, cms, ids = _load(path)
    import mujoco  # _load has required it

    eq = {int(mujoco.mjtEq.mjEQ_JOINT): "joint", int(mujoco.mjtEq.mjEQ_TENDON): "tendon",
          int(mujoco.mjtEq.mjEQ_CONNECT): "connect", int(mujoco.mjtEq.mjEQ_WELD): "weld"}
    kinds = [eq.get(int(mj.eq_type[i]), "other") for i in range(mj.neq)]
    tendons = [i for i, k in enumerate(kinds) if k in ("tendon", "other")]
    if tendons:
        raise UnsupportedFeatureError(f"{path}: {len(tendons)} tendon (or other) equalities (the first: equality "
                                      f"{tendons[0]}); h4pin's constraints are connect, weld and joint couplings")
    out_cms = _closures(path, mj, model, cms, ids, kinds)
    q = from_qpos(mj, model, mj.key_qpos[0] if mj.nkey else mj.qpos0)
    lo, hi = np.full(model.nq, np.nan), np.full(model.nq, np.nan)
    springs, rest = {}, {}
    for i in range(mj.njnt):
        name = _joint_name(mj, i)
        if not model.existJointName(name):
            raise MalformedURDFError(f"{path}: joint {name!r} of the file is not in Pinocchio's model")
        jm = model.joints[model.getJointId(name)]
        if int(mj.jnt_type[i]) in (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)):
            continue
        ref = _ref(mj, i)
        if mj.jnt_limited[i]:
            lo[jm.idx_q], hi[jm.idx_q] = mj.jnt_range[i] - ref
        if mj.jnt_stiffness[i] > 0:
            springs[name] = float(mj.jnt_stiffness[i])
            rest[name] = float(mj.qpos_spring[mj.jnt_qposadr[i]] - ref)
    _check_kinematics(path, mj, model)
    couplings = []
    for i, k in enumerate(kinds):
        if k != "joint" or not mj.eq_active0[i]:
            continue
        j1, j2 = mj.eq_obj1id[i], mj.eq_obj2id[i]
        origin1 = float(mj.qpos0[mj.jnt_qposadr[j1]]) - _ref(mj, j1)
        origin2 = float(mj.qpos0[mj.jnt_qposadr[j2]]) - _ref(mj, j2) if j2 >= 0 else 0.0
        couplings.append(JointCoupling(_joint_name(mj, j1), _joint_name(mj, j2) if j2 >= 0 else None,
                                       tuple(float(c) for c in mj.eq_data[i, :5]), origin1, origin2))
    motors, refused = [], []
    for a in range(mj.nu):
        aname = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator {a}"
        if int(mj.actuator_trntype[a]) not in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            refused.append(aname)
            continue
        joint = _joint_name(mj, mj.actuator_trnid[a, 0])
        if not model.existJointName(joint):
            raise ParameterError(f"{path}: actuator {aname!r} drives joint {joint!r}, not a joint of the model")
        if joint not in motors:
            motors.append(joint)
    return model, out_cms, MjcfInfo(model.name or path.stem, q, (lo, hi), springs, rest, tuple(motors),
                                     tuple(refused), tuple(couplings))


__all__ = ["MjcfInfo", "check_files", "from_qpos", "read"]
