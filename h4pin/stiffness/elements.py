# SPDX-License-Identifier: Apache-2.0
"""The terms of the compliant elements that eq. 30 neglects, by unit loads on the plate's statics.

The elements and their data: :mod:`h4pin.description.elements` (read from the URDF into
:attr:`H4.elements <h4pin.H4>`); :func:`h4pin.compliance` adds one named term per kind that is on.

Unit-load method on a statics route: the equilibrium of the central bar and the two lateral bars
under ``Gamma_ext = [F, T, t1, t2]`` (:func:`plate_loads`) gives each element's load per unit
load (the joint reactions, the bar tensions, the wrenches at the beams' tips and on the actuator
mounts, :func:`element_loads`), and ``C_extra = sum_s c_s g_s g_s^T`` over scalar springs,
``sum_b W_b^T C_b W_b`` over beams and 6-D mounts (:func:`element_terms`). The terms are
symmetric and the same in both models of eq. 30.

Beams (:func:`beam_compliance`): Euler-Bernoulli, isotropic bending, axial and shear compliance
neglected; tip compliance L^3/(3EI), L^2/(2EI), L/(EI), L/(GJ).

The finite-difference route of :mod:`h4pin.checks.elements` (the plate solved with joint frames,
beam tips and forearm roots moved and turned) checks each term.
"""

from __future__ import annotations

import numpy as np

from h4pin.description.elements import KINDS, Elements, kinds
from h4pin.description.geometry import H4Geometry
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import normal_pair, skew


