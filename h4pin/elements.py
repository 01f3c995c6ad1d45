# SPDX-License-Identifier: Apache-2.0
"""Compliances that eq. 30 neglects, as optional elements (all off by default).

Elements (SI, one value per element; 0 switches one off):

* ``revolute_radial`` (2,) m/N: each lateral-bar revolute joint C_k, in the plane normal to its
  axis v_k;
* ``revolute_axial`` (2,) m/N: the same joint along its axis v_k;
* ``revolute_tilt`` (2,) rad/(N.m): the same joint about the two axes normal to v_k;
* ``ball_radial`` (8,) m/N: each ball joint of bar ij (both ends, each with this compliance),
  along the bar (in series with it).

The data sit in the URDF next to their element, like the springs of eq. 30 (:mod:`h4pin.urdf`):
``<h4_revolute radial="..." axial="..." tilt="..."/>`` inside each lateral revolute ``<joint>``,
``<h4_ball radial="..."/>`` inside each bar ``<link>``; a missing element or attribute is off.
:func:`h4pin.load` reads them into :attr:`h4pin.H4.elements`.

Unit-load method on a statics route: the equilibrium of the central bar and the two lateral bars
under ``Gamma_ext = [F, T, t1, t2]`` (:func:`plate_loads`) gives each element's load per unit
load ``g_s`` (the joint reactions, the bar tensions), and ``C_extra = sum_s c_s g_s g_s^T``
(:func:`element_terms`). With every element off, :func:`compliance_with_elements` returns eq. 30
unchanged. The finite-difference route of :class:`DeformedElementsH4` (the plate solved with the
joints displaced or tilted) checks each term.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from h4pin import geometry
from h4pin.deformed import DeformedH4
from h4pin.errors import ParameterError
from h4pin.model import H4Geometry
from h4pin.stiffness import Compliance, compliance

if TYPE_CHECKING:
    from h4pin.robot import H4

ELEMENTS = ("revolute_radial", "revolute_axial", "revolute_tilt", "ball_radial")
#: Number of elements of each kind: per lateral revolute joint (2) or per bar (8).
COUNTS = {"revolute_radial": 2, "revolute_axial": 2, "revolute_tilt": 2, "ball_radial": 8}


def element_name(name: str, index: int) -> str:
    """Human name of element ``index`` of kind ``name`` (lateral joint k or bar ij, 1-based)."""
    if COUNTS[name] == 2:
        return f"revolute joint of lateral bar {index + 1}"
    return f"ball joints of bar {index // 2 + 1}{index % 2 + 1}"


def check_elements(values: dict[str, Any], error: type[Exception] = ParameterError, where: str = "",
                   owners: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Element data as float arrays (scalars broadcast; 2 per revolute kind, 8 for ball_radial),
    each finite and >= 0; otherwise ``error`` naming the element (and ``owners[name][index]``)."""
    out = {}
    prefix = f"{where}: " if where else ""
    for name in ELEMENTS:
        raw = values.get(name, 0.0)
        n = COUNTS[name]
        try:
            arr = np.array(raw, dtype=float)
            arr = np.broadcast_to(arr, (n,)).copy()
        except (TypeError, ValueError):
            raise error(f"{prefix}{name} must be a real number or {n} of them, got {raw!r}") from None
        bad = ~np.isfinite(arr) | (arr < 0.0)
        if np.any(bad):
            k = int(np.argmax(bad))
            owner = owners[name][k] if owners else element_name(name, k)
            raise error(f"{prefix}{owner}: {name} = {arr[k]!r} is not physical (must be finite and >= 0; 0 switches "
                        "it off)")
        arr.setflags(write=False)
        out[name] = arr
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Elements:
    """Compliances of the neglected elements, SI, per element, each >= 0 (0: off, the default).

    Each field accepts a scalar (every element of that kind) or one value per element:
    ``revolute_*`` (2,) for the lateral bars' revolute joints k = 1, 2; ``ball_radial`` (8,) for
    the ball joints of bars 11, 12, ..., 42 (each bar's two ball joints have that compliance).
    """

    revolute_radial: Any = 0.0
    revolute_axial: Any = 0.0
    revolute_tilt: Any = 0.0
    ball_radial: Any = 0.0

    def __post_init__(self) -> None:
        checked = check_elements({n: getattr(self, n) for n in ELEMENTS})
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    @property
    def off(self) -> bool:
        """True when every element is switched off (eq. 30 as it is)."""
        return all(not np.any(getattr(self, n)) for n in ELEMENTS)

    def allclose(self, other: Elements, rtol: float = 1e-15) -> bool:
        """Every element equal to ``other``'s within ``rtol`` (relative)."""
        return all(np.allclose(getattr(self, n), getattr(other, n), rtol=rtol, atol=0.0) for n in ELEMENTS)


