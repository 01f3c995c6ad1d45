# SPDX-License-Identifier: Apache-2.0
"""Compliances that eq. 30 neglects, as optional elements (all off by default).

Elements (SI, one value per element; 0 switches a compliance off, ``inf`` a rigidity):

* ``revolute_radial`` (2,) m/N: each lateral-bar revolute joint C_k, in the plane normal to its
  axis v_k;
* ``revolute_axial`` (2,) m/N: the same joint along its axis v_k;
* ``revolute_tilt`` (2,) rad/(N.m): the same joint about the two axes normal to v_k;
* ``ball_radial`` (8,) m/N: each ball joint of bar ij (both ends, each with this compliance),
  along the bar (in series with it);
* ``central_EI``, ``central_GJ`` (2,) N.m^2: bending and torsion of the central bar's segment
  D-C_k, a cantilever clamped at D loaded at C_k by lateral bar k (and the joint torque t_k);
* ``lateral_EI``, ``lateral_GJ`` (4,) N.m^2: the same for lateral bar k's arm C_k-B_i (leg i),
  clamped at C_k, loaded at B_i by bars i1, i2 (the cross-piece B_i1-B_i2 rigid);
* ``shaft_tilt`` (4,) rad/(N.m): actuator i's shaft and bearings, forearm i's root turning about
  the two axes normal to u_i through P_i under the bars' couple about P_i;
* ``base_translation`` (4,) m/N, ``base_rotation`` (4,) rad/(N.m): actuator i's mount on the base,
  an isotropic 6-D spring at P_i under the full wrench of leg i.

Beams (:func:`beam_compliance`): Euler-Bernoulli, isotropic bending, axial and shear compliance
neglected; tip compliance L^3/(3EI), L^2/(2EI), L/(EI), L/(GJ).

The data sit in the URDF next to their element, like the springs of eq. 30 (:mod:`h4pin.urdf`):
``<h4_revolute radial="..." axial="..." tilt="..."/>`` inside each lateral revolute ``<joint>``,
``<h4_ball radial="..."/>`` inside each bar ``<link>``, ``<h4_plate_bar EI_n= GJ_n=/>`` inside the
central bar's ``<link>`` (n = k of segment D-C_k) and each lateral bar's ``<link>`` (n = i of arm
C_k-B_i), ``<h4_actuator kc= shaft_tilt=/>`` and ``<h4_base translation= rotation=/>`` inside each
actuated ``<joint>``; a missing element or attribute is off. :func:`h4pin.load` reads them into
:attr:`h4pin.H4.elements`.

Unit-load method on a statics route: the equilibrium of the central bar and the two lateral bars
under ``Gamma_ext = [F, T, t1, t2]`` (:func:`plate_loads`) gives each element's load per unit
load (the joint reactions, the bar tensions, the wrenches at the beams' tips and on the actuator
mounts, :func:`element_loads`), and ``C_extra = sum_s c_s g_s g_s^T`` over scalar springs,
``sum_b W_b^T C_b W_b`` over beams and 6-D mounts (:func:`element_terms`). With every element
off, :func:`compliance_with_elements` returns eq. 30 unchanged. The finite-difference route of
:class:`DeformedElementsH4` (the plate solved with joint frames, beam tips and forearm roots moved
and turned) checks each term.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from h4pin import geometry
from h4pin.deformed import DeformedH4
from h4pin.errors import ParameterError
from h4pin.geometry import normal_pair, skew
from h4pin.model import H4Geometry
from h4pin.stiffness import Compliance, compliance

if TYPE_CHECKING:
    from h4pin.robot import H4

ELEMENTS = ("revolute_radial", "revolute_axial", "revolute_tilt", "ball_radial", "central_EI", "central_GJ",
            "lateral_EI", "lateral_GJ", "shaft_tilt", "base_translation", "base_rotation")
#: Number of elements of each kind: per lateral revolute joint or central-bar segment D-C_k (2),
#: per leg (4: lateral arm C_k-B_i, actuator shaft, base mount) or per bar (8).
COUNTS = {"revolute_radial": 2, "revolute_axial": 2, "revolute_tilt": 2, "ball_radial": 8, "central_EI": 2,
          "central_GJ": 2, "lateral_EI": 4, "lateral_GJ": 4, "shaft_tilt": 4, "base_translation": 4,
          "base_rotation": 4}
#: Kinds given as a stiffness (N.m^2): > 0, ``inf`` (the default) is rigid, i.e. off. The others
#: are compliances: >= 0, 0 (the default) is off.
RIGIDITIES = ("central_EI", "central_GJ", "lateral_EI", "lateral_GJ")
UNITS = {"revolute_radial": "m/N", "revolute_axial": "m/N", "revolute_tilt": "rad/(N.m)", "ball_radial": "m/N",
         "central_EI": "N.m^2", "central_GJ": "N.m^2", "lateral_EI": "N.m^2", "lateral_GJ": "N.m^2",
         "shaft_tilt": "rad/(N.m)", "base_translation": "m/N", "base_rotation": "rad/(N.m)"}


def element_name(name: str, index: int) -> str:
    """Human name of element ``index`` of kind ``name`` (1-based joint, segment, leg or bar)."""
    if name.startswith("revolute"):
        return f"revolute joint of lateral bar {index + 1}"
    if name.startswith("central"):
        return f"central-bar segment D-C_{index + 1}"
    if name.startswith("lateral"):
        return f"lateral-bar arm to B_{index + 1}"
    if name == "shaft_tilt":
        return f"actuator shaft of leg {index + 1}"
    if name.startswith("base"):
        return f"base mount of actuator {index + 1}"
    return f"ball joints of bar {index // 2 + 1}{index % 2 + 1}"


def is_on(name: str, value: np.ndarray) -> bool:
    """True when some element of kind ``name`` with data ``value`` is not rigid."""
    return bool(np.any(np.isfinite(value))) if name in RIGIDITIES else bool(np.any(value))


def check_elements(values: dict[str, Any], error: type[Exception] = ParameterError, where: str = "",
                   owners: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Element data as float arrays (scalars broadcast to :data:`COUNTS`): compliances finite and
    >= 0, rigidities (:data:`RIGIDITIES`) > 0 (``inf``: rigid); otherwise ``error`` naming the
    element (and ``owners[name][index]``)."""
    out = {}
    prefix = f"{where}: " if where else ""
    for name in ELEMENTS:
        rigidity = name in RIGIDITIES
        raw = values.get(name, np.inf if rigidity else 0.0)
        n = COUNTS[name]
        try:
            arr = np.array(raw, dtype=float)
            arr = np.broadcast_to(arr, (n,)).copy()
        except (TypeError, ValueError):
            raise error(f"{prefix}{name} must be a real number or {n} of them, got {raw!r}") from None
        bad = np.isnan(arr) | (arr <= 0.0) if rigidity else ~np.isfinite(arr) | (arr < 0.0)
        if np.any(bad):
            k = int(np.argmax(bad))
            owner = owners[name][k] if owners else element_name(name, k)
            rule = "> 0; inf switches it off" if rigidity else "finite and >= 0; 0 switches it off"
            raise error(f"{prefix}{owner}: {name} = {arr[k]!r} is not physical (must be {rule})")
        arr.setflags(write=False)
        out[name] = arr
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Elements:
    """Data of the neglected elements, SI, per element (all off by default).

    Each field accepts a scalar (every element of that kind) or one value per element:

    * ``revolute_radial``, ``revolute_axial`` (m/N), ``revolute_tilt`` (rad/(N.m)), (2,): the
      lateral bars' revolute joints k = 1, 2; ``ball_radial`` (8,) m/N: the ball joints of bars
      11, 12, ..., 42 (each bar's two ball joints have that compliance). 0: off.
    * ``central_EI``, ``central_GJ`` (2,) N.m^2: bending and torsion rigidity of the central bar's
      segment from D to C_k; ``lateral_EI``, ``lateral_GJ`` (4,) N.m^2: the same for the arm of a
      lateral bar from C_k to B_i (leg i). ``inf``: rigid (off).
    * ``shaft_tilt`` (4,) rad/(N.m): actuator i's shaft and bearings, the forearm root at P_i
      turning about the two axes normal to u_i. 0: off.
    * ``base_translation`` (4,) m/N and ``base_rotation`` (4,) rad/(N.m): actuator i's mount on
      the base, an isotropic 6-D spring at P_i. 0: off.
    """

    revolute_radial: Any = 0.0
    revolute_axial: Any = 0.0
    revolute_tilt: Any = 0.0
    ball_radial: Any = 0.0
    central_EI: Any = np.inf
    central_GJ: Any = np.inf
    lateral_EI: Any = np.inf
    lateral_GJ: Any = np.inf
    shaft_tilt: Any = 0.0
    base_translation: Any = 0.0
    base_rotation: Any = 0.0

    def __post_init__(self) -> None:
        checked = check_elements({n: getattr(self, n) for n in ELEMENTS})
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    def on(self, name: str) -> bool:
        """True when some element of kind ``name`` is switched on."""
        return is_on(name, getattr(self, name))

    @property
    def off(self) -> bool:
        """True when every element is switched off (eq. 30 as it is)."""
        return not any(self.on(n) for n in ELEMENTS)

    def allclose(self, other: Elements, rtol: float = 1e-15) -> bool:
        """Every element equal to ``other``'s within ``rtol`` (relative; ``inf`` equals ``inf``)."""
        return all(np.allclose(getattr(self, n), getattr(other, n), rtol=rtol, atol=0.0) for n in ELEMENTS)


