# SPDX-License-Identifier: Apache-2.0
"""What h4pin refuses before it starts: sizes that do not fit, values that are not physical.

Sizes (project issue 30, "impossible sizes are not estimated"). Every call that allocates per
pose, design, robot or sample estimates its bytes (and its time, from a rate measured once on a
2-core x86-64 machine, stated beside each rate) *before* it allocates, and refuses a job over the
limits with a :class:`TooLargeError` in one line that names the size, the estimate and the limit:

* memory: ``H4PIN_MEMORY_LIMIT`` (bytes, or a number with a unit: ``512MiB``, ``8GiB``, ``8G``,
  ``1.5e9``; ``0`` or ``none``: no limit); default :data:`MEMORY_FRACTION` of the memory
  available now (``MemAvailable`` of ``/proc/meminfo``, else ``os.sysconf``; no limit where
  neither says).
* time: ``H4PIN_TIME_LIMIT`` (seconds, or a number with ``s``, ``min``, ``h``, ``d``); none by
  default (a long sweep or atlas is legitimate and resumable); the estimate is in the message of
  a memory refusal either way.

The costs per unit are here for :func:`h4pin.compliance`, the natural frequencies and the cycle,
and beside their study for the atlas (``h4pin.studies.atlas.BYTES_PER_POSE``, ``check_memory``),
the sweep (``BYTES_PER_DESIGN``, ``check_size``) and the tolerance study (``BYTES_PER_ROBOT``,
``BYTES_PER_PAIR``, ``check_size``).

Plausible ranges (issue 30, "absurd values pass silently"): :data:`RANGES` below, SI units, and
:data:`SPRING_RANGES` for the spring data of a robot (:func:`check_springs`). A value outside
its range is a :class:`ImplausibleValueError` naming the value and the range; a result that
comes out non-finite from values inside them is a :class:`NonFiniteResultWarning`.

=================  ======================  ==================================================
name               range                   why
=================  ======================  ==================================================
load               abs(F) <= 1e6 N         a force component at D (100 t): far past any H4
torque             abs(T) <= 1e5 N.m       a torque component at D
payload            0 to 1e3 kg             a point mass at D (the robot's plate is ~1 kg)
exaggeration       0 < e <= 1e6            factor on a drawn deflection (um to m)
scale              1e-9 to 1e9             ellipsoid scale of the viewer, mm per um/N
cycle time         1e-3 to 1e6 s           one pick-and-place cycle (the paper's is 0.5 s)
stroke             0 to 10 m               a cycle's stroke length or height (the paper's: 305
                                           mm across, 25 mm up); its centre within 10 m of the base
tool offset        abs(o) <= 10 m          a tool point from D (the elastic cycle's ``tool``)
damping            0 to 1 s                the elastic cycle's stiffness-proportional damping
                                           (1e-4 s: 1 % at 32.7 Hz; 1 s damps any mode to a crawl)
stiffness          1e-6 to 1e25            kc (N.m/rad), E, G, Eb (Pa); a near-rigid stand-in
                                           (1e9 x steel, as the identification's limits use) passes
second moment      1e-24 to 1e3 m^4        I, I0 of the forearm section (same: a stand-in passes)
section            1e-12 to 1 m^2          Sb of a bar
stressed fraction  1e-6 to 1               forearm_stressed_fraction
com offset         abs(c) <= 10 m          a payload's centre of mass from D (the robot spans ~1 m)
payload inertia    0 to 1e3 kg.m^2         a payload's principal moments
element m/N        0, or 1e-15 to 1e-2     a joint's or mount's compliance (0: off); 10 mm/N is
                                           a rubber mount, 1e-15 a near-rigid stand-in
element rad/(N.m)  0, or 1e-15 to 1        a shaft's or mount's rotational compliance (0: off)
element N.m^2      1e-6 to 1e12, or inf    a link's EI or GJ (inf: rigid, off); 1e12 is a steel
                                           beam a metre deep, 1e-6 a strand of hair
robot length       abs(x) <= 1e3 m         a position in a robot file (a URDF origin, an MJCF
                                           pos or anchor): a kilometre is past any robot, and
                                           1e308 overflows every product with it
motor angle        abs(a) <= 20 pi rad     a revolute motor's position on a grid or in an
                                           assembly: ten turns either way
motor travel       abs(s) <= 10 m          a prismatic motor's position
timestep           1e-9 to 0.1 s           a MuJoCo time step (the elastic export's default is
                                           5e-5 s, MuJoCo's 2e-3 s)
=================  ======================  ==================================================

:data:`BEAM_RANGES` holds a flexible link's (:class:`h4pin.mechanism.Beam`) section and material,
SI: ``E`` and ``G`` 1e-6 to 1e25 Pa (as the spring data's E and G: a near-rigid stand-in passes),
``A`` 1e-12 to 1e2 m^2, ``Iy``, ``Iz`` and ``J`` 1e-24 to 1e4 m^4 (``inf``: rigid that way), and
the sizes of :meth:`~h4pin.mechanism.Beam.circle`, ``tube`` and ``rect`` (``d``, ``t``, ``b``,
``h``) 1e-5 to 10 m (a wire of ten microns to a girder of ten metres, whose sections fall within
the ranges above): a value of 1e-308 or 1e308 there makes the compliance fail in its linear
algebra, a size of 1e200 overflows the section's fourth powers.

Counts that are capped rather than refused: ``threads`` of a batch beyond :data:`MAX_THREADS`
(a :class:`CappedWarning` says so).

:data:`ELEMENT_RANGES` holds the element rows, by the kind's unit (checked by
:func:`h4pin.description.elements.check_elements`: making :class:`h4pin.Elements`, reading a URDF,
unpickling a robot).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from h4pin.errors import ParameterError
from h4pin.inputs import short

#: Share of the available memory a job may plan to use when ``H4PIN_MEMORY_LIMIT`` is not set.
MEMORY_FRACTION = 0.8
MEMORY_ENV = "H4PIN_MEMORY_LIMIT"
TIME_ENV = "H4PIN_TIME_LIMIT"
GiB = 2**30


class TooLargeError(ParameterError):
    """A job whose estimated memory (or time) is over the limit (:mod:`h4pin.limits`); the
    message names the size, the estimate and the limit, and how to raise it."""


class ImplausibleValueError(ParameterError):
    """A value outside its stated plausible range (:data:`h4pin.limits.RANGES`); the message
    names the value and the range."""


class CappedWarning(UserWarning):
    """A count over its maximum (``threads``) was capped to it; the message names both."""


class NonFiniteResultWarning(RuntimeWarning):
    """Values inside their ranges gave a result that is not finite (or a frequency of 0 Hz)."""


# ----------------------------------------------------------------------------------------------
# Sizes

_UNITS = {"": 1, "b": 1, "k": 10**3, "kb": 10**3, "kib": 2**10, "m": 10**6, "mb": 10**6, "mib": 2**20,
          "g": 10**9, "gb": 10**9, "gib": 2**30, "t": 10**12, "tb": 10**12, "tib": 2**40}
_SECONDS = {"": 1, "s": 1, "min": 60, "h": 3600, "d": 86400}


def _parse(text: str, units: dict[str, float], env: str, what: str) -> float | None:
    t = text.strip().lower().replace(" ", "")
    if t in ("", "none", "off", "inf", "unlimited") or re.fullmatch(r"0*\.?0*(e[+-]?[0-9]+)?", t) and "0" in t:
        return None  # 0, 0.0, 0e0: no limit
    m = re.fullmatch(r"([0-9.]+(?:e[+-]?[0-9]+)?)([a-z]*)", t)
    if m is None or m.group(2) not in units:
        raise ParameterError(f"{env} must be {what}, got {text!r}")
    try:
        value = float(m.group(1)) * units[m.group(2)]
    except ValueError:
        raise ParameterError(f"{env} must be {what}, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"{env} must be {what}, got {text!r}")
    return value


def available_memory() -> int | None:
    """Bytes of memory available now (``MemAvailable``, else free pages), or None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def memory_limit() -> tuple[float | None, str]:
    """The memory limit in bytes (None: none) and where it comes from, for a message."""
    text = os.environ.get(MEMORY_ENV)
    if text is not None:
        return _parse(text, _UNITS, MEMORY_ENV, "bytes, or a number with a unit (e.g. 8GiB), or 0 for none"), \
            f"{MEMORY_ENV}={text.strip()}"
    avail = available_memory()
    if avail is None:
        return None, "unknown memory"
    return MEMORY_FRACTION * avail, f"{MEMORY_FRACTION:.0%} of the {fmt_bytes(avail)} available"


