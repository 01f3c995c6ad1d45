# SPDX-License-Identifier: Apache-2.0
"""The H4 with deformed springs, solved non-linearly: a finite-difference route to K and the
loaded equilibrium.

Nothing here uses the paper's matrices. A spring deformation moves the forearm-side ball joints
A_ij or changes a bar length l_ij; the plate (8 coordinates: D, a rotation vector Omega of the
central bar, and the relative rotations omega_k of the lateral bars) is then found by solving
the eight closures ``|B_ij(tp) - A_ij| = l_ij`` by Newton's method.

* :func:`sensitivities`: ``G_s = d tp / d eps_s`` for every spring by central differences;
  with virtual work, ``K = sum_s c_s G_s G_s^T`` (:func:`compliance_terms`).
* :func:`loaded_equilibrium`: the deflection under a force at D, from the stationary point of
  the potential ``sum eps_s^2 / (2 c_s) - F . D(eps)``, without linearising the geometry.

Spring deformations (the paper's model of each element):

* actuator and bending of forearm i: a rotation of forearm i about u_i (eqs. 10, 14);
* torsion of forearm i: a rotation of A_i1, A_i2 about the forearm axis through A_i (eq. 21);
* tension of bar ij: a change of l_ij (eq. 25).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from h4pin.description.geometry import H4Geometry
from h4pin.errors import ConvergenceError
from h4pin.kinematics import closed_form as geometry

#: Kinds of spring deformation and how many of each.
KINDS = {"rotation": 4, "torsion": 4, "tension": 8}


def _rotate(points: np.ndarray, origin: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    return origin + (points - origin) @ pin.exp3(angle * axis).T


class DeformedH4:
    """An H4 at a rigid pose whose springs can be deformed; solves the plate non-linearly.

    Args:
        g: The robot's geometry (``h4.geometry`` of an :class:`h4pin.H4`).
        pose: The reference pose [x, y, z, theta] (m, rad), assembled by the inverse geometry.
    """

    def __init__(self, g: H4Geometry, pose: np.ndarray):
        self.g = g
        self.pose = geometry.as_pose(pose).copy()
        sol = geometry.solve(g, self.pose, check=False)
        geometry.raise_for_status(sol.status, sol.detail, batch=False)
        self.state = sol.state
        self.q = sol.state.q
        self.pts = geometry.points(g, sol.state)

    def plate_points(self, tp: np.ndarray) -> np.ndarray:
        """B_ij (8, 3) for plate coordinates tp = [dD, Omega, domega_1, domega_2] (finite)."""
        st = self.state
        _, bij, _ = geometry.plate_points(self.g, st.D + tp[:3], pin.exp3(tp[3:6]) @ st.R, st.omega + tp[6:8])
        return bij

    def anchors(self, eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A_ij (8, 3) and l_ij (8,) for spring deformations eps = [rotation (4), torsion (4),
        tension (8)] (rad, rad, m)."""
        g, pts = self.g, self.pts
        aij = pts.Aij.copy()
        for i in range(4):
            aij[i] = _rotate(aij[i], pts.P[i], g.u[i], eps[i])
            e = (pts.A[i] - pts.P[i]) / np.linalg.norm(pts.A[i] - pts.P[i])
            centre = _rotate(pts.A[i], pts.P[i], g.u[i], eps[i])
            axis = pin.exp3(eps[i] * g.u[i]) @ e
            aij[i] = _rotate(aij[i], centre, axis, eps[4 + i])
        return aij.reshape(8, 3), g.l + eps[8:]

    def solve_plate(self, eps: np.ndarray, guess: np.ndarray | None = None, tol: float = 1e-14,
                    max_iter: int = 30) -> np.ndarray:
        """Plate coordinates tp (8,) that close all bars for spring deformations ``eps`` (16,).

        Newton's method on ``|B_ij(tp) - A_ij| - l_ij = 0`` with a central-difference Jacobian
        (no analytic derivative, so nothing is shared with M1).

        Raises:
            ConvergenceError: the closures cannot be solved to ``tol`` (m).
        """
        aij, lengths = self.anchors(eps)

        def residual(tp: np.ndarray) -> np.ndarray:
            return np.linalg.norm(self.plate_points(tp) - aij, axis=1) - lengths

        tp = np.zeros(8) if guess is None else np.array(guess, dtype=float)
        res = residual(tp)
        h = 1e-7
        for _ in range(max_iter):
            if np.max(np.abs(res)) < tol:
                return tp
            jac = np.column_stack([(residual(tp + h * e) - residual(tp - h * e)) / (2 * h) for e in np.eye(8)])
            tp = tp - np.linalg.solve(jac, res)
            res = residual(tp)
        raise ConvergenceError(f"the deformed plate does not close: residual {np.max(np.abs(res)):.2e} m "
                               f"after {max_iter} Newton steps")

    def sensitivities(self, step: float = 1e-6) -> np.ndarray:
        """``G = d tp / d eps`` (8, 16) by central differences of :meth:`solve_plate`."""
        g = np.empty((8, 16))
        for s in range(16):
            e = np.zeros(16)
            e[s] = step
            g[:, s] = (self.solve_plate(e) - self.solve_plate(-e)) / (2 * step)
        return g