#: Plate rods of the generated URDF: solid aluminium rounds of radius 8 mm (E = 70 GPa,
#: G = 26 GPa): EI = E pi r^4 / 4, GJ = G pi r^4 / 2.
_ROD_I = np.pi * 8e-3**4 / 4.0
#: Orders of magnitude for a report, not data of the prototype: a pair of deep-groove bearings
#: (radial/axial ~1e8 N/m, tilt ~2e4 N.m/rad with 20 mm between them), a 10 mm ball joint ~5e7 N/m;
#: the plate's bars as the URDF's 8 mm aluminium rods (EI 225 N.m^2, GJ 167 N.m^2); the actuator
#: shaft on two bearings of ~1e8 N/m 30 mm apart (k s^2 / 2 = 4.5e4 N.m/rad: 2e-5 rad/(N.m)); a
#: motor bolted to an aluminium frame through a ~10 mm bracket (1e8 N/m, 1e5 N.m/rad).
ILLUSTRATIVE = Elements(revolute_radial=1e-8, revolute_axial=1e-8, revolute_tilt=5e-5, ball_radial=2e-8,
                        central_EI=70e9 * _ROD_I, central_GJ=26e9 * 2 * _ROD_I, lateral_EI=70e9 * _ROD_I,
                        lateral_GJ=26e9 * 2 * _ROD_I, shaft_tilt=2e-5, base_translation=1e-8, base_rotation=1e-5)


