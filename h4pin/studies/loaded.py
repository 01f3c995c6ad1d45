# SPDX-License-Identifier: Apache-2.0
"""The H4 under its own weight and a payload: the sag of its tool (D), how the load changes its
compliance, and the actuator angles that compensate the sag along the pick-and-place cycle.

Each pose is the elastic H4 (:func:`h4pin.elastic_model`, every compliance of eq. 30 a virtual
spring, the URDF's link inertias) as a :class:`~h4pin.mechanism.Mechanism`
(:attr:`ElasticH4.mechanism <h4pin.elastic.h4.ElasticH4.mechanism>`), its actuators held at the
pose's angles, in the non-linear equilibrium of :meth:`Mechanism.equilibrium
<h4pin.mechanism.Mechanism.equilibrium>` under gravity (``model.gravity``, 9.81 m/s² down) and a
point payload at D. See ``docs/loaded.md``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from tqdm import tqdm

from h4pin import limits
from h4pin.errors import H4Error, ParameterError
from h4pin.kinematics import closed_form as geometry
from h4pin.mechanism import Payload
from h4pin.robot import H4

#: Seconds an equilibrium of the elastic H4 takes (measured about 0.2 s on this 2-core machine;
#: its tangent is 44 central differences of Pinocchio's forces): for the size estimates.
SECONDS_PER_POSE = 0.3


def _payload(kg: float) -> tuple[str, Payload] | None:
    kg = float(limits.check_range("payload", kg, "payload"))
    if not kg >= 0:
        raise ParameterError(f"payload: a mass >= 0 (kg), got {kg!r}")
    return ("D", Payload(kg)) if kg > 0 else None


@dataclasses.dataclass(frozen=True)
class Sag:
    """The loaded H4 at poses (:func:`sag`).

    Attributes:
        poses: (N, 4) [x, y, z, theta] (m, rad). payload: kg at D.
        displacement: (N, 6) D's motion from the unloaded pose, ``[dp; dθ]`` (m, rad), world axes;
            NaN where the pose is refused (``status``).
        linear: (N, 3, 3) K_tt of the unloaded robot (m/N; the elastic model's, ``consistent``).
        tangent: (N, 3, 3) the tangent K_tt under the load (m/N).
        status: (N,) 0 computed; 1 the pose is unreachable or singular.
    """

    poses: np.ndarray
    payload: float
    displacement: np.ndarray
    linear: np.ndarray
    tangent: np.ndarray
    status: np.ndarray

    @property
    def change(self) -> np.ndarray:
        """(N,) the largest change of the tangent K_tt from the linear one, over its largest entry."""
        return np.max(np.abs(self.tangent - self.linear), axis=(1, 2)) / np.max(np.abs(self.linear), axis=(1, 2))


def sag(h4: H4, poses: Any, payload: float = 0.0, *, progress: bool = False) -> Sag:
    """D's sag under the robot's weight and ``payload`` kg at D, and the loaded tangent K_tt, at
    each pose (N, 4) (or one (4,)), by the elastic model's equilibrium (module docstring).

    Raises:
        ParameterError: a bad pose array or payload. TooLargeError: too many poses for the limits.
    """
    from h4pin.elastic import elastic_model

    x = np.atleast_2d(geometry.as_poses(poses))
    pay = _payload(payload)
    limits.check_size(f"sag at {len(x):,} poses", len(x) * 512.0, len(x) * SECONDS_PER_POSE)
    em = elastic_model(h4)
    mech = em.mechanism
    n = len(x)
    out = {"displacement": np.full((n, 6), np.nan), "linear": np.full((n, 3, 3), np.nan),
           "tangent": np.full((n, 3, 3), np.nan)}
    status = np.ones(n, dtype=np.int8)
    for i in tqdm(range(n), desc="sag", unit="pose", disable=not progress):
        try:
            q = em.configuration(x[i])
            eq = mech.equilibrium(q, {}, gravity=True, payload=pay, locked=em.locked)
            out["linear"][i] = mech.compliance(q, {}, ["D"], em.locked)[:3, :3]
        except H4Error:
            continue
        out["displacement"][i] = eq.displacement("D")
        out["tangent"][i] = eq.compliance(["D"])[:3, :3]
        status[i] = 0
    return Sag(x, float(payload), out["displacement"], out["linear"], out["tangent"], status)


def sag_map(h4: H4, x: Any, y: Any, z: float, theta: float = 0.0, payload: float = 0.0, *,
            progress: bool = True) -> Any:
    """:func:`sag` over the x-y grid at height z and rotation theta: an :class:`xarray.Dataset` with
    ``sag`` (y, x, xyz) m, ``sag_norm`` (y, x) m, ``change`` (y, x) (:attr:`Sag.change`) and
    ``status`` (y, x)."""
    import xarray as xr

    xs, ys = (np.atleast_1d(np.asarray(v, float)) for v in (x, y))
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    poses = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, float(z)), np.full(xx.size, float(theta))])
    res = sag(h4, poses, payload, progress=progress)
    shape = (len(ys), len(xs))
    d = res.displacement[:, :3].reshape(*shape, 3)
    return xr.Dataset(
        {"sag": (("y", "x", "xyz"), d, {"units": "m", "long_name": "D's displacement under the load"}),
         "sag_norm": (("y", "x"), np.linalg.norm(d, axis=-1), {"units": "m", "long_name": "|sag of D|"}),
         "change": (("y", "x"), res.change.reshape(shape), {"units": "1",
                                                           "long_name": "largest change of K_tt under the load"}),
         "status": (("y", "x"), res.status.reshape(shape), {"units": "1", "long_name": "0 computed, 1 refused"})},
        coords={"x": ("x", xs, {"units": "m"}), "y": ("y", ys, {"units": "m"})},
        attrs={"z": float(z), "theta": float(theta), "payload_kg": float(payload), "h4pin": "sag_map"})


def loaded_report(h4: H4, payload: float = 0.0) -> str:
    """Text: the sag of D at Table II's pose (all actuators at 45 deg) under the robot's weight and
    ``payload`` kg at D, and the loaded (tangent) K_tt beside the unloaded one, um/N."""
    from h4pin.kinematics.closed_form import centre_pose

    s = sag(h4, centre_pose(h4), payload)
    if s.status[0]:
        return "under its own weight: the pose is refused (unreachable or singular)"
    d = s.displacement[0]
    lines = [f"under its own weight{f' and {payload:g} kg at D' if payload else ''} (loaded equilibrium of the "
             f"elastic model): D sags by ({d[0] * 1e6:.1f}, {d[1] * 1e6:.1f}, {d[2] * 1e6:.1f}) um, turns by "
             f"({d[3] * 1e6:.1f}, {d[4] * 1e6:.1f}, {d[5] * 1e6:.1f}) urad",
             f"{'K_tt [um/N]':<22}{'unloaded':>30}{'loaded (tangent)':>32}"]
    for i, axis in enumerate("xyz"):
        row = "".join(f"{v * 1e6:10.2f}" for v in s.linear[0, i]) + "  " + \
            "".join(f"{v * 1e6:10.2f}" for v in s.tangent[0, i])
        lines.append(f"  d{axis}{'':<18}{row}")
    lines.append(f"largest change of K_tt under the load: {s.change[0] * 100:.3f} % (the consistent model's, "
                 "elastic route; docs/loaded.md)")
    return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class CompensatedCycle:
    """The pick-and-place cycle under the robot's weight and a payload, quasi-static
    (:func:`compensated_cycle`).

    Attributes:
        t: (N,) s. poses: (N, 4) the cycle's poses (the targets).
        rigid: (N, 4) the rigid inverse's actuator angles (rad).
        motors: (N, 4) the compensated actuator angles (rad).
        sag: (N, 3) D's error from the target at the rigid inverse under the load (m).
        error: (N, 3) D's error at the compensated angles (m).
    """

    t: np.ndarray
    poses: np.ndarray
    payload: float
    rigid: np.ndarray
    motors: np.ndarray
    sag: np.ndarray
    error: np.ndarray


def compensated_cycle(h4: H4, period: float = 0.5, payload: float = 0.5, *, samples: int = 40,
                      progress: bool = False, **cycle: Any) -> CompensatedCycle:
    """The actuator angles that put D on the pick-and-place cycle's path (:func:`h4pin.studies.cycle.adept_cycle`,
    its options ``cycle``) under the robot's weight and ``payload`` kg at D, at ``samples`` equal
    steps, quasi-static (no inertia: the sag a slow pass would show), by
    :meth:`Mechanism.compensate <h4pin.mechanism.Mechanism.compensate>` from each pose's rigid
    inverse."""
    from h4pin.elastic import elastic_model
    from h4pin.studies.cycle import adept_cycle

    pay = _payload(payload)
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 10_000:
        raise ParameterError(f"samples: an integer from 1 to 10000, got {samples!r}")
    limits.check_size(f"compensated cycle of {samples:,} samples", samples * 1024.0, samples * 4 * SECONDS_PER_POSE)
    c = adept_cycle(h4, period, **cycle)
    t = c.times(samples)[:-1]
    poses = c.sample(t)[0]
    em = elastic_model(h4)
    out = {k: np.empty((samples, n)) for k, n in (("rigid", 4), ("motors", 4), ("sag", 3), ("error", 3))}
    for i in tqdm(range(samples), desc="compensated cycle", unit="pose", disable=not progress):
        comp = em.mechanism.compensate({"D": poses[i, :3]}, {}, gravity=True, payload=pay, locked=em.locked,
                                       start=em.configuration(poses[i]))
        for k in out:
            out[k][i] = getattr(comp, k)
    return CompensatedCycle(t, poses, float(payload), out["rigid"], out["motors"], out["sag"], out["error"])


__all__ = ["SECONDS_PER_POSE", "CompensatedCycle", "Sag", "compensated_cycle", "loaded_report", "sag", "sag_map"]
