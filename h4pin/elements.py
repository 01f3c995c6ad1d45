# SPDX-License-Identifier: Apache-2.0
"""Compliances that eq. 30 neglects, as optional elements (all off by default).

Elements (SI, per joint; 0 switches one off):

* ``revolute_radial`` (m/N): each lateral-bar revolute joint C_k, in the plane normal to its axis
  (central-bar x and y);
* ``revolute_axial`` (m/N): the same joint along its axis z;
* ``revolute_tilt`` (rad/(N.m)): the same joint about the central-bar x and y axes;
* ``ball_radial`` (m/N): each of the 16 ball joints, along its bar (in series with the bar).

Unit-load method on a statics route: the equilibrium of the central bar and the two lateral bars
under ``Gamma_ext = [F, T, t1, t2]`` (:func:`plate_loads`) gives each element's load per unit
load ``g_s`` (the joint reactions, the bar tensions), and ``C_extra = sum_s c_s g_s g_s^T``
(:func:`element_terms`). With every element off, :func:`compliance_with_elements` returns eq. 30
unchanged. The finite-difference route of :class:`DeformedElementsH4` (the plate solved with the
joints displaced or tilted) checks each term.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from h4pin import geometry
from h4pin.deformed import DeformedH4
from h4pin.errors import ParameterError
from h4pin.params import LEG_LATERAL, H4Params
from h4pin.robot import H4
from h4pin.stiffness import Compliance, compliance

ELEMENTS = ("revolute_radial", "revolute_axial", "revolute_tilt", "ball_radial")


@dataclasses.dataclass(frozen=True)
class Elements:
    """Compliances of the neglected elements, SI, each >= 0 (0: off, the default)."""

    revolute_radial: float = 0.0
    revolute_axial: float = 0.0
    revolute_tilt: float = 0.0
    ball_radial: float = 0.0

    def __post_init__(self) -> None:
        for name in ELEMENTS:
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} must be a real number, got {value!r}") from None
            if not np.isfinite(value) or value < 0.0:
                raise ParameterError(f"{name} must be finite and >= 0 (0 switches it off), got {value!r}")
            object.__setattr__(self, name, value)

    @property
    def off(self) -> bool:
        """True when every element is switched off (eq. 30 as it is)."""
        return all(getattr(self, n) == 0.0 for n in ELEMENTS)


#: Orders of magnitude for a report, not data of the prototype: a pair of deep-groove bearings
#: (radial/axial ~1e8 N/m, tilt ~2e4 N.m/rad with 20 mm between them), a 10 mm ball joint ~5e7 N/m.
ILLUSTRATIVE = Elements(revolute_radial=1e-8, revolute_axial=1e-8, revolute_tilt=5e-5, ball_radial=2e-8)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def plate_loads(params: H4Params, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Loads per unit ``Gamma_ext`` (8 columns) from the equilibrium of the three plate bodies.

    Returns ``{"bars": (8, 8)`` tensions (N per unit load), ``"force": (2, 3, 8)`` the joint force
    on lateral bar k in the central-bar frame, ``"moment": (2, 2, 8)`` the joint moment on lateral
    bar k about the central-bar x and y axes}. Moments are taken about D; the joint carries no
    moment about its axis but the applied torque t_k.
    """
    x = geometry.as_poses(pose)
    q = geometry.inverse_geometry(params, x)
    pts = geometry.points(params, x, q)
    w = (pts.Bij - pts.Aij).reshape(8, 3)
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    b = pts.Bij.reshape(8, 3) - pts.D
    lat = np.repeat(LEG_LATERAL, 2)
    a = np.zeros((18, 18))
    rhs = np.zeros((18, 8))
    rhs[0:3, 0:3] = -np.eye(3)
    rhs[3:6, 3:6] = -np.eye(3)
    for k in range(2):
        cf, cm = 8 + 5 * k, 11 + 5 * k
        ck = pts.C[k] - pts.D
        r0 = 6 + 6 * k
        for sign, rows in ((-1.0, 0), (1.0, r0)):  # central bar gets minus the joint load
            a[rows:rows + 3, cf:cf + 3] += sign * np.eye(3)
            a[rows + 3:rows + 6, cf:cf + 3] += sign * _skew(ck)
            a[rows + 3:rows + 6, cm:cm + 2] += sign * np.eye(3)[:, :2]
        for n in np.flatnonzero(lat == k):
            a[r0:r0 + 3, n] = -w[n]
            a[r0 + 3:r0 + 6, n] = -np.cross(b[n], w[n])
        rhs[5, 6 + k] = 1.0  # -t_k z on the central bar
        rhs[r0 + 5, 6 + k] = -1.0  # +t_k z on lateral bar k
    sol = np.linalg.solve(a, rhs)
    rot = geometry.rot_z(float(x[3]))
    force = np.stack([rot.T @ sol[8 + 5 * k:11 + 5 * k] for k in range(2)])
    moment = np.stack([(rot.T @ np.vstack([sol[11 + 5 * k:13 + 5 * k], np.zeros((1, 8))]))[:2] for k in range(2)])
    return {"bars": sol[:8], "force": force, "moment": moment}