def time_limit() -> float | None:
    """The time limit in seconds (``H4PIN_TIME_LIMIT``), or None (the default: none)."""
    text = os.environ.get(TIME_ENV)
    return None if text is None else _parse(text, _SECONDS, TIME_ENV, "seconds, or a number with s, min, h or d")


def fmt_bytes(n: float) -> str:
    """``n`` bytes for a message: ``1.5 GiB``, ``3.0 EiB``."""
    for unit, size in (("EiB", 2**60), ("PiB", 2**50), ("TiB", 2**40), ("GiB", 2**30)):
        if n >= size:
            return f"{n / size:.1f} {unit}" if n < 1e6 * size else f"{n / size:.3g} {unit}"
    return f"{n / 2**20:.1f} MiB"


def fmt_seconds(s: float) -> str:
    """``s`` seconds for a message: ``40 s``, ``3.2 h``, ``2.0e+04 years``."""
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    if s < 2 * 86400:
        return f"{s / 3600:.1f} h"
    if s < 365 * 86400:
        return f"{s / 86400:.0f} days"
    return f"{s / (365 * 86400):.2g} years"


def fmt_count(n: int) -> str:
    """A count for a message: ``12,345``, or ``1.6e+302`` once it has more than 15 digits (past
    the floats: ``over 1e+308``)."""
    if n < 10**15:
        return f"{n:,}"
    return f"{float(n):.3g}" if n < 10**308 else "over 1e+308"


