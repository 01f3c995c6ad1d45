# SPDX-License-Identifier: Apache-2.0
"""Parameters of an H4 robot: geometry and spring data, in SI, validated when made.

:class:`H4Params` holds every number the model of Company, Pierrot and Fauroux (ICRA 2005)
needs. Its defaults are the prototype of section V.A of the paper, converted to SI, with the
values the paper does not state filled in as documented in ``shared/H4-NOTES.md``. Each
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
# a sign typo (H4-NOTES). With it every u_i x z points outward, the layout is mirror-symmetric
# about y = 0 and q_i = 45 deg is a true centre pose.
_P = np.array([[-200.0, 60.0, 60.0, -200.0], [-60.0, -200.0, 200.0, 60.0], [0.0, 0.0, 0.0, 0.0]]) * _MM
_U = np.array([[0.0, 1.0, -1.0, 0.0], [-1.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]])
_DB = np.array([[-60.0, 60.0, 60.0, -60.0], [-60.0, -60.0, 60.0, 60.0], [50.0, 50.0, 50.0, 50.0]]) * _MM
# Not in the paper: C_k is the middle of lateral bar k, so the plate is a true "H" (H4-NOTES).
# Only its x, y matter (the revolute axis is z).
_DC = np.array([[0.0, 0.0], [-60.0, 60.0], [50.0, 50.0]]) * _MM

_ARRAY_SHAPES = {"P": (3, 4), "U": (3, 4), "DB": (3, 4), "DC": (3, 2)}
_POSITIVE = ("r", "l", "half_width", "kc", "E", "I", "G", "I0", "Sb", "Eb", "ball_radius")


def _default(array: np.ndarray) -> Any:
    return dataclasses.field(default_factory=lambda: array.copy())


@dataclasses.dataclass(frozen=True, eq=False)
class H4Params:
    """Geometry and stiffness data of an H4 robot, in SI units (m, rad, N, Pa).

    Every field can be changed (``dataclasses.replace(params, half_width=0.02)``); the result is
    validated again. Arrays are stored as read-only float64 copies.

    Attributes:
        P: (3, 4) m. A point P_i of each actuator axis (paper, V.A; P_1 sign typo fixed).
        U: (3, 4) unit, horizontal. Actuator axis directions u_i (paper, V.A).
        r: m. Forearm length, P_i to A_i (paper: 260 mm).
        l: m. Bar length, A_ij to B_ij (paper: 480 mm).
        DB: (3, 4) m. Vector D -> B_i at theta = 0 (paper: DB_nominal).
        DC: (3, 2) m. Vector D -> C_k at theta = 0. Not in the paper: (0, -+60, 50) mm, the
            middle of each lateral bar.
        half_width: m. Half the width h of each parallelogram: A_ij = A_i +- h u_i (j = 1 is +).
            Not in the paper: 40 mm; below 60 mm (ball joints of legs 1 and 4 would collide), and
            between 20 and 60 mm the compliance changes by under 2 %.
        kc: N.m/rad. Actuator control stiffness (paper: 7.4e6 N.mm per radian).
        E: Pa. Young's modulus of the forearms (paper: 70 000 N/mm^2, aluminium).
        I: m^4. Second moment of area of the forearm section (paper: 1.6e4 mm^4).
        G: Pa. Shear modulus of the forearms (paper: 0.4 E).
        I0: m^4. Polar moment of the forearm section (paper: 2 I).
        Sb: m^2. Section of a bar (paper: 28 mm^2).
        Eb: Pa. Young's modulus of the bars (paper: 200 000 N/mm^2).
        forearm_stressed_fraction: Fraction phi of the forearm length that bends and twists.
            Default 1, as in the paper's numbers (eq. 30 uses the full r). The paper remarks that
            only 2/3 of the prototype's forearms are stressed; with phi < 1 the stressed part is
            the outer phi*r of the forearm, clamped on a rigid hub, which scales the bending
            compliance by phi^3 and the torsion compliance by phi.
        ball_radius: m. Radius of the ball joints, used for drawing and for the collision check
            of the half-width (plate-side ball centres of different legs must be at least two
            radii apart). Not in the paper: 5 mm.
    """

    P: np.ndarray = _default(_P)
    U: np.ndarray = _default(_U)
    r: float = 260.0 * _MM
    l: float = 480.0 * _MM
    DB: np.ndarray = _default(_DB)
    DC: np.ndarray = _default(_DC)
    half_width: float = 40.0 * _MM
    kc: float = 7.4e6 * _MM
    E: float = 70_000.0e6
    I: float = 1.6e4 * _MM**4  # noqa: E741 (the paper's name)
    G: float = 0.4 * 70_000.0e6
    I0: float = 2 * 1.6e4 * _MM**4
    Sb: float = 28.0 * _MM**2
    Eb: float = 200_000.0e6
    forearm_stressed_fraction: float = 1.0
    ball_radius: float = 5.0 * _MM

    def __post_init__(self) -> None:
        for name, shape in _ARRAY_SHAPES.items():
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != shape:
                raise ParameterError(f"{name} must have shape {shape}, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ParameterError(f"{name} has non-finite entries: {value.tolist()}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        for name in (*_POSITIVE, "forearm_stressed_fraction"):
            raw = getattr(self, name)
            try:
                value = float(raw)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} must be a real number, got {raw!r}") from None
            if not np.isfinite(value) or value <= 0.0:
                raise ParameterError(f"{name} must be finite and > 0, got {value!r}")
            object.__setattr__(self, name, value)
        if self.forearm_stressed_fraction > 1.0:
            raise ParameterError(
                f"forearm_stressed_fraction must be in (0, 1], got {self.forearm_stressed_fraction!r}"
            )
        norms = np.linalg.norm(self.U, axis=0)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            raise ParameterError(f"U columns must be unit vectors, got norms {norms.tolist()}")
        if np.any(np.abs(self.U[2]) > 1e-9):
            raise ParameterError(f"U columns must be horizontal (u_z = 0), got u_z = {self.U[2].tolist()}")
        a = np.cross(self.U.T, [0.0, 0.0, 1.0]).T
        a.setflags(write=False)
        object.__setattr__(self, "_forearm_dirs", a)
        self._check_ball_joints()

    def _check_ball_joints(self) -> None:
        """Refuse a half-width for which plate-side ball joints of two legs overlap."""
        b = self.plate_ball_centres()  # (4, 2, 3), at theta = 0
        for i in range(4):
            for i2 in range(i + 1, 4):
                gap = np.min(np.linalg.norm(b[i][:, None, :] - b[i2][None, :, :], axis=-1))
                if gap < 2 * self.ball_radius:
                    raise ParameterError(
                        f"half_width = {self.half_width * 1e3:.1f} mm makes the ball joints of legs "
                        f"{i + 1} and {i2 + 1} collide on the plate (centres {gap * 1e3:.1f} mm apart, "
                        f"ball_radius = {self.ball_radius * 1e3:.1f} mm)"
                    )

    def plate_ball_centres(self) -> np.ndarray:
        """B_ij - D at theta = 0, shape (4, 2, 3), in m (j = 1 is B_i + h u_i)."""
        signs = np.array([1.0, -1.0])
        return self.DB.T[:, None, :] + signs[None, :, None] * self.half_width * self.U.T[:, None, :]

    @property
    def forearm_dirs(self) -> np.ndarray:
        """a_i = u_i x z, the forearm directions at q = 0, shape (3, 4) (computed once)."""
        return self._forearm_dirs

    def compliances(self) -> dict[str, float]:
        """The four spring compliances of eq. 30, SI: control 1/kc, bending phi^3 r/(3EI) and
        torsion phi r/(G I0) (rad/(N.m)), tension l/(Sb Eb) (m/N)."""
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

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, H4Params):
            return NotImplemented
        return all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
        )

    __hash__ = None  # type: ignore[assignment]


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


#: Named variants shipped as URDF files in ``urdf/h4_<name>.urdf``.
VARIANTS = {
    "prototype": H4Params,
    "symmetric": symmetric_params,
}