def element_loads(params: H4Params, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Load of every spring of each element per unit Gamma_ext, ``{element: (n_springs, 8)}``:
    radial 4 (joints x {x, y}), axial 2, tilt 4, ball 16 (each bar's tension, twice)."""
    p = plate_loads(params, pose)
    return {
        "revolute_radial": p["force"][:, :2].reshape(4, 8),
        "revolute_axial": p["force"][:, 2],
        "revolute_tilt": p["moment"].reshape(4, 8),
        "ball_radial": np.repeat(p["bars"], 2, axis=0),
    }


def element_terms(params: H4Params, pose: np.ndarray, elements: Elements) -> dict[str, np.ndarray]:
    """``c_s sum g_s g_s^T`` (8, 8) of each element that is on, SI."""
    loads = element_loads(params, pose)
    return {n: getattr(elements, n) * (loads[n].T @ loads[n]) for n in ELEMENTS if getattr(elements, n) > 0.0}


def compliance_with_elements(h4: H4, pose: np.ndarray, elements: Elements = Elements(),
                             model: str = "consistent") -> Compliance:
    """:func:`h4pin.stiffness.compliance` (one pose) plus the terms of the elements that are on.

    The extra terms are symmetric, so with ``model="consistent"`` K stays symmetric. With every
    element off the result is :func:`h4pin.stiffness.compliance`'s, unchanged.
    """
    res = compliance(h4, pose, model)
    if elements.off:
        return res
    extra = element_terms(h4.params, res.pose, elements)
    terms = dict(res.terms) | extra
    return dataclasses.replace(res, matrix=res.matrix + sum(extra.values()), terms=terms)


#: Springs of :class:`DeformedElementsH4`, in the order of its ``joint_eps``.
JOINT_SPRINGS = {"revolute_radial": slice(0, 4), "revolute_axial": slice(4, 6), "revolute_tilt": slice(6, 10)}


class DeformedElementsH4(DeformedH4):
    """:class:`h4pin.deformed.DeformedH4` whose revolute joints can also be displaced and tilted.

    ``joint_eps`` (10,): joint k's lateral bar displaced by (e_x, e_y) (entries 2k, 2k + 1) and
    e_z (entry 4 + k) relative to the central bar at C_k, and turned by (phi_x, phi_y)
    (entries 6 + 2k, 7 + 2k) about C_k; all in the central-bar frame (m, rad).
    """

    def __init__(self, params: H4Params, pose: np.ndarray):
        super().__init__(params, pose)
        self.joint_eps = np.zeros(10)

    def plate_points(self, tp: np.ndarray) -> np.ndarray:
        theta = self.pose[3]
        rc = pin.exp3(tp[3:6]) @ geometry.rot_z(theta)
        d = self.pose[:3] + tp[:3]
        e = self.joint_eps
        out = np.empty((8, 3))
        for k in range(2):
            shift = np.array([e[2 * k], e[2 * k + 1], e[4 + k]])
            tilt = pin.exp3(np.array([e[6 + 2 * k], e[7 + 2 * k], 0.0]))
            rk = rc @ tilt @ geometry.rot_z(-theta + tp[6 + k])
            ck = d + rc @ (self.params.DC[:, k] + shift)
            rows = self._lat == k
            out[rows] = ck + self._b_local[rows] @ rk.T
        return out

    def joint_sensitivities(self, step: float = 1e-6) -> np.ndarray:
        """``d tp / d joint_eps`` (8, 10) by central differences of the non-linear plate."""
        g = np.empty((8, 10))
        for s in range(10):
            e = np.zeros(10)
            e[s] = step
            self.joint_eps = e
            plus = self.solve_plate(np.zeros(16))
            self.joint_eps = -e
            minus = self.solve_plate(np.zeros(16))
            g[:, s] = (plus - minus) / (2 * step)
        self.joint_eps = np.zeros(10)
        return g


def element_terms_fd(params: H4Params, pose: np.ndarray, elements: Elements, step: float = 1e-6
                     ) -> dict[str, np.ndarray]:
    """The element terms by finite differences of the deformed robot and virtual work:
    ``c G G^T`` with G the plate's motion per joint deformation (ball joints: per change of
    the bar length, two per bar)."""
    robot = DeformedElementsH4(params, pose)
    g = robot.joint_sensitivities(step)
    out = {}
    for name, sl in JOINT_SPRINGS.items():
        c = getattr(elements, name)
        if c > 0.0:
            out[name] = c * g[:, sl] @ g[:, sl].T
    if elements.ball_radial > 0.0:
        gl = robot.sensitivities(step)[:, 8:]
        out["ball_radial"] = 2.0 * elements.ball_radial * gl @ gl.T
    return out


def term_entries(h4: H4, pose: np.ndarray, elements: Elements = ILLUSTRATIVE) -> dict[str, np.ndarray]:
    """Each term's (eq. 30's four and the elements that are on) Table II entries xx, yy, zz, xz,
    shape (4,) in m/N, at one pose; they sum to the entries of :func:`compliance_with_elements`."""
    res = compliance_with_elements(h4, pose, elements)
    return {t: np.array([b[0, 0], b[1, 1], b[2, 2], b[0, 2]]) for t, b in
            ((t, m[:3, :3]) for t, m in res.terms.items())}