def check_size(what: str, need: float, seconds: float | None = None, hint: str = "") -> None:
    """Refuse a job of ``need`` bytes (and ``seconds``, estimated) over the memory or the time
    limit, in one line: ``what`` (e.g. "sweep --designs: 10,000,000,000 designs") names the size.

    Raises:
        TooLargeError: over a limit; the message says how to raise it.
    """
    limit, source = memory_limit()
    took = f" and about {fmt_seconds(seconds)}" if seconds is not None else ""
    hint = f"; {hint}" if hint else ""
    if limit is not None and need > limit:
        raise TooLargeError(f"{what} would need about {fmt_bytes(need)} of memory{took}, over the limit of "
                            f"{fmt_bytes(limit)} ({source}; raise it with {MEMORY_ENV}, e.g. {MEMORY_ENV}=64GiB){hint}")
    tl = time_limit()
    if tl is not None and seconds is not None and seconds > tl:
        raise TooLargeError(f"{what} would take about {fmt_seconds(seconds)}, over the time limit of {fmt_seconds(tl)} "
                            f"({TIME_ENV}={os.environ.get(TIME_ENV, '').strip()}; raise or unset it){hint}")


#: The largest count an estimate takes (a larger one is over any limit anyway, and stays a float).
MAX_COUNT = 10**300


def count(value: Any) -> int:
    """An integer count for an estimate, at most :data:`MAX_COUNT` (0 for something that is not
    one: its own check refuses it)."""
    try:
        return min(MAX_COUNT, max(0, int(value)))
    except (TypeError, ValueError, OverflowError):
        return 0


# ----------------------------------------------------------------------------------------------
# Bytes and rates per unit of work (measured with tracemalloc and time.perf_counter, numba
# compiled, on the 2-core x86-64 machine of the project; rounded up: an estimate refuses only what
# cannot fit)

