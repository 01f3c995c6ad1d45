# SPDX-License-Identifier: Apache-2.0
"""The closed-loop sidecar of a URDF (the YAML of Gepetto's closed-loop toolbox), read once, checked.

Gepetto's ``example-parallel-robots`` publishes each robot as ``robot.urdf`` (a tree) and
``robot.yaml``:

* ``closed_loop``: pairs of frame names; each pair is a loop closure between the two frames'
  parent joints at the frames' placements;
* ``type``: ``3D`` (a point contact, ``CONTACT_3D``) or ``6D`` (a weld, ``CONTACT_6D``) per pair,
  either case;
* ``name_mot``: the motor joints;
* ``beams`` (optional, h4pin's own key): flexible links, ``{link: {E:, G:, d:}}`` for a round
  section or the six values ``E, G, A, Iy, Iz, J``, with ``to:`` and ``carry:`` where needed
  (:class:`h4pin.mechanism.Beam`);
* ``springs`` (optional, h4pin's own key): the joints' springs ``{joint: stiffness}`` (N.m/rad,
  N/m), as a Mechanism's ``springs`` holds them (what a
  calibration writes);
* ``elastic`` (optional, h4pin's own key): the virtual elastic joints among the springs (a beam's,
  a lateral hinge's): at 0 in a rigid assembly, as a Mechanism's ``beam_springs``;
* ``gravity`` (optional, h4pin's own key): the gravity vector in the file's world axes (m/s², default
  Pinocchio's 9.81 down z): a robot written in a tracker's frame;
* ``joint_name`` / ``joint_type`` (optional): joints the loader replaces before it closes the
  loops, because a URDF has no ball or universal joint: ``SPHERICAL`` (a ball joint at the same
  place), ``UJOINT_ab`` (a universal joint: a hinge about axis a then one about axis b, each of X,
  Y, Z; named ``<joint>_a`` and ``<joint>_b``) and ``FIXED`` (the joint locked at 0).

:func:`read` checks every key (a :class:`~h4pin.errors.MalformedURDFError` naming the key and
what it holds); :func:`build` makes the Pinocchio model and closures the way the toolbox's
``completeRobotLoader`` does (the conversions applied before the closures are built). One reader
for the package: :class:`h4pin.mechanism.Mechanism` and :mod:`h4pin.io.interop` use it.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pinocchio as pin

from h4pin.errors import MalformedURDFError, MechanismWarning

#: The joint conversions the toolbox's loader accepts (``joint_type``).
JOINT_TYPES = ("SPHERICAL", "FIXED") + tuple(f"UJOINT_{a}{b}" for a in "XYZ" for b in "XYZ" if a != b)
#: The keys a sidecar may hold.
KEYS = ("closed_loop", "type", "name_mot", "joint_name", "joint_type", "beams", "springs", "elastic", "gravity")
#: A ``beams:`` entry's keys: a round section (``E``, ``G``, ``d``) or the six values; ``to``, ``carry``.
BEAM_KEYS = ("E", "G", "d", "A", "Iy", "Iz", "J", "to", "carry")
_HINGE = {"X": pin.JointModelRX, "Y": pin.JointModelRY, "Z": pin.JointModelRZ}


@dataclasses.dataclass(frozen=True)
class Sidecar:
    """A checked sidecar: ``closed_loop`` pairs, their ``types`` (``"3D"`` / ``"6D"``), the
    ``motors`` (``name_mot``) and the joint conversions ``{joint: type}`` (``joint_name`` /
    ``joint_type``), in file order; ``path`` for messages."""

    path: str
    closed_loop: tuple[tuple[str, str], ...]
    types: tuple[str, ...]
    motors: tuple[str, ...]
    joints: Mapping[str, str]
    beams: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    springs: Mapping[str, float] = dataclasses.field(default_factory=dict)
    elastic: tuple[str, ...] = ()
    gravity: tuple[float, float, float] | None = None


def _strings(path: str, key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise MalformedURDFError(f"{path}: {key} must be a list of names, got {value!r}")
    bad = [v for v in value if not isinstance(v, str) or not v]
    if bad:
        raise MalformedURDFError(f"{path}: {key} must hold names (strings), got {bad[0]!r}")
    return tuple(value)


def parse(content: Any, path: str = "sidecar") -> Sidecar:
    """A :class:`Sidecar` from the YAML's loaded content (a mapping), every key checked.

    Raises:
        MalformedURDFError: not a mapping, an unknown key, a key of the wrong kind or length.
    """
    if not isinstance(content, Mapping):
        raise MalformedURDFError(f"{path}: a closed-loop sidecar is a mapping with closed_loop, type and name_mot, "
                                 f"got {type(content).__name__}")
    unknown = [k for k in content if k not in KEYS]
    if unknown:
        raise MalformedURDFError(f"{path}: unknown key {unknown[0]!r} (known: {', '.join(KEYS)})")
    pairs = content.get("closed_loop")
    if pairs is None:
        raise MalformedURDFError(f"{path}: closed_loop is missing or empty: a list of [frame, frame] pairs")
    if isinstance(pairs, str) or not isinstance(pairs, (list, tuple)):
        raise MalformedURDFError(f"{path}: closed_loop must be a list of [frame, frame] pairs, got {pairs!r}")
    loops = []
    for pair in pairs:
        if isinstance(pair, str) or not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise MalformedURDFError(f"{path}: a closed_loop entry is a pair of frame names, got {pair!r}")
        loops.append(_strings(path, "closed_loop", pair))
    kinds = content.get("type", [])
    if isinstance(kinds, str) or not isinstance(kinds, (list, tuple)):
        raise MalformedURDFError(f"{path}: type must be a list of 3D or 6D, one per closed_loop pair, got {kinds!r}")
    if len(kinds) != len(loops):
        raise MalformedURDFError(f"{path}: {len(loops)} closed_loop pairs but {len(kinds)} types")
    types = []
    for kind in kinds:
        if not isinstance(kind, str) or kind.upper() not in ("3D", "6D"):
            raise MalformedURDFError(f"{path}: a closure type is 3D or 6D, got {kind!r}")
        types.append(kind.upper())
    motors = _strings(path, "name_mot", content.get("name_mot", []))
    if len(set(motors)) != len(motors):
        raise MalformedURDFError(f"{path}: name_mot names a joint twice")
    names = _strings(path, "joint_name", content.get("joint_name", []))
    kinds_j = _strings(path, "joint_type", content.get("joint_type", []))
    if len(names) != len(kinds_j):
        raise MalformedURDFError(f"{path}: {len(names)} joint_name entries but {len(kinds_j)} joint_type entries")
    for kind in kinds_j:
        if kind not in JOINT_TYPES:
            raise MalformedURDFError(f"{path}: joint_type {kind!r} (known: {', '.join(JOINT_TYPES)})")
    if len(set(names)) != len(names):
        raise MalformedURDFError(f"{path}: joint_name names a joint twice")
    return Sidecar(path, tuple(loops), tuple(types), motors, dict(zip(names, kinds_j, strict=True)),
                   _beams(path, content.get("beams", {})), _springs(path, content.get("springs", {})),
                   _elastic(path, content.get("elastic", []), content.get("springs", {})),
                   _gravity(path, content.get("gravity")))


def _gravity(path: str, value: Any) -> tuple[float, float, float] | None:
    """The ``gravity:`` key: the gravity vector in the file's world axes (m/s^2), or None."""
    import math

    if value is None:
        return None
    try:
        g = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        g = ()
    if len(g) != 3 or not all(math.isfinite(v) for v in g) or math.hypot(*g) > 1e3 or isinstance(value, str):
        raise MalformedURDFError(f"{path}: gravity must be three finite numbers (m/s^2), got {value!r}")
    return g


