# SPDX-License-Identifier: Apache-2.0
"""Any mechanism as an elastic MuJoCo model (``mujoco`` extra): :meth:`Mechanism.to_mjcf
<h4pin.mechanism.Mechanism.to_mjcf>`, the counterpart of :mod:`h4pin.mechanism.mjcf_reader`.

:func:`spec` builds a ``mujoco.MjSpec`` from the mechanism's Pinocchio model, its closures and a
set of joint springs; :func:`to_xml` has MuJoCo write it (every number to 17 significant
digits) and :func:`write` writes it to a file (atomically, with h4pin's mark: replaced later only
if unchanged, or with ``overwrite``). What the file holds (``docs/mechanisms.md``):

- one body per Pinocchio joint, named after it, whose frame is the joint's frame, in the model's
  tree under a fixed body ``base`` (the universe; a free joint's body is in the world, as MuJoCo
  wants); its inertia is ``model.inertias`` (mass, centre of mass, full tensor). A moving body with
  no mass (a beam's virtual joint, a closure's massless joint) gets :data:`CHAIN_MASS`, next to
  nothing, as the H4's elastic export does;
- each joint as a MuJoCo joint of its name: revolute (any axis, bounded or not) -> ``hinge``,
  prismatic -> ``slide`` (each with its range where the mechanism has one), spherical -> ``ball``,
  a free-flyer on the universe -> ``free``; other kinds are refused by name. Hinges and slides
  are drawn at Pinocchio's neutral configuration (no ``ref``: the file means the same to any MJCF
  reader); a ball's or free joint's body is drawn at its rotation (and a free body at its
  placement) in ``q``, since MuJoCo measures their springs from the drawn pose;
- a joint with a spring (``springs``, and the beams' :attr:`Mechanism.beam_springs`): its
  ``stiffness`` (N.m/rad, N/m; a ball's or free joint's must be one value for all its
  coordinates), ``springref`` its value in ``q`` (``q`` is the springs' rest configuration), and
  ``damping = damping * stiffness`` (stiffness-proportional: a mode of frequency f gets the
  damping ratio ``pi f damping``); a sprung joint whose own inertia I (the diagonal of the mass
  matrix in ``q``) is below ``stiffness (ARMATURE_STEPS * timestep)^2`` gets the rest as armature,
  so that alone on its spring it swings no faster than ``1 / (ARMATURE_STEPS * timestep)`` rad/s,
  which MuJoCo's explicit springs integrate stably (a joint that moves no mass gets it all, as in
  the H4's export; the statics are unchanged, the fastest local modes slowed);
- locked joints (``locked``, the motors without a spring and the free-flyer roots without one,
  as :meth:`Mechanism.compliance` holds them) are left out: their bodies welded at their value in
  ``q``. A motor with a spring is a sprung joint (the spring: its servo's stiffness) and carries a
  torque ``motor`` actuator (N.m, gear 1) for loads on top of it;
- each closure as an equality between two sites ``<closure>_1`` and ``<closure>_2`` at its two
  frames (``joint1_placement``, ``joint2_placement``): ``CONTACT_3D`` -> ``connect``,
  ``CONTACT_6D`` -> ``weld``, with the stiff :data:`ELASTIC_SOLREF` and :data:`ELASTIC_SOLIMP` at
  :data:`ELASTIC_TIMESTEP`; each joint coupling as a ``joint`` equality;
- a site at each frame of ``sites`` (its name, its placement), the keyframe :data:`KEYFRAME`
  holding ``q``, and gravity as the model's (switch it off for a load test: the compliance has
  no preload).

The helpers and settings the H4's export (:mod:`h4pin.io.mjcf`) shares live here too.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import warnings
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.errors import ParameterError, UnsupportedFeatureError
from h4pin.files import check_output, check_replace, write_text
from h4pin.inputs import check_real, real_array
from h4pin.mechanism import engine
from h4pin.mechanism.arguments import items

#: The elastic exports: time step (s), and the closures' solref (time constant s, damping ratio)
#: and solimp. A closure then acts as a spring of stiffness ~ m_eff d / ((1 - d) tau^2) (m_eff
#: the mass it moves, d = 0.9999 the impedance, tau = 1e-4 s), some 1e12 m_eff N/m: stiffer
#: than the joint springs by many orders, so it adds < 0.1 % to the compliance
#: (``docs/mujoco.md``); MuJoCo keeps tau >= 2 time steps, hence the time step.
ELASTIC_TIMESTEP = 5e-5
ELASTIC_SOLREF = (1e-4, 1.0)
ELASTIC_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: Stiffness-proportional damping of the elastic joints (s): damping = DAMPING * stiffness, so a
#: mode of frequency f has the damping ratio pi f DAMPING (1.0 % at the prototype's first, 32.7 Hz).
DAMPING = 1e-4
#: Mass (kg) and principal inertias (kg.m^2) of the body of a virtual joint: next to nothing,
#: but MuJoCo refuses a body that moves on joints with no mass and inertia of its own.
CHAIN_MASS = (1e-6, 1e-12)
#: A virtual joint that moves no mass gets the armature ``k (ARMATURE_STEPS * timestep)^2`` (kg.m^2 or
#: kg; k its stiffness): alone on its spring it would swing at ``1 / (ARMATURE_STEPS * timestep)``
#: rad/s, slow enough for MuJoCo's explicit springs (mass scaling; docs/mujoco.md).
ARMATURE_STEPS = 2.0
#: Name of the keyframe holding the configuration the file was written at.
KEYFRAME = "q0"
#: Lowest MuJoCo version the elastic exports work with (tested in CI): 3.2.4's ``MjSpec.compile``
#: steps the model at its reference configuration, where an elastic file's loops are open
#: (hinges drawn at zero, locked joints at a pose), and refuses it as unstable.
MIN_MUJOCO_ELASTIC = "3.2.5"
#: Largest closure error (m, rad) of a configuration written as the rest configuration.
CLOSED_TOL = 1e-9
_WHAT = "the elastic MuJoCo export of a mechanism (h4pin.mechanism.mjcf_writer)"


# ---------------------------------------------------------------- helpers shared with h4pin.io.mjcf
def version(text: str) -> tuple[int, ...]:
    """A version string as a tuple of up to three integers (``"3.2.5"`` -> ``(3, 2, 5)``)."""
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


def require_mujoco(least: str, what: str) -> Any:
    """The ``mujoco`` module, at least version ``least``, for ``what`` (named in the error).

    Raises:
        MissingExtraError: MuJoCo is not installed, or older than ``least``.
    """
    from h4pin.extras import MissingExtraError, require

    require("mujoco", extra="mujoco", what=what)
    import mujoco

    if version(mujoco.__version__) < version(least):
        raise MissingExtraError(f"{what} needs MuJoCo >= {least}, this is {mujoco.__version__}: "
                                f"pip install 'mujoco>={least}'")
    return mujoco


@contextlib.contextmanager
def full_precision(mujoco: Any) -> Iterator[bool]:
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


def floats(values: Any) -> list[float]:
    """``values`` flattened to a list of Python floats (what ``MjSpec`` fields take)."""
    return [float(v) for v in np.ravel(values)]


def quaternion(rotation: np.ndarray) -> list[float]:
    """Quaternion (w x y z, w >= 0) of a rotation matrix."""
    q = pin.Quaternion(np.asarray(rotation, float))
    q.normalize()
    w = np.array([q.w, q.x, q.y, q.z])
    return floats(w if w[0] >= 0 else -w)


def _neutral(joint: Any) -> np.ndarray:
    q = np.zeros(joint.nq)
    if joint.nq == 2:  # unbounded revolute: (cos, sin)
        q[0] = 1.0
    return q


def motion(joint: Any) -> np.ndarray:
    """First column of a joint's motion subspace (linear, angular), in its joint frame."""
    jd = joint.createData()
    joint.calc(jd, _neutral(joint))
    s = jd.S
    return np.asarray(s.matrix() if hasattr(s, "matrix") else s, float).reshape(6, -1)[:, 0]


