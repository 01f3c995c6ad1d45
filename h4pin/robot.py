# SPDX-License-Identifier: Apache-2.0
"""The H4 as a Pinocchio model with loop closures: :func:`load` and :class:`H4`.

``load("prototype")`` returns an :class:`H4` holding a plain ``pin.Model`` (a tree: base, four
legs with universal joints, and the plate as a floating subtree), its geometry models, the
eight Pinocchio 3-D point constraints (``pin.RigidConstraintModel``, ``CONTACT_3D``) that close
the bars on the plate, and :attr:`H4.geometry`, the per-leg and per-bar constants read from the
model (:mod:`h4pin.model`). The URDF is the single source of truth: any URDF with the H4's named
frames, closures and spring data loads (see the README, "Describe your own H4").

What the loader reads, and checks, from the tree at its neutral configuration:

* actuator i: the joint that carries frames A_i1, A_i2 (a revolute on the base); its axis u_i;
* bar ij: the closure whose plate-side point is frame B_ij; the bar's two joints (a universal
  joint centred on A_ij, below actuator i); its length |bar end - A_ij|;
* the plate: frame D on a free-flyer body; C_k on the revolute joint of lateral bar k, a child
  of that body; B_ij on a lateral bar. Optional frames P_i, A_i, B_i are checked if present.

Velocity split: the 4 actuated joints ``v_a`` and the 24 passive ones ``v_p`` (16 bar
revolutes, 6 plate free-flyer, 2 lateral revolutes). The 24 closure equations
``Jc_a v_a + Jc_p v_p = 0`` have a square 24x24 passive block away from singularities, so the
passive velocities follow from the actuated ones: ``v_p = -Jc_p^-1 Jc_a v_a``.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from h4pin import _fast, geometry
from h4pin.elements import ELEMENTS, RIGIDITIES, Elements, check_elements
from h4pin.errors import MalformedURDFError, ParameterError, SingularPoseError, URDFNotFoundError
from h4pin.geometry import PlateState, Points
from h4pin.model import BAR_CLEARANCE, POINT_TOL, H4Geometry, check_springs, params_from_geometry
from h4pin.params import PER_LEG, SPRINGS, VARIANTS, H4Params
from h4pin.urdf import SPRING_ELEMENTS, URDFExtras, decode, parse, to_urdf

#: Condition number of the passive closure Jacobian above which :meth:`H4.passive_map` refuses.
SINGULAR_COND = 1e10


def urdf_dir() -> Path:
    """Folder of the shipped URDF files (inside the installed package, or the repo's ``urdf/``)."""
    packaged = Path(str(resources.files("h4pin"))) / "urdf"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent / "urdf"


def variant_path(name: str) -> Path:
    """Path of the shipped URDF of variant ``name`` (``urdf/h4_<name>.urdf``)."""
    return urdf_dir() / f"h4_{name}.urdf"


def load(source: str | Path | H4Params = "prototype", *, springs: dict[str, Any] | None = None,
         bar_clearance: float = BAR_CLEARANCE) -> H4:
    """Load an H4: a variant name, a path to a URDF file, or an :class:`H4Params`.

    Args:
        source: ``"prototype"`` (default), ``"symmetric"``, ``"toleranced"``, ``"fitted"`` (see
            :data:`h4pin.VARIANTS`), a path to any H4 URDF (an existing file is always taken as
            a path), or parameters (the URDF is then generated in memory).
        springs: Spring data given or overridden at load, by H4Params field name: ``kc``, ``E``,
            ``I``, ``G``, ``I0``, ``forearm_stressed_fraction`` (a scalar or 4 values, one per
            leg), ``Sb``, ``Eb`` (a scalar or 8 values, one per bar).
        bar_clearance: m, the smallest distance allowed between the axes of bars of two legs.

    Raises:
        ParameterError: unknown variant name (the message lists them), bad ``springs``.
        URDFNotFoundError: the path does not exist.
        MalformedURDFError: the file does not describe an H4 (the message names the element).
    """
    if isinstance(source, H4Params):
        return H4(to_urdf(source), "<H4Params>", springs=springs, bar_clearance=bar_clearance)
    if not isinstance(source, (str, Path)):
        raise ParameterError(f"source must be a variant name, a path or an H4Params, got {type(source).__name__}")
    path = Path(source)
    if not path.is_file():
        text_source = str(source)
        if isinstance(source, str) and text_source in VARIANTS:
            path = variant_path(text_source)
        elif isinstance(source, Path) or text_source.endswith(".urdf") or "/" in text_source:
            raise URDFNotFoundError(f"no URDF file at {path}")
        else:
            raise ParameterError(f"unknown H4 variant {text_source!r}; available: {', '.join(sorted(VARIANTS))} "
                                 "(or pass a path to a URDF, or an H4Params)")
    return H4(decode(path.read_bytes(), str(path)), str(path), springs=springs, bar_clearance=bar_clearance)


class Kinematics(NamedTuple):
    """One pose of an H4, through Pinocchio: everything the stiffness model needs, no hidden state.

    Attributes:
        pose: (4,) [x, y, z, theta].
        state: the assembled :class:`h4pin.geometry.PlateState`.
        configuration: (nq,) Pinocchio configuration, all loops closed.
        points: characteristic points from Pinocchio's frame placements.
        JB: (8, 3, 8) Jacobians of the B_ij w.r.t. dtp = [dD, dOmega, domega_1, domega_2].
        JA: (8, 3, 4) Jacobians of the A_ij w.r.t. the actuator angles.
    """

    pose: np.ndarray
    state: PlateState
    configuration: np.ndarray
    points: Points
    JB: np.ndarray
    JA: np.ndarray


class H4:
    """An H4 robot: Pinocchio model, geometry models, closures and per-element geometry.

    Attributes:
        geometry: :class:`h4pin.model.H4Geometry`, read from the model at load.
        elements: the data of the elements eq. 30 neglects (property).
        model, data: Pinocchio model and its data.
        visual_model, collision_model: Pinocchio geometry models.
        constraint_models, constraint_datas: the 8 ``CONTACT_3D`` closures, bar ij at B_ij,
            in the order 11, 12, 21, ..., 42 (index n = 2(i-1) + (j-1)); joint 1 is the bar's.
        frames: Frame ids by name.
        actuated_joint_names: the 4 actuated joints, leg order.
        v_act, v_pas: Velocity indices of the 4 actuators and of the passive joints.
        urdf: The URDF text; source: where it came from.
    """

    def __init__(self, urdf_text: str, source: str = "URDF", *, springs: dict[str, Any] | None = None,
                 bar_clearance: float = BAR_CLEARANCE):
        self.urdf = urdf_text
        self.source = source
        extras = parse(urdf_text, source)
        try:
            self.model = pin.buildModelFromXML(urdf_text)
            self.visual_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.VISUAL)
            self.collision_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.COLLISION)
        except (RuntimeError, ValueError) as exc:
            raise MalformedURDFError(f"{source}: Pinocchio cannot load it ({exc})") from None
        self.data = self.model.createData()
        self.frames = {f.name: i for i, f in enumerate(self.model.frames)}
        if not (isinstance(bar_clearance, (int, float)) and np.isfinite(bar_clearance) and bar_clearance >= 0):
            raise ParameterError(f"bar_clearance must be a finite length >= 0 (m), got {bar_clearance!r}")
        self._read(extras, springs or {}, float(bar_clearance))

    # ------------------------------------------------------------------ reading
    def _frame(self, name: str) -> int:
        if name not in self.frames:
            raise MalformedURDFError(f"{self.source}: frame {name} is missing (the H4's named frames: "
                                     "A_ij, B_ij, C_k, D; see the README)")
        return self.frames[name]

    def _err(self, message: str) -> MalformedURDFError:
        return MalformedURDFError(f"{self.source}: {message}")

    def _read(self, extras: URDFExtras, springs: dict[str, Any], bar_clearance: float) -> None:
        m, d = self.model, self.data
        q0 = pin.neutral(m)
        pin.framesForwardKinematics(m, d, q0)
        pin.computeJointJacobians(m, d, q0)
        pos = {name: d.oMf[fid].translation.copy() for name, fid in self.frames.items()}

        def parent(name: str) -> int:
            return m.frames[self._frame(name)].parentJoint

        def axis(j: int) -> np.ndarray:
            col = pin.getJointJacobian(m, d, j, pin.LOCAL_WORLD_ALIGNED)[3:, m.joints[j].idx_v]
            return col / np.linalg.norm(col)

        def off_axis(point: np.ndarray, j: int) -> float:
            rel = point - d.oMi[j].translation
            return float(np.linalg.norm(rel - axis(j) * (rel @ axis(j))))

        def revolute(j: int) -> bool:
            name = m.joints[j].shortname()
            return (name in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
                    and m.joints[j].nq == 1)

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

        self.actuated_joint_names = tuple(m.names[j] for j in act)
        data = self._springs(extras, springs, act, bar_links)
        self._element_data = self._elements(extras, lateral, bar_links, act, central, lat_arr[0::2])
        lo, hi = m.lowerPositionLimit, m.upperPositionLimit
        q_idx = [m.joints[j].idx_q for j in act]
        lat_idx = [m.joints[j].idx_q for j in lateral]
        om_lo = np.where(sign > 0, lo[lat_idx], -hi[lat_idx])
        om_hi = np.where(sign > 0, hi[lat_idx], -lo[lat_idx])
        self.geometry = H4Geometry(P=P, u=u, A0=A0, l=np.array(lengths), lat=lat_arr, C0=np.array(
            [pos["C_1"], pos["C_2"]]) - pos["D"], b=np.array(b), v=v, springs=data, q_lo=lo[q_idx], q_hi=hi[q_idx],
            omega_lo=om_lo, omega_hi=om_hi, bar_clearance=bar_clearance)

        self.constraint_models = pin.StdVec_RigidConstraintModel()
        for cm in cms:
            self.constraint_models.append(cm)
        self.constraint_datas = pin.StdVec_RigidConstraintData()
        for cm in self.constraint_models:
            self.constraint_datas.append(cm.createData())
        self.v_act = np.array([m.joints[j].idx_v for j in act])
        self.v_pas = np.setdiff1d(np.arange(m.nv), self.v_act)
        self._q_act = np.array(q_idx)
        self._q_lat = np.array(lat_idx)
        self._lat_sign = sign
        self._q_u = np.array([[m.joints[jp].idx_q, m.joints[jb].idx_q] for jp, jb, *_ in ujoint])
        self._e1 = np.array([e1 for _, _, e1, _, _ in ujoint])
        self._e2 = np.array([e2 for _, _, _, e2, _ in ujoint])
        self._p0 = np.array([p0 for *_, p0 in ujoint])
        self._central = central
        self._q_plate = m.joints[central].idx_q
        self._X0R = np.ascontiguousarray(d.oMi[central].rotation)
        self._X0t = d.oMi[central].translation.copy()
        self._D0 = pos["D"]
        self._fid_D = self.frames["D"]
        self._v_plate = np.r_[m.joints[central].idx_v + np.arange(6), [m.joints[j].idx_v for j in lateral]]
        self._jid_lat = lateral
        self._jid_act = act
        order = [f"{i}{j}" for i in range(1, 5) for j in (1, 2)]
        self._point_frames = [self.frames[n] for n in ["D", "C_1", "C_2"] + [f"B_{s}" for s in order]
                              + [f"A_{s}" for s in order]]
        parents = [m.frames[f].parentJoint for f in self._point_frames]
        self._point_joints = sorted(set(parents) | set(lateral) | set(act))
        self._point_joint_index = np.array([self._point_joints.index(j) for j in parents])
        self._point_local = np.array([m.frames[f].placement.translation for f in self._point_frames])
        self._q_neutral = q0
        g, c = self.geometry, self.geometry.compliances()
        self._pack_conf = _fast.pack_configuration(g.P, g.u, g.A0, g.C0, g.b, g.v, self._e1, self._e2, self._p0,
                                                   self._lat_sign, self._X0R, self._X0t, self._D0, g.lat, self._q_act,
                                                   self._q_u, self._q_plate, self._q_lat)
        self._pack_mat = _fast.pack_matrices(self._point_joint_index, self._point_local, self._v_plate, self.v_act,
                                             g.lat, g.P, g.u, c["control"], c["bending"], c["torsion"], c["tension"])

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
        """The optional elements' data (<h4_revolute> in the lateral joints, <h4_ball> in the bar
        links, <h4_plate_bar> in the plate links, shaft_tilt of <h4_actuator> and <h4_base> in the
        actuated joints); a missing element or attribute is off."""
        joints = [self.model.names[j] for j in lateral]
        actuated = [self.model.names[j] for j in act]
        central_link = extras.joint_child.get(self.model.names[central], "")
        lateral_links = [extras.joint_child.get(name, "") for name in joints]
        # <h4_plate_bar> EI_n/GJ_n: n is C_n on the central bar, leg n (B_n) on a lateral bar.
        allowed = {central_link: {1, 2}} | {link: {int(i) + 1 for i in np.flatnonzero(leg_lat == k)}
                                            for k, link in enumerate(lateral_links)}
        for owner, data in extras.springs.items():
            for field in data:
                if field.startswith("plate_"):
                    n = int(field[-1])
                    if n not in allowed.get(owner, set()):
                        what = {central_link: "central bar"}.get(owner, "lateral bar" if owner in allowed else "link")
                        raise self._err(f"{what} link '{owner}': <h4_plate_bar {field[6:]}> names no beam of it "
                                        f"(allowed: {sorted(allowed.get(owner, set())) or 'none'})")
        # the other elements only where they belong
        places = {"revolute": (set(joints), "a lateral revolute joint"), "ball": (set(bar_links), "a bar link"),
                  "shaft": (set(actuated), "an actuated joint"), "base": (set(actuated), "an actuated joint")}
        source = {field: (tag, attr) for tag, (_, fields) in SPRING_ELEMENTS.items() for attr, field in fields.items()}
        for owner, data in extras.springs.items():
            for field in data:
                if field in ELEMENTS and field not in RIGIDITIES and owner not in places[field.split("_")[0]][0]:
                    tag, attr = source[field]
                    raise self._err(f"<{tag} {attr}> sits in '{owner}', which is not "
                                    f"{places[field.split('_')[0]][1]} (the element it describes)")
        owners, values = {}, {}
        for name in ELEMENTS:
            rigid = np.inf if name in RIGIDITIES else 0.0
            if name.startswith("revolute"):
                attr = name.split("_")[1]
                keys = [(j, name) for j in joints]
                owners[name] = [f"lateral joint '{j}' (<h4_revolute {attr}>)" for j in joints]
            elif name == "ball_radial":
                keys = [(b, name) for b in bar_links]
                owners[name] = [f"bar link '{b}' (<h4_ball radial>)" for b in bar_links]
            elif name in RIGIDITIES:
                q = name.split("_")[1]
                if name.startswith("central"):
                    keys = [(central_link, f"plate_{q}_{k + 1}") for k in range(2)]
                else:
                    keys = [(lateral_links[leg_lat[i]], f"plate_{q}_{i + 1}") for i in range(4)]
                owners[name] = [f"{name.split('_')[0]} bar link '{link}' (<h4_plate_bar {f[6:]}>)" for link, f in keys]
            else:
                tag, attr = ("h4_actuator", "shaft_tilt") if name == "shaft_tilt" else ("h4_base", name.split("_")[1])
                keys = [(j, name) for j in actuated]
                owners[name] = [f"actuated joint '{j}' (<{tag} {attr}>)" for j in actuated]
            values[name] = [extras.springs.get(key, {}).get(field, rigid) for key, field in keys]
        return Elements(**check_elements(values, MalformedURDFError, self.source, owners))

    # ----------------------------------------------------------------- geometry
    @property
    def elements(self) -> Elements:
        """The data of the elements eq. 30 neglects (:class:`h4pin.elements.Elements`), read from
        the URDF's ``<h4_revolute>``, ``<h4_ball>``, ``<h4_plate_bar>``, ``<h4_actuator
        shaft_tilt>`` and ``<h4_base>``; all off when the URDF has none."""
        return self._element_data

    @property
    def params(self) -> H4Params:
        """The nominal :class:`H4Params` of this robot, if its layout is one they describe.

        Raises:
            MalformedURDFError: the robot is not of that family (e.g. a toleranced robot)."""
        return params_from_geometry(self.geometry)

    def inverse_geometry(self, pose: np.ndarray, *, on_error: str = "raise", check: bool = True) -> np.ndarray:
        """Actuator angles (rad) of pose [x, y, z, theta] (m, rad); (4,) -> (4,), (N, 4) -> (N, 4).

        See :func:`h4pin.geometry.inverse_geometry` (elbow-out; joint limits and interferences
        checked unless ``check=False``).

        Raises:
            UnreachablePoseError: a leg cannot reach its plate point (the message names the leg),
                or (subclasses) :class:`h4pin.JointLimitError`, :class:`h4pin.InterferenceError`.
        """
        return geometry.inverse_geometry(self.geometry, pose, on_error=on_error, check=check)

    def forward_geometry(self, q: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """Pose [x, y, z, theta] (m, rad) of actuator angles q (4,), by Newton.

        Raises:
            ConvergenceError: the legs do not assemble (or Newton failed from ``guess``).
        """
        return geometry.forward_geometry(self.geometry, q, guess)

    def state(self, pose: np.ndarray, *, check: bool = True) -> PlateState:
        """The assembled :class:`h4pin.geometry.PlateState` of one pose (raises on a bad pose)."""
        x = geometry.as_pose(pose)
        if check and self.geometry.ideal:
            from h4pin.stiffness import _kernel

            _, q, _, status = _kernel(self)(x)  # the compiled closed form and its verdict
            if status in (geometry.OK, geometry.SINGULAR):
                c, s = math.cos(x[3]), math.sin(x[3])
                return PlateState(q, x[:3].copy(), np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
                                  np.array([-x[3], -x[3]]))
        sol = geometry.solve(self.geometry, x, check=check)
        geometry.raise_for_status(sol.status, sol.detail, batch=False)
        return sol.state

    def configuration(self, pose: np.ndarray, *, check: bool = True) -> np.ndarray:
        """Full Pinocchio configuration (nq,) of ``pose`` (4,), all 8 closures satisfied.

        Actuators from the inverse geometry; each bar's universal joint in closed form (it points
        the bar from A_ij to B_ij); plate free-flyer at D with its orientation; lateral joints at
        their relative angles (-theta for an ideal robot: the lateral bars only translate).
        """
        return self.assemble(self.state(pose, check=check))

    def assemble(self, state: PlateState) -> np.ndarray:
        """Configuration (nq,) of actuator angles and plate placement; bars aimed at B_ij.

        The closures hold exactly when ``state`` is assembled (e.g. from :meth:`state`), and
        approximately for a slightly deformed robot (used to draw deflected shapes). Each
        universal joint is solved in closed form (two rotations about axes through A_ij that
        take the bar's end to the direction of B_ij; the branch closest to the reference).
        """
        q, D, R, omega = (np.ascontiguousarray(a, dtype=float) for a in state)
        return _fast.configuration_packed(self._q_neutral.copy(), q, D, R, omega, *self._pack_conf)

    def kinematics(self, pose: np.ndarray) -> Kinematics:
        """Everything about one pose through Pinocchio (:class:`Kinematics`): the assembled
        configuration, the points from Pinocchio's frame placements, and the Jacobians of the
        B_ij and A_ij points from Pinocchio's joint Jacobians.

        ``dB_ij = JB[n] dtp`` with ``dtp = [dD, dOmega, domega_1, domega_2]`` (world-aligned at
        D), and ``dA_ij = JA[n] dq``: the joint Jacobians (LOCAL_WORLD_ALIGNED) of the lateral
        bars and forearms shifted to the points (``v_X = v_joint + w x (X - joint)``); the plate
        columns mapped from the free-flyer's local velocity to dtp with the frame Jacobian of D.

        Raises:
            UnreachablePoseError (and subclasses): the robot cannot take the pose.
        """
        x = geometry.as_pose(pose)
        st = self.state(x)
        q = self.assemble(st)
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        homog = np.array([d.oMi[j].homogeneous for j in self._point_joints])
        xyz = np.einsum("nab,nb->na", homog[self._point_joint_index, :3, :3], self._point_local) \
            + homog[self._point_joint_index, :3, 3]
        g = self.geometry
        bij, aij = xyz[3:11], xyz[11:19]
        lwa = pin.LOCAL_WORLD_ALIGNED
        jd = pin.getFrameJacobian(m, d, self._fid_D, lwa)[:, self._v_plate]
        to_tp = np.eye(8)
        to_tp[:6, :6] = jd[:, :6]
        jlat = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, self._v_plate] for j in self._jid_lat])
        jact = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, self.v_act] for j in self._jid_act])
        olat = homog[[self._point_joints.index(j) for j in self._jid_lat], :3, 3]
        oact = homog[[self._point_joints.index(j) for j in self._jid_act], :3, 3]
        jl, ja = jlat[g.lat], jact[np.arange(8) // 2]
        jb = jl[:, :3] - _cross_columns(bij - olat[g.lat], jl[:, 3:])
        ja = ja[:, :3] - _cross_columns(aij - oact[np.arange(8) // 2], ja[:, 3:])
        v_world = st.R @ g.v.T
        pts = Points(D=xyz[0], C=xyz[1:3], B=bij.reshape(4, 2, 3).mean(axis=1), Bij=bij.reshape(4, 2, 3), P=g.P,
                     A=aij.reshape(4, 2, 3).mean(axis=1), Aij=aij.reshape(4, 2, 3), v=v_world.T)
        return Kinematics(x, st, q, pts, jb @ np.linalg.inv(to_tp), ja)

    def pinocchio_compliance(self, pose: np.ndarray, model: str = "paper") -> tuple[np.ndarray, float, np.ndarray,
                                                                                  np.ndarray]:
        """K (8, 8) of eq. 30, the scaled condition number of M1, J (4, 4) and the actuator angles
        (4,) at one pose, through Pinocchio: the assembled configuration, ``computeJointJacobians``
        and the joint placements; M1 (eq. 6) and M2 M3 (eq. 11) from Pinocchio's world-frame joint
        Jacobians shifted to the B_ij and A_ij points (compiled arithmetic,
        :func:`h4pin._fast.pinocchio_matrices`).

        Raises:
            UnreachablePoseError (and subclasses): the robot cannot take the pose.
        """
        st = self.state(pose)
        q = self.assemble(st)
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        homog = np.array([d.oMi[j].homogeneous for j in self._point_joints])
        K, cond, J, _, _ = _fast.pinocchio_matrices_packed(d.J, homog, *self._pack_mat,
                                                            1 if model == "consistent" else 0)
        return K, cond, J, st.q

    def closure_residuals(self, q: np.ndarray) -> np.ndarray:
        """Position errors of the 8 closures at configuration q, (8, 3) in m, from Pinocchio."""
        q = self._as_configuration(q)
        pin.forwardKinematics(self.model, self.data, q)
        out = np.empty((8, 3))
        for n, (cm, cd) in enumerate(zip(self.constraint_models, self.constraint_datas, strict=True)):
            cm.calc(self.model, self.data, cd)
            out[n] = cd.c1Mc2.translation
        return out

    def _as_configuration(self, q: Any) -> np.ndarray:
        try:
            qv = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"q must be a configuration of {self.model.nq} numbers, got {q!r}") from None
        if qv.shape != (self.model.nq,) or not np.all(np.isfinite(qv)):
            raise ParameterError(f"q must be a finite configuration of shape ({self.model.nq},), got shape {qv.shape}")
        return qv

    # ---------------------------------------------------------------- Jacobians
    def passive_map(self, q: np.ndarray) -> np.ndarray:
        """``S`` (nv, 4) with ``v = S q_dot`` at configuration q: the closed-loop velocity of
        every joint, from Pinocchio's closure Jacobian: ``v_p = -Jc_p^-1 Jc_a q_dot``.

        Raises:
            SingularPoseError: the 24x24 passive closure block is singular (cond > 1e10).
        """
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        for cm, cd in zip(self.constraint_models, self.constraint_datas, strict=True):
            cm.calc(m, d, cd)
        jc = pin.getConstraintsJacobian(m, d, self.constraint_models, self.constraint_datas)
        jp, ja = jc[:, self.v_pas], jc[:, self.v_act]
        try:
            inv = np.linalg.inv(jp)
            cond = np.abs(jp).sum(0).max() * np.abs(inv).sum(0).max()  # 1-norm condition number
        except np.linalg.LinAlgError:
            cond = np.inf
        if not cond < SINGULAR_COND:
            raise SingularPoseError(f"the passive closure Jacobian is singular (cond = {cond:.2e}): "
                                    "the plate has an uncontrolled motion at this pose")
        s = np.zeros((m.nv, 4))
        s[self.v_act] = np.eye(4)
        s[self.v_pas] = -inv @ ja
        return s

    def jacobian(self, pose: np.ndarray) -> np.ndarray:
        """J (4, 4) with x_dot = J q_dot (eq. 8), from Pinocchio's closure and frame Jacobians.

        The passive velocities come from the 24x24 closure Jacobian (:meth:`passive_map`), the
        plate motion from the frame Jacobian of D (LOCAL_WORLD_ALIGNED), rows v_x, v_y, v_z, w_z.
        An independent route to the J that :mod:`h4pin.stiffness` computes from M1 and M3.
        """
        s = self.passive_map(self.configuration(pose))
        jd = pin.getFrameJacobian(self.model, self.data, self._fid_D, pin.LOCAL_WORLD_ALIGNED)
        return jd[[0, 1, 2, 5]] @ s

    def jx_jq(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The paper's Jx and Jq of eq. 8 (closed form), ``Jx x_dot = Jq q_dot``."""
        x = geometry.as_poses(pose)
        return geometry.jx_jq(self.geometry, x, self.inverse_geometry(x))

    def frame_position(self, name: str) -> np.ndarray:
        """World position (3,) of a named frame after Pinocchio's forward kinematics and
        ``updateFramePlacements`` on :attr:`data`."""
        if name not in self.frames:
            raise ParameterError(f"no frame named {name!r}")
        return self.data.oMf[self.frames[name]].translation.copy()

    # ---------------------------------------------------------------- statics
    def gravity_torques(self, pose: np.ndarray, gravity: np.ndarray | None = None) -> np.ndarray:
        """Actuator torques (4,) in N.m that hold the robot still at ``pose`` under gravity.

        From Pinocchio's generalized gravity ``g(q)`` (nv) and the closure Jacobians: with
        ``v = S q_dot`` (:meth:`passive_map`), virtual work gives ``tau = S^T g(q)``; this is the
        same as eliminating the closure forces ``lambda`` from ``g = tau_full + Jc^T lambda``.

        Args:
            gravity: (3,) m/s^2, default the model's (0, 0, -9.81).
        """
        if gravity is not None:
            gv = np.asarray(gravity, dtype=float) if np.ndim(gravity) else np.array([np.nan])
            if gv.shape != (3,) or not np.all(np.isfinite(gv)):
                raise ParameterError(f"gravity must be a finite vector of 3 numbers (m/s^2), got {gravity!r}")
        q = self.configuration(pose)
        saved = self.model.gravity.linear.copy()
        if gravity is not None:
            self.model.gravity.linear = gv
        try:
            g = pin.computeGeneralizedGravity(self.model, self.data, q)
            return self.passive_map(q).T @ g
        finally:
            self.model.gravity.linear = saved

    def potential_energy(self, pose: np.ndarray) -> float:
        """Gravitational potential energy (J) of the assembled robot at ``pose``, from Pinocchio."""
        return float(pin.computePotentialEnergy(self.model, self.data, self.configuration(pose)))

    def __repr__(self) -> str:
        return (f"H4(source={self.source!r}, nq={self.model.nq}, nv={self.model.nv}, "
                f"closures={len(self.constraint_models)})")


def _cross_columns(r: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``r[n] x cols[n, :, c]`` for every n and column c: (n, 3) x (n, 3, m) -> (n, 3, m)."""
    rx, ry, rz = (r[:, i, None] for i in range(3))
    cx, cy, cz = cols[:, 0], cols[:, 1], cols[:, 2]
    return np.stack([ry * cz - rz * cy, rz * cx - rx * cz, rx * cy - ry * cx], axis=1)


__all__ = ["H4", "Kinematics", "load", "urdf_dir", "variant_path"]