def _elastic(path: str, value: Any, springs: Any) -> tuple[str, ...]:
    """The ``elastic:`` key: virtual elastic joints (a beam's, a lateral hinge's), each with a
    spring, held at 0 in a rigid assembly."""
    names = _strings(path, "elastic", value)
    missing = [n for n in names if not isinstance(springs, Mapping) or n not in springs]
    if missing:
        raise MalformedURDFError(f"{path}: elastic: joint {missing[0]!r} has no entry in springs")
    return names


def _springs(path: str, value: Any) -> dict[str, float]:
    """The ``springs:`` key (h4pin's own): ``{joint: stiffness}``, N.m/rad or N/m, each finite > 0."""
    import math

    if not isinstance(value, Mapping):
        raise MalformedURDFError(f"{path}: springs must be a mapping {{joint: stiffness}}, got {value!r}")
    out = {}
    for joint, k in value.items():
        try:
            v = float(k)
        except (TypeError, ValueError):
            v = math.nan
        if not isinstance(joint, str) or isinstance(k, bool) or not 0 < v < math.inf:
            raise MalformedURDFError(f"{path}: springs: {joint!r} must map to a finite stiffness > 0, got {k!r}")
        out[joint] = v
    return out


def _beams(path: str, value: Any) -> dict[str, Any]:
    """The ``beams:`` key: ``{link: {E:, G:, d:}}`` (a round section) or ``{link: {E:, G:, A:, Iy:,
    Iz:, J:}}``, each with an optional ``to:`` and ``carry:``; as :class:`h4pin.mechanism.Beam`."""
    from h4pin.errors import ParameterError
    from h4pin.mechanism.beams import Beam

    if value is None or value == {}:
        return {}
    if not isinstance(value, Mapping):
        raise MalformedURDFError(f"{path}: beams must be a mapping {{link: {{E:, G:, d:}}}}, got {value!r}")
    out = {}
    for link, spec in value.items():
        if not isinstance(link, str) or not isinstance(spec, Mapping):
            raise MalformedURDFError(f"{path}: beams: {link!r} must map to {{E:, G:, d:}} or the six values, "
                                     f"got {spec!r}")
        unknown = [k for k in spec if k not in BEAM_KEYS]
        if unknown:
            raise MalformedURDFError(f"{path}: beams: {link}: unknown key {unknown[0]!r} "
                                     f"(known: {', '.join(BEAM_KEYS)})")
        extra = {"to": spec.get("to"), "carry": tuple(spec.get("carry", ()) or ())}
        try:
            if "d" in spec:
                if any(k in spec for k in ("A", "Iy", "Iz", "J")):
                    raise ParameterError("give d (a round section) or A, Iy, Iz, J, not both")
                beam = Beam.circle(spec["d"], spec.get("E"), spec.get("G"), to=extra["to"])
                beam = dataclasses.replace(beam, carry=extra["carry"])
            else:
                missing = [k for k in ("E", "G", "A", "Iy", "Iz", "J") if k not in spec]
                if missing:
                    raise ParameterError(f"missing {', '.join(missing)} (or give d for a round section)")
                beam = Beam(*(spec[k] for k in ("E", "G", "A", "Iy", "Iz", "J")), **extra)
        except (ParameterError, TypeError) as exc:
            raise MalformedURDFError(f"{path}: beams: {link}: {exc}") from None
        out[link] = beam
    return out