#: h4pin.compliance, per pose: the pose copy (32), K (512), q (32), condition and status (9),
#: the Compliance's own arrays (~100); measured 612 bytes a pose over 50,000 poses. Terms: 512
#: bytes a term a pose.
COMPLIANCE_BYTES_PER_POSE = 700
COMPLIANCE_BYTES_PER_TERM = 512
#: Compiled pipeline: measured 7.1e5 poses/s over 200,000 poses on 2 cores; rounded down.
COMPLIANCE_POSES_PER_S = 5e5
#: Natural frequencies of a batch of poses (vibration.modes, compiled): the pose (32), the
#: pipeline's intermediates (NX = 332 floats: 2,656), K, q (544), the frequencies (96 floats: 768),
#: counts and status (17), the grid's coordinates (~100); measured 4,041 bytes and 2.3e4 poses/s
#: over 20,000 poses on 2 cores.
MODES_BYTES_PER_POSE = 4200
MODES_POSES_PER_S = 2e4


#: The cycle (h4pin.studies.cycle.run), per sample: its Pinocchio state, closed-loop dynamics,
#: load, K and the vibration's matrices; measured 12,045 bytes and 637 samples/s over 4,000
#: samples on 2 cores.
CYCLE_BYTES_PER_SAMPLE = 12_500
CYCLE_SAMPLES_PER_S = 500.0


#: The elastic cycle (h4pin.studies.elastic_cycle.run), per sample of the motion: its springs'
#: mass, velocity and stiffness matrices (16 x 16 each), output map and loads (about 7 kB; 10 kB
#: with the Newmark work), at about 70 samples/s on this machine (rounded down: 50); per sample of
#: the stop after it: the same arrays repeated, integrated at about 1e4 samples/s (5e3).
ELASTIC_BYTES_PER_SAMPLE = 10_000
ELASTIC_SAMPLES_PER_S = 50.0
ELASTIC_STOP_SAMPLES_PER_S = 5e3


def check_elastic_cycle(samples: int, stop: int, payloads: int = 1) -> None:
    """Refuse an elastic cycle of ``samples`` motion samples and ``stop`` samples of the stop
    after it (for ``payloads`` payloads, one after the other) that does not fit in memory or
    time (:func:`check_size`)."""
    n, m = count(samples), count(stop)
    check_size(f"elastic cycle: {fmt_count(n)} samples and {fmt_count(m)} of the stop",
               (n + m + 1) * ELASTIC_BYTES_PER_SAMPLE,
               payloads * (n / ELASTIC_SAMPLES_PER_S + m / ELASTIC_STOP_SAMPLES_PER_S),
               "use fewer samples or a shorter hold, or a longer cycle time (the stop is sampled at the cycle's step)")


def check_cycle_samples(samples: int, payloads: int = 1) -> None:
    """Refuse a cycle of ``samples`` time steps (for ``payloads`` payloads, one after the other)
    that does not fit in memory (:data:`CYCLE_BYTES_PER_SAMPLE`, :func:`check_size`)."""
    n = count(samples)
    check_size(f"cycle: {n:,} samples", (n + 1) * CYCLE_BYTES_PER_SAMPLE, payloads * n / CYCLE_SAMPLES_PER_S,
               "use fewer samples (--samples)")


# ----------------------------------------------------------------------------------------------
# Plausible ranges

