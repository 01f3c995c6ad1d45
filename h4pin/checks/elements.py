# SPDX-License-Identifier: Apache-2.0
"""The optional elements' compliance by finite differences of the deformed robot: the independent
route that checks :mod:`h4pin.stiffness.elements` (unit loads on the statics).

:class:`DeformedElementsH4` is :class:`h4pin.checks.deformed.DeformedH4` whose plate joints,
plate beams and actuator mounts can be deformed too; :func:`element_terms_fd` moves each element
by a small step, solves the non-linear plate and assembles ``sum c G G^T`` by virtual work.

Nothing of :mod:`h4pin.stiffness.elements` is used: each spring's compliance is read from the
:class:`~h4pin.description.elements.Elements` here, and a beam's tip compliance comes from its
strain energy (:func:`_cantilever`), not from the closed forms it checks.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from h4pin.checks.deformed import DeformedH4
from h4pin.description.elements import ELEMENTS, Elements
from h4pin.description.geometry import H4Geometry
from h4pin.kinematics.closed_form import normal_pair

_GAUSS = (0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0))


def _cantilever(axis: np.ndarray, length: float, section: np.ndarray) -> np.ndarray:
    """Tip compliance (6, 6), ``[delta, phi] = C [P, M]``, of a straight beam of ``length`` along
    the unit ``axis`` e, clamped at its root, with the section's compliance per unit length
    ``section`` (3, 3) (curvature and twist per unit moment: ``(I - e e^T) / EI`` for bending,
    ``e e^T / GJ`` for torsion, ``b b^T / EI`` for bending in one plane only), by Castigliano:
    the tip load gives the moment ``m(s) = M + (L - s) e x P`` at s from the root, the strain
    energy is ``1/2 int m^T section m ds`` and C its Hessian in [P, M] (the integrand is
    quadratic in s: two Gauss points are exact). Axial and shear strain neglected."""
    cross = pin.skew(np.asarray(axis, dtype=float))
    out = np.zeros((6, 6))
    for x in _GAUSS:
        moment = np.hstack([(1.0 - x) * length * cross, np.eye(3)])  # m = moment @ [P, M]
        out += 0.5 * length * moment.T @ section @ moment
    return out


def _flexibility(rigidity: float) -> float:
    """1 / rigidity (0 for an infinite one: the element is rigid)."""
    return 0.0 if np.isinf(rigidity) else 1.0 / rigidity


class DeformedElementsH4(DeformedH4):
    """:class:`h4pin.checks.deformed.DeformedH4` whose plate joints, plate beams and actuator mounts can
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
    * ``eps_a`` (4, 6): forearm i's tip moved and turned about A_i (midway between A_i1 and
      A_i2), world frame: A_i1 and A_i2 follow (the forearm bending out of its plane).
    """

    def __init__(self, g: H4Geometry, pose: np.ndarray):
        super().__init__(g, pose)
        self.eps_c = np.zeros((2, 6))
        self.eps_b = np.zeros((4, 6))
        self.eps_p = np.zeros((4, 6))
        self.eps_a = np.zeros((4, 6))
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
        tip = np.repeat(0.5 * (out[0::2] + out[1::2]), 2, axis=0)
        ea = np.repeat(self.eps_a, 2, axis=0)
        out = np.stack([tip[n] + ea[n, :3] + pin.exp3(ea[n, 3:]) @ (out[n] - tip[n]) for n in range(8)])
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
    out = {}
    on = {n for n in ELEMENTS if elements.on(n)}
    if on & {"revolute_radial", "revolute_axial", "revolute_tilt"}:
        cols = {"revolute_radial": [], "revolute_axial": [], "revolute_tilt": []}
        comp = {name: [] for name in cols}
        for k in range(2):  # joint k: two radial springs, one axial, two tilt
            nk, vk = robot.normals[k], g.v[k]
            cols["revolute_radial"] += [robot.sensitivity("c", k, _pad(nk[:, j]), step) for j in range(2)]
            cols["revolute_axial"].append(robot.sensitivity("c", k, _pad(vk), step))
            cols["revolute_tilt"] += [robot.sensitivity("c", k, _pad(None, nk[:, j]), step) for j in range(2)]
            for name in cols:
                comp[name] += [getattr(elements, name)[k]] * (1 if name == "revolute_axial" else 2)
        for name, c in cols.items():
            if name in on:
                sens = np.column_stack(c)
                out[name] = (sens * np.array(comp[name])) @ sens.T
    if "ball_radial" in on:  # per bar, its two ball joints in series along it
        gl = robot.sensitivities(step)[:, 8:]
        out["ball_radial"] = (gl * (2.0 * np.asarray(elements.ball_radial))) @ gl.T
    # the plate's beams: D-C_k in the central bar's frame, C_k-B_i in lateral bar k's
    beams = {"central": ("c", np.asarray(g.C0)), "lateral": ("b", np.asarray(g.b_leg))}
    for name in ("central_EI", "central_GJ", "lateral_EI", "lateral_GJ"):
        if name in on:
            fam, kind = name.split("_")
            which, vectors = beams[fam]
            term = np.zeros((8, 8))
            for index, vec in enumerate(vectors):
                length = float(np.linalg.norm(vec))
                e = vec / length
                flex = _flexibility(getattr(elements, name)[index])
                section = flex * (np.eye(3) - np.outer(e, e) if kind == "EI" else np.outer(e, e))
                sens = robot.sensitivities_6d(which, index, step)
                term += sens @ _cantilever(e, length, section) @ sens.T
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
            out["shaft_tilt"] = (shaft * np.repeat(elements.shaft_tilt, 2)) @ shaft.T
    if "forearm_out_EI" in on:  # the tip A_i moved and turned (world frame) at the assembled pose
        tips = robot.pts.A - robot.pts.P
        term = np.zeros((8, 8))
        for i in range(4):
            sens = robot.sensitivities_6d("a", i, step)
            length = float(np.linalg.norm(tips[i]))
            e = tips[i] / length
            b = np.cross(e, g.u[i])  # bending out of the forearm's plane: the tip along u_i, turning about e x u_i
            b /= np.linalg.norm(b)
            section = _flexibility(elements.forearm_out_EI[i]) * np.outer(b, b)
            term += sens @ _cantilever(e, length, section) @ sens.T
        out["forearm_out_EI"] = term
    return out


__all__ = ["DeformedElementsH4", "element_terms_fd"]