def compliance_terms(g: H4Geometry, pose: np.ndarray, step: float = 1e-6) -> dict[str, np.ndarray]:
    """The four terms of K (8, 8 each) from finite-difference sensitivities and virtual work.

    The load of spring s under Gamma_ext is ``G_s^T Gamma_ext`` (virtual work), its deformation
    ``c_s`` times that, so term = ``c sum_s G_s G_s^T`` over the springs of the term. Equals the
    ``consistent`` model, and the ``paper`` model in its translational block.
    """
    sens = DeformedH4(g, pose).sensitivities(step)
    c = g.compliances()
    rot, tors, tens = sens[:, :4], sens[:, 4:8], sens[:, 8:]
    return {
        "control": (rot * c["control"]) @ rot.T,
        "bending": (rot * c["bending"]) @ rot.T,
        "torsion": (tors * c["torsion"]) @ tors.T,
        "tension": (tens * c["tension"]) @ tens.T,
    }


def loaded_equilibrium(g: H4Geometry, pose: np.ndarray, force: np.ndarray, *, rtol: float = 1e-7,
                       max_iter: int = 50, step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Non-linear static equilibrium under a force (3,) N at D: returns (dD (3,) m, eps (16,)).

    Fixed point of ``eps_s = c_s F . dD/deps_s (eps)``, the stationarity of the potential
    ``sum eps_s^2 / (2 c_s) - F . D(eps)``, with the sensitivities re-computed at the deformed
    state each iteration (geometry not linearised).

    Converged when an iteration changes eps by at most ``rtol`` times its largest entry.

    Raises:
        ConvergenceError: no fixed point within ``max_iter`` iterations.
    """
    robot = DeformedH4(g, pose)
    force = np.asarray(force, dtype=float)
    c = g.compliances()
    comp = np.r_[c["control"] + c["bending"], c["torsion"], c["tension"]]
    eps = np.zeros(16)
    for _ in range(max_iter):
        tp0 = robot.solve_plate(eps)
        g = np.empty((3, 16))
        for s in range(16):
            e = np.zeros(16)
            e[s] = step
            g[:, s] = (robot.solve_plate(eps + e, tp0)[:3] - robot.solve_plate(eps - e, tp0)[:3]) / (2 * step)
        new = comp * (force @ g)
        converged = np.max(np.abs(new - eps)) <= rtol * np.max(np.abs(new))
        eps = new
        if converged:
            return robot.solve_plate(eps, tp0)[:3], eps
    raise ConvergenceError(f"loaded equilibrium did not converge in {max_iter} iterations")