def plate_loads(g: H4Geometry, pose: np.ndarray) -> dict[str, np.ndarray]:
    """Loads per unit ``Gamma_ext`` (8 columns) from the equilibrium of the three plate bodies.

    Returns ``{"bars": (8, 8)`` tensions (N per unit load), ``"force": (2, 3, 8)`` the joint force
    on lateral bar k (world frame), ``"moment": (2, 3, 8)`` the joint couple on lateral bar k
    (world frame, normal to the joint axis), ``"axis": (2, 3)`` the joint axes v_k (world),
    ``"points"``: the :class:`h4pin.kinematics.closed_form.Points` of the pose, ``"w": (8, 3)`` unit bar
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
    """Loads of the elements' sites per unit Gamma_ext (world frame, SI per unit load).

    * ``central`` (2, 6, 8): the wrench [force, couple about C_k] the lateral bar k and the joint
      torque t_k put on the tip C_k of the central-bar segment D-C_k (the joint site: the revolute
      joint carries it too, its couple about v_k apart).
    * ``lateral`` (4, 6, 8): the wrench [force, couple about B_i] bars i1, i2 put on the tip B_i
      of lateral bar k's arm C_k-B_i (clamped at C_k).
    * ``base`` (4, 6, 8): the wrench [force, couple about P_i] of leg i on the base: the pulls of
      bars i1, i2 on the forearm at A_ij (the actuator's shaft and mount).
    * ``tip`` (4, 6, 8): the wrench [force, couple about A_i] bars i1, i2 put on the tip A_i of
      forearm i (the forearm clamped at P_i; A_i midway between A_i1 and A_i2).
    * ``bars`` (8, 8): each bar's tension; ``w`` (8, 3) the bars' unit directions; ``axis``
      (2, 3) the lateral revolutes' axes v_k.
    """
    p = plate_loads(g, pose)
    pts, w, f = p["points"], p["w"], p["bars"]
    central = np.zeros((2, 6, 8))
    for k in range(2):
        central[k, :3] = -p["force"][k]
        central[k, 3:] = -p["moment"][k]
        central[k, 3:, 6 + k] -= p["axis"][k]
    pulls = w[:, :, None] * f[:, None, :]  # (8, 3, 8): bar n's pull on its forearm at A_n per unit load
    bij, aij = pts.Bij.reshape(8, 3), pts.Aij.reshape(8, 3)
    lateral = np.zeros((4, 6, 8))
    base = np.zeros((4, 6, 8))
    tip = np.zeros((4, 6, 8))
    for n in range(8):
        i = n // 2
        lateral[i, :3] -= pulls[n]
        lateral[i, 3:] -= np.cross(bij[n] - pts.B[i], pulls[n], axis=0)
        base[i, :3] += pulls[n]
        base[i, 3:] += np.cross(aij[n] - pts.P[i], pulls[n], axis=0)
        tip[i, :3] += pulls[n]
        tip[i, 3:] += np.cross(aij[n] - pts.A[i], pulls[n], axis=0)
    return {"central": central, "lateral": lateral, "base": base, "tip": tip, "bars": f, "w": w, "axis": p["axis"],
            "points": pts}


def spring_compliances(elements: Elements) -> dict[str, np.ndarray]:
    """Compliance of every scalar spring of the kinds whose form is made of equal scalar springs
    (a joint's radial and tilt: two springs per element; a bar's ball joints: in series), SI."""
    springs = {"force_normal": 2, "force_axial": 1, "couple_normal": 2, "couple_axial": 1}
    return {k.name: np.repeat(k.compliance(getattr(elements, k.name)), springs[k.form])
            for k in kinds() if k.form in springs}


#: Beam kinds of the central-bar segments and the lateral arms: rigidity field -> (beam family
#: of :func:`element_loads`, part of :func:`beam_compliance`: 0 bending, 1 torsion).
BEAMS = {k.name: ({"central": "central", "arm": "lateral"}[k.axis], ("beam_bending", "beam_torsion").index(k.form))
         for k in KINDS if k.axis in ("central", "arm") and k.form in ("beam_bending", "beam_torsion")}


def out_of_plane_compliance(axis: np.ndarray, normal: np.ndarray, length: float, ei: float) -> np.ndarray:
    """Tip compliance (6, 6) of a cantilever bending in one plane only: the beam of
    :func:`beam_compliance` (length L along the unit ``axis`` e, clamped at its root, loaded at
    its tip) whose tip moves along n (``normal`` made normal to e) and turns about b = e x n:
    ``[delta_n, phi_b] = 1/EI [[L^3/3, L^2/2], [L^2/2, L]] [P.n, M.b]`` (a forearm out of its
    plane: n = u_i). Zero for an infinite rigidity."""
    e = np.asarray(axis, dtype=float)
    n = np.asarray(normal, dtype=float) - (np.dot(normal, e)) * e
    n /= np.linalg.norm(n)
    b = np.cross(e, n)
    f = 0.0 if np.isinf(ei) else 1.0 / ei
    out = np.zeros((6, 6))
    out[:3, :3] = length**3 / 3.0 * f * np.outer(n, n)
    out[3:, 3:] = length * f * np.outer(b, b)
    out[:3, 3:] = length**2 / 2.0 * f * np.outer(n, b)
    out[3:, :3] = out[:3, 3:].T
    return out


def beam_axes(g: H4Geometry) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each beam's inner-to-outer vector in its own body's frame (the central bar's for D-C_k,
    lateral bar k's for C_k-B_i): ``{"central": (2, 3), "lateral": (4, 3)}`` and lengths."""
    out = {}
    for fam, vec in (("central", np.asarray(g.C0)), ("lateral", np.asarray(g.b_leg))):
        length = np.linalg.norm(vec, axis=1)
        out[fam] = (vec / length[:, None], length)
    return out


def beam_matrix(name: str, elements: Elements, index: int, axis: np.ndarray, length: float) -> np.ndarray:
    """The (6, 6) tip compliance of beam ``index`` of the beam kind ``name`` (:data:`BEAMS`)."""
    fam, part = BEAMS[name]
    rigidity = getattr(elements, name)[index]
    return beam_compliance(axis, length, *((rigidity, np.inf) if part == 0 else (np.inf, rigidity)))[part]


#: The name h4pin.checks.elements calls it by, until it uses the public one.


def form_compliance(form: str, e: np.ndarray, n: np.ndarray, length: float) -> np.ndarray:
    """The (6, 6) compliance on a wrench [force, couple] of an element of unit compliance in its
    form (:data:`h4pin.description.elements.FORMS`), axis e, second axis n and length (the numpy
    reading of each form, apart from the compiled :func:`h4pin.stiffness.pipeline.form_part`)."""
    out = np.zeros((6, 6))
    ee = np.outer(e, e)
    block = {"force": np.eye(3), "force_normal": np.eye(3) - ee, "force_axial": ee}
    if form in block:
        out[:3, :3] = block[form]
    elif form.startswith("couple"):
        out[3:, 3:] = block[form.replace("couple", "force")]
    elif form == "beam_bending_out":
        out = out_of_plane_compliance(e, n, length, 1.0)
    else:
        out = beam_compliance(e, length, *((1.0, np.inf) if form == "beam_bending" else (np.inf, 1.0)))[
            form == "beam_torsion"]
    return out


def _site_axes(g: H4Geometry, pts, loads: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each axis of :data:`h4pin.description.elements.AXES` per element (world, from the element's
    root to its site's point: a beam's length)."""
    z = np.tile([0.0, 0.0, 1.0], (8, 1))
    return {"none": z, "z": z, "revolute": loads["axis"], "actuator": np.asarray(g.u), "central": pts.C - pts.D,
            "arm": pts.B - pts.C[g.leg_lat], "forearm": pts.A - pts.P, "bar": loads["w"]}


def element_terms(g: H4Geometry, pose: np.ndarray, elements: Elements) -> dict[str, np.ndarray]:
    """Compliance term (8, 8) of each element kind that is on, SI: ``sum_s W_s^T C_s W_s`` over
    its elements, W_s the (6, 8) wrench its site carries per unit load (:data:`SITE_LOADS`) and
    C_s its compliance in its form (:func:`form_compliance`) times its value."""
    loads = element_loads(g, pose)
    axes = _site_axes(g, loads["points"], loads)
    out = {}
    for k in elements.kinds_on():
        wrenches = _site_wrenches(k.site, loads)
        c = k.compliance(getattr(elements, k.name))
        term = np.zeros((8, 8))
        for s in np.flatnonzero(c):
            vec = axes[k.axis][s]
            length = float(np.linalg.norm(vec))
            normal = axes[k.normal][s]
            c6 = form_compliance(k.form, vec / length, normal / np.linalg.norm(normal), length)
            term += c[s] * wrenches[s].T @ c6 @ wrenches[s]
        out[k.name] = term
    return out


#: The loads of :func:`element_loads` that are each site's wrench [force, couple] per unit load.
SITE_LOADS = {"joint": "central", "arm": "lateral", "mount": "base", "tip": "tip"}


def _site_wrenches(site: str, loads: dict[str, np.ndarray]) -> np.ndarray:
    """(count, 6, 8): the wrench each element of a site carries per unit load; a bar's tension
    as a force along its unit direction w_n."""
    if site in SITE_LOADS:
        return loads[SITE_LOADS[site]]
    out = np.zeros((8, 6, 8))
    out[:, :3] = loads["w"][:, :, None] * loads["bars"][:, None, :]
    return out


def add_terms(g: H4Geometry, x: np.ndarray, raw, elements: Elements | None):
    """A backend's result (:class:`h4pin.stiffness.eq30.Raw` at poses x (N, 4)) with the terms of
    ``elements`` by this module's statics route, pose by pose (the reference of the compiled
    pipeline's element terms, and the route of robots it does not take): added to the matrices of
    the poses whose status is 0, and after eq. 30's four terms when the result has terms."""
    if elements is None or elements.off:
        return raw
    names = [k.name for k in elements.kinds_on()]
    extra = None if raw.terms is None else np.full((len(x), len(names), 8, 8), np.nan)
    for k in np.flatnonzero(raw.status == 0):
        terms = element_terms(g, x[k], elements)
        raw.matrix[k] += sum(terms[n] for n in names)
        if extra is not None:
            extra[k] = [terms[n] for n in names]
    if extra is None:
        return raw
    return raw._replace(terms=np.concatenate([raw.terms, extra], axis=1))


__all__ = ["BEAMS", "SITE_LOADS", "add_terms", "beam_axes", "beam_compliance", "beam_matrix", "element_loads",
           "element_terms", "form_compliance", "out_of_plane_compliance", "plate_loads", "spring_compliances"]