#: Orders of magnitude for a report, not data of the prototype: a pair of deep-groove bearings
#: (radial/axial ~1e8 N/m, tilt ~2e4 N.m/rad with 20 mm between them), a 10 mm ball joint ~5e7 N/m.
ILLUSTRATIVE = Elements(revolute_radial=1e-8, revolute_axial=1e-8, revolute_tilt=5e-5, ball_radial=2e-8)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def normal_pair(axis: np.ndarray) -> np.ndarray:
    """(3, 2): two orthonormal vectors normal to the unit ``axis``, as columns."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(axis, e1)])


def _pose_points(g: H4Geometry, pose: np.ndarray) -> geometry.Points:
    x = geometry.as_pose(pose)
    sol = geometry.solve(g, x, check=False)
    geometry.raise_for_status(sol.status, sol.detail, batch=False)
    return geometry.points(g, sol.state)


def plate_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Loads per unit ``Gamma_ext`` (8 columns) from the equilibrium of the three plate bodies.

    Returns ``{"bars": (8, 8)`` tensions (N per unit load), ``"force": (2, 3, 8)`` the joint force
    on lateral bar k (world frame), ``"moment": (2, 3, 8)`` the joint couple on lateral bar k
    (world frame, normal to the joint axis), ``"axis": (2, 3)`` the joint axes v_k (world)}.
    Moments are taken about D; the joint carries no moment about its axis but the applied
    torque t_k.
    """
    pts = _pose_points(g, pose)
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
            a[rows + 3:rows + 6, cf:cf + 3] += sign * _skew(ck)
            a[rows + 3:rows + 6, cm:cm + 2] += sign * normal
        for n in np.flatnonzero(g.lat == k):
            a[r0:r0 + 3, n] = -w[n]
            a[r0 + 3:r0 + 6, n] = -np.cross(b[n], w[n])
        rhs[3:6, 6 + k] = pts.v[k]  # -t_k v_k on the central bar
        rhs[r0 + 3:r0 + 6, 6 + k] = -pts.v[k]  # +t_k v_k on lateral bar k
    sol = np.linalg.solve(a, rhs)
    force = np.stack([sol[8 + 5 * k:11 + 5 * k] for k in range(2)])
    moment = np.stack([normals[k] @ sol[11 + 5 * k:13 + 5 * k] for k in range(2)])
    return {"bars": sol[:8], "force": force, "moment": moment, "axis": pts.v.copy()}