def is_revolute(joint: Any) -> bool:
    """Whether a Pinocchio joint model turns about one axis (any axis, bounded or not)."""
    return joint.nv == 1 and joint.nq in (1, 2) and bool(np.allclose(motion(joint)[:3], 0.0))


def is_prismatic(joint: Any) -> bool:
    """Whether a Pinocchio joint model slides along one axis."""
    return joint.nv == 1 and joint.nq == 1 and bool(np.allclose(motion(joint)[3:], 0.0))


def is_free(joint: Any) -> bool:
    """Whether a Pinocchio joint model is a free-flyer."""
    return joint.nq == 7 and joint.nv == 6


def angle(joint: Any, q: np.ndarray) -> float:
    """The angle of a revolute joint (bounded: q; unbounded: atan2(sin, cos))."""
    v = q[joint.idx_q:joint.idx_q + joint.nq]
    return float(v[0]) if joint.nq == 1 else float(np.arctan2(v[1], v[0]))


def set_spring(mujoco: Any, j: Any, stiffness: float, damping: float, springref: float, armature: float) -> None:
    """A spring on MuJoCo joint ``j`` (``MjsJoint``): stiffness, damping, rest position and
    armature, without limits."""
    for field, value in (("stiffness", stiffness), ("damping", damping)):
        now = getattr(j, field)
        setattr(j, field, [value] + [0.0] * (len(now) - 1) if np.ndim(now) else value)  # MuJoCo 4: a 3-vector
    j.springref = springref
    j.armature = armature
    j.limited = mujoco.mjtLimited.mjLIMITED_FALSE


