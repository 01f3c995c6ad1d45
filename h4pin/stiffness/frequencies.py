# SPDX-License-Identifier: Apache-2.0
"""Natural frequencies of the elastic H4 at many poses, compiled: the twin of the Pinocchio route
(:func:`h4pin.elastic.modal.modes`), under the same assumptions.

The elastic H4 of :func:`h4pin.elastic.elastic_model`: every compliance (eq. 30's four families and
each element that is on) a spring, the actuators locked, the link inertias of the robot's URDF
(the forearm turning with its actuator's elastic rotation), an optional rigid payload on the
central bar, small undamped vibrations about a rigid pose, massless motions condensed
statically.

**The flexibility form.** Call s the springs (compliance c_s), and y the motion of every body with
mass per unit spring deformation. The structure with locked actuators is statically determinate
(one spring per admissible motion), so the springs' deformations are coordinates: the stiffness is
``diag(1 / c_s)`` and the mass ``B^T M B`` (B the body twists per unit deformation, M the bodies'
spatial inertias). The eigenvalues mu of ``H = C^1/2 B^T M B C^1/2`` are ``1 / omega^2`` of the
modes; the massless motions are its zero eigenvalues (the static condensation of the Pinocchio
route). A spring's effect on the plate is its load per unit Gamma_ext (reciprocity), which the
compiled pipeline already computes (:mod:`h4pin.stiffness.pipeline`: ``Y a_s``, the columns of
M1^-1 M2 M3, the torsion vectors); its effect on its own body is a unit rotation or a unit twist
at its site. The bodies' twists follow from the plate's, the forearms' and the universal joints'
kinematics (a 3 x 3 solve per bar for its two universal-joint rates and its length rate). Per
pose: the pipeline's one call, then :func:`_pose_frequencies` (H of 16 x 16 without elements,
Householder tridiagonalisation and rational QL). Robots whose parallelograms are exact, as the
pipeline; :func:`h4pin.modes` takes the Pinocchio route for the others.
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import numpy as np
import pinocchio as pin
from numba import njit

from h4pin import _jit
from h4pin.description.elements import SITE_BAR, SITE_MOUNT, SITE_TIP
from h4pin.errors import ParameterError
from h4pin.kinematics import _compiled
from h4pin.kinematics import pinocchio as kin
from h4pin.stiffness import kernel, pipeline
from h4pin.stiffness.packed import EL_HEADER, EL_ROW, G_CBEND, G_CCTRL, G_CTENS, G_CTORS, G_LAT, G_P
from h4pin.stiffness.pipeline import EA, F_GC, F_TV, S_A, S_B, S_LW, S_ROWS, X_F, X_S, X_Y, XROWS

#: Relative eigenvalue of H (to its largest) at or under which a direction is massless: 16 eps.
#: The massless directions' eigenvalues are round-off (at most 6.6e-16 of the largest over 80 poses
#: of every variant with the 11 element kinds of the time, 88 springs; 96 with forearm_out_EI);
#: the massive ones reach down to 1.5e-14
#: (the symmetric variant near its singular centre with every element on: a 0.1 Hz mode beside a
#: 1e5 Hz one). The Pinocchio route decides on the modal mass alone (its own 1e-12).
MASSLESS_TOL = 16 * 2.220446049250313e-16

# Layout of the packed mass model (one float64 vector a robot, :func:`pack_masses`): per body its
# inertia as [mass, lever (3), inertia about the centre of mass (9)] in its joint's frame.
_INERTIA = 13
_LEG = 15 + _INERTIA  # R_a (9), t_a (3), axis (3) of the actuator joint; the forearm's inertia
_BAR = 2 * (15 + _INERTIA)  # R, t, axis of the universal joint's first revolute, the cross; the same, the bar
_PLATE = 15 + _INERTIA  # X0R (9), X0t (3), D0 (3) of the central bar; its inertia
_LAT = 16 + _INERTIA  # R (9), t (3), axis (3), sign (1) of lateral revolute k; the lateral bar
_O_LEG, _O_BAR = 0, 4 * _LEG
_O_PLATE = _O_BAR + 8 * _BAR
_O_LAT = _O_PLATE + _PLATE
_O_PAY = _O_LAT + 2 * _LAT  # the payload's spatial inertia (6 x 6) in frame D
_SIZE = _O_PAY + 36


def _axis(model: pin.Model, j: int) -> np.ndarray:
    """The unit axis of revolute joint j in its own frame."""
    name = model.joints[j].shortname()
    if name.startswith("JointModelR") and name[-1] in "XYZ" and len(name) == len("JointModelRX"):
        return np.eye(3)["XYZ".index(name[-1])]
    return np.asarray(model.joints[j].extract().axis, dtype=float)


def _inertia(inertia: pin.Inertia, on: bool) -> np.ndarray:
    if not on:
        return np.zeros(_INERTIA)
    return np.concatenate([[inertia.mass], inertia.lever, np.ravel(inertia.inertia)])


def _placement(model: pin.Model, j: int) -> np.ndarray:
    p = model.jointPlacements[j]
    return np.concatenate([np.ravel(p.rotation), p.translation, _axis(model, j) if j else np.zeros(3)])


_PACKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_EYE = np.eye(3)


def _pack(records: dict[str, Any], payload: Any) -> np.ndarray:
    """The mass model vector of :func:`_pose_frequencies` from per-body records: for each joint
    its placement in its parent's frame (R, t) and axis, for each link [mass, lever, inertia]."""
    out = np.zeros(_SIZE)
    for i in range(4):
        R, t, axis = records["actuator"][i]
        out[_O_LEG + _LEG * i:_O_LEG + _LEG * (i + 1)] = np.concatenate([np.ravel(R), t, axis, records["forearm"][i]])
    for n in range(8):
        (R1, t1, a1), (R2, t2, a2) = records["universal"][n]
        out[_O_BAR + _BAR * n:_O_BAR + _BAR * (n + 1)] = np.concatenate(
            [np.ravel(R1), t1, a1, records["cross"][n], np.ravel(R2), t2, a2, records["bar"][n]])
    X0R, X0t, D0 = records["plate"]
    out[_O_PLATE:_O_PLATE + _PLATE] = np.concatenate([np.ravel(X0R), X0t, D0, records["central"]])
    for k in range(2):
        R, t, axis, sign = records["lateral_joint"][k]
        out[_O_LAT + _LAT * k:_O_LAT + _LAT * (k + 1)] = np.concatenate([np.ravel(R), t, axis, [sign],
                                                                         records["lateral"][k]])
    if payload is not None:
        out[_O_PAY:_O_PAY + 36] = np.ravel(payload.spatial())
    out.setflags(write=False)
    return out