#: name -> (low, high, unit, what): the stated plausible range of a value (module docstring).
RANGES: dict[str, tuple[float, float, str, str]] = {
    "load": (-1e6, 1e6, "N", "a force component at D"),
    "torque": (-1e5, 1e5, "N.m", "a torque component at D"),
    "payload": (0.0, 1e3, "kg", "a point payload at D"),
    "com offset": (-10.0, 10.0, "m", "a payload's centre of mass from D"),
    "payload inertia": (0.0, 1e3, "kg.m^2", "a payload's principal moments"),
    "exaggeration": (1e-300, 1e6, "", "a factor on the drawn deflection"),
    "scale": (1e-9, 1e9, "mm per um/N", "the ellipsoid scale"),
    "cycle_time": (1e-3, 1e6, "s", "the cycle time"),
    "stroke": (0.0, 10.0, "m", "a cycle's stroke length or height"),
    "stroke centre": (-10.0, 10.0, "m", "a cycle's centre from the base"),
    "tool offset": (-10.0, 10.0, "m", "a tool point's offset from D"),
    "damping": (0.0, 1.0, "s", "stiffness-proportional damping (1e-4 s: 1 % at 32.7 Hz)"),
    "robot length": (-1e3, 1e3, "m", "a position in a robot file"),
    "motor angle": (-20 * math.pi, 20 * math.pi, "rad", "a revolute motor's position (ten turns either way)"),
    "motor travel": (-10.0, 10.0, "m", "a prismatic motor's position"),
    "timestep": (1e-9, 0.1, "s", "a MuJoCo time step"),
}
#: A flexible link's section and material (:class:`h4pin.mechanism.Beam`): name -> (low, high,
#: unit, what); ``inf`` (rigid) is allowed where :class:`~h4pin.mechanism.Beam` allows it.
BEAM_RANGES: dict[str, tuple[float, float, str, str]] = {
    "E": (1e-6, 1e25, "Pa", "a Young's modulus"), "G": (1e-6, 1e25, "Pa", "a shear modulus"),
    "A": (1e-12, 1e2, "m^2", "a section's area"), "Iy": (1e-24, 1e4, "m^4", "a second moment of area"),
    "Iz": (1e-24, 1e4, "m^4", "a second moment of area"), "J": (1e-24, 1e4, "m^4", "a torsion constant"),
    "d": (1e-5, 10.0, "m", "a section's size"), "t": (1e-5, 10.0, "m", "a section's size"),
    "b": (1e-5, 10.0, "m", "a section's size"), "h": (1e-5, 10.0, "m", "a section's size"),
}
#: The most threads a batch runs on; more are capped to it, with a :class:`CappedWarning`.
MAX_THREADS = 256
#: Plausible ranges of the element data (:class:`h4pin.Elements`) by unit; 0 (a compliance) and
#: inf (a rigidity) switch an element off and are always allowed.
ELEMENT_RANGES: dict[str, tuple[float, float]] = {"m/N": (1e-15, 1e-2), "rad/(N.m)": (1e-15, 1.0),
                                                  "N.m^2": (1e-6, 1e12)}
#: Spring datum (h4pin.H4Params / URDF field) -> (low, high, unit).

SPRING_RANGES: dict[str, tuple[float, float, str]] = {
    "kc": (1e-6, 1e25, "N.m/rad"), "E": (1e-6, 1e25, "Pa"), "G": (1e-6, 1e25, "Pa"), "Eb": (1e-6, 1e25, "Pa"),
    "I": (1e-24, 1e3, "m^4"), "I0": (1e-24, 1e3, "m^4"), "Sb": (1e-12, 1.0, "m^2"),
    "forearm_stressed_fraction": (1e-6, 1.0, "1"),
}


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""


def check_range(name: str, value: Any, kind: str) -> Any:
    """``value`` (a number or numbers) if every one is finite and within :data:`RANGES` ``[kind]``;
    else an :class:`ImplausibleValueError` naming ``name``, the value and the range."""
    lo, hi, unit, what = RANGES[kind]
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ImplausibleValueError(f"{name} must be a number{_unit(unit)}, got {short(value)}") from None
    bad = ~(np.isfinite(arr) & (arr >= lo) & (arr <= hi))
    if np.any(bad):
        v = float(arr.reshape(-1)[int(np.argmax(bad.reshape(-1)))])
        span = f"({0:g}, {hi:g}]" if kind == "exaggeration" else f"[{lo:g}, {hi:g}]"
        raise ImplausibleValueError(f"{name} = {v:g}{_unit(unit)} is outside the plausible range {span}{_unit(unit)} "
                                    f"of {what} (h4pin.limits.RANGES)")
    return value