# ---------------------------------------------------------------- a mechanism
def _spring_values(model: pin.Model, springs: Mapping[Any, Any], beam_springs: Mapping[str, Any]) -> dict[str, float]:
    """``{joint name: one stiffness}`` of the beams' springs and ``springs`` (names or joint ids),
    checked as :func:`h4pin.mechanism.engine.stiffness_vector` checks them."""
    if not isinstance(springs, Mapping):
        raise ParameterError(f"springs: a mapping {{joint: stiffness}}, got {springs!r}")
    named: dict[str, Any] = dict(beam_springs)
    for key, value in springs.items():
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool) and 0 < int(key) < model.njoints:
            key = model.names[int(key)]
        if not isinstance(key, str) or not model.existJointName(key):
            raise ParameterError(f"springs: no joint {key!r} in the model (joints: {', '.join(list(model.names)[1:])})")
        named[key] = value
    k = engine.stiffness_vector(model, named)
    out = {}
    for name in named:
        jm = model.joints[model.getJointId(name)]
        values = k[jm.idx_v:jm.idx_v + jm.nv]
        if not np.all(values == values[0]):
            raise UnsupportedFeatureError(f"springs: joint {name!r} has {jm.nv} stiffnesses {floats(values)}; "
                                          "MuJoCo gives a ball or free joint one stiffness for all its coordinates")
        out[name] = float(values[0])
    return out


def _configuration(mech: Any, q: Any) -> np.ndarray:
    """``q`` (default: :meth:`Mechanism.assemble`) checked: (nq,), finite, closing every loop."""
    model = mech.model
    if q is None:
        return np.asarray(mech.assemble(), float)
    q = np.array(real_array(q, "q", ParameterError, f"a configuration ({model.nq},) of real numbers"))
    if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
        raise ParameterError(f"q: a finite configuration of shape ({model.nq},), got shape {q.shape}")
    worst = max(((max(e), n) for n, e in mech.closure_errors(q).items()), default=(0.0, ""))
    if not worst[0] <= CLOSED_TOL:
        raise engine.UnassembledError(f"q: closure {worst[1]!r} is off by {worst[0]:.3e} (m or rad; at most "
                                      f"{CLOSED_TOL:g}): write an assembled configuration (mech.assemble())")
    return q