def pack_masses(h4, payload: Any = None, link_inertias: bool = True) -> np.ndarray:
    """The mass model of :func:`_pose_frequencies` (read-only, cached per robot): each moving body's
    joint placement, axis and inertia from the robot's Pinocchio model (as its URDF gives them),
    and the payload's spatial inertia in frame D (:class:`h4pin.Payload`; zero without).
    ``link_inertias=False``: only the payload has mass."""
    # by value: an id would be reused by a new payload once the old one is freed (a stale mass model)
    key = (bool(link_inertias), None if payload is None else np.asarray(payload.spatial(), dtype=float).tobytes())
    packs = _PACKS.setdefault(h4, {})
    if key in packs:
        return packs[key]
    m, ix = h4.model, h4.index

    def joint(j: int) -> tuple:
        p = m.jointPlacements[j]
        return p.rotation, p.translation, _axis(m, j)

    for j in ix.jid_act:
        if m.parents[j] != 0:
            raise ParameterError(f"actuator joint {m.names[j]!r} must hang from the world")
    bars = [(m.parents[cm.joint1_id], cm.joint1_id) for cm in h4.constraint_models]
    for n, (j1, _) in enumerate(bars):
        if m.parents[j1] != ix.jid_act[n // 2]:
            raise ParameterError(f"bar {n // 2 + 1}{n % 2 + 1}: its universal joint must hang from its actuator")
    records = {"actuator": [joint(j) for j in ix.jid_act],
               "forearm": [_inertia(m.inertias[j], link_inertias) for j in ix.jid_act],
               "universal": [(joint(j1), joint(j2)) for j1, j2 in bars],
               "cross": [_inertia(m.inertias[j1], link_inertias) for j1, _ in bars],
               "bar": [_inertia(m.inertias[j2], link_inertias) for _, j2 in bars],
               "plate": (ix.X0R, ix.X0t, ix.D0),
               "central": _inertia(m.inertias[m.parents[ix.jid_lat[0]]], link_inertias),
               "lateral_joint": [(*joint(j), ix.lat_sign[k]) for k, j in enumerate(ix.jid_lat)],
               "lateral": [_inertia(m.inertias[j], link_inertias) for j in ix.jid_lat]}
    packs[key] = _pack(records, payload)
    return packs[key]


def _inertial(mci: tuple) -> np.ndarray:
    """[mass, centre of mass (3), inertia about it (9)] of a (mass, com, inertia) triple."""
    return np.concatenate([[mci[0]], mci[1], np.ravel(mci[2])])


def pack_masses_params(params: Any, payload: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mass model (:func:`pack_masses`) and the configuration constants (as
    :func:`h4pin.kinematics.pinocchio.configuration_pack`) of the robot
    :func:`h4pin.description.urdf.to_urdf` writes for an :class:`h4pin.H4Params`, without writing
    or loading it (:func:`h4pin.description.urdf.mass_model`): the design sweep's frequencies.
    Equal to those of ``h4pin.load(params)`` (``tests/test_frequencies.py``)."""
    from h4pin.description.geometry import geometry_from_params
    from h4pin.description.urdf import mass_model

    mm = mass_model(params)
    zero = np.zeros(3)
    records = {"actuator": [(_EYE, mm.actuator_origin[i], mm.actuator_axis[i]) for i in range(4)],
               "forearm": [_inertial(f) for f in mm.forearm],
               "universal": [((_EYE, mm.anchor[n], mm.u1_axis[n]), (_EYE, zero, mm.u2_axis[n])) for n in range(8)],
               "cross": [_inertial(c) for c in mm.cross], "bar": [_inertial(b) for b in mm.bar],
               "plate": (_EYE, zero, zero), "central": _inertial(mm.central),
               "lateral_joint": [(_EYE, mm.lateral_origin[k], np.array([0.0, 0.0, 1.0]), 1.0) for k in range(2)],
               "lateral": [_inertial(c) for c in mm.lateral]}
    g = geometry_from_params(params)
    CF, CI = _compiled.pack_configuration(g.P, g.u, g.A0, g.C0, g.b, g.v, mm.u1_axis, mm.u2_axis, mm.bar_end,
                                          np.ones(2), _EYE, zero, zero, g.lat, np.zeros(4, dtype=np.int64),
                                          np.zeros((8, 2), dtype=np.int64), 0, np.zeros(2, dtype=np.int64))
    for a in (CF, CI):  # read-only, as a loaded robot's (one compiled version of frequencies_run for both)
        a.setflags(write=False)
    return _pack(records, payload), CF, CI


# ----------------------------------------------------------------------------------------------
# Compiled: small dense algebra


@njit(cache=True, nogil=True)
def _mm(A, B, C):
    """C = A B (3 x 3, C apart from A and B): no allocation, no BLAS call."""
    for a in range(3):
        for b in range(3):
            C[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]


@njit(cache=True, nogil=True)
def _mv(A, v, out):
    """out = A v (3 x 3 times 3)."""
    x, y, z = v[0], v[1], v[2]
    for a in range(3):
        out[a] = A[a, 0] * x + A[a, 1] * y + A[a, 2] * z


@njit(cache=True, nogil=True)
def _rotm(a, angle, C):
    """C = the rotation of ``angle`` about the unit axis a (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    x, y, z = a[0], a[1], a[2]
    C[0, 0], C[0, 1], C[0, 2] = c + x * x * t, x * y * t - z * s, x * z * t + y * s
    C[1, 0], C[1, 1], C[1, 2] = y * x * t + z * s, c + y * y * t, y * z * t - x * s
    C[2, 0], C[2, 1], C[2, 2] = z * x * t - y * s, z * y * t + x * s, c + z * z * t


@njit(cache=True, nogil=True)
def _spatial(R, o, inertia, out):
    """The 6 x 6 spatial inertia [linear; angular] at the world point o, world axes, of a body
    whose frame is (R, o) and whose inertia is [mass, lever (3), I about the centre of mass (9)]
    in that frame (Pinocchio's ``Inertia.matrix()`` turned to the world)."""
    m = inertia[0]
    cx = R[0, 0] * inertia[1] + R[0, 1] * inertia[2] + R[0, 2] * inertia[3]
    cy = R[1, 0] * inertia[1] + R[1, 1] * inertia[2] + R[1, 2] * inertia[3]
    cz = R[2, 0] * inertia[1] + R[2, 1] * inertia[2] + R[2, 2] * inertia[3]
    out[:, :] = 0.0
    out[0, 0] = out[1, 1] = out[2, 2] = m
    out[0, 4], out[0, 5], out[1, 3], out[1, 5], out[2, 3], out[2, 4] = m * cz, -m * cy, -m * cz, m * cx, m * cy, -m * cx
    out[4, 0], out[5, 0], out[3, 1], out[5, 1], out[3, 2], out[4, 2] = m * cz, -m * cy, -m * cz, m * cx, m * cy, -m * cx
    for a in range(3):  # R I R^T: (R I) row a, then its products with the rows of R
        r0 = R[a, 0] * inertia[4] + R[a, 1] * inertia[7] + R[a, 2] * inertia[10]
        r1 = R[a, 0] * inertia[5] + R[a, 1] * inertia[8] + R[a, 2] * inertia[11]
        r2 = R[a, 0] * inertia[6] + R[a, 1] * inertia[9] + R[a, 2] * inertia[12]
        for b in range(3):
            out[3 + a, 3 + b] = r0 * R[b, 0] + r1 * R[b, 1] + r2 * R[b, 2]
    out[3, 3] += m * (cy * cy + cz * cz)  # - m [c]x [c]x
    out[4, 4] += m * (cx * cx + cz * cz)
    out[5, 5] += m * (cx * cx + cy * cy)
    out[3, 4] -= m * cx * cy
    out[4, 3] -= m * cx * cy
    out[3, 5] -= m * cx * cz
    out[5, 3] -= m * cx * cz
    out[4, 5] -= m * cy * cz
    out[5, 4] -= m * cy * cz


@njit(cache=True, nogil=True)
def _tridiagonal(H, n, d, e):
    """Householder reduction of the symmetric n x n leading block of H (overwritten) to a
    tridiagonal matrix: diagonal d, sub-diagonal e[1:n] (EISPACK tred1)."""
    for i in range(n - 1, 0, -1):
        scale = 0.0
        for k in range(i):
            scale += abs(H[i, k])
        if i == 1 or scale == 0.0:
            e[i] = H[i, i - 1]
            continue
        h = 0.0
        for k in range(i):
            H[i, k] /= scale
            h += H[i, k] * H[i, k]
        f = H[i, i - 1]
        g = -math.sqrt(h) if f >= 0.0 else math.sqrt(h)
        e[i] = scale * g
        h -= f * g
        H[i, i - 1] = f - g
        f = 0.0
        for j in range(i):
            g = 0.0
            for k in range(j + 1):
                g += H[j, k] * H[i, k]
            for k in range(j + 1, i):
                g += H[k, j] * H[i, k]
            e[j] = g / h
            f += e[j] * H[i, j]
        hh = f / (h + h)
        for j in range(i):
            f = H[i, j]
            g = e[j] - hh * f
            e[j] = g
            for k in range(j + 1):
                H[j, k] -= f * e[k] + g * H[i, k]
    for i in range(n):
        d[i] = H[i, i]
    e[0] = 0.0


@njit(cache=True, nogil=True)
def _ql(d, e, n):
    """All eigenvalues (into d, ascending) of the tridiagonal (d, e[1:n]) by the rational QL method
    (EISPACK tqlrat: the Pal-Walker-Kahan iteration on the squared sub-diagonal, no square root in
    its inner loop; about twice as fast as tql1 here). e is overwritten with the squares."""
    for i in range(1, n):
        e[i - 1] = e[i] * e[i]
    e[n - 1] = 0.0
    f = 0.0
    t = 0.0
    b = 0.0
    c = 0.0
    for l in range(n):
        j = 0
        h = abs(d[l]) + math.sqrt(e[l])
        if t <= h:
            t = h
            b = 2.220446049250313e-16 * t
            c = b * b
        m = l
        while m < n - 1 and e[m] > c:  # a small squared sub-diagonal element (e[n - 1] is 0)
            m += 1
        if m != l:
            while True:
                if j == 30:
                    break
                j += 1
                s = math.sqrt(e[l])  # the shift
                g = d[l]
                p = (d[l + 1] - g) / (2.0 * s)
                r = math.sqrt(p * p + 1.0)
                d[l] = s / (p + (r if p >= 0.0 else -r))
                h = g - d[l]
                for i in range(l + 1, n):
                    d[i] -= h
                f += h
                g = d[m]  # the rational QL transformation
                if g == 0.0:
                    g = b
                h = g
                s = 0.0
                for i in range(m - 1, l - 1, -1):
                    p = g * h
                    r = p + e[i]
                    e[i + 1] = s * r
                    s = e[i] / r
                    d[i + 1] = h + s * (h + d[i])
                    g = d[i] - e[i] / g
                    if g == 0.0:
                        g = b
                    h = g * p / r
                e[l] = s * g
                d[l] = h
                if h == 0.0 or abs(e[l]) <= abs(c / h):  # converged (guarded against underflow)
                    break
                e[l] = h * e[l]
                if e[l] == 0.0:
                    break
        p = d[l] + f
        i = l  # insert p among the converged ones, ascending
        while i > 0 and p < d[i - 1]:
            d[i] = d[i - 1]
            i -= 1
        d[i] = p


@njit(cache=True, nogil=True)
def _cr(ax, ay, az, bx, by, bz):
    """(a x b) as a tuple (no array: nothing to allocate)."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, nogil=True)
def _inv3(a, b, c, d, e, f, g, h, k, out):
    """out = [[a, b, c], [d, e, f], [g, h, k]]^-1 (adjugate over determinant)."""
    A, B, C = e * k - f * h, f * g - d * k, d * h - e * g
    det = a * A + b * B + c * C
    i = 1.0 / det
    out[0, 0], out[0, 1], out[0, 2] = A * i, (c * h - b * k) * i, (b * f - c * e) * i
    out[1, 0], out[1, 1], out[1, 2] = B * i, (a * k - c * g) * i, (c * d - a * f) * i
    out[2, 0], out[2, 1], out[2, 2] = C * i, (b * g - a * h) * i, (a * e - b * d) * i


@njit(cache=True, nogil=True)
def _y_layout(EG, sy):
    """The y coordinates (rows of M_y): dtp (8), then per leg its forearm's elastic rotation phi_i
    and tip torsion tau_i (8), then a 6-D twist per site that carries an element other than a bar
    (rows sy[type, index]: type 0 joint k, 1 arm i, 2 mount i, 3 tip i; -1 none). Returns ny and
    the number of spring columns ns."""
    sy[:, :] = -1
    ny = 16
    ns = 16
    for row in range(int(EG[0])):
        base = EL_HEADER + EL_ROW * row
        site, form, count, off = int(EG[base]), int(EG[base + 1]), int(EG[base + 3]), int(EG[base + 4])
        if site == SITE_BAR:
            continue
        per = pipeline.form_count(form)
        st = site  # the site codes joint, arm, mount, tip are 0..3
        for s in range(count):
            if EG[off + 2 * s] == 0.0:
                continue
            ns += per
            if sy[st, s] < 0:
                sy[st, s] = ny
                ny += 6
    return ny, ns


@njit(cache=True, nogil=True)
def _add_body(My, M6, J, cols, nc):
    """My[cols, cols] += J^T M6 J (J (6, nc), the body's twist [v at its origin; omega] per unit
    y coordinate cols[c])."""
    for c in range(nc):  # M6 J[:, c] in six scalars (no allocation)
        j0, j1, j2, j3, j4, j5 = J[0, c], J[1, c], J[2, c], J[3, c], J[4, c], J[5, c]
        m0 = M6[0, 0] * j0 + M6[0, 1] * j1 + M6[0, 2] * j2 + M6[0, 3] * j3 + M6[0, 4] * j4 + M6[0, 5] * j5
        m1 = M6[1, 0] * j0 + M6[1, 1] * j1 + M6[1, 2] * j2 + M6[1, 3] * j3 + M6[1, 4] * j4 + M6[1, 5] * j5
        m2 = M6[2, 0] * j0 + M6[2, 1] * j1 + M6[2, 2] * j2 + M6[2, 3] * j3 + M6[2, 4] * j4 + M6[2, 5] * j5
        m3 = M6[3, 0] * j0 + M6[3, 1] * j1 + M6[3, 2] * j2 + M6[3, 3] * j3 + M6[3, 4] * j4 + M6[3, 5] * j5
        m4 = M6[4, 0] * j0 + M6[4, 1] * j1 + M6[4, 2] * j2 + M6[4, 3] * j3 + M6[4, 4] * j4 + M6[4, 5] * j5
        m5 = M6[5, 0] * j0 + M6[5, 1] * j1 + M6[5, 2] * j2 + M6[5, 3] * j3 + M6[5, 4] * j4 + M6[5, 5] * j5
        for c2 in range(c, nc):
            t = (J[0, c2] * m0 + J[1, c2] * m1 + J[2, c2] * m2 + J[3, c2] * m3 + J[4, c2] * m4 + J[5, c2] * m5)
            My[cols[c], cols[c2]] += t
            if c2 != c:
                My[cols[c2], cols[c]] += t


@njit(cache=True, nogil=True)
def _put(J, c, v0, v1, v2, w0, w1, w2):
    J[0, c], J[1, c], J[2, c] = v0, v1, v2
    J[3, c], J[4, c], J[5, c] = w0, w1, w2


@njit(cache=True, nogil=True, inline="always")  # into frequencies_run: one LLVM pass over its module less
def _pose_frequencies(x, q, Xrow, G, EG, MP, CF, CI, freq, W):  # pragma: no cover - compiled
    """The natural frequencies (Hz, ascending, NaN past the massive count) into freq of one pose
    x (4,), from the pipeline's q (4,) and intermediates Xrow (:data:`h4pin.stiffness.pipeline.NX`),
    the packed geometry G and element table EG, the mass model MP (:func:`pack_masses`), the
    configuration constants CF, CI (:func:`h4pin.kinematics.pinocchio.configuration_pack`) and
    the work arrays W (:func:`work_arrays`). Returns the number of massive directions.

    The bodies' twists are linear in y (:func:`_y_layout`): J_b (6 x its y columns) per body,
    ``M_y = sum J_b^T M6_b J_b``; the springs' columns R (y per unit deformation, times
    sqrt(c)); ``H = R^T M_y R``. Its eigenvalues mu (Householder, then QL: all of them cost less
    than four by bisection, whose Sturm counts divide at every step): the massive ones (above
    :data:`MASSLESS_TOL` of the largest) give ``1 / (2 pi sqrt(mu))``, as many as freq holds."""
    _bodies(x, q, Xrow, G, MP, CF, CI, W)
    ny, ns = _springs(Xrow, G, EG, W)
    _mass_matrix(x, Xrow, G, ny, W)
    return _eigenvalues(ny, ns, W, freq)


@njit(cache=True, nogil=True)
def _bodies(x, q, Xrow, G, MP, CF, CI, W):  # pragma: no cover - compiled
    """Every body's origin O, world spatial inertia M6 and joint axes (rows of ``axes``), and the
    bars' 3 x 3 rate solves Sinv, at pose x (the forward kinematics of the mass model)."""
    O, M6, axes, Sinv, T3 = W[0], W[1], W[2], W[3], W[15]
    D = x[:3]
    th = x[3]
    ct, st = math.cos(th), math.sin(th)
    Rz, Rf, R1p, R1, R2p, Rq, Rp, Rlp = T3[0], T3[1], T3[2], T3[3], T3[4], T3[5], T3[6], T3[7]
    Rz[0, 0], Rz[0, 1], Rz[0, 2], Rz[1, 0], Rz[1, 1], Rz[1, 2] = ct, -st, 0.0, st, ct, 0.0
    Rz[2, 0], Rz[2, 1], Rz[2, 2] = 0.0, 0.0, 1.0
    omega = W[19]
    omega[0] = omega[1] = -th
    v3 = W[20]
    v3[0], v3[1], v3[2] = D[0], D[1], D[2]  # writable, as the configuration's: one compiled version
    alpha, beta = _compiled.universal_packed(q, v3, Rz, omega, CF, CI)
    A = Xrow[X_S + S_A:X_S + S_A + 24].reshape(8, 3)
    B = Xrow[X_S + S_B:X_S + S_B + 24].reshape(8, 3)
    # axes rows: 0-3 u_i, 4-7 A_i, 8-11 e_i (forearm axis), 12-19 a1_n, 20-27 a2_n, 28-29 lateral
    # axes, 30-45 the sites' points (joint k, arm i, mount i, tip i)
    for i in range(4):
        b0 = MP[_LEG * i:_LEG * (i + 1)]
        Ra = b0[0:9].reshape(3, 3)
        _rotm(b0[12:15], q[i], Rq)
        _mm(Ra, Rq, Rf)
        _mv(Ra, b0[12:15], axes[i])
        for a in range(3):  # element by element: an array-to-slice copy compiles numba's error formatter
            O[i, a] = b0[9 + a]
        _spatial(Rf, O[i], b0[15:15 + _INERTIA], M6[i])
        for a in range(3):
            axes[4 + i, a] = 0.5 * (A[2 * i, a] + A[2 * i + 1, a])
            axes[8 + i, a] = axes[4 + i, a] - G[G_P + 3 * i + a]
        norm = math.sqrt(axes[8 + i, 0] ** 2 + axes[8 + i, 1] ** 2 + axes[8 + i, 2] ** 2)
        for a in range(3):  # element by element: an array into a slice compiles numba's shape-error formatter
            axes[8 + i, a] /= norm
        for j in range(2):
            n = 2 * i + j
            b1 = MP[_O_BAR + _BAR * n:_O_BAR + _BAR * n + 15 + _INERTIA]
            b2 = MP[_O_BAR + _BAR * n + 15 + _INERTIA:_O_BAR + _BAR * (n + 1)]
            _mm(Rf, b1[0:9].reshape(3, 3), R1p)
            _mv(Rf, b1[9:12], v3)
            for a in range(3):
                O[4 + n, a] = O[i, a] + v3[a]
            _mv(R1p, b1[12:15], axes[12 + n])
            _rotm(b1[12:15], alpha[n], Rq)
            _mm(R1p, Rq, R1)
            _mm(R1, b2[0:9].reshape(3, 3), R2p)
            _mv(R1, b2[9:12], v3)
            for a in range(3):
                O[12 + n, a] = O[4 + n, a] + v3[a]
            _mv(R2p, b2[12:15], axes[20 + n])
            _spatial(R1, O[4 + n], b1[15:15 + _INERTIA], M6[4 + n])
            _rotm(b2[12:15], beta[n], Rq)
            _mm(R2p, Rq, R1p)  # R1p, spent, takes the bar's rotation
            _spatial(R1p, O[12 + n], b2[15:15 + _INERTIA], M6[12 + n])
            # the bar's 3 x 3 solve: [a1 x (B - o1), a2 x (B - o2), w] [rates] = v_B - v(o1) - w_t x (B - o1)
            c1 = _cr(axes[12 + n, 0], axes[12 + n, 1], axes[12 + n, 2], B[n, 0] - O[4 + n, 0], B[n, 1] - O[4 + n, 1],
                     B[n, 2] - O[4 + n, 2])
            c2 = _cr(axes[20 + n, 0], axes[20 + n, 1], axes[20 + n, 2], B[n, 0] - O[12 + n, 0],
                     B[n, 1] - O[12 + n, 1], B[n, 2] - O[12 + n, 2])
            wx, wy, wz = B[n, 0] - A[n, 0], B[n, 1] - A[n, 1], B[n, 2] - A[n, 2]
            _inv3(c1[0], c2[0], wx, c1[1], c2[1], wy, c1[2], c2[2], wz, Sinv[n])
    bp = MP[_O_PLATE:_O_PLATE + _PLATE]
    _mm(Rz, bp[0:9].reshape(3, 3), Rp)
    for a in range(3):
        v3[a] = bp[9 + a] - bp[12 + a]
    _mv(Rz, v3, O[20])
    for a in range(3):
        O[20, a] += D[a]
    _spatial(Rp, O[20], bp[15:15 + _INERTIA], M6[20])
    for a in range(3):  # the payload: its spatial inertia in frame D (central-bar axes), at D, turned to the world
        O[23, a] = D[a]
    pay = MP[_O_PAY:_O_PAY + 36].reshape(6, 6)
    for a in range(6):
        for b in range(6):
            t = 0.0
            for k in range(3):
                for l in range(3):
                    t += Rz[a % 3, k] * pay[3 * (a // 3) + k, 3 * (b // 3) + l] * Rz[b % 3, l]
            M6[23, a, b] = t
    for k in range(2):
        bl = MP[_O_LAT + _LAT * k:_O_LAT + _LAT * (k + 1)]
        _mm(Rp, bl[0:9].reshape(3, 3), Rlp)
        _mv(Rp, bl[9:12], v3)
        for a in range(3):
            O[21 + k, a] = O[20, a] + v3[a]
        _mv(Rlp, bl[12:15], axes[28 + k])
        _rotm(bl[12:15], -bl[15] * th, Rq)
        _mm(Rlp, Rq, R1)
        _spatial(R1, O[21 + k], bl[16:16 + _INERTIA], M6[21 + k])


@njit(cache=True, nogil=True)
def _springs(Xrow, G, EG, W):  # noqa: C901  # pragma: no cover - compiled
    """The springs' columns of R (y per unit deformation, times sqrt(c)); returns (ny, ns)."""
    axes, sy, R, us, Xs = W[2], W[4], W[6], W[13], W[14]
    lane1 = Xs.shape[1]  # 1 (one lane), at run time: a constant would compile the callees again
    Y = Xrow[X_Y:X_Y + 64].reshape(8, 8)
    S = Xrow[X_S:X_S + S_ROWS].reshape(S_ROWS, 1)
    A = Xrow[X_S + S_A:X_S + S_A + 24].reshape(8, 3)
    B = Xrow[X_S + S_B:X_S + S_B + 24].reshape(8, 3)
    ny, ns = _y_layout(EG, sy)
    R[:ny, :ns] = 0.0
    ball = W[18]
    ball[:] = 0.0
    for row in range(int(EG[0])):
        base = EL_HEADER + EL_ROW * row
        if int(EG[base]) == SITE_BAR:
            off = int(EG[base + 4])
            for n in range(8):
                ball[n] += EG[off + 2 * n]
    for i in range(4):  # the actuators (forearm rotation phi_i) and the torsions (tau_i)
        sa = math.sqrt(G[G_CCTRL + i] + G[G_CBEND + i])
        so = math.sqrt(G[G_CTORS + i])
        for a in range(8):
            R[a, 2 * i] = sa * Xrow[X_F + F_GC + 4 * a + i]
            R[a, 2 * i + 1] = -so * Xrow[X_F + F_TV + 4 * a + i]
        R[8 + 2 * i, 2 * i] = sa
        R[9 + 2 * i, 2 * i + 1] = so
    for n in range(8):  # the bars (tension and ball joints in series)
        sb = math.sqrt(G[G_CTENS + n] + ball[n])
        for a in range(8):
            R[a, 8 + n] = sb * S[S_LW + n, 0] * Y[a, n]
    t = 16
    for row in range(int(EG[0])):
        base = EL_HEADER + EL_ROW * row
        site, form, axis = int(EG[base]), int(EG[base + 1]), int(EG[base + 2])
        count, off, normal = int(EG[base + 3]), int(EG[base + 4]), int(EG[base + 5])
        if site == SITE_BAR:
            continue
        stype = site  # the site codes joint, arm, mount, tip are 0..3 (the rows of sy)
        # the bars' closures give the plate's motion: M1 dtp = w . (dA - dB) over the bars that load
        # the site: + for a twist of the forearm side (mount, tip), - of the plate side (joint, arm)
        sign = 1.0 if (site == SITE_MOUNT or site == SITE_TIP) else -1.0
        for s in range(count):
            c, length = EG[off + 2 * s], EG[off + 2 * s + 1]
            if c == 0.0:
                continue
            for k in range(2):  # the axis into Xs[EA], the second axis into Xs[EA + 3] (one inlined copy)
                pipeline.element_axis(G, axis if k == 0 else normal, s, lane1, S, Xs, EA + 3 * k)
            e0, e1, e2 = Xs[EA, 0], Xs[EA + 1, 0], Xs[EA + 2, 0]
            a0, a1, a2, b0, b1, b2 = pipeline.form_frame(pipeline.form_plane(form), e0, e1, e2, Xs[EA + 3, 0],
                                                         Xs[EA + 4, 0], Xs[EA + 5, 0])
            pipeline.site_point(G, site, s, lane1 - 1, lane1, S, Xs)
            o = Xs[EA:EA + 3, 0].copy()
            y0 = sy[stype, s]
            for p in range(pipeline.form_count(form)):
                cp, fe, fa, fb, fw, me, ma, mb, mw = pipeline.form_part(form, p, c, length)
                sc = math.sqrt(cp)
                for d in range(3):  # u_p in the world (pipeline.form_part)
                    w = 1.0 if d == p else 0.0
                    ve, va, vb = (e0, a0, b0) if d == 0 else ((e1, a1, b1) if d == 1 else (e2, a2, b2))
                    us[d] = fe * ve + fa * va + fb * vb + fw * w
                    us[3 + d] = me * ve + ma * va + mb * vb + mw * w
                u0, u1, u2, u3, u4, u5 = us[0], us[1], us[2], us[3], us[4], us[5]
                for d in range(6):
                    R[y0 + d, t] = sc * us[d]
                for m in range(8):
                    if not pipeline.site_bars(G, site, s, m):
                        continue
                    pt = A[m] if (site == SITE_MOUNT or site == SITE_TIP) else B[m]
                    fx, fy, fz = B[m, 0] - A[m, 0], B[m, 1] - A[m, 1], B[m, 2] - A[m, 2]
                    mx, my, mz = _cr(pt[0] - o[0], pt[1] - o[1], pt[2] - o[2], fx, fy, fz)
                    g = sign * sc * (fx * u0 + fy * u1 + fz * u2 + mx * u3 + my * u4 + mz * u5)
                    for a in range(8):
                        R[a, t] += Y[a, m] * g
                t += 1
            for d in range(3):  # the site's point, for the bodies' twists below
                axes[30 + 4 * stype + s, d] = o[d]
    return ny, ns


@njit(cache=True, nogil=True)
def _mass_matrix(x, Xrow, G, ny, W):  # pragma: no cover - compiled
    """M_y = sum_b J_b^T M6_b J_b: the bodies' twists per unit y coordinate."""
    O, M6, axes, Sinv, sy, My, J, Jc, cols = W[0], W[1], W[2], W[3], W[4], W[5], W[9], W[10], W[11]
    D = W[20]  # x[:3], writable as the other points: one compiled version of the callees
    D[0], D[1], D[2] = x[0], x[1], x[2]
    B = Xrow[X_S + S_B:X_S + S_B + 24].reshape(8, 3)
    My[:ny, :ny] = 0.0
    zero = 0 * ny  # a run-time 0 and 1: a constant argument would compile a version of its own
    one = zero + 1
    for b in (20, 23):  # the central bar (at its origin) and the payload (at D): dtp's first six
        _add_body(My, M6[b], J, cols, _site_columns(J, cols, zero, zero, O[b], D))
    for k in range(2):  # lateral bar k: dtp's first six, its revolute, its joint site
        b = 21 + k
        nc = _site_columns(J, cols, zero, zero, O[b], D)
        _put(J, nc, 0.0, 0.0, 0.0, axes[28 + k, 0], axes[28 + k, 1], axes[28 + k, 2])
        cols[nc] = 6 + k
        nc += 1
        nc = _site_columns(J, cols, nc, sy[0, k], O[b], axes[30 + k])
        _add_body(My, M6[b], J, cols, nc)
    for i in range(4):
        k = int(G[G_LAT + 2 * i])
        P = G[G_P + 3 * i:G_P + 3 * i + 3]
        # the forearm: phi_i and the mount site
        w0, w1, w2 = axes[i, 0], axes[i, 1], axes[i, 2]
        v0, v1, v2 = _cr(w0, w1, w2, O[i, 0] - P[0], O[i, 1] - P[1], O[i, 2] - P[2])
        _put(J, zero, v0, v1, v2, w0, w1, w2)
        cols[0] = 8 + 2 * i
        nc = _site_columns(J, cols, one, sy[2, i], O[i], axes[38 + i])
        _add_body(My, M6[i], J, cols, nc)
        for j in range(2):
            _bar_columns(i, 2 * i + j, k, D, O, axes, B, Sinv, sy, M6, My, J, Jc, cols)


@njit(cache=True, nogil=True)
def _eigenvalues(ny, ns, W, freq):  # pragma: no cover - compiled
    """H = R^T M_y R and its eigenvalues into freq (Hz); returns the massive count."""
    My, R, MR, H = W[5], W[6], W[7], W[8]
    for a in range(ny):
        for c in range(ns):
            t2 = 0.0
            for b in range(ny):
                t2 += My[a, b] * R[b, c]
            MR[a, c] = t2
    for c in range(ns):
        for c2 in range(c, ns):
            t2 = 0.0
            for a in range(ny):
                t2 += R[a, c] * MR[a, c2]
            H[c, c2] = t2
            H[c2, c] = t2
    d = W[16][:ns]
    e = W[17][:ns]
    _tridiagonal(H, ns, d, e)
    _ql(d, e, ns)  # ascending: mu, largest first, is d[ns - 1 - a]
    top = d[ns - 1]
    massive = 0
    for a in range(ns):
        if d[ns - 1 - a] > MASSLESS_TOL * top and top > 0.0:
            massive += 1
    for a in range(freq.shape[0]):
        freq[a] = 1.0 / (2.0 * math.pi * math.sqrt(d[ns - 1 - a])) if a < massive else np.nan
    return massive


@njit(cache=True, nogil=True)
def _site_columns(J, cols, nc, y0, origin, o):
    """The six columns of a site's twist [translation at o; rotation] (y rows y0..y0 + 5, none if
    y0 < 0) for a body moved by it, twist at its ``origin``: returns the new column count."""
    if y0 < 0:
        return nc
    for d in range(6):
        if d < 3:
            _put(J, nc, 1.0 if d == 0 else 0.0, 1.0 if d == 1 else 0.0, 1.0 if d == 2 else 0.0, 0.0, 0.0, 0.0)
        else:
            w0, w1, w2 = 1.0 if d == 3 else 0.0, 1.0 if d == 4 else 0.0, 1.0 if d == 5 else 0.0
            v0, v1, v2 = _cr(w0, w1, w2, origin[0] - o[0], origin[1] - o[1], origin[2] - o[2])
            _put(J, nc, v0, v1, v2, w0, w1, w2)
        cols[nc] = y0 + d
        nc += 1
    return nc


@njit(cache=True, nogil=True)
def _bar_columns(i, n, k, D, O, axes, B, Sinv, sy, M6, My, J, Jc, cols):  # noqa: C901
    """The cross and the bar of bar n (leg i, lateral bar k): their twists per unit y column (the
    tip's and the bar end's motions, then the universal joint's two rates from the bar's 3 x 3
    solve), added to M_y."""
    ax, ay, az = axes[4 + i, 0], axes[4 + i, 1], axes[4 + i, 2]  # A_i
    bx, by, bz = B[n, 0], B[n, 1], B[n, 2]
    o1x, o1y, o1z = O[4 + n, 0], O[4 + n, 1], O[4 + n, 2]
    nc = 0 * n  # a run-time 0: a constant argument would compile the callees' versions of their own
    for c in range(9 + 24):  # 0..5 dtp, 6 omega_k, 7 phi, 8 tau, then the mount, tip, joint and arm sites
        vbx = vby = vbz = 0.0  # the bar end B's velocity
        wtx = wty = wtz = 0.0  # the tip's rotation and its velocity at A_i
        vax = vay = vaz = 0.0
        if c < 3:
            yc = c
            vbx, vby, vbz = (1.0 if c == 0 else 0.0), (1.0 if c == 1 else 0.0), (1.0 if c == 2 else 0.0)
        elif c < 6:
            yc = c
            vbx, vby, vbz = _cr(1.0 if c == 3 else 0.0, 1.0 if c == 4 else 0.0, 1.0 if c == 5 else 0.0,
                                bx - D[0], by - D[1], bz - D[2])
        elif c == 6:
            yc = 6 + k
            vbx, vby, vbz = _cr(axes[28 + k, 0], axes[28 + k, 1], axes[28 + k, 2], bx - O[21 + k, 0],
                                by - O[21 + k, 1], bz - O[21 + k, 2])
        elif c == 7:
            yc = 8 + 2 * i
            wtx, wty, wtz = axes[i, 0], axes[i, 1], axes[i, 2]
            vax, vay, vaz = _cr(wtx, wty, wtz, ax - O[i, 0], ay - O[i, 1], az - O[i, 2])
        elif c == 8:
            yc = 9 + 2 * i
            wtx, wty, wtz = axes[8 + i, 0], axes[8 + i, 1], axes[8 + i, 2]
        else:
            g, d = (c - 9) // 6, (c - 9) % 6  # 0 mount, 1 tip (the tip's twist); 2 joint, 3 arm (B's)
            y0 = sy[2, i] if g == 0 else (sy[3, i] if g == 1 else (sy[0, k] if g == 2 else sy[1, i]))
            if y0 < 0:
                continue
            yc = y0 + d
            r = 38 + i if g == 0 else (42 + i if g == 1 else (30 + k if g == 2 else 34 + i))
            tvx, tvy, tvz = (1.0 if d == 0 else 0.0), (1.0 if d == 1 else 0.0), (1.0 if d == 2 else 0.0)
            twx, twy, twz = (1.0 if d == 3 else 0.0), (1.0 if d == 4 else 0.0), (1.0 if d == 5 else 0.0)
            px, py, pz = (ax, ay, az) if g < 2 else (bx, by, bz)
            ex, ey, ez = _cr(twx, twy, twz, px - axes[r, 0], py - axes[r, 1], pz - axes[r, 2])
            if g < 2:
                wtx, wty, wtz = twx, twy, twz
                vax, vay, vaz = tvx + ex, tvy + ey, tvz + ez
            else:
                vbx, vby, vbz = tvx + ex, tvy + ey, tvz + ez
        ux, uy, uz = _cr(wtx, wty, wtz, o1x - ax, o1y - ay, o1z - az)
        v1x, v1y, v1z = vax + ux, vay + uy, vaz + uz
        rx, ry, rz = _cr(wtx, wty, wtz, bx - o1x, by - o1y, bz - o1z)
        hx, hy, hz = vbx - v1x - rx, vby - v1y - ry, vbz - v1z - rz
        r0 = Sinv[n, 0, 0] * hx + Sinv[n, 0, 1] * hy + Sinv[n, 0, 2] * hz
        r1 = Sinv[n, 1, 0] * hx + Sinv[n, 1, 1] * hy + Sinv[n, 1, 2] * hz
        w1x, w1y, w1z = wtx + r0 * axes[12 + n, 0], wty + r0 * axes[12 + n, 1], wtz + r0 * axes[12 + n, 2]
        Jc[0, nc], Jc[1, nc], Jc[2, nc], Jc[3, nc], Jc[4, nc], Jc[5, nc] = v1x, v1y, v1z, w1x, w1y, w1z
        sx, sy2, sz = _cr(w1x, w1y, w1z, O[12 + n, 0] - o1x, O[12 + n, 1] - o1y, O[12 + n, 2] - o1z)
        J[0, nc], J[1, nc], J[2, nc] = v1x + sx, v1y + sy2, v1z + sz
        J[3, nc] = w1x + r1 * axes[20 + n, 0]
        J[4, nc] = w1y + r1 * axes[20 + n, 1]
        J[5, nc] = w1z + r1 * axes[20 + n, 2]
        cols[nc] = yc
        nc += 1
    _add_body(My, M6[4 + n], Jc, cols, nc)
    _add_body(My, M6[12 + n], J, cols, nc)


def work_arrays(ny: int, ns: int) -> tuple:
    """The work arrays of :func:`_pose_frequencies` for up to ny y rows and ns springs."""
    return (np.zeros((24, 3)), np.zeros((24, 6, 6)), np.zeros((46, 3)), np.zeros((8, 3, 3)),
            np.full((4, 4), -1, dtype=np.int64), np.zeros((ny, ny)), np.zeros((ny, ns)), np.zeros((ny, ns)),
            np.zeros((ns, ns)), np.zeros((6, 34)), np.zeros((6, 34)), np.zeros(34, dtype=np.int64), np.zeros(4),
            np.zeros(6),
            np.zeros((XROWS, 1)), np.zeros((8, 3, 3)),
            np.zeros(ns), np.zeros(ns), np.zeros(8), np.zeros(2), np.zeros(3))  # d, e; ball; omega; v3


@_jit.link_as_compiled
@njit(cache=True, nogil=True)
def frequencies_run(poses, start, stop, q, status, X, G, EG, MP, CF, CI, freq, count, W):  # pragma: no cover
    """:func:`_pose_frequencies` for poses start .. stop - 1 whose status is 0 (else NaN, count 0):
    count[p] = [massive directions, springs (the admissible directions)]."""
    for p in range(start, stop):
        if status[p] != 0:
            freq[p] = np.nan
            count[p, 0] = 0
            count[p, 1] = 0
            continue
        count[p, 0] = _pose_frequencies(poses[p], q[p], X[p], G, EG, MP, CF, CI, freq[p], W)
        count[p, 1] = _y_layout(EG, W[4])[1]


#: Whether :func:`frequencies_run` is compiled (:mod:`h4pin._jit`); until then :func:`modes` takes
#: the Pinocchio route.
FREQUENCIES = _jit.Gate("natural frequencies", frequencies_run, step="frequencies")
#: Largest y and spring counts of a robot with every element on (:func:`_y_layout`).
NY, NS = 16 + 6 * 14, 16 + 10 * 2 + 5 * 4 + 8 * 4 + 2 * 4


def frequencies(h4, poses: np.ndarray, payload: Any = None, *, link_inertias: bool = True,
                count: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The compiled twin at poses (N, 4) of a robot whose parallelograms are exact, with its own
    elements: (frequencies (N, m) Hz ascending, NaN past each pose's massive count and where the
    status is not 0; the massive count (N,); the status (N,), :mod:`h4pin.verdicts`). ``count``:
    how many frequencies to keep (default: all)."""
    el = None if h4.elements.off else h4.elements
    kern = kernel.for_geometry(h4.geometry, el)
    x = kernel.readonly(np.ascontiguousarray(poses, dtype=float).reshape(-1, 4))
    n = len(x)
    inter = np.empty((n, pipeline.NX))
    if n == 1:  # the one-pose entry (no block of lanes)
        _, q, cond, status, _ = kernel.one(kern, x[0], pipeline.CONSISTENT, inter=inter[0])
        q, status = q[None], np.array([status], dtype=np.int8)
    else:
        res = kernel.run_poses(kern, x, pipeline.CONSISTENT, kernel.empty_result(n, False, False), False, False, inter)
        q, status = res.q, res.status
    CF, CI = kin.configuration_pack(h4)
    width = NS if count is None else int(count)
    freq = np.empty((n, width))
    counts = np.empty((n, 2), dtype=np.int64)
    frequencies_run(x, 0, n, q, status, inter, kern.packed, kern.elements, pack_masses(h4, payload, link_inertias),
                    CF, CI, freq, counts, work_arrays(NY, NS))
    if count is None:
        freq = freq[:, :max(int(counts[:, 0].max(initial=0)), 1)]
    return freq, counts, status


__all__ = ["FREQUENCIES", "MASSLESS_TOL", "frequencies", "frequencies_run", "pack_masses", "pack_masses_params"]
