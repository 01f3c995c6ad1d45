# SPDX-License-Identifier: Apache-2.0
"""Parameters of an H4 robot: geometry and spring data, in SI, validated when made.

:class:`H4Params` holds every number the model of Company, Pierrot and Fauroux (ICRA 2005)
needs. Its defaults are the prototype of section V.A of the paper, converted to SI, with the
values the paper does not state filled in as documented in ``docs/parameters.md``. Each
default that is not printed in the paper says so, with its reason, next to the field.

Conventions (see the README):

* Legs ``i = 1..4`` are columns ``0..3`` of ``P``, ``U`` and ``DB``; legs 1, 2 hang on lateral
  bar ``k = 1`` and legs 3, 4 on ``k = 2`` (:data:`LEG_LATERAL`).
* The forearm direction at ``q = 0`` is ``a_i = u_i x z`` and ``q`` is right-handed about
  ``u_i``: ``A_i = P_i + r (a_i cos q - z sin q)``, so ``q > 0`` moves the forearm down.
* ``DB`` and ``DC`` are the vectors from ``D`` to ``B_i`` and ``C_k`` at ``theta = 0``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from h4pin.errors import ParameterError

#: Lateral bar (0-based k) carrying each leg (0-based i): legs 1, 2 -> bar 1; legs 3, 4 -> bar 2.
LEG_LATERAL = np.array([0, 0, 1, 1])

_MM = 1e-3

# Section V.A of the paper, with P_1 = (-200, -60, 0) mm instead of the printed (+200, -60, 0):
# a sign typo (docs/parameters.md). With it every u_i x z points outward, the layout is mirror-symmetric
# about y = 0 and q_i = 45 deg is a true centre pose.
_P = np.array([[-200.0, 60.0, 60.0, -200.0], [-60.0, -200.0, 200.0, 60.0], [0.0, 0.0, 0.0, 0.0]]) * _MM
_U = np.array([[0.0, 1.0, -1.0, 0.0], [-1.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]])
_DB = np.array([[-60.0, 60.0, 60.0, -60.0], [-60.0, -60.0, 60.0, 60.0], [50.0, 50.0, 50.0, 50.0]]) * _MM
# Not in the paper: C_k is the middle of lateral bar k, so the plate is a true "H" (docs/parameters.md).
# Only its x, y matter (the revolute axis is z).
_DC = np.array([[0.0, 0.0], [-60.0, 60.0], [50.0, 50.0]]) * _MM

_ARRAY_SHAPES = {"P": (3, 4), "U": (3, 4), "DB": (3, 4), "DC": (3, 2)}
#: Per-element fields: a scalar is broadcast to one value per leg (4) or per bar (8).
PER_LEG = ("r", "half_width", "kc", "E", "I", "G", "I0", "forearm_stressed_fraction")
PER_BAR = ("l", "Sb", "Eb")
SPRINGS = ("kc", "E", "I", "G", "I0", "forearm_stressed_fraction", "Sb", "Eb")


def _default(array: np.ndarray) -> Any:
    return dataclasses.field(default_factory=lambda: array.copy())


def _numbers(name: str, raw: Any) -> np.ndarray:
    """``raw`` as a float64 array; bools, strings and other non-numbers are refused."""
    values = raw if isinstance(raw, np.ndarray) else np.asarray(raw, dtype=object)
    flat = values.reshape(-1)
    for v in flat:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ParameterError(f"{name} must be a real number (or an array of them), got {raw!r}")
    return np.array(values, dtype=float)


@dataclasses.dataclass(frozen=True, eq=False)
class H4Params:
    """Geometry and stiffness data of a nominal H4 robot, in SI units (m, rad, N, Pa).

    H4Params generates robots: :func:`h4pin.description.urdf.to_urdf` writes its URDF, and from there the URDF
    is the model (:func:`h4pin.load` reads every length, position and spring from the file).
    Every field can be changed (``params.replace(half_width=0.02)``); the result is validated
    again. Per-leg and per-bar fields accept a scalar (broadcast) or one value per element; all
    arrays are stored as read-only float64 copies.

    Attributes:
        P: (3, 4) m. A point P_i of each actuator axis (paper, V.A; P_1 sign typo fixed).
        U: (3, 4) unit, horizontal. Actuator axis directions u_i (paper, V.A).
        r: (4,) m. Forearm length per leg, P_i to A_i (paper: 260 mm).
        l: (8,) m. Bar length per bar, A_ij to B_ij, n = 2(i-1) + (j-1) (paper: 480 mm).
        DB: (3, 4) m. Vector D -> B_i at theta = 0 (paper: DB_nominal).
        DC: (3, 2) m. Vector D -> C_k at theta = 0. Not in the paper: (0, -+60, 50) mm, the
            middle of each lateral bar.
        half_width: (4,) m. Half the width h of each parallelogram: A_ij = A_i +- h u_i (j = 1 is +).
            Not in the paper: 40 mm; the ball joints of legs 1 and 4 meet at 60 mm, and between
            20 and 60 mm the compliance changes by under 2 %.
        kc: (4,) N.m/rad. Actuator control stiffness (paper: 7.4e6 N.mm per radian).
        E: (4,) Pa. Young's modulus of each forearm (paper: 70 000 N/mm^2, aluminium).
        I: (4,) m^4. Second moment of area of each forearm section (paper: 1.6e4 mm^4).
        G: (4,) Pa. Shear modulus of each forearm (paper: 0.4 E).
        I0: (4,) m^4. Polar moment of each forearm section (paper: 2 I).
        Sb: (8,) m^2. Section of each bar (paper: 28 mm^2).
        Eb: (8,) Pa. Young's modulus of each bar (paper: 200 000 N/mm^2).
        forearm_stressed_fraction: (4,) Fraction phi of each forearm that bends and twists.
            Default 1, as in the paper's numbers (eq. 30 uses the full r). The paper remarks that
            only 2/3 of the prototype's forearms are stressed; with phi < 1 the stressed part is
            the outer phi*r of the forearm, clamped on a rigid hub, which scales the bending
            compliance by phi^3 and the torsion compliance by phi.
        ball_radius: m. Radius of the ball joints, used for drawing and for the collision check
            of the half-width (plate-side ball joints of different legs, and the segments between
            the two balls of a leg, must be at least two radii apart). Not in the paper: 5 mm.
    """

    P: np.ndarray = _default(_P)
    U: np.ndarray = _default(_U)
    r: Any = 260.0 * _MM
    l: Any = 480.0 * _MM
    DB: np.ndarray = _default(_DB)
    DC: np.ndarray = _default(_DC)
    half_width: Any = 40.0 * _MM
    kc: Any = 7.4e6 * _MM
    E: Any = 70_000.0e6
    I: Any = 1.6e4 * _MM**4  # noqa: E741 (the paper's name)
    G: Any = 0.4 * 70_000.0e6
    I0: Any = 2 * 1.6e4 * _MM**4
    Sb: Any = 28.0 * _MM**2
    Eb: Any = 200_000.0e6
    forearm_stressed_fraction: Any = 1.0
    ball_radius: float = 5.0 * _MM

    def __post_init__(self) -> None:
        for name, shape in _ARRAY_SHAPES.items():
            value = _numbers(name, getattr(self, name))
            if value.shape != shape:
                raise ParameterError(f"{name} must have shape {shape}, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ParameterError(f"{name} has non-finite entries: {value.tolist()}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        for names, n in ((PER_LEG, 4), (PER_BAR, 8)):
            for name in names:
                value = _numbers(name, getattr(self, name))
                if value.ndim == 2 and value.shape == (4, 2) and n == 8:
                    value = value.reshape(8)
                try:
                    value = np.broadcast_to(value, (n,)).copy()
                except ValueError:
                    raise ParameterError(f"{name} must be a scalar or have {n} entries "
                                         f"(one per {'leg' if n == 4 else 'bar'}), got shape {value.shape}") from None
                if not np.all(np.isfinite(value)) or np.any(value <= 0.0):
                    raise ParameterError(f"{name} must be finite and > 0, got {value.tolist()}")
                value.setflags(write=False)
                object.__setattr__(self, name, value)
        radius = _numbers("ball_radius", self.ball_radius)
        if radius.shape != () or not np.isfinite(radius) or radius <= 0:
            raise ParameterError(f"ball_radius must be a finite number > 0, got {self.ball_radius!r}")
        object.__setattr__(self, "ball_radius", float(radius))
        if np.any(self.forearm_stressed_fraction > 1.0):
            raise ParameterError(
                f"forearm_stressed_fraction must be in (0, 1], got {self.forearm_stressed_fraction.tolist()}")
        norms = np.linalg.norm(self.U, axis=0)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            raise ParameterError(f"U columns must be unit vectors, got norms {norms.tolist()}")
        if np.any(np.abs(self.U[2]) > 1e-9):
            raise ParameterError(f"U columns must be horizontal (u_z = 0), got u_z = {self.U[2].tolist()}")
        a = np.cross(self.U.T, [0.0, 0.0, 1.0]).T
        a.setflags(write=False)
        object.__setattr__(self, "_forearm_dirs", a)
        self._check_ball_joints()
        self._check_bars_reach()

    def _check_ball_joints(self) -> None:
        """Refuse a half-width for which plate-side ball joints of two legs collide or cross
        (:func:`ball_joints_apart`)."""
        gaps = ball_joint_gaps(self.DB, self.U, self.half_width)
        bad = gaps < 2 * self.ball_radius
        if np.any(bad):
            k = int(np.argmax(bad))
            i, i2 = LEG_PAIRS[k]
            raise ParameterError(
                f"half_width = {self.half_width[i] * 1e3:.1f} / {self.half_width[i2] * 1e3:.1f} mm makes "
                f"the ball joints of legs {i + 1} and {i2 + 1} collide or cross on the plate (their "
                f"segments are {gaps[k] * 1e3:.1f} mm apart, ball_radius = {self.ball_radius * 1e3:.1f} mm)")

    def _check_bars_reach(self) -> None:
        """Refuse lengths with which the four legs cannot hold the plate together (:func:`bars_reach`)."""
        ok = _reach_table(self.P, self.U, self.DB, self.r, self.l)  # (heights, 4)
        if not np.any(ok.all(axis=1)):
            worst = int(np.argmin(ok.sum(axis=0)))
            lb = self.l.reshape(4, 2).mean(axis=1)
            raise ParameterError(
                f"the legs cannot hold the plate: with r = {self.r[worst] * 1e3:.1f} mm and bars of "
                f"{lb[worst] * 1e3:.1f} mm, leg {worst + 1} cannot reach B_{worst + 1} at any plate height "
                f"where the other legs can (check r, l, P, DB)")

    def plate_ball_centres(self) -> np.ndarray:
        """B_ij - D at theta = 0, shape (4, 2, 3), in m (j = 1 is B_i + h u_i)."""
        return ball_centres(self.DB, self.U, self.half_width)

    @property
    def forearm_dirs(self) -> np.ndarray:
        """a_i = u_i x z, the forearm directions at q = 0, shape (3, 4) (computed once)."""
        return self._forearm_dirs

    def compliances(self) -> dict[str, np.ndarray]:
        """The spring compliances of eq. 30 per element, SI: control 1/kc_i, bending
        phi^3 r_i/(3 E_i I_i) and torsion phi r_i/(G_i I0_i) (4,) in rad/(N.m); tension
        l_ij/(Sb_ij Eb_ij) (8,) in m/N."""
        phi = self.forearm_stressed_fraction
        return {
            "control": 1.0 / self.kc,
            "bending": phi**3 * self.r / (3.0 * self.E * self.I),
            "torsion": phi * self.r / (self.G * self.I0),
            "tension": self.l / (self.Sb * self.Eb),
        }

    def replace(self, **changes: Any) -> H4Params:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Fields as plain Python values (lists for arrays), in SI."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = v.tolist() if isinstance(v, np.ndarray) else v
        return out

    def allclose(self, other: H4Params, atol: float = 1e-15) -> bool:
        """Every field equal to ``other``'s within ``atol`` (absolute, SI; relative for springs)."""
        for f in dataclasses.fields(self):
            a, b = np.asarray(getattr(self, f.name)), np.asarray(getattr(other, f.name))
            scale = np.maximum(np.abs(b), 1.0) if f.name in SPRINGS else 1.0
            if a.shape != b.shape or np.any(np.abs(a - b) > atol * scale):
                return False
        return True

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, H4Params):
            return NotImplemented
        return all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
        )

    __hash__ = None  # type: ignore[assignment]