def _locked(mech: Any, locked: Iterable[Any], springs: Mapping[str, float]) -> set[int]:
    """Joint ids left out of the file: ``locked``, the motors and free-flyer roots without a spring."""
    model = mech.model
    out = set()
    for name in items(locked, (str, bytes), "locked: joint names"):
        if not isinstance(name, str) or not model.existJointName(name):
            raise ParameterError(f"locked: no joint {name!r} in the model")
        if name in springs:
            raise ParameterError(f"joint {name!r} cannot be both locked and sprung")
        out.add(int(model.getJointId(name)))
    for name in (*mech.actuated, *mech.free_flyers):
        if name not in springs:
            out.add(int(model.getJointId(name)))
    return out


def _kind(mujoco: Any, model: pin.Model, j: int) -> Any:
    """The MuJoCo joint type of Pinocchio joint ``j``, or an :class:`UnsupportedFeatureError`."""
    jm, kinds = model.joints[j], mujoco.mjtJoint
    if is_revolute(jm):
        return kinds.mjJNT_HINGE
    if is_prismatic(jm):
        return kinds.mjJNT_SLIDE
    if jm.shortname() == "JointModelSpherical":
        return kinds.mjJNT_BALL
    if is_free(jm) and jm.shortname() == "JointModelFreeFlyer":
        if model.parents[j] != 0:
            raise UnsupportedFeatureError(f"joint {model.names[j]!r}: MuJoCo has free joints only on the world "
                                          "(lock it, or give it a spring)")
        return kinds.mjJNT_FREE
    raise UnsupportedFeatureError(f"joint {model.names[j]!r} ({jm.shortname()}) has no MuJoCo counterpart here "
                                  "(revolute, prismatic, spherical and free-flyer joints only)")


def _inertia(body: Any, inertia: Any, moving: bool) -> None:
    """A body's mass, centre of mass and full inertia tensor (a moving body at least :data:`CHAIN_MASS`)."""
    mass, tensor = float(inertia.mass), np.array(inertia.inertia, float)
    if moving and mass < CHAIN_MASS[0]:
        mass, tensor = CHAIN_MASS[0], np.eye(3) * CHAIN_MASS[1]
    elif moving and np.min(np.linalg.eigvalsh(tensor)) < CHAIN_MASS[1]:
        tensor = tensor + np.eye(3) * CHAIN_MASS[1]  # a point mass: MuJoCo wants inertia too
    if mass <= 0:
        return
    body.mass, body.ipos = mass, floats(inertia.lever)
    body.fullinertia = floats([tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]])
    if hasattr(body, "explicitinertial"):
        body.explicitinertial = True


