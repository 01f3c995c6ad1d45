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
has not one value per coordinate (MuJoCo fills the rest). What neither reader can represent is
refused by name (:class:`~h4pin.errors.UnsupportedFeatureError`): tendon equalities, actuators
that do not drive a joint (unless the motors are given), a second body on the world with joints
(Pinocchio's reader reads the first tree only).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import MalformedURDFError, ParameterError, UnsupportedFeatureError
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

    reader = getattr(pin, "buildModelAndLegacyConstraintsFromMJCF", None)
    if reader is None:
        raise MissingExtraError(f"Mechanism.from_mjcf needs Pinocchio >= 4 (its MJCF reader's closures); "
                                f"this is {pin.__version__}")
    require("mujoco", extra="mujoco", what="Mechanism.from_mjcf")
    import mujoco

    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # MuJoCo's reader raises ValueError with its own message
        raise MalformedURDFError(f"{path}: MuJoCo cannot read it ({exc})") from None
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


__all__ = ["MjcfInfo", "from_qpos", "read"]