def element_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Load of every spring of each element per unit Gamma_ext, ``{element: (n_springs, 8)}``:
    radial 4 (joint k's force along two unit vectors normal to v_k, rows 2k, 2k + 1), axial 2
    (along v_k), tilt 4 (joint k's couple about the two normals), ball 8 (each bar's tension;
    the bar's two ball joints carry it)."""
    p = plate_loads(g, pose)
    normals = [normal_pair(v) for v in p["axis"]]
    radial = np.concatenate([normals[k].T @ p["force"][k] for k in range(2)])
    axial = np.stack([p["axis"][k] @ p["force"][k] for k in range(2)])
    tilt = np.concatenate([normals[k].T @ p["moment"][k] for k in range(2)])
    return {"revolute_radial": radial, "revolute_axial": axial, "revolute_tilt": tilt, "ball_radial": p["bars"]}


def spring_compliances(elements: Elements) -> dict[str, np.ndarray]:
    """Compliance of every spring of :func:`element_loads`, per element kind (SI): radial and
    tilt two springs per joint, the ball joints two in series per bar."""
    return {"revolute_radial": np.repeat(elements.revolute_radial, 2),
            "revolute_axial": elements.revolute_axial,
            "revolute_tilt": np.repeat(elements.revolute_tilt, 2),
            "ball_radial": 2.0 * elements.ball_radial}


def element_terms(g: H4Geometry, pose: np.ndarray, elements: Elements) -> dict[str, np.ndarray]:
    """``sum_s c_s g_s g_s^T`` (8, 8) of each element kind that is on (some element > 0), SI."""
    loads = element_loads(g, pose)
    comp = spring_compliances(elements)
    return {n: (loads[n].T * comp[n]) @ loads[n] for n in ELEMENTS if np.any(getattr(elements, n))}


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


#: Springs of :class:`DeformedElementsH4`, in the order of its ``joint_eps``.
JOINT_SPRINGS = {"revolute_radial": slice(0, 4), "revolute_axial": slice(4, 6), "revolute_tilt": slice(6, 10)}


class DeformedElementsH4(DeformedH4):
    """:class:`h4pin.deformed.DeformedH4` whose revolute joints can also be displaced and tilted.

    ``joint_eps`` (10,): joint k's lateral bar displaced relative to the central bar at C_k by
    (e_1, e_2) along two unit vectors normal to the joint axis v_k (entries 2k, 2k + 1) and by
    e_v along v_k (entry 4 + k), and turned by (phi_1, phi_2) about the two normals (entries
    6 + 2k, 7 + 2k) about C_k; all in the central bar's frame (m, rad). The normals are those of
    :func:`normal_pair` of the world axis at the pose, taken back to the central bar's frame, so
    the springs are those of :func:`element_loads`.
    """

    def __init__(self, g: H4Geometry, pose: np.ndarray):
        super().__init__(g, pose)
        self.joint_eps = np.zeros(10)
        R = self.state.R
        self._normals = [R.T @ normal_pair(v) for v in self.pts.v]  # central-bar frame

    def plate_points(self, tp: np.ndarray) -> np.ndarray:
        g, st, e = self.g, self.state, self.joint_eps
        rc = pin.exp3(tp[3:6]) @ st.R
        d = st.D + tp[:3]
        out = np.empty((8, 3))
        for k in range(2):
            nk, vk = self._normals[k], g.v[k]
            shift = nk @ e[2 * k:2 * k + 2] + vk * e[4 + k]
            tilt = pin.exp3(nk @ e[6 + 2 * k:8 + 2 * k])
            rk = rc @ tilt @ pin.exp3(vk * (st.omega[k] + tp[6 + k]))
            ck = d + rc @ (g.C0[k] + shift)
            rows = g.lat == k
            out[rows] = ck + g.b[rows] @ rk.T
        return out

    def joint_sensitivities(self, step: float = 1e-6) -> np.ndarray:
        """``d tp / d joint_eps`` (8, 10) by central differences of the non-linear plate."""
        out = np.empty((8, 10))
        for s in range(10):
            e = np.zeros(10)
            e[s] = step
            self.joint_eps = e
            plus = self.solve_plate(np.zeros(16))
            self.joint_eps = -e
            minus = self.solve_plate(np.zeros(16))
            out[:, s] = (plus - minus) / (2 * step)
        self.joint_eps = np.zeros(10)
        return out


def element_terms_fd(g: H4Geometry, pose: np.ndarray, elements: Elements, step: float = 1e-6
                     ) -> dict[str, np.ndarray]:
    """The element terms by finite differences of the deformed robot and virtual work:
    ``sum c G G^T`` with G the plate's motion per joint deformation (ball joints: per change of
    the bar length, two per bar)."""
    robot = DeformedElementsH4(g, pose)
    comp = spring_compliances(elements)
    out = {}
    if any(np.any(getattr(elements, n)) for n in JOINT_SPRINGS):
        sens = robot.joint_sensitivities(step)
        for name, sl in JOINT_SPRINGS.items():
            if np.any(getattr(elements, name)):
                out[name] = (sens[:, sl] * comp[name]) @ sens[:, sl].T
    if np.any(elements.ball_radial):
        gl = robot.sensitivities(step)[:, 8:]
        out["ball_radial"] = (gl * comp["ball_radial"]) @ gl.T
    return out


def term_entries(h4: H4, pose: np.ndarray, elements: Elements = ILLUSTRATIVE) -> dict[str, np.ndarray]:
    """Each term's (eq. 30's four and the elements that are on) Table II entries xx, yy, zz, xz,
    shape (4,) in m/N, at one pose; they sum to the entries of :func:`compliance_with_elements`."""
    res = compliance_with_elements(h4, pose, elements)
    return {t: np.array([b[0, 0], b[1, 1], b[2, 2], b[0, 2]]) for t, b in
            ((t, m[:3, :3]) for t, m in res.terms.items())}