def _bodies(mujoco: Any, s: Any, mech: Any, q: np.ndarray, springs: Mapping[str, float], locked: set[int],
            damping: float, timestep: float) -> tuple[dict[int, Any], dict[str, float]]:
    """One body per joint (its joint, spring and inertia); returns the bodies by joint id and each
    MuJoCo joint's value in ``q`` (hinges and slides)."""
    model = mech.model
    at_q, at_zero = model.createData(), model.createData()
    pin.forwardKinematics(model, at_q, q)
    pin.forwardKinematics(model, at_zero, pin.neutral(model))
    inertia = np.diag(pin.crba(model, at_q, q)).copy()  # each coordinate's own inertia in q (kg.m^2, kg)
    lo, hi = mech.ranges
    base = s.worldbody.add_body()  # one tree: Pinocchio's MJCF reader reads the world's first body only
    base.name = next(n for n in ("base", *(f"base_{i}" for i in range(1, model.njoints + 1)))
                     if not model.existJointName(n))
    bodies, values = {0: base}, {}
    for j in range(1, model.njoints):
        jm, name = model.joints[j], model.names[j]
        kind = None if j in locked else _kind(mujoco, model, j)
        drawn = at_zero if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE) else at_q
        up = s.worldbody if kind == mujoco.mjtJoint.mjJNT_FREE else bodies[model.parents[j]]
        body = up.add_body()
        body.name = name
        body.pos, body.quat = floats(drawn.liMi[j].translation), quaternion(drawn.liMi[j].rotation)
        bodies[j] = body
        _inertia(body, model.inertias[j], kind is not None)
        if kind is None:
            continue
        joint = body.add_joint()
        joint.name, joint.type = name, kind
        if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            axis = motion(jm)
            joint.axis = floats(axis[3:] if kind == mujoco.mjtJoint.mjJNT_HINGE else axis[:3])
            values[name] = angle(jm, q) if jm.nq == 2 else float(q[jm.idx_q])
        if name in springs:
            k = springs[name]
            own = float(np.min(inertia[jm.idx_v:jm.idx_v + jm.nv]))
            set_spring(mujoco, joint, k, damping * k, values.get(name, 0.0),
                       max(k * (ARMATURE_STEPS * timestep) ** 2 - own, 0.0))
        if jm.nq == 1 and np.isfinite(lo[jm.idx_q]) and np.isfinite(hi[jm.idx_q]):
            joint.limited, joint.range = mujoco.mjtLimited.mjLIMITED_TRUE, [float(lo[jm.idx_q]), float(hi[jm.idx_q])]
        else:
            joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    return bodies, values


def _closures(mujoco: Any, s: Any, mech: Any, bodies: dict[int, Any], solref: Any, solimp: Any) -> None:
    """Each closure as a connect (3-D) or weld (6-D) between two sites at its frames."""
    for cm in mech.constraint_models:
        for side, (joint, place) in enumerate(((cm.joint1_id, cm.joint1_placement),
                                               (cm.joint2_id, cm.joint2_placement)), 1):
            site = bodies[int(joint)].add_site()
            site.name, site.pos, site.quat = f"{cm.name}_{side}", floats(place.translation), quaternion(place.rotation)
            site.size, site.group = [0.003, 0.0, 0.0], 3
        e = s.add_equality()
        e.name, e.objtype = cm.name, mujoco.mjtObj.mjOBJ_SITE
        e.type = mujoco.mjtEq.mjEQ_CONNECT if cm.type == pin.ContactType.CONTACT_3D else mujoco.mjtEq.mjEQ_WELD
        e.name1, e.name2 = f"{cm.name}_1", f"{cm.name}_2"
        e.solref, e.solimp = floats(solref), floats(solimp)


def _couplings(mujoco: Any, s: Any, mech: Any, locked: set[int], solref: Any, solimp: Any) -> None:
    """Each joint coupling as a ``joint`` equality: its polynomial about the origins re-expanded
    about 0 (MuJoCo measures from ``qpos0``, here Pinocchio's zero)."""
    model = mech.model
    for c in mech.couplings:
        joints = [c.joint1] + ([c.joint2] if c.joint2 is not None else [])
        if any(model.getJointId(n) in locked for n in joints):
            raise UnsupportedFeatureError(f"coupling of {c.joint1!r}: a coupled joint is locked (left out of the file)")
        shifted = np.polynomial.Polynomial(c.poly)(np.polynomial.Polynomial([-c.origin2, 1.0]))
        coef = np.zeros(5)
        if len(shifted.coef) > 5:
            raise UnsupportedFeatureError(f"coupling of {c.joint1!r}: MuJoCo takes polynomials of degree 4 at most")
        coef[:len(shifted.coef)] = shifted.coef
        coef[0] += c.origin1
        e = s.add_equality()
        e.name, e.type, e.objtype = f"coupling_{c.joint1}", mujoco.mjtEq.mjEQ_JOINT, mujoco.mjtObj.mjOBJ_JOINT
        e.name1 = c.joint1
        if c.joint2 is not None:
            e.name2 = c.joint2
        e.data = floats(np.r_[coef, np.zeros(len(e.data) - 5)])
        e.solref, e.solimp = floats(solref), floats(solimp)


