# SPDX-License-Identifier: Apache-2.0
"""Reading an H4 URDF into its description: Pinocchio models, closures, per-element constants.

:func:`read` takes the URDF text and returns a :class:`Description`: the ``pin.Model`` (a tree:
base, four legs with universal joints, and the plate as a floating subtree), its geometry models,
the eight loop closures (``pin.RigidConstraintModel``, ``CONTACT_3D``), the per-leg and per-bar
constants (:class:`h4pin.H4Geometry`), the optional elements' data and the indices the kinematics
need. The URDF is the single source of truth: any URDF with the H4's named frames, closures and
spring data loads (see the README, "Describe your own H4").

What is read, and checked, from the tree at its neutral configuration:

* actuator i: the joint that carries frames A_i1, A_i2 (a revolute on the base); its axis u_i;
* bar ij: the closure whose plate-side point is frame B_ij; the bar's two joints (a universal
  joint centred on A_ij, below actuator i); its length ‖bar end - A_ij‖;
* the plate: frame D on a free-flyer body; C_k on the revolute joint of lateral bar k, a child
  of that body; B_ij on a lateral bar. Optional frames P_i, A_i, B_i are checked if present.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin.description.elements import PLACES, Elements, check_elements, kinds
from h4pin.description.geometry import POINT_TOL, H4Geometry, check_springs, params_from_geometry
from h4pin.description.params import PER_LEG, SPRINGS, H4Params
from h4pin.description.urdf import URDFExtras, element_field, parse
from h4pin.errors import MalformedURDFError, ParameterError

#: Frames every H4 URDF has (the optional P_i, A_i, B_i are checked when present).
H4_FRAMES = (*(f"A_{i}{j}" for i in range(1, 5) for j in (1, 2)), *(f"B_{i}{j}" for i in range(1, 5) for j in (1, 2)),
             "C_1", "C_2", "D")


class Index(NamedTuple):
    """Where the H4's parts sit in its Pinocchio model (read once, read-only).

    q_act, q_lat: configuration indices of the actuators and lateral revolutes; lat_sign (2,):
    +1 where the URDF's lateral axis points up; q_u (8, 2): the two revolutes of each bar's
    universal joint; e1, e2 (8, 3) their axes and p0 (8, 3) the bar's end relative to A_ij at
    the neutral configuration; q_plate: the free-flyer's first index; X0R, X0t: its reference
    placement; D0: frame D at the neutral configuration; fid_D: frame id of D; v_plate (8,): the
    plate's velocity indices (free-flyer 6, lateral 2); jid_lat, jid_act: joint ids;
    point_joints, point_joint_index, point_local: the joint and local position of the 19 points
    D, C_1, C_2, B_11..B_42, A_11..A_42; q_neutral: Pinocchio's neutral configuration.
    """

    q_act: np.ndarray
    q_lat: np.ndarray
    lat_sign: np.ndarray
    q_u: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    p0: np.ndarray
    q_plate: int
    X0R: np.ndarray
    X0t: np.ndarray
    D0: np.ndarray
    fid_D: int
    v_plate: np.ndarray
    jid_lat: list[int]
    jid_act: list[int]
    point_joints: list[int]
    point_joint_index: np.ndarray
    point_local: np.ndarray
    q_neutral: np.ndarray


class Description(NamedTuple):
    """Everything read from one H4 URDF (see the module docstring)."""

    model: pin.Model
    visual_model: pin.GeometryModel
    collision_model: pin.GeometryModel
    constraint_models: Any
    frames: dict[str, int]
    geometry: H4Geometry
    elements: Elements
    actuated_joint_names: tuple[str, ...]
    v_act: np.ndarray
    v_pas: np.ndarray
    index: Index


def read(urdf_text: str, source: str, springs: dict[str, Any] | None = None,
         bar_clearance: float = 0.01) -> Description:
    """Read an H4 URDF (its text; ``source`` names it in messages).

    Raises:
        MalformedURDFError: the text does not describe an H4 (the message names the element).
        ParameterError: bad ``springs`` or ``bar_clearance``.
    """
    if not (isinstance(bar_clearance, (int, float)) and np.isfinite(bar_clearance) and bar_clearance >= 0):
        raise ParameterError(f"bar_clearance must be a finite length >= 0 (m), got {bar_clearance!r}")
    return _Reader(urdf_text, source).read(springs or {}, float(bar_clearance))


class _DataReader:
    """The spring and element data of a URDF, per element of the tree (a base of :class:`_Reader`,
    which provides ``model``, ``source`` and ``_err``)."""

    model: pin.Model
    source: str

    def _err(self, message: str) -> MalformedURDFError:
        return MalformedURDFError(f"{self.source}: {message}")

    def _springs(self, extras: URDFExtras, override: dict[str, Any], act: list[int],
                 bar_links: list[str]) -> dict[str, np.ndarray]:
        unknown = set(override) - set(SPRINGS)
        if unknown:
            raise ParameterError(f"springs: unknown field(s) {', '.join(sorted(unknown))}; known: {', '.join(SPRINGS)}")
        joints = [self.model.names[j] for j in act]
        forearms = [extras.joint_child.get(name, "") for name in joints]
        owners = {}
        for name in SPRINGS:
            if name == "kc":
                owners[name] = [f"the actuated joint '{j}'" for j in joints]
            elif name in PER_LEG:
                owners[name] = [f"the forearm link '{f or '?'}'" for f in forearms]
            else:
                owners[name] = [f"the bar link '{link}'" for link in bar_links]
        out = {}
        for name in SPRINGS:
            elements = joints if name == "kc" else forearms if name in PER_LEG else bar_links
            values = np.array([extras.springs.get(e, {}).get(name, np.nan) for e in elements])
            if name in override:
                try:
                    values = np.broadcast_to(np.asarray(override[name], dtype=float), values.shape).copy()
                except (TypeError, ValueError):
                    raise ParameterError(f"springs['{name}'] must be a number or {values.size} numbers, got "
                                         f"{override[name]!r}") from None
                bad = ~np.isfinite(values) | (values <= 0) | ((values > 1) if name == "forearm_stressed_fraction"
                                                              else False)
                if np.any(bad):
                    k = int(np.argmax(bad))
                    limit = ", at most 1" if name == "forearm_stressed_fraction" else ""
                    raise ParameterError(f"springs['{name}'] = {override[name]!r}: the value for {owners[name][k]} "
                                         f"({float(values[k])!r}) is not physical (must be finite and > 0{limit})")
            missing = np.flatnonzero(np.isnan(values))
            if missing.size:
                tag = {"kc": "h4_actuator"}.get(name, "h4_forearm" if name in PER_LEG else "h4_bar")
                attr = "stressed_fraction" if name == "forearm_stressed_fraction" else name
                raise self._err(f"spring datum '{attr}' of {owners[name][missing[0]]} is missing "
                                f"(<{tag} {attr}=\"...\"/> inside it, or load(..., springs={{'{name}': ...}}))")
            out[name] = values
        return check_springs(out, self.source, owners)

    def _elements(self, extras: URDFExtras, lateral: list[int], bar_links: list[str], act: list[int],
                  central: int, leg_lat: np.ndarray) -> Elements:
        """The optional elements' data, each schema row's (:data:`h4pin.description.elements.KINDS`:
        its tag and attribute in the URDF element of its place); a missing element or attribute
        is off, a datum in a URDF element that holds no element of its kind is refused."""
        joints = [self.model.names[j] for j in lateral]
        actuated = [self.model.names[j] for j in act]
        lateral_links = [extras.joint_child.get(name, "") for name in joints]
        holders = {"lateral_joint": joints, "bar_link": bar_links, "actuated_joint": actuated,
                   "forearm_link": [extras.joint_child.get(name, "") for name in actuated],
                   "central_link": [extras.joint_child.get(self.model.names[central], "")] * 8,
                   "lateral_link": [lateral_links[leg_lat[i]] for i in range(4)]}
        expected: dict[str, dict[str, str]] = {}  # field -> owner -> place: where each datum may sit
        for k in kinds():
            for s in range(k.count):
                expected.setdefault(element_field(k, s), {})[holders[k.place][s]] = k.place
        for owner, data in extras.springs.items():
            for field in data:
                if field in expected and owner not in expected[field]:
                    self._misplaced(field, owner, expected, holders)
        owners, values = {}, {}
        for k in kinds():
            fields = [element_field(k, s) for s in range(k.count)]
            keys = holders[k.place][:k.count]
            owners[k.name] = [f"{PLACES[k.place][0]} '{o}' ({f})" for o, f in zip(keys, fields, strict=True)]
            values[k.name] = [extras.springs.get(o, {}).get(f, k.off) for o, f in zip(keys, fields, strict=True)]
        return Elements(**check_elements(values, MalformedURDFError, self.source, owners))

    def _misplaced(self, field: str, owner: str, expected: dict[str, dict[str, str]],
                   holders: dict[str, list[str]]) -> None:
        """Refuse element datum ``field`` in URDF element ``owner``, which holds none of its kind."""
        places = set(expected[field].values())
        if any(PLACES[p][2] for p in places):  # an indexed attribute: the number names no element of it
            what = next((PLACES[p][0] for p, names in holders.items() if PLACES[p][2] and owner in names), "link")
            allowed = sorted(int(f.rsplit("_", 1)[1][:-1]) for f, o in expected.items()
                             if f.startswith(field.rsplit("_", 1)[0] + "_") and owner in o)
            raise self._err(f"{what} '{owner}': {field} names no beam of it (allowed: {allowed or 'none'})")
        what = " or ".join(sorted({("an " if PLACES[p][0][0] in "aeiou" else "a ") + PLACES[p][0] for p in places}))
        raise self._err(f"{field} sits in '{owner}', which is not {what} (the element it describes)")


class _Reader(_DataReader):
    """One reading of a URDF: the model at its neutral configuration and the checks' helpers."""

    def __init__(self, urdf_text: str, source: str):
        self.source = source
        self.extras: URDFExtras = parse(urdf_text, source)
        try:
            self.model = pin.buildModelFromXML(urdf_text)
        except (RuntimeError, ValueError) as exc:
            raise MalformedURDFError(f"{source}: Pinocchio cannot load it ({exc})") from None
        self.frames = {f.name: i for i, f in enumerate(self.model.frames)}
        missing = [n for n in H4_FRAMES if n not in self.frames]
        if missing:
            raise MalformedURDFError(f"{source}: not an H4: it has no frame {', '.join(missing[:4])}"
                                     f"{' ...' if len(missing) > 4 else ''} (an H4 URDF names A_ij, B_ij, C_k and D; "
                                     "see the README, 'Describe your own H4')")
        try:
            self.visual_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.VISUAL)
            self.collision_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.COLLISION)
        except (RuntimeError, ValueError) as exc:
            raise MalformedURDFError(f"{source}: Pinocchio cannot load its geometry ({exc})") from None
        self.data = self.model.createData()
        self.q0 = pin.neutral(self.model)
        pin.framesForwardKinematics(self.model, self.data, self.q0)
        pin.computeJointJacobians(self.model, self.data, self.q0)
        self.pos = {name: self.data.oMf[fid].translation.copy() for name, fid in self.frames.items()}

    def _frame(self, name: str) -> int:
        if name not in self.frames:
            raise MalformedURDFError(f"{self.source}: frame {name} is missing (the H4's named frames: "
                                     "A_ij, B_ij, C_k, D; see the README)")
        return self.frames[name]

    def parent(self, name: str) -> int:
        return self.model.frames[self._frame(name)].parentJoint

    def axis(self, j: int) -> np.ndarray:
        m = self.model
        col = pin.getJointJacobian(m, self.data, j, pin.LOCAL_WORLD_ALIGNED)[3:, m.joints[j].idx_v]
        return col / np.linalg.norm(col)

    def off_axis(self, point: np.ndarray, j: int) -> float:
        rel = point - self.data.oMi[j].translation
        return float(np.linalg.norm(rel - self.axis(j) * (rel @ self.axis(j))))

    def revolute(self, j: int) -> bool:
        name = self.model.joints[j].shortname()
        return (name in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
                and self.model.joints[j].nq == 1)

    def actuators(self) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
        """The actuated joints, their axes u, the ball joints A0 and the axis points P."""
        m, d, pos = self.model, self.data, self.pos
        parent, axis, off_axis, revolute = self.parent, self.axis, self.off_axis, self.revolute
        # Actuators: the joint carrying A_i1 and A_i2.
        act = []
        for i in range(1, 5):
            j = parent(f"A_{i}1")
            if parent(f"A_{i}2") != j:
                raise self._err(f"frames A_{i}1 and A_{i}2 are not on the same body (forearm {i})")
            if not revolute(j) or m.parents[j] != 0:
                raise self._err(f"forearm {i} (frame A_{i}1) must hang from the base on one revolute joint, "
                                f"found joint '{m.names[j]}' ({m.joints[j].shortname()})")
            act.append(j)
        if len(set(act)) != 4:
            raise self._err("the four legs must have four different actuated joints")
        u = np.array([axis(j) for j in act])
        A0 = np.array([pos[f"A_{i}{j}"] for i in range(1, 5) for j in (1, 2)])
        A_mid = A0.reshape(4, 2, 3).mean(axis=1)
        origin = np.array([d.oMi[j].translation for j in act])
        P = origin + u * np.sum((A_mid - origin) * u, axis=1, keepdims=True)
        for i in range(4):
            name = f"P_{i + 1}"
            if name in self.frames and off_axis(pos[name], act[i]) > POINT_TOL:
                raise self._err(f"frame {name} is not on the axis of actuator '{m.names[act[i]]}'")
            name = f"A_{i + 1}"
            if name in self.frames and np.linalg.norm(pos[name] - A_mid[i]) > POINT_TOL:
                raise self._err(f"frame {name} is not the middle of A_{i + 1}1 and A_{i + 1}2")

        return act, u, A0, P

    def plate(self) -> tuple[int, list[int], np.ndarray, np.ndarray]:
        """The central bar's joint, the lateral revolutes, their axes v (signed up) and signs."""
        m, pos = self.model, self.pos
        parent, axis, off_axis, revolute = self.parent, self.axis, self.off_axis, self.revolute
        # Plate: D on a free-flyer body, C_k on lateral revolutes under it.
        central = parent("D")
        if "FreeFlyer" not in m.joints[central].shortname() or m.parents[central] != 0:
            raise self._err("frame D must be on the central bar, a floating body (URDF joint type 'floating')")
        lateral = []
        for k in (1, 2):
            j = parent(f"C_{k}")
            if not revolute(j) or m.parents[j] != central:
                raise self._err(f"frame C_{k} must be on lateral bar {k}, on a revolute joint of the central bar")
            if off_axis(pos[f"C_{k}"], j) > POINT_TOL:
                raise self._err(f"frame C_{k} is not on the axis of its revolute joint '{m.names[j]}'")
            lateral.append(j)
        v = np.array([axis(j) for j in lateral])
        sign = np.where(v[:, 2] >= 0, 1.0, -1.0)
        v = v * sign[:, None]
        if np.any(v[:, 2] < 0.5):
            raise self._err("the lateral bars' revolute axes must be close to vertical (the plate's design)")

        return central, lateral, v, sign

    def bars(self, act: list[int], A0: np.ndarray, lateral: list[int]) -> tuple:
        """Per bar: its lateral bar, length, B_ij - C_k, link name, closure and universal joint."""
        m, d, pos, extras = self.model, self.data, self.pos, self.extras
        parent, axis, off_axis, revolute = self.parent, self.axis, self.off_axis, self.revolute
        # Bars: each closure ends on one B_ij frame; the other side is the bar.
        closures = {}
        for c in extras.closures:
            sides = []
            for link, xyz in ((c.parent, c.parent_xyz), (c.child, c.child_xyz)):
                if link not in self.frames:
                    raise self._err(f"closure '{c.name}' names unknown link '{link}'")
                f = m.frames[self.frames[link]]
                sides.append((link, f.parentJoint, f.placement * pin.SE3(np.eye(3), xyz)))
            plate_side = [s for s in sides if s[1] in lateral]
            if len(plate_side) != 1:
                raise self._err(f"closure '{c.name}' must join a bar to a lateral bar of the plate")
            bar_side = sides[1 - sides.index(plate_side[0])]
            world = d.oMi[plate_side[0][1]] * plate_side[0][2]
            closures[c.name] = (bar_side, plate_side[0], world.translation)
        lat, lengths, b, bar_links, cms, ujoint = [], [], [], [], [], []
        for i in range(4):
            for jj in range(2):
                name = f"B_{i + 1}{jj + 1}"
                target = pos[name] if name in self.frames else None
                if target is None:
                    self._frame(name)
                found = [c for c, (_, _, w) in closures.items() if np.linalg.norm(w - target) <= POINT_TOL]
                if not found:
                    raise self._err(f"loop closure of bar {i + 1}{jj + 1} is missing: no <constraint> ends at "
                                    f"frame {name}")
                (link, jb, place_b), (_, jl, place_l), _ = closures.pop(found[0])
                if parent(name) != jl:
                    raise self._err(f"closure '{found[0]}' ends at {name} but on another body than that frame")
                jp = m.parents[jb]
                anchor = A0[2 * i + jj]
                if not (revolute(jb) and revolute(jp) and m.parents[jp] == act[i]):
                    raise self._err(f"bar {i + 1}{jj + 1} ('{link}') must hang from forearm {i + 1} on two revolute "
                                    "joints (a universal joint)")
                if max(off_axis(anchor, jb), off_axis(anchor, jp)) > POINT_TOL:
                    raise self._err(f"the universal joint of bar {i + 1}{jj + 1} is not centred on A_{i + 1}{jj + 1}")
                end = (d.oMi[jb] * place_b).translation
                lengths.append(float(np.linalg.norm(end - anchor)))
                lat.append(lateral.index(jl))
                b.append(pos[name] - pos[f"C_{lateral.index(jl) + 1}"])
                bar_links.append(link)
                ujoint.append((jp, jb, axis(jp), axis(jb), end - anchor))
                cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, m, jb, place_b, jl, place_l,
                                              pin.ReferenceFrame.LOCAL)
                cm.name = found[0]
                cms.append(cm)
        if closures:
            raise self._err(f"closure(s) {', '.join(closures)} end at no B_ij frame")
        lat_arr = np.array(lat)
        for i in range(4):
            if lat_arr[2 * i] != lat_arr[2 * i + 1]:
                raise self._err(f"the two bars of leg {i + 1} end on different lateral bars")
            name = f"B_{i + 1}"
            mid = 0.5 * (pos[f"B_{i + 1}1"] + pos[f"B_{i + 1}2"])
            if name in self.frames and np.linalg.norm(pos[name] - mid) > POINT_TOL:
                raise self._err(f"frame {name} is not the middle of B_{i + 1}1 and B_{i + 1}2")

        return lat_arr, lengths, b, bar_links, cms, ujoint

    def read(self, springs: dict[str, Any], bar_clearance: float) -> Description:
        m, d, pos = self.model, self.data, self.pos
        act, u, A0, P = self.actuators()
        central, lateral, v, sign = self.plate()
        lat_arr, lengths, b, bar_links, cms, ujoint = self.bars(act, A0, lateral)
        data = self._springs(self.extras, springs, act, bar_links)
        element_data = self._elements(self.extras, lateral, bar_links, act, central, lat_arr[0::2])
        lo, hi = m.lowerPositionLimit, m.upperPositionLimit
        q_idx = [m.joints[j].idx_q for j in act]
        lat_idx = [m.joints[j].idx_q for j in lateral]
        om_lo = np.where(sign > 0, lo[lat_idx], -hi[lat_idx])
        om_hi = np.where(sign > 0, hi[lat_idx], -lo[lat_idx])
        geometry = H4Geometry(P=P, u=u, A0=A0, l=np.array(lengths), lat=lat_arr, C0=np.array(
            [pos["C_1"], pos["C_2"]]) - pos["D"], b=np.array(b), v=v, springs=data, q_lo=lo[q_idx], q_hi=hi[q_idx],
            omega_lo=om_lo, omega_hi=om_hi, bar_clearance=bar_clearance)
        constraint_models = pin.StdVec_RigidConstraintModel()
        for cm in cms:
            constraint_models.append(cm)
        v_act = np.array([m.joints[j].idx_v for j in act])
        order = [f"{i}{j}" for i in range(1, 5) for j in (1, 2)]
        point_frames = [self.frames[n] for n in ["D", "C_1", "C_2"] + [f"B_{s}" for s in order]
                        + [f"A_{s}" for s in order]]
        parents = [m.frames[f].parentJoint for f in point_frames]
        point_joints = sorted(set(parents) | set(lateral) | set(act))
        index = Index(
            q_act=np.array(q_idx), q_lat=np.array(lat_idx), lat_sign=sign,
            q_u=np.array([[m.joints[jp].idx_q, m.joints[jb].idx_q] for jp, jb, *_ in ujoint]),
            e1=np.array([e1 for _, _, e1, _, _ in ujoint]), e2=np.array([e2 for _, _, _, e2, _ in ujoint]),
            p0=np.array([p0 for *_, p0 in ujoint]), q_plate=m.joints[central].idx_q,
            X0R=np.ascontiguousarray(d.oMi[central].rotation), X0t=d.oMi[central].translation.copy(), D0=pos["D"],
            fid_D=self.frames["D"],
            v_plate=np.r_[m.joints[central].idx_v + np.arange(6), [m.joints[j].idx_v for j in lateral]],
            jid_lat=lateral, jid_act=act, point_joints=point_joints,
            point_joint_index=np.array([point_joints.index(j) for j in parents]),
            point_local=np.array([m.frames[f].placement.translation for f in point_frames]), q_neutral=self.q0)
        for a in index:
            if isinstance(a, np.ndarray):
                a.setflags(write=False)
        return Description(m, self.visual_model, self.collision_model, constraint_models, dict(self.frames), geometry,
                           element_data, tuple(m.names[j] for j in act), v_act,
                           np.setdiff1d(np.arange(m.nv), v_act), index)


def params_from_urdf(text: str, where: str = "URDF") -> H4Params:
    """The nominal :class:`H4Params` of an H4 URDF whose layout they can describe, read from
    the model (the inverse of :func:`to_urdf`, to round-off).

    Raises:
        MalformedURDFError: as :func:`h4pin.load`, or the robot is not of the H4Params family.
    """
    return params_from_geometry(read(text, where).geometry)


__all__ = ["Description", "Index", "params_from_urdf", "read"]