def plate_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Loads per unit ``Gamma_ext`` (8 columns) from the equilibrium of the three plate bodies.

    Returns ``{"bars": (8, 8)`` tensions (N per unit load), ``"force": (2, 3, 8)`` the joint force
    on lateral bar k (world frame), ``"moment": (2, 3, 8)`` the joint couple on lateral bar k
    (world frame, normal to the joint axis), ``"axis": (2, 3)`` the joint axes v_k (world),
    ``"points"``: the :class:`h4pin.geometry.Points` of the pose, ``"w": (8, 3)`` unit bar
    directions A_ij -> B_ij}. Moments are taken about D; the joint carries no moment about its
    axis but the applied torque t_k.
    """
    pts = geometry.assembled_points(g, pose)
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    b = pts.Bij.reshape(8, 3) - pts.D
    a = np.zeros((18, 18))
    rhs = np.zeros((18, 8))
    rhs[0:3, 0:3] = -np.eye(3)
    rhs[3:6, 3:6] = -np.eye(3)
    normals = []
    for k in range(2):
        cf, cm = 8 + 5 * k, 11 + 5 * k
        ck = pts.C[k] - pts.D
        normal = normal_pair(pts.v[k])
        normals.append(normal)
        r0 = 6 + 6 * k
        for sign, rows in ((-1.0, 0), (1.0, r0)):  # central bar gets minus the joint load
            a[rows:rows + 3, cf:cf + 3] += sign * np.eye(3)
            a[rows + 3:rows + 6, cf:cf + 3] += sign * skew(ck)
            a[rows + 3:rows + 6, cm:cm + 2] += sign * normal
        for n in np.flatnonzero(g.lat == k):
            a[r0:r0 + 3, n] = -w[n]
            a[r0 + 3:r0 + 6, n] = -np.cross(b[n], w[n])
        rhs[3:6, 6 + k] = pts.v[k]  # -t_k v_k on the central bar
        rhs[r0 + 3:r0 + 6, 6 + k] = -pts.v[k]  # +t_k v_k on lateral bar k
    sol = np.linalg.solve(a, rhs)
    force = np.stack([sol[8 + 5 * k:11 + 5 * k] for k in range(2)])
    moment = np.stack([normals[k] @ sol[11 + 5 * k:13 + 5 * k] for k in range(2)])
    return {"bars": sol[:8], "force": force, "moment": moment, "axis": pts.v.copy(), "points": pts, "w": w}


def beam_compliance(axis: np.ndarray, length: float, ei: float, gj: float) -> tuple[np.ndarray, np.ndarray]:
    """Tip compliance (6, 6) of a straight cantilever, split into bending and torsion.

    Beam model: an Euler-Bernoulli beam of ``length`` L along the unit ``axis`` e, clamped at its
    inner end, loaded at its outer end by a force P and a couple M (about the tip); isotropic
    bending rigidity ``ei`` about every axis normal to e, torsion rigidity ``gj`` about e; axial
    and shear compliance neglected. Tip translation and rotation ``[delta, phi] = C [P, M]``:
    ``delta = L^3/(3EI) P_perp + L^2/(2EI) M x e``, ``phi = L^2/(2EI) e x P + L/(EI) M_perp
    + L/(GJ) (M.e) e``. Returns (bending part, torsion part), in the frame of ``axis``; an
    infinite rigidity gives a zero part.
    """
    e = np.asarray(axis, dtype=float)
    perp = np.eye(3) - np.outer(e, e)
    f = 1.0 / ei
    bend = np.zeros((6, 6))
    bend[:3, :3] = length**3 / 3.0 * f * perp
    bend[3:, 3:] = length * f * perp
    bend[3:, :3] = length**2 / 2.0 * f * skew(e)
    bend[:3, 3:] = bend[3:, :3].T
    tors = np.zeros((6, 6))
    tors[3:, 3:] = length / gj * np.outer(e, e)
    return bend, tors


def element_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Loads of the elements per unit Gamma_ext (world frame, SI per unit load).

    * ``revolute_radial`` (4, 8): joint k's force along two unit vectors normal to v_k (rows
      2k, 2k + 1); ``revolute_axial`` (2, 8) along v_k; ``revolute_tilt`` (4, 8): joint k's
      couple about the two normals; ``ball_radial`` (8, 8): each bar's tension (the bar's two
      ball joints carry it).
    * ``central`` (2, 6, 8): the wrench [force, couple about C_k] the lateral bar k and the joint
      torque t_k put on the tip C_k of the central-bar segment D-C_k (the same force and its
      moment about D at the root section, the segment being clamped at D where the load applies).
    * ``lateral`` (4, 6, 8): the wrench [force, couple about B_i] bars i1, i2 put on the tip B_i
      of lateral bar k's arm C_k-B_i (clamped at C_k).
    * ``base`` (4, 6, 8): the wrench [force, couple about P_i] of leg i on the base: the pulls of
      bars i1, i2 on the forearm at A_ij; ``shaft_tilt`` (8, 8): its couple about the two unit
      normals to u_i (rows 2i, 2i + 1).
    """
    p = plate_loads(g, pose)
    pts, w, f = p["points"], p["w"], p["bars"]
    normals = [normal_pair(v) for v in p["axis"]]
    radial = np.concatenate([normals[k].T @ p["force"][k] for k in range(2)])
    axial = np.stack([p["axis"][k] @ p["force"][k] for k in range(2)])
    tilt = np.concatenate([normals[k].T @ p["moment"][k] for k in range(2)])
    central = np.zeros((2, 6, 8))
    for k in range(2):
        central[k, :3] = -p["force"][k]
        central[k, 3:] = -p["moment"][k]
        central[k, 3:, 6 + k] -= p["axis"][k]
    pulls = w[:, :, None] * f[:, None, :]  # (8, 3, 8): bar n's pull on its forearm at A_n per unit load
    bij, aij = pts.Bij.reshape(8, 3), pts.Aij.reshape(8, 3)
    lateral = np.zeros((4, 6, 8))
    base = np.zeros((4, 6, 8))
    for n in range(8):
        i = n // 2
        lateral[i, :3] -= pulls[n]
        lateral[i, 3:] -= np.cross(bij[n] - pts.B[i], pulls[n], axis=0)
        base[i, :3] += pulls[n]
        base[i, 3:] += np.cross(aij[n] - pts.P[i], pulls[n], axis=0)
    shaft = np.concatenate([normal_pair(g.u[i]).T @ base[i, 3:] for i in range(4)])
    return {"revolute_radial": radial, "revolute_axial": axial, "revolute_tilt": tilt, "ball_radial": f,
            "central": central, "lateral": lateral, "base": base, "shaft_tilt": shaft}