def compile_spec(mujoco: Any, s: Any) -> Any:
    """``s.compile()``; MuJoCo 3.2.5 to 3.9 step a model once from ``qpos0`` as they compile it and
    refuse it when the accelerations there pass their limit: the file's ``qpos0`` is the drawn
    pose, where the loops are open, and its closures' forces there grow as ``1 / timestep^2``.

    Raises:
        UnsupportedFeatureError: that refusal, with what to change (MuJoCo's message in it).
    """
    try:
        return s.compile()
    except ValueError as exc:
        if "QACC" not in str(exc):
            raise
        raise UnsupportedFeatureError(
            f"MuJoCo {mujoco.__version__} refuses the elastic file: its compiler steps the model once from qpos0, "
            "the drawn pose where the loops are open, and the closures' forces there (stiff as 1/timestep^2) pass its "
            f"limit ({' '.join(str(exc).split())}); use a larger timestep, or MuJoCo >= 3.10 (it does not step "
            "the model)") from None


def _keyframe(mujoco: Any, s: Any, values: Mapping[str, float]) -> None:
    """Keyframe :data:`KEYFRAME`: hinges and slides at their values in ``q``, balls and free joints
    at their drawn pose (``q`` too)."""
    m = compile_spec(mujoco, s)
    qpos = np.array(m.qpos0)
    for i in range(m.njnt):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i)
        if name in values:
            qpos[m.jnt_qposadr[i]] = values[name]
    key = s.add_key()
    key.name, key.qpos = KEYFRAME, floats(qpos)


def _payload(s: Any, mech: Any, bodies: dict[int, Any], payload: Any) -> None:
    """A body ``payload`` fixed at the payload's frame: its mass, centre of mass and inertia."""
    from h4pin.mechanism.payload import at_frame

    _, body, f = at_frame(mech.model, payload)
    b = bodies[int(f.parentJoint)].add_body()
    b.name, b.pos, b.quat = "payload", floats(f.placement.translation), quaternion(f.placement.rotation)
    if body.mass > 0:
        b.mass, b.ipos = float(body.mass), floats(body.com)
        i = np.asarray(body.inertia, float) + np.eye(3) * CHAIN_MASS[1]  # MuJoCo wants inertia on a mass
        b.fullinertia = floats([i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]])
        if hasattr(b, "explicitinertial"):
            b.explicitinertial = True


#: The options of :func:`spec` (and of :func:`to_xml`, :func:`write`, ``Mechanism.to_mjcf``).
OPTIONS = ("locked", "sites", "name", "damping", "solref", "solimp", "timestep", "payload")


def check_options(options: Mapping[str, Any]) -> None:
    """Refuse an option :func:`spec` does not take, naming it and the options."""
    unknown = [k for k in options if k not in OPTIONS]
    if unknown:
        raise ParameterError(f"to_mjcf: no option {unknown[0]!r}; the options are {', '.join(OPTIONS)}")


def _check_spec_options(sites: Any, name: Any, solref: Any, solimp: Any) -> tuple[list[str], Any, Any]:
    """``(sites, solref, solimp)`` of :func:`spec` checked: frame names, a name that is a ``str``
    or None, ``solref`` None or 2 finite numbers, ``solimp`` 5 finite numbers."""
    sites = items(sites, (str,), "sites: frame names")
    if not all(isinstance(f, str) for f in sites):
        raise ParameterError(f"sites: frame names (str), got {sites!r:.200}")
    if name is not None and not isinstance(name, str):
        raise ParameterError(f"name: the model's name, a str or None, got {name!r:.100}")
    for label, value, sizes in (("solref", solref, (2,)), ("solimp", solimp, (5,))):
        if value is None and label == "solref":
            continue
        arr = real_array(value, label, ParameterError, f"{' or '.join(map(str, sizes))} real numbers")
        if arr.shape not in [(n,) for n in sizes] or not np.all(np.isfinite(arr)):
            raise ParameterError(f"{label}: {' or '.join(map(str, sizes))} finite numbers (MuJoCo's {label}), "
                                 f"got {value!r:.100}")
    return sites, solref, solimp


