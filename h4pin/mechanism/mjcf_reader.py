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
  joint of its own. Every file read is checked: the two readers' body placements agree at the
  reference and at random configurations (relative to the root body: Pinocchio's reader drops a
  fixed root's placement on the world), or the bodies that differ are named
  (:class:`~h4pin.errors.UnsupportedFeatureError`; Pinocchio's reader ignores a joint ``pos`` set
  by a default class, for one).
* MuJoCo's compiler (``mujoco.MjModel``): the reference configuration (the first keyframe, else
  ``qpos0``, where each joint's ``ref`` is), the ranges of limited hinges and slides, the joints'
  ``stiffness`` and ``springref`` (all in Pinocchio's coordinates), the equalities
  and the actuators' transmissions.

Joint couplings (``<equality><joint polycoef>``) become :class:`~h4pin.mechanism.couplings.JointCoupling`
constraints. What neither reader can represent is refused by name
(:class:`~h4pin.errors.UnsupportedFeatureError`): tendon equalities, actuators that do not drive a
joint (unless the motors are given).
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
        out.addFrame(pin.Frame(f.name, ids[f.parentJoint], f.placement, f.type, f.inertia), False)
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


def _check_kinematics(path: Path, mj: Any, model: pin.Model, reference: np.ndarray) -> None:
    """Refuse a file whose two readings place a body differently (module docstring)."""
    import mujoco

    d, pd = mujoco.MjData(mj), model.createData()
    rng = np.random.default_rng(0)
    bodies = [(b, mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b)) for b in range(1, mj.nbody)]
    bodies = [(b, n) for b, n in bodies if n and model.existFrame(n, pin.FrameType.BODY)]
    if not bodies:
        return
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
        root_mj = pin.SE3(d.xmat[bodies[0][0]].reshape(3, 3), d.xpos[bodies[0][0]])
        root_pin = pd.oMf[model.getFrameId(bodies[0][1], pin.FrameType.BODY)]
        length = max(1e-3, float(np.ptp(d.xpos, axis=0).max()))
        for b, n in bodies:
            a = root_mj.actInv(pin.SE3(d.xmat[b].reshape(3, 3), d.xpos[b]))
            p = root_pin.actInv(pd.oMf[model.getFrameId(n, pin.FrameType.BODY)])
            gap = float(np.linalg.norm(a.translation - p.translation))
            turn = float(np.linalg.norm(pin.log3(a.rotation.T @ p.rotation)))
            if gap > 1e-9 * length or turn > 1e-9:
                raise UnsupportedFeatureError(
                    f"{path}: Pinocchio's MJCF reader places body {n!r} {gap * 1e3:.3g} mm and {turn:.3g} rad away "
                    "from where MuJoCo does (a joint pos from a default class, or a feature it reads otherwise); "
                    "h4pin would compute another robot")


def read(path: str | Path) -> tuple[pin.Model, list[Any], MjcfInfo]:
    """The Pinocchio model (composites split), its closures and :class:`MjcfInfo` of an MJCF file
    (module docstring).

    Raises:
        as :meth:`h4pin.mechanism.Mechanism.from_mjcf`.
    """
    from h4pin.extras import MissingExtraError, require

    reader = getattr(pin, "buildModelAndLegacyConstraintsFromMJCF", None)
    if reader is None:
        raise MissingExtraError(f"Mechanism.from_mjcf needs Pinocchio >= 4 (its MJCF reader's closures); "
                                f"this is {pin.__version__}")
    require("mujoco", extra="mujoco", what="Mechanism.from_mjcf")
    import mujoco

    path = Path(path)
    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # MuJoCo's reader raises ValueError with its own message
        raise MalformedURDFError(f"{path}: MuJoCo cannot read it ({exc})") from None
    try:
        model, cms = reader(str(path))
    except Exception as exc:  # Pinocchio's reader: ValueError, RuntimeError, IndexError, ...
        raise MalformedURDFError(f"{path}: Pinocchio's MJCF reader fails ({type(exc).__name__}: {exc})") from None

    eq = {int(mujoco.mjtEq.mjEQ_JOINT): "joint", int(mujoco.mjtEq.mjEQ_TENDON): "tendon",
          int(mujoco.mjtEq.mjEQ_CONNECT): "connect", int(mujoco.mjtEq.mjEQ_WELD): "weld"}
    kinds = [eq.get(int(mj.eq_type[i]), "other") for i in range(mj.neq)]
    tendons = [i for i, k in enumerate(kinds) if k in ("tendon", "other")]
    if tendons:
        raise UnsupportedFeatureError(f"{path}: {len(tendons)} tendon (or other) equalities (the first: equality "
                                      f"{tendons[0]}); h4pin's constraints are connect, weld and joint couplings")
    loops = [i for i, k in enumerate(kinds) if k in ("connect", "weld")]
    if len(loops) != len(cms):
        raise MalformedURDFError(f"{path}: MuJoCo reads {len(loops)} connect/weld equalities, Pinocchio's reader "
                                 f"{len(cms)} closures (it reads one tree: a second body on the world is lost)")
    names_of: dict[str, list[str]] = {}
    for b in range(mj.nbody):
        joints = list(range(mj.body_jntadr[b], mj.body_jntadr[b] + mj.body_jntnum[b]))
        if len(joints) > 1:
            names_of[f"Composite_{_joint_name(mj, joints[0])}"] = [_joint_name(mj, i) for i in joints]
    model, ids = _split(model, names_of)
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
    _check_kinematics(path, mj, model, q)
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