def spring_compliances(elements: Elements) -> dict[str, np.ndarray]:
    """Compliance of every scalar spring of :func:`element_loads` (SI): radial and tilt two
    springs per joint, the ball joints two in series per bar, the shaft two per actuator."""
    return {"revolute_radial": np.repeat(elements.revolute_radial, 2),
            "revolute_axial": elements.revolute_axial,
            "revolute_tilt": np.repeat(elements.revolute_tilt, 2),
            "ball_radial": 2.0 * elements.ball_radial,
            "shaft_tilt": np.repeat(elements.shaft_tilt, 2)}


#: Beam kinds: rigidity field -> (beam family, part of :func:`beam_compliance`: 0 bending, 1 torsion).
BEAMS = {"central_EI": ("central", 0), "central_GJ": ("central", 1), "lateral_EI": ("lateral", 0),
         "lateral_GJ": ("lateral", 1)}


def beam_axes(g: H4Geometry) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each beam's inner-to-outer vector in its own body's frame (the central bar's for D-C_k,
    lateral bar k's for C_k-B_i): ``{"central": (2, 3), "lateral": (4, 3)}`` and lengths."""
    out = {}
    for fam, vec in (("central", np.asarray(g.C0)), ("lateral", np.asarray(g.b_leg))):
        length = np.linalg.norm(vec, axis=1)
        out[fam] = (vec / length[:, None], length)
    return out


def _beam_matrix(name: str, elements: Elements, index: int, axis: np.ndarray, length: float) -> np.ndarray:
    fam, part = BEAMS[name]
    ei, gj = getattr(elements, f"{fam}_EI")[index], getattr(elements, f"{fam}_GJ")[index]
    return beam_compliance(axis, length, ei, gj)[part]


def element_terms(g: H4Geometry, pose: np.ndarray, elements: Elements) -> dict[str, np.ndarray]:
    """Compliance term (8, 8) of each element kind that is on, SI: ``sum_s c_s g_s g_s^T`` over
    its scalar springs, ``sum_b W_b^T C_b W_b`` over its beams or 6-D mounts (W_b the (6, 8)
    wrench per unit load, C_b the (6, 6) tip or mount compliance)."""
    loads = element_loads(g, pose)
    comp = spring_compliances(elements)
    out = {}
    pts = geometry.assembled_points(g, pose)
    for name in ELEMENTS:
        if not elements.on(name):
            continue
        if name in comp:
            out[name] = (loads[name].T * comp[name]) @ loads[name]
        elif name in BEAMS:
            fam = BEAMS[name][0]
            vec = (pts.C - pts.D) if fam == "central" else (pts.B - pts.C[g.leg_lat])
            term = np.zeros((8, 8))
            for index, wrench in enumerate(loads[fam]):
                length = float(np.linalg.norm(vec[index]))
                term += wrench.T @ _beam_matrix(name, elements, index, vec[index] / length, length) @ wrench
            out[name] = term
        else:  # base: isotropic translation on the force, rotation on the couple
            part = slice(0, 3) if name == "base_translation" else slice(3, 6)
            c = getattr(elements, name)
            out[name] = sum(c[i] * loads["base"][i, part].T @ loads["base"][i, part] for i in range(4))
    return out


def compliance_with_elements(h4: H4, pose: np.ndarray, elements: Elements | None = None,
                             model: str = "consistent") -> Compliance:
    """:func:`h4pin.stiffness.compliance` (one pose) plus the terms of the elements that are on.

    ``elements``: default the robot's own (:attr:`h4pin.H4.elements`, read from its URDF; all
    off when the URDF has none). The extra terms are symmetric, so with ``model="consistent"``
    K stays symmetric. With every element off the result is
    :func:`h4pin.stiffness.compliance`'s, unchanged.
    """
    elements = h4.elements if elements is None else elements
    res = compliance(h4, pose, model)
    if elements.off:
        return res
    extra = element_terms(h4.geometry, res.pose, elements)
    terms = dict(res.terms) | extra
    return dataclasses.replace(res, matrix=res.matrix + sum(extra.values()), terms=terms)


class DeformedElementsH4(DeformedH4):
    """:class:`h4pin.deformed.DeformedH4` whose plate joints, plate beams and actuator mounts can
    be deformed too.

    Deformations, each a 6-vector [translation (m), rotation vector (rad)]:

    * ``eps_c`` (2, 6): the frame of joint k at C_k (the tip of the central bar's segment D-C_k)
      moved relative to the central bar, in the central bar's frame; lateral bar k follows it
      (then turns by omega_k about v_k). The revolute joint's radial, axial and tilt springs
      and the segment's bending and torsion are such motions.
    * ``eps_b`` (4, 6): the tip B_i of lateral bar k's arm C_k-B_i moved and turned about B_i
      relative to the lateral bar, in its frame: B_i1 and B_i2 follow.
    * ``eps_p`` (4, 6): forearm i's root moved and turned about P_i, world frame: A_i1 and A_i2
      follow (base mount; the shaft tilt is a turn about a normal to u_i).
    """

    def __init__(self, g: H4Geometry, pose: np.ndarray):
        super().__init__(g, pose)
        self.eps_c = np.zeros((2, 6))
        self.eps_b = np.zeros((4, 6))
        self.eps_p = np.zeros((4, 6))
        R = self.state.R
        self.normals = [R.T @ normal_pair(v) for v in self.pts.v]  # central-bar frame

    def plate_points(self, tp: np.ndarray) -> np.ndarray:
        g, st, ec, eb = self.g, self.state, self.eps_c, self.eps_b
        rc = pin.exp3(tp[3:6]) @ st.R
        d = st.D + tp[:3]
        out = np.empty((8, 3))
        for n in range(8):
            k, i = g.lat[n], n // 2
            rk = rc @ pin.exp3(ec[k, 3:]) @ pin.exp3(g.v[k] * (st.omega[k] + tp[6 + k]))
            ck = d + rc @ (g.C0[k] + ec[k, :3])
            local = g.b_leg[i] + eb[i, :3] + pin.exp3(eb[i, 3:]) @ (g.b[n] - g.b_leg[i])
            out[n] = ck + rk @ local
        return out

    def anchors(self, eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        aij, lengths = super().anchors(eps)
        P = np.repeat(self.g.P, 2, axis=0)
        ep = np.repeat(self.eps_p, 2, axis=0)
        out = np.stack([P[n] + ep[n, :3] + pin.exp3(ep[n, 3:]) @ (aij[n] - P[n]) for n in range(8)])
        return out, lengths

    def sensitivity(self, which: str, index: int, direction: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """``d tp / d s`` (8,) for the deformation ``s * direction`` (6,) of ``eps_<which>[index]``,
        by central differences of the non-linear plate."""
        eps = getattr(self, f"eps_{which}")
        out = []
        for sign in (1.0, -1.0):
            eps[index] = sign * step * np.asarray(direction, dtype=float)
            out.append(self.solve_plate(np.zeros(16)))
        eps[index] = 0.0
        return (out[0] - out[1]) / (2 * step)

    def sensitivities_6d(self, which: str, index: int, step: float = 1e-6) -> np.ndarray:
        """(8, 6): :meth:`sensitivity` along the six unit deformations of ``eps_<which>[index]``."""
        return np.column_stack([self.sensitivity(which, index, e, step) for e in np.eye(6)])


def _pad(translation: np.ndarray | None = None, rotation: np.ndarray | None = None) -> np.ndarray:
    out = np.zeros(6)
    if translation is not None:
        out[:3] = translation
    if rotation is not None:
        out[3:] = rotation
    return out


def element_terms_fd(g: H4Geometry, pose: np.ndarray, elements: Elements, step: float = 1e-6
                     ) -> dict[str, np.ndarray]:
    """The element terms by finite differences of the deformed robot and virtual work:
    ``sum c G G^T`` with G the plate's motion per deformation of the element (ball joints: per
    change of the bar length, two per bar), ``sum G C G^T`` with the (8, 6) G of a beam's tip or
    an actuator mount and its (6, 6) compliance in the same frame."""
    robot = DeformedElementsH4(g, pose)
    comp = spring_compliances(elements)
    out = {}
    on = {n for n in ELEMENTS if elements.on(n)}
    if on & {"revolute_radial", "revolute_axial", "revolute_tilt"}:
        cols = {"revolute_radial": [], "revolute_axial": [], "revolute_tilt": []}
        for k in range(2):
            nk, vk = robot.normals[k], g.v[k]
            cols["revolute_radial"] += [robot.sensitivity("c", k, _pad(nk[:, j]), step) for j in range(2)]
            cols["revolute_axial"].append(robot.sensitivity("c", k, _pad(vk), step))
            cols["revolute_tilt"] += [robot.sensitivity("c", k, _pad(None, nk[:, j]), step) for j in range(2)]
        for name, c in cols.items():
            if name in on:
                sens = np.column_stack(c)
                out[name] = (sens * comp[name]) @ sens.T
    if "ball_radial" in on:
        gl = robot.sensitivities(step)[:, 8:]
        out["ball_radial"] = (gl * comp["ball_radial"]) @ gl.T
    axes = beam_axes(g)
    for name in BEAMS:
        if name in on:
            fam = BEAMS[name][0]
            which = "c" if fam == "central" else "b"
            term = np.zeros((8, 8))
            for index, (axis, length) in enumerate(zip(*axes[fam], strict=True)):
                sens = robot.sensitivities_6d(which, index, step)
                term += sens @ _beam_matrix(name, elements, index, axis, float(length)) @ sens.T
            out[name] = term
    if on & {"base_translation", "base_rotation", "shaft_tilt"}:
        sens = [robot.sensitivities_6d("p", i, step) for i in range(4)]
        if "base_translation" in on:
            out["base_translation"] = sum(elements.base_translation[i] * s[:, :3] @ s[:, :3].T
                                          for i, s in enumerate(sens))
        if "base_rotation" in on:
            out["base_rotation"] = sum(elements.base_rotation[i] * s[:, 3:] @ s[:, 3:].T for i, s in enumerate(sens))
        if "shaft_tilt" in on:  # the forearm root turned about each normal to u_i, through P_i
            shaft = np.column_stack([robot.sensitivity("p", i, _pad(None, normal_pair(g.u[i])[:, j]), step)
                                     for i in range(4) for j in range(2)])
            out["shaft_tilt"] = (shaft * comp["shaft_tilt"]) @ shaft.T
    return out


def term_entries(h4: H4, pose: np.ndarray, elements: Elements = ILLUSTRATIVE) -> dict[str, np.ndarray]:
    """Each term's (eq. 30's four and the elements that are on) Table II entries xx, yy, zz, xz,
    shape (4,) in m/N, at one pose; they sum to the entries of :func:`compliance_with_elements`."""
    res = compliance_with_elements(h4, pose, elements)
    return {t: np.array([b[0, 0], b[1, 1], b[2, 2], b[0, 2]]) for t, b in
            ((t, m[:3, :3]) for t, m in res.terms.items())}