def check_settings(damping: Any, timestep: Any) -> tuple[float, float]:
    """``(damping, timestep)`` (s) as floats: real numbers (not bools), the damping within
    ``h4pin.limits.RANGES["damping"]`` (0 to 1 s) and the time step within ``["timestep"]``
    (1e-9 to 0.1 s); else a :class:`ParameterError` naming the option and its range."""
    out = []
    for label, value in (("damping", damping), ("timestep", timestep)):
        check_real(value, label, unit="s")
        out.append(float(limits.check_range(label, float(value), label)))
    return out[0], out[1]


def spec(mech: Any, springs: Mapping[Any, Any], q: Any = None, *, locked: Iterable[Any] = (),
         sites: Iterable[str] = (), name: str | None = None, damping: float = DAMPING,
         solref: Any = None, solimp: Any = ELASTIC_SOLIMP, timestep: float = ELASTIC_TIMESTEP,
         payload: Any = None) -> Any:
    """The mechanism with its springs as a ``mujoco.MjSpec`` (not compiled; what it holds: the
    module's description).

    Args:
        mech: an :class:`h4pin.mechanism.Mechanism` (with beams: their springs are added).
        springs: ``{joint: stiffness}`` (names or joint ids; N.m/rad, N/m), as
            :meth:`Mechanism.compliance` takes them.
        q: an assembled configuration (nq,), the springs' rest and the keyframe (default
            ``mech.assemble()``).
        locked: joints held at their value in ``q`` (as :meth:`Mechanism.compliance`); motors
            and free-flyer roots without a spring are locked too.
        sites: frame names given a site each (outputs to measure or load).
        name: the model's name (default the mechanism's).
        damping: stiffness-proportional damping coefficient (s), 0 to 1 (:func:`check_settings`).
        solref, solimp: the closures' (and couplings') constraint parameters (default
            ``(2 timestep, 1)``, the stiffest MuJoCo keeps, and :data:`ELASTIC_SOLIMP`).
        timestep: MuJoCo time step (s), 1e-9 to 0.1 (:func:`check_settings`). A closure is a spring of stiffness about
            ``2.5e3 m / timestep^2`` (N/m; m the mass it moves, ``docs/mechanisms.md``): a light
            mechanism (links of grams) needs a smaller step than the default for its closures to
            stay far stiffer than its springs.
        payload: ``(frame, h4pin.mechanism.Payload)``: a body of its mass, centre of mass and
            inertia (in the frame's axes) fixed to that frame, as
            :meth:`Mechanism.equilibrium <h4pin.mechanism.Mechanism.equilibrium>` weighs it.

    Raises:
        MissingExtraError: MuJoCo is not installed, or older than :data:`MIN_MUJOCO_ELASTIC`.
        ParameterError: an unknown joint or frame, a bad stiffness, damping or time step, a joint
            both locked and sprung.
        UnassembledError: ``q`` does not close the loops (:data:`CLOSED_TOL`).
        UnsupportedFeatureError: a joint MuJoCo has no counterpart of, a ball or free joint with
            several stiffnesses, a coupling MuJoCo cannot state.
    """
    model = mech.model
    stiff = _spring_values(model, springs, mech.beam_springs)
    sites, solref, solimp = _check_spec_options(sites, name, solref, solimp)
    held = _locked(mech, locked, stiff)
    for frame in sites:
        engine.frame_id(model, frame, what="sites")
    damping, timestep = check_settings(damping, timestep)
    mujoco = require_mujoco(MIN_MUJOCO_ELASTIC, _WHAT)  # after the values: a bad one is named first
    q = _configuration(mech, q)
    solref = (2.0 * float(timestep), 1.0) if solref is None else solref
    s = mujoco.MjSpec()
    s.modelname = name or mech.name
    getattr(s, "compiler", s).degree = False  # MuJoCo >= 3.2.5 groups it under spec.compiler
    s.option.timestep = float(timestep)
    s.option.gravity = floats(model.gravity.linear)
    s.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    bodies, values = _bodies(mujoco, s, mech, q, stiff, held, float(damping), float(timestep))
    _closures(mujoco, s, mech, bodies, solref, solimp)
    _couplings(mujoco, s, mech, held, solref, solimp)
    for frame in sites:
        f = model.frames[engine.frame_id(model, frame)]
        site = bodies[int(f.parentJoint)].add_site()
        site.name, site.pos, site.quat = frame, floats(f.placement.translation), quaternion(f.placement.rotation)
        site.size, site.group = [0.004, 0.0, 0.0], 2
    if payload is not None:
        _payload(s, mech, bodies, payload)
    for motor in mech.actuated:
        if motor in stiff:
            a = s.add_actuator()
            a.name, a.trntype, a.target = motor, mujoco.mjtTrn.mjTRN_JOINT, motor
            a.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    _keyframe(mujoco, s, values)
    return s