def read(path: str | Path) -> Sidecar:
    """:func:`parse` of a YAML file.

    Raises:
        MissingExtraError: PyYAML is not installed (the ``interop`` extra).
        MalformedURDFError: the file cannot be read, is not YAML text, or as :func:`parse`.
    """
    from h4pin.extras import require

    require("yaml", extra="interop", what="reading a closed-loop sidecar")
    import yaml

    path = Path(path)
    try:
        content = yaml.safe_load(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError:
        raise MalformedURDFError(f"{path}: not a text (UTF-8) file") from None
    except (OSError, yaml.YAMLError) as exc:
        raise MalformedURDFError(f"{path}: cannot read the sidecar ({exc})") from None
    return parse(content, str(path))


def convert(model: pin.Model, joints: Mapping[str, str], where: str = "sidecar") -> pin.Model:
    """``model`` with the joints of ``joints`` ``{name: joint_type}`` replaced as the toolbox's
    loader does (module docstring): a ball joint, or two hinges named ``<name>_a``, ``<name>_b``
    (the second carries the body and the frames), or the joint locked at 0 (``FIXED``). Other
    joints keep their kind, placement, limits and body.

    A name that is not a joint of the model is ignored, as the toolbox's loader ignores it, with a
    :class:`~h4pin.errors.MechanismWarning` naming it (``where`` names the file).
    """
    missing = [n for n in joints if not model.existJointName(n)]
    if missing:
        warnings.warn(f"{where}: joint_name {', '.join(map(repr, missing))} not a joint of the model: ignored "
                      "(as Gepetto's loader does)", MechanismWarning, stacklevel=3)
        joints = {n: k for n, k in joints.items() if n not in missing}
    if not joints:
        return pin.Model(model)
    out = pin.Model()
    out.name, out.gravity = model.name, model.gravity
    ids = {0: 0}
    last: dict[int, int] = {0: 0}
    fixed = []
    for j in range(1, model.njoints):
        name, jm, place = model.names[j], model.joints[j], model.jointPlacements[j]
        parent = last[model.parents[j]]
        kind = joints.get(name)
        v, c = slice(jm.idx_v, jm.idx_v + jm.nv), slice(jm.idx_q, jm.idx_q + jm.nq)
        limits = (model.effortLimit[v], model.velocityLimit[v],
                  model.lowerPositionLimit[c], model.upperPositionLimit[c])
        if kind is None or kind == "FIXED":
            new = out.addJoint(parent, jm, place, name, *limits)
            if kind == "FIXED":
                fixed.append(new)
        elif kind == "SPHERICAL":
            new = out.addJoint(parent, pin.JointModelSpherical(), place, name)
        else:
            a, b = kind[-2], kind[-1]
            first = out.addJoint(parent, _HINGE[a](), place, f"{name}_{a}")
            new = out.addJoint(first, _HINGE[b](), pin.SE3.Identity(), f"{name}_{b}")
        ids[j] = new
        last[j] = new
        out.appendBodyToJoint(new, model.inertias[j], pin.SE3.Identity())
    for f in list(model.frames)[1:]:
        if f.type == pin.FrameType.JOINT and joints.get(f.name, "").startswith("UJOINT"):
            kind = joints[f.name]
            for axis in kind[-2:]:
                jn = f"{f.name}_{axis}"
                out.addFrame(pin.Frame(jn, out.getJointId(jn), pin.SE3.Identity(), pin.FrameType.JOINT), False)
            continue
        parent = ids[f.parentJoint]
        out.addFrame(pin.Frame(f.name, parent, f.placement, f.type, f.inertia), False)
    if fixed:
        out = pin.buildReducedModel(out, fixed, pin.neutral(out))
    return out


def build(urdf_path: str | Path, sidecar: Sidecar, *, free_flyer: bool = False) -> tuple[pin.Model, list[Any]]:
    """The Pinocchio model of a URDF with the sidecar's joint conversions, and its closures
    (``RigidConstraintModel`` named ``<frame1>C<frame2>``, LOCAL), as the toolbox's loader builds
    them; ``free_flyer``: the root on a free-flyer joint (legged robots).

    Raises:
        MalformedURDFError: Pinocchio cannot read the URDF; the sidecar names a frame or joint
            the model lacks.
    """
    urdf_path = Path(urdf_path)
    try:
        if free_flyer:
            model = pin.buildModelFromUrdf(str(urdf_path), pin.JointModelFreeFlyer())
        else:
            model = pin.buildModelFromUrdf(str(urdf_path))
    except (RuntimeError, ValueError, OSError, IndexError) as exc:
        raise MalformedURDFError(f"{urdf_path}: Pinocchio cannot read it ({exc})") from None
    model = convert(model, sidecar.joints, sidecar.path)
    cms = []
    for pair, kind in zip(sidecar.closed_loop, sidecar.types, strict=True):
        missing = [n for n in pair if not model.existFrame(n)]
        if missing:
            raise MalformedURDFError(f"{sidecar.path}: closed_loop names frame {missing[0]!r}, not in {urdf_path.name}")
        f1, f2 = (model.frames[model.getFrameId(n)] for n in pair)
        ctype = pin.ContactType.CONTACT_3D if kind == "3D" else pin.ContactType.CONTACT_6D
        cm = pin.RigidConstraintModel(ctype, model, f1.parentJoint, f1.placement, f2.parentJoint, f2.placement,
                                      pin.ReferenceFrame.LOCAL)
        cm.name = f"{pair[0]}C{pair[1]}"
        cms.append(cm)
    missing = [n for n in sidecar.motors if not model.existJointName(n)]
    if missing:
        raise MalformedURDFError(f"{sidecar.path}: name_mot names joint {missing[0]!r}, not in {urdf_path.name}")
    return model, cms


__all__ = ["JOINT_TYPES", "KEYS", "Sidecar", "build", "convert", "parse", "read"]