def segment_distance(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Shortest distance between the segments p1-p2 and q1-q2 (m), for the collision checks;
    broadcasts over leading axes: (..., 3) -> (...)."""
    d1, d2, r = p2 - p1, q2 - q1, p1 - q1
    a, e, f = (d1 * d1).sum(-1), (d2 * d2).sum(-1), (d2 * r).sum(-1)
    c, b = (d1 * r).sum(-1), (d1 * d2).sum(-1)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > 1e-18 * a * e, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t = np.where(e > 0, (b * s + f) / e, 0.0)
        out = (t < 0.0) | (t > 1.0)
        t = np.where(out, np.clip(t, 0.0, 1.0), t)
        s = np.where(out, np.where(a > 0, np.clip((b * t - c) / a, 0.0, 1.0), 0.0), s)
    return np.linalg.norm(p1 + s[..., None] * d1 - q1 - t[..., None] * d2, axis=-1)


#: The pairs of legs (i, i2), i < i2, in the order the ball-joint check reports them.
LEG_PAIRS = tuple((i, i2) for i in range(4) for i2 in range(i + 1, 4))
_SIGNS = np.array([1.0, -1.0])
#: Plate heights of the reach check, as fractions of the longest leg (r_i + l_i) below the motors.
_HEIGHTS = np.linspace(-2.0, 0.0, 401)


def ball_centres(DB: np.ndarray, U: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """B_ij - D at theta = 0 (j = 1 is B_i + h u_i), m: DB, U (..., 3, 4), half_width (..., 4)
    -> (..., 4, 2, 3), leading design axes broadcast."""
    DB, U, h = np.asarray(DB, dtype=float), np.asarray(U, dtype=float), np.asarray(half_width, dtype=float)
    return (np.swapaxes(DB, -1, -2)[..., :, None, :]
            + _SIGNS[:, None] * h[..., :, None, None] * np.swapaxes(U, -1, -2)[..., :, None, :])


def ball_joint_gaps(DB: np.ndarray, U: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """Distances (m) between the plate-side segments B_i1 B_i2 of two legs, one per pair of
    :data:`LEG_PAIRS`: (..., 6), leading design axes broadcast (a crossed pair has distance 0)."""
    b = ball_centres(DB, U, half_width)
    return np.stack([segment_distance(b[..., i, 0, :], b[..., i, 1, :], b[..., i2, 0, :], b[..., i2, 1, :])
                     for i, i2 in LEG_PAIRS], axis=-1)


def ball_joints_apart(DB: np.ndarray, U: np.ndarray, half_width: np.ndarray, ball_radius: float) -> np.ndarray:
    """Whether the plate-side ball joints of every two legs stay two ball radii apart, the
    segments B_i1 B_i2 of two legs included (the check of :class:`H4Params`, which raises where
    this is False): bool (...) over leading design axes."""
    return ~np.any(ball_joint_gaps(DB, U, half_width) < 2 * ball_radius, axis=-1)


def _reach_table(P: np.ndarray, U: np.ndarray, DB: np.ndarray, r: np.ndarray, l: np.ndarray,
                 heights: np.ndarray = _HEIGHTS) -> np.ndarray:
    """Whether leg i reaches B_i with the plate level under the actuators' centroid, at each
    plate height of ``heights`` (fractions of the longest leg, :data:`_HEIGHTS`): bool
    (..., heights, 4) (see :func:`bars_reach`)."""
    P, U, DB = (np.asarray(x, dtype=float) for x in (P, U, DB))
    r, l = np.asarray(r, dtype=float), np.asarray(l, dtype=float)
    lb = l.reshape(l.shape[:-1] + (4, 2)).mean(axis=-1)
    z = heights * np.max(r + lb, axis=-1)[..., None]  # (..., heights) below the motors
    centre = P.mean(axis=-1) - DB.mean(axis=-1)
    e = centre[..., :, None] + DB - P  # (..., 3, 4): B_i - P_i at z = 0; at height z, e + z e_z
    # Along the axis u_i and off it, in closed form in z (no (heights, 3, 4) array: a design sweep
    # checks thousands of designs): e.u + z u_z, and |e + z e_z|^2 - (e.u + z u_z)^2.
    eu0, uz = np.einsum("...ai,...ai->...i", e, U)[..., None, :], U[..., None, 2, :]
    ee0, ez = np.einsum("...ai,...ai->...i", e, e)[..., None, :], e[..., None, 2, :]
    zz = z[..., None]
    eu = eu0 + zz * uz
    rho = np.sqrt(np.maximum(ee0 + zz * (2.0 * ez + zz) - eu * eu, 0.0))
    r, lb = r[..., None, :], lb[..., None, :]
    near, far = np.hypot(eu, rho - r), np.hypot(eu, rho + r)
    return (near <= lb) & (lb <= far)


def bars_reach(P: np.ndarray, U: np.ndarray, DB: np.ndarray, r: np.ndarray, l: np.ndarray) -> np.ndarray:
    """Whether the four legs can hold the plate together (the check of :class:`H4Params`, which
    raises where this is False): bool (...) over leading design axes of P, U, DB (..., 3, 4),
    r (..., 4), l (..., 8).

    With the plate level (theta = 0) under the actuators' centroid, leg i reaches B_i iff the
    distance from B_i to the circle of A_i (radius r_i about the axis through P_i) brackets its
    bar length. Some plate height must suit all four legs at once.
    """
    P, U, DB = (np.asarray(x, dtype=float) for x in (P, U, DB))
    r, l = np.asarray(r, dtype=float), np.asarray(l, dtype=float)
    lead = np.broadcast_shapes(P.shape[:-2], U.shape[:-2], DB.shape[:-2], r.shape[:-1], l.shape[:-1])
    P, U, DB = (np.broadcast_to(x, lead + (3, 4)).reshape(-1, 3, 4) for x in (P, U, DB))
    r, l = np.broadcast_to(r, lead + (4,)).reshape(-1, 4), np.broadcast_to(l, lead + (8,)).reshape(-1, 8)
    # Every 8th height first (a subset of the heights: a design that reaches at one of them
    # reaches); the whole table only for the designs that did not (most designs of a sweep reach
    # at a coarse height: 8x less work for them).
    ok = np.any(np.all(_reach_table(P, U, DB, r, l, _HEIGHTS[::8]), axis=-1), axis=-1)
    rest = np.flatnonzero(~ok)
    if rest.size:
        ok[rest] = np.any(np.all(_reach_table(P[rest], U[rest], DB[rest], r[rest], l[rest]), axis=-1), axis=-1)
    return ok.reshape(lead)


def symmetric_params(base: H4Params | None = None) -> H4Params:
    """The ``symmetric`` variant: leg i is leg 1 of ``base`` rotated by (i-1)*90 deg about z.

    P, U and DB of leg 1 turn together; legs 1, 2 stay on lateral bar 1 and legs 3, 4 on bar 2,
    so the plate is unchanged. The paper's conclusion predicts a null stiffness for such a
    layout: its centre pose (q_i = 45 deg) is singular.
    """
    base = base or H4Params()
    P, U, DB = (np.empty((3, 4)) for _ in range(3))
    for i in range(4):
        c, s = np.cos(i * np.pi / 2), np.sin(i * np.pi / 2)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).round(15)
        P[:, i], U[:, i], DB[:, i] = rot @ base.P[:, 0], rot @ base.U[:, 0], rot @ base.DB[:, 0]
    return base.replace(P=P, U=U, DB=DB)


#: Manufacturing errors of the ``toleranced`` variant (1 sigma, SI): a machined part is held
#: to about +-0.1 mm (ISO 2768-m over 120-400 mm), a bar pair is cut to length together to a few
#: hundredths, an axis is aligned to about 1 mrad, and motor gains and tube sections vary by a
#: few percent.
TOLERANCES = {"P": 1e-4, "U_angle": 1e-3, "r": 1e-4, "l": 5e-5, "DB": 5e-5, "DC": 5e-5, "half_width": 5e-5,
              "kc": 0.03, "Sb": 0.02}


def toleranced_params(base: H4Params | None = None, seed: int = 2005, scale: float = 1.0) -> H4Params:
    """The ``toleranced`` variant: ``base`` (the prototype) with one draw of per-leg and per-bar
    manufacturing errors of the sizes in :data:`TOLERANCES` (times ``scale``), seeded.

    Every bar gets its own length, so the parallelograms are no longer exact: the plate tilts a
    little and the geometry is solved by Newton's method (:mod:`h4pin.kinematics.closed_form`).
    """
    base = base or H4Params()
    rng = np.random.default_rng(seed)
    t = {k: v * scale for k, v in TOLERANCES.items()}
    angle = rng.normal(0.0, t["U_angle"], 4)
    c, s = np.cos(angle), np.sin(angle)
    U = np.stack([c * base.U[0] - s * base.U[1], s * base.U[0] + c * base.U[1], np.zeros(4)])
    return base.replace(
        P=base.P + rng.normal(0.0, t["P"], (3, 4)),
        U=U,
        r=base.r + rng.normal(0.0, t["r"], 4),
        l=base.l + rng.normal(0.0, t["l"], 8),
        DB=base.DB + rng.normal(0.0, t["DB"], (3, 4)),
        DC=base.DC + rng.normal(0.0, t["DC"], (3, 2)),
        half_width=base.half_width + rng.normal(0.0, t["half_width"], 4),
        kc=base.kc * (1.0 + rng.normal(0.0, t["kc"], 4)),
        Sb=base.Sb * (1.0 + rng.normal(0.0, t["Sb"], 8)),
    )


#: Names of the variants shipped as URDF files in ``urdf/h4_<name>.urdf`` (how each is made:
#: :data:`h4pin.studies.variants.GENERATORS`).
VARIANTS = ("prototype", "symmetric", "toleranced", "measured_match")