def to_xml(mech: Any, springs: Mapping[Any, Any], q: Any = None, **options: Any) -> str:
    """MJCF text of :func:`spec` (same arguments), compiled and written by MuJoCo to 17
    significant digits, after two comment lines: the licence, and what wrote it."""
    check_options(options)
    s = spec(mech, springs, q, **options)
    mujoco = require_mujoco(MIN_MUJOCO_ELASTIC, _WHAT)
    compile_spec(mujoco, s)
    with full_precision(mujoco):
        text = s.to_xml()
    note = ("<!-- SPDX-License-Identifier: Apache-2.0 -->\n"
            f"<!-- The mechanism '{s.modelname}', written by h4pin.mechanism.mjcf_writer through MuJoCo "
            f"{mujoco.__version__}'s MjSpec: one body per joint, the springs as joint stiffness (rest at keyframe "
            f"{KEYFRAME}), the motors without a spring locked, the closures as connect/weld equalities. -->\n")
    head, sep, rest = text.partition("\n")
    return head + sep + note + rest if head.startswith("<?xml") else note + text


def write(mech: Any, path: str | os.PathLike[str], springs: Mapping[Any, Any], q: Any = None, *,
          overwrite: bool = False, **options: Any) -> Path:
    """Write :func:`to_xml` (the options of :func:`spec`) to ``path`` atomically (a temporary file
    renamed, mode 0644, with h4pin's mark); the model is named after the file unless ``name`` is
    given. An existing file is replaced only if h4pin wrote it and it is unchanged, or with
    ``overwrite``; nothing is written when anything fails.

    Raises:
        ParameterError: ``path`` cannot be written (no folder, a folder, not ``.xml``), or is a
            file h4pin did not write and ``overwrite`` is False; as :func:`spec`.
    """
    check_options(options)
    path = check_output(path, "path", suffixes=(".xml",))
    check_replace(path, "path", overwrite)
    options.setdefault("name", path.stem)
    return write_text(path, to_xml(mech, springs, q, **options))


__all__ = ["ARMATURE_STEPS", "CHAIN_MASS", "CLOSED_TOL", "DAMPING", "ELASTIC_SOLIMP", "ELASTIC_SOLREF",
           "ELASTIC_TIMESTEP", "KEYFRAME", "MIN_MUJOCO_ELASTIC", "OPTIONS", "angle", "check_options", "check_settings",
           "compile_spec", "floats", "full_precision", "is_free", "is_prismatic", "is_revolute", "motion", "quaternion",
           "require_mujoco", "set_spring", "spec", "to_xml", "version", "write"]
