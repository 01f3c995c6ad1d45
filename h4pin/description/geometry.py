# SPDX-License-Identifier: Apache-2.0
"""The robot as h4pin computes it: per-leg and per-bar geometry and springs, read from a model.

:class:`H4Geometry` holds every constant the closed-loop geometry and the stiffness model need,
one value per leg (actuators, forearms) and per bar, in SI. It is read once, at load, from the
Pinocchio model of the URDF (:func:`read_geometry`): the kinematic tree at its neutral
configuration gives the actuator axes, the forearm ends, the bar lengths and the plate points;
the loop closures say which bar ends on which point of the plate; the spring data sit in the
URDF next to their elements (:mod:`h4pin.description.urdf`). Nothing geometric comes from a side element,
so a hand-edited URDF is the robot it describes.

Coordinates: legs in the world frame at the neutral configuration (all joint angles zero); the
plate relative to D in the plate's reference orientation (its neutral one), which a pose
``[x, y, z, theta]`` turns by Rz(theta) about z. At a rigid pose the lateral bars keep their
reference orientation (they only translate; the relative angle of lateral bar k is -theta).

:func:`geometry_from_params` builds the same object straight from :class:`h4pin.H4Params`
(for design sweeps, where writing and parsing a URDF per design would dominate); a test keeps
it equal to reading the generated URDF.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from h4pin.description.params import LEG_LATERAL, PER_LEG, SPRINGS, H4Params, ball_centres
from h4pin.errors import MalformedURDFError

#: Tolerance (m) for "this point lies on that axis" checks when reading a model.
POINT_TOL = 1e-9
#: Default limits written by :func:`h4pin.description.urdf.to_urdf` (rad): actuators, lateral revolutes.
#: The plate's rotation range without the 4:1 amplifier is 45 deg (paper, section II).
ACTUATOR_LIMITS = (-1.0, 2.0)
LATERAL_LIMITS = (-np.pi / 4, np.pi / 4)
#: Default minimum distance (m) between the axes of bars of different legs: two bar tubes of
#: 5 mm radius touch at 10 mm.
BAR_CLEARANCE = 0.01
_Z = np.array([0.0, 0.0, 1.0])
_SIGNS = np.array([1.0, -1.0])


def _ro(a: Any, dtype: Any = float) -> np.ndarray:
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class H4Geometry:
    """Per-leg and per-bar constants of one H4, SI (see the module docstring for frames).

    Legs i = 0..3, bars n = 2 i + j (j = 0, 1), lateral bars k = 0, 1.

    Attributes:
        P: (4, 3) point of actuator axis i: the foot of the perpendicular from A_i.
        u: (4, 3) unit actuator axes; q_i is right-handed about u_i.
        A0: (8, 3) forearm-side ball joints A_ij at q = 0.
        l: (8,) bar lengths.
        lat: (8,) lateral bar of each bar; leg_lat (4,) of each leg.
        C0: (2, 3) C_k - D in the plate's reference orientation.
        b: (8, 3) B_ij - C_k (lateral bar k's reference orientation).
        v: (2, 3) unit axes of the lateral revolutes in the plate's reference orientation,
            signed so that v . z > 0 (omega_k is right-handed about v_k).
        springs: spring data per element: kc, E, I, G, I0, forearm_stressed_fraction (4,) and
            Sb, Eb (8,).
        q_lo, q_hi: (4,) actuator limits; omega_lo, omega_hi (2,) lateral relative angles.
        bar_clearance: m, minimum distance between the axes of bars of different legs.
    """

    P: np.ndarray
    u: np.ndarray
    A0: np.ndarray
    l: np.ndarray
    lat: np.ndarray
    C0: np.ndarray
    b: np.ndarray
    v: np.ndarray
    springs: dict[str, np.ndarray]
    q_lo: np.ndarray
    q_hi: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    bar_clearance: float = BAR_CLEARANCE

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if not f.init:
                continue
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                object.__setattr__(self, f.name, _ro(value, value.dtype))
        object.__setattr__(self, "springs", {k: _ro(v) for k, v in self.springs.items()})
        lat = self.lat.reshape(4, 2)
        object.__setattr__(self, "leg_lat", _ro(lat[:, 0], int))
        A, m, r = forearms(self.A0, self.P)
        object.__setattr__(self, "A0_leg", _ro(A))
        object.__setattr__(self, "m", _ro(m))
        object.__setattr__(self, "um", _ro(np.cross(self.u, m)))
        object.__setattr__(self, "r", _ro(r))
        b_leg = self.b.reshape(4, 2, 3).mean(axis=1)
        object.__setattr__(self, "b_leg", _ro(b_leg))
        object.__setattr__(self, "l_leg", _ro(self.l.reshape(4, 2).mean(axis=1)))
        # The closed form holds when every parallelogram is one: equal bars, equal offsets on
        # both sides, parallel to the actuator axis (so a forearm rotation keeps it), and
        # vertical lateral axes (so a rigid pose keeps the lateral bars' orientation).
        da = self.A0[0::2] - self.A0[1::2]
        db = self.b[0::2] - self.b[1::2]
        scale = float(np.max(self.l))
        ideal = (np.all(np.abs(self.l[0::2] - self.l[1::2]) <= 1e-12 * scale)
                 and np.all(np.abs(da - db) <= 1e-12 * scale)
                 and np.all(np.linalg.norm(np.cross(da, self.u), axis=1) <= 1e-12 * scale)
                 and np.all(np.abs(self.v - _Z) <= 1e-12))
        object.__setattr__(self, "ideal", bool(ideal))

    # Declared for type checkers; set in __post_init__.
    leg_lat: np.ndarray = dataclasses.field(init=False, repr=False)
    A0_leg: np.ndarray = dataclasses.field(init=False, repr=False)
    m: np.ndarray = dataclasses.field(init=False, repr=False)
    um: np.ndarray = dataclasses.field(init=False, repr=False)
    r: np.ndarray = dataclasses.field(init=False, repr=False)
    b_leg: np.ndarray = dataclasses.field(init=False, repr=False)
    l_leg: np.ndarray = dataclasses.field(init=False, repr=False)
    ideal: bool = dataclasses.field(init=False, repr=False)

    def compliances(self) -> dict[str, np.ndarray]:
        """Spring compliances per element (eq. 30): control 1/kc, bending phi^3 r/(3 E I),
        torsion phi r/(G I0) per leg (4,) in rad/(N.m), with r_i this robot's forearm
        lengths; tension l/(Sb Eb) per bar (8,) in m/N."""
        return spring_compliances(self.springs, self.r, self.l)

    def replace(self, **changes: Any) -> H4Geometry:
        """A copy with some fields changed (derived quantities recomputed)."""
        kept = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}
        kept.update(changes)
        return H4Geometry(**kept)

    def rotated(self, angle: float) -> H4Geometry:
        """The same robot turned by ``angle`` (rad) about the world z axis (legs and plate)."""
        c, s = np.cos(angle), np.sin(angle)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return self.replace(P=self.P @ rot.T, u=self.u @ rot.T, A0=self.A0 @ rot.T, C0=self.C0 @ rot.T,
                            b=self.b @ rot.T, v=self.v @ rot.T)


def spring_compliances(springs: dict[str, np.ndarray], r: np.ndarray, l: np.ndarray) -> dict[str, np.ndarray]:
    """Spring compliances per element (eq. 30) from the spring data, the forearm lengths r (..., 4)
    and the bar lengths l (..., 8) (leading robot axes broadcast): control 1/kc, bending
    phi^3 r/(3 E I), torsion phi r/(G I0) in rad/(N.m); tension l/(Sb Eb) in m/N."""
    s = springs
    phi = s["forearm_stressed_fraction"]
    return {
        "control": np.broadcast_to(1.0 / s["kc"], np.shape(r)),
        "bending": phi**3 * r / (3.0 * s["E"] * s["I"]),
        "torsion": phi * r / (s["G"] * s["I0"]),
        "tension": l / (s["Sb"] * s["Eb"]),
    }


def check_springs(springs: dict[str, Any], where: str,
                  owners: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Spring data per element as float arrays (scalars broadcast); refuses missing or
    non-physical values with a :class:`MalformedURDFError` naming the element (``owners[name][k]``
    when given, e.g. "the bar link 'bar_11'"; else its leg or bar)."""
    out = {}
    for name in SPRINGS:
        n = 4 if name in PER_LEG else 8
        if name not in springs:
            raise MalformedURDFError(f"{where}: spring datum '{name}' is missing")
        raw = springs[name]
        try:
            value = np.broadcast_to(np.asarray(raw, dtype=float), (n,)).copy()
        except (TypeError, ValueError):
            raise MalformedURDFError(f"{where}: spring datum '{name}' = {raw!r} is not {n} numbers") from None
        bad = ~np.isfinite(value) | (value <= 0)
        if name == "forearm_stressed_fraction":
            bad |= value > 1.0
        if np.any(bad):
            k = int(np.argmax(bad))
            if owners is not None:
                element = owners[name][k]
            else:
                element = f"actuator/forearm of leg {k + 1}" if n == 4 else f"bar {k // 2 + 1}{k % 2 + 1}"
            limit = ", at most 1" if name == "forearm_stressed_fraction" else ""
            raise MalformedURDFError(f"{where}: {element}: spring datum '{name}' = {float(value[k])!r} is not physical "
                                     f"(must be finite and > 0{limit})")
        out[name] = value
    return out


def forearms(A0: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The forearm ends A_i (mid-points of A_i1, A_i2), the forearms m_i = A_i - P_i (..., 4, 3)
    and their lengths r_i (..., 4), from A0 (..., 8, 3) and P (..., 4, 3) (leading axes broadcast)."""
    A = A0.reshape(A0.shape[:-2] + (4, 2, 3)).mean(axis=-2)
    m = A - P
    return A, m, np.linalg.norm(m, axis=-1)


def geometry_arrays(P: np.ndarray, U: np.ndarray, forearm_dirs: np.ndarray, r: np.ndarray, l: np.ndarray,
                    half_width: np.ndarray, DB: np.ndarray, DC: np.ndarray, springs: dict[str, np.ndarray],
                    bar_clearance: float = BAR_CLEARANCE) -> dict[str, Any]:
    """The fields of :class:`H4Geometry` (its keyword arguments) of the robots
    :func:`h4pin.description.urdf.to_urdf` writes for :class:`H4Params` arrays with leading design
    axes (broadcast): P, U, forearm_dirs, DB (..., 3, 4), DC (..., 3, 2), r, half_width (..., 4),
    l (..., 8), springs as :class:`H4Params` holds them (leading axes too). One design gives
    :func:`geometry_from_params`; many at once, the design sweep (:mod:`h4pin.studies.sweep`)."""
    P, u, a = (np.swapaxes(np.asarray(x, dtype=float), -1, -2) for x in (P, U, forearm_dirs))
    r, h = np.asarray(r, dtype=float), np.asarray(half_width, dtype=float)
    A = P + r[..., None] * a
    A0 = A[..., :, None, :] + _SIGNS[:, None] * h[..., :, None, None] * u[..., :, None, :]
    A0 = A0.reshape(A0.shape[:-3] + (8, 3))
    C0 = np.swapaxes(np.asarray(DC, dtype=float), -1, -2)
    b = ball_centres(DB, U, h) - C0[..., LEG_LATERAL, :][..., None, :]
    b = b.reshape(b.shape[:-3] + (8, 3))
    batch = A0.shape[:-2]
    return dict(P=P, u=u, A0=A0, l=np.asarray(l, dtype=float), lat=np.repeat(LEG_LATERAL, 2), C0=C0, b=b,
                v=np.broadcast_to(_Z, batch + (2, 3)), springs=springs,
                q_lo=np.full(batch + (4,), ACTUATOR_LIMITS[0]), q_hi=np.full(batch + (4,), ACTUATOR_LIMITS[1]),
                omega_lo=np.full(batch + (2,), LATERAL_LIMITS[0]), omega_hi=np.full(batch + (2,), LATERAL_LIMITS[1]),
                bar_clearance=bar_clearance)


def geometry_from_params(params: H4Params, bar_clearance: float = BAR_CLEARANCE) -> H4Geometry:
    """The :class:`H4Geometry` of the robot :func:`h4pin.description.urdf.to_urdf` writes for ``params``."""
    p = params
    return H4Geometry(**geometry_arrays(p.P, p.U, p.forearm_dirs, p.r, p.l, p.half_width, p.DB, p.DC,
                                        {name: getattr(p, name) for name in SPRINGS}, bar_clearance))


def params_from_geometry(g: H4Geometry, ball_radius: float = 5e-3) -> H4Params:
    """The nominal parameters of a geometry whose layout :class:`H4Params` can describe.

    Reads P, U, r, l, DB, DC, half_width back (the inverse of :func:`geometry_from_params`).

    Raises:
        MalformedURDFError: the robot is not of that family (a forearm not along u_i x z at
            q = 0, a parallelogram that is not one, a tilted lateral axis...).
    """
    a = np.cross(g.u, _Z)
    h = 0.5 * np.einsum("ia,ia->i", g.A0[0::2] - g.A0[1::2], g.u)
    dc = g.C0.T
    db = (g.C0[g.leg_lat] + g.b_leg).T
    want = geometry_arrays(g.P.T, g.u.T, a.T, g.r, g.l, h, db, dc, g.springs)
    if not (np.allclose(want["A0"], g.A0, atol=1e-12) and np.allclose(want["b"], g.b, atol=1e-12)
            and np.allclose(g.lat, want["lat"]) and np.allclose(g.v, _Z, atol=1e-12)):
        raise MalformedURDFError("this robot's layout is not one H4Params describes (per-bar offsets, tilted "
                                 "lateral axes or another leg-to-lateral-bar assignment)")
    return H4Params(P=g.P.T, U=g.u.T, r=g.r, l=g.l, DB=db, DC=dc, half_width=h, ball_radius=ball_radius,
                    **{k: v for k, v in g.springs.items()})


__all__ = ["H4Geometry", "check_springs", "forearms", "geometry_arrays", "geometry_from_params",
           "params_from_geometry"]