def check_beam(name: str, value: float, where: str = "Beam") -> float:
    """``value`` if within :data:`BEAM_RANGES` ``[name]`` (or ``inf`` where a rigid section is
    allowed: the caller's check); else an :class:`ImplausibleValueError` naming it and the range."""
    lo, hi, unit, what = BEAM_RANGES[name]
    if not (lo <= value <= hi or value == math.inf):
        raise ImplausibleValueError(f"{where}: {name} = {value:g} {unit} is outside the plausible range [{lo:g}, "
                                    f"{hi:g}] {unit} of {what} (h4pin.limits.BEAM_RANGES)")
    return value


def check_threads(threads: Any, default: int) -> int:
    """``threads`` as a count: ``default`` for None; an integer >= 1 (not a bool), capped to
    :data:`MAX_THREADS` with a :class:`CappedWarning`; else a :class:`ParameterError`."""
    if threads is None:
        return default
    if isinstance(threads, (bool, np.bool_)) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ParameterError(f"threads: a count, an integer >= 1 (default: one per core), got {short(threads)}")
    if threads > MAX_THREADS:
        import warnings

        warnings.warn(f"threads = {fmt_count(int(threads))} capped to {MAX_THREADS} (h4pin.limits.MAX_THREADS)",
                      CappedWarning, stacklevel=3)
        return MAX_THREADS
    return int(threads)


def check_springs(springs: Mapping[str, Any] | Any, where: str = "springs") -> None:
    """Refuse spring data outside :data:`SPRING_RANGES`: ``springs`` is a dict of H4Params field
    -> value(s), or a robot (an :class:`h4pin.H4` or a geometry, its ``springs``; an
    :class:`h4pin.H4Params`, its fields). Names outside the table, and values that are not numbers,
    are left to their own checks."""
    if not isinstance(springs, Mapping):
        geometry = getattr(springs, "geometry", springs)  # an H4's geometry, or a geometry itself
        if isinstance(getattr(geometry, "springs", None), Mapping):
            springs = geometry.springs
        else:  # an H4Params (its fields), or anything else (nothing to check)
            springs = {name: getattr(springs, name) for name in SPRING_RANGES if hasattr(springs, name)}
    for name, (lo, hi, unit) in SPRING_RANGES.items():
        if name not in springs:
            continue
        try:
            arr = np.asarray(springs[name], dtype=float).reshape(-1)
        except (TypeError, ValueError):
            continue  # not numbers: the robot's own check names it
        bad = ~(np.isfinite(arr) & (arr >= lo) & (arr <= hi))
        if np.any(bad):
            v = float(arr[int(np.argmax(bad))])
            raise ImplausibleValueError(f"{where}: spring datum '{name}' = {v:g} {unit} is outside the plausible range "
                                        f"[{lo:g}, {hi:g}] {unit} (h4pin.limits.SPRING_RANGES)")


def warn_non_finite(what: str, bad: int, total: int, hint: str = "") -> None:
    """Warn (:class:`NonFiniteResultWarning`) that ``bad`` of ``total`` results of ``what`` are not
    finite although their inputs are within range."""
    if bad:
        import warnings

        warnings.warn(f"{what}: {bad:,} of {total:,} results are not finite{'; ' + hint if hint else ''}",
                      NonFiniteResultWarning, stacklevel=3)


__all__ = ["BEAM_RANGES", "ELEMENT_RANGES", "MAX_THREADS", "CappedWarning", "GiB", "ImplausibleValueError",
           "MEMORY_ENV", "MEMORY_FRACTION", "NonFiniteResultWarning", "RANGES", "SPRING_RANGES", "TIME_ENV",
           "TooLargeError", "available_memory", "check_beam", "check_cycle_samples", "check_elastic_cycle",
           "check_range", "check_size", "check_springs", "check_threads", "fmt_bytes", "fmt_count", "fmt_seconds",
           "memory_limit", "time_limit", "warn_non_finite"]
