#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Speed of h4pin's compliance and natural frequencies, printed as a table (nothing here is
asserted by the tests).

Rows: the numpy batch path (eq. 30 with the inverse geometry), the compiled pipeline
(:mod:`h4pin.stiffness.pipeline`: batch on 1 and 2 threads, one pose, with terms, a robot with all
12 element kinds), the Pinocchio route, a straightforward per-pose numpy implementation of eq. 30
(loops, np.cross, explicit inverses: what one writes first; that code compiled by numba, and the
same math written for speed by hand, bare calls of both beside one pose through
h4pin.compliance), the two validation routes, the
natural frequencies (the compiled twin and the Pinocchio route), an atlas with the first
frequency; optionally a 1e7-pose streaming run (``--big``), the Dask overhead per task
(``--dask``), a design sweep of 10 000 designs x 1 000 poses (``--sweep``) and the tolerance
study (``--tolerance``). Each row beside the same row of the release before this one (measured on
the same machine, :data:`PREVIOUS`). The naive implementation and the pipeline are compared to
h4pin's reference, so the table is only printed if they agree.

    python scripts/bench.py [--batch 100000] [--repeat 3] [--big] [--dask] [--sweep]
    python scripts/bench.py --cold   # first use: the warm-up in a fresh process, empty numba cache
                                     # (idle, then beside two busy processes): seconds and peak memory
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import time
from pathlib import Path

import numba
import numpy as np
from independent_kernel import constants as independent_constants
from independent_kernel import independent_compliance
from independent_tight import tight_compliance

import h4pin
from h4pin import verdicts
from h4pin.checks import deformed, statics
from h4pin.description.elements import ILLUSTRATIVE
from h4pin.description.params import H4Params
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import frequencies, kernel, pipeline
from h4pin.stiffness.api import compliance


def naive_compliance(p: H4Params, pose: np.ndarray) -> np.ndarray:
    """Eq. 30 ("paper" model) for one pose, written plainly with per-bar loops, ``np.cross`` and
    explicit inverses: the independent kernel of ``independent_kernel.py`` run by the interpreter
    (its Python source, numpy per statement), its constants read per call."""
    return independent_compliance.py_func(pose, *independent_constants(p))


def best_of(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


#: The previous release's rows (commit 7099350: the scalar kernel, the lane kernel, numpy element
#: terms and the Pinocchio modes), measured on this machine (2-core AMD EPYC VM, load 0.7), us/pose.
PREVIOUS = {
    "numpy batch (reference), 'paper', incl. inverse geometry": 13.3,
    "h4pin.compliance(h4, poses): default batch path, 1 thread": 0.873,
    "h4pin.compliance(h4, poses): default batch path, 2 threads": 0.464,
    "h4pin.compliance(h4, pose): default one-pose path": 6.7,
    "h4pin.compliance(h4, pose, method='pinocchio')": 35.7,
    "h4pin.compliance, robot with every element kind, batch": 3451.0,
    "h4pin.compliance, robot with every element kind, one pose": 3335.0,
    "atlas, 500 x 500 x 3 grid, 'consistent' (derived fields)": 1.10,
    "naive per-pose numpy eq. 30 (loops, np.cross, inv)": 1927.0,
    "h4pin.compliance(h4, poses, terms=True): batch with terms": 0.88,
    "h4pin.compliance(h4, pose, terms=True): one pose with terms": 8.7,
    "h4pin.compliance(h4, poses) for a batch of 1 pose (per call)": 19.0,
    "h4pin.compliance(h4, poses) for a batch of 10 poses (per call)": 34.0,
    "pipeline batch, 'paper', 1 thread, incl. IGM + verdict": 0.69,
    "pipeline batch, 'paper', 2 threads, incl. IGM + verdict": 0.42,
    "kernel, one pose (Kernel call, incl. Python overhead)": 4.0,
    "h4pin.modes(h4, pose): all frequencies, one pose": 2425.0,
    "h4pin.modes(h4, poses): batch, all frequencies": 2425.0,
    "h4pin.modes, robot with every element kind, batch": 9400.0,
    "atlas with first frequency, 1e6 poses (per pose)": 2425.0,
}
#: Floating-point operations of one pose (inverse geometry, verdicts including the bar interference
#: check, M1, its inverse and condition, eq. 30), counted from the source of the kernel of the
#: release that introduced this column. A nominal count, kept fixed so that the column compares
#: releases: the kernels now execute fewer (eq. 30 as dot products over one triangle, the bar
#: check behind a division-free line test).
KERNEL_FLOPS = 7389


def cpu_summary() -> str:
    """The CPU's model, clock and vector units (from /proc/cpuinfo)."""
    info = _cpuinfo()
    flags = f" {info.get('flags', '')} "
    units = ", ".join(name if f" {name.lower()} " in flags else f"no {name}" for name in ("AVX2", "FMA", "AVX512F"))
    return f"{info.get('model name', '?')}, {info.get('cpu MHz', '?')} MHz, {units}"


def _cpuinfo() -> dict[str, str]:
    try:
        text = open("/proc/cpuinfo").read().split("\n\n")[0]
    except OSError:
        return {}
    return {k.strip(): v.strip() for k, _, v in (line.partition(":") for line in text.splitlines())}


def peak_flops() -> float:
    """One core's nominal double-precision peak, flop/s: 2 FMA pipes x the vector width (8 doubles
    with AVX-512, 4 with AVX2) x 2 flops x clock (0 when unknown). Whether the pipes are as wide
    as the registers is the CPU's secret (AMD Zen 4 splits a 512-bit FMA in two, Zen 5 does not):
    :func:`measured_dgemm` is the rate one core actually reaches on dense FMA work."""
    info = _cpuinfo()
    flags = f" {info.get('flags', '')} "
    if " fma " not in flags or "cpu MHz" not in info:
        return 0.0
    lanes = 8 if " avx512f " in flags else (4 if " avx2 " in flags else 0)
    return 2 * lanes * 2 * float(info["cpu MHz"]) * 1e6


def measured_dgemm() -> float:
    """flop/s of numpy's 3000 x 3000 matrix product on one thread (OpenBLAS in a fresh process:
    a dense-FMA rate this machine reaches, near its real peak)."""
    import subprocess
    import sys

    code = ("import numpy as np, time; a = np.random.rand(3000, 3000); a @ a; "
            "t = min((lambda t0: (a @ a, time.perf_counter() - t0)[1])(time.perf_counter()) for _ in range(3)); "
            "print(2 * 3000 ** 3 / t)")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    try:
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
        return float(out.stdout.strip())
    except (OSError, ValueError, subprocess.SubprocessError):
        return 0.0


def bytes_per_pose_of(call, n: int) -> float:
    """Peak bytes a pose allocated by ``call`` (tracemalloc; numpy reports its buffers)."""
    import tracemalloc

    call()
    tracemalloc.start()
    out = call()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    del out
    return peak / n


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far, MB (Linux reports ru_maxrss in KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def kernel_rows(h4: h4pin.H4, poses: np.ndarray, repeat: int) -> tuple[dict[tuple[str, int], float], float]:
    """Seconds per pose of the pipeline's batch per (model, threads) and into preallocated arrays
    (1 and 2 threads alternating), and of one pose (a Kernel call)."""
    kern = kernel.prepare(h4.geometry)
    kernel.compliance_batch(kern, poses[:10])  # load (or compile) once
    times = {}
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        for model in ("paper", "consistent"):
            run = lambda m=model: kernel.compliance_batch(kern, poses, m)  # noqa: E731
            times[model, threads] = best_of(repeat, run) / len(poses)
    out = kernel.compliance_batch(kern, poses)
    best = {1: np.inf, 2: np.inf}
    for _ in range(repeat):  # into the same arrays (no page faults), 1 and 2 threads alternating
        for threads in (1, 2):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            t0 = time.perf_counter()
            kernel.compliance_batch(kern, poses, "paper", out)
            best[threads] = min(best[threads], (time.perf_counter() - t0) / len(poses))
    for threads, t in best.items():
        times["into out= paper", threads] = t
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    x = poses[0]
    kern(x)
    n_one = 20_000
    t_one = best_of(repeat, lambda: [kern(x) for _ in range(n_one)]) / n_one
    return times, t_one


def modes_rows(h4: h4pin.H4, poses: np.ndarray, repeat: int) -> dict[str, float]:
    """Seconds a pose of the natural frequencies: the compiled twin (one pose; a batch, on one
    thread, all the frequencies and the first four) and the Pinocchio route it replaces (the
    previous release's), bare and with every element kind."""
    numba.set_num_threads(1)
    with_el = h4.with_elements(ILLUSTRATIVE)
    few = poses[:2000]
    h4pin.modes(h4, few[:3])
    h4pin.modes(with_el, few[:3])
    out = {
        "twin, one pose": best_of(repeat, lambda: [h4pin.modes(h4, x) for x in few[:500]]) / 500,
        "twin, batch, all": best_of(repeat, lambda: h4pin.modes(h4, few)) / len(few),
        "twin, batch, first four": best_of(repeat, lambda: frequencies.frequencies(h4, few, count=4)) / len(few),
        "twin, batch, elements": best_of(repeat, lambda: h4pin.modes(with_el, few[:500])) / 500,
        "pinocchio, one pose": best_of(1, lambda: [h4pin.modes(h4, x, method="pinocchio") for x in few[:40]]) / 40,
        "pinocchio, elements": best_of(1, lambda: [h4pin.modes(with_el, x, method="pinocchio")
                                                      for x in few[:20]]) / 20,
    }
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


def frequency_atlas_row(h4: h4pin.H4, n_side: int = 1000) -> float:
    """Seconds a pose of an atlas with the first frequency: n_side^2 poses at the centre height
    (1e6 by default), on numba's threads."""
    from h4pin.studies import atlas

    c = centre_pose(h4)
    xs = np.linspace(-0.3, 0.3, n_side)
    atlas.atlas(h4, xs[:8], xs[:8], [c[2]], progress=False, frequency=True)
    t0 = time.perf_counter()
    atlas.atlas(h4, xs, xs, [c[2]], progress=False, frequency=True)
    return (time.perf_counter() - t0) / n_side**2


def big_stream(h4: h4pin.H4, n: int, chunk: int) -> tuple[float, float, float]:
    """Stream n poses (generated chunk by chunk) to a reduction: (seconds, peak RSS MB, worst
    translational compliance m/N)."""
    rng = np.random.default_rng(1)
    centre = centre_pose(h4)
    kern = kernel.prepare(h4.geometry)

    def chunks():
        for start in range(0, n, chunk):
            yield centre + rng.uniform(-1, 1, (min(chunk, n - start), 4)) * [0.1, 0.1, 0.06, 0.4]

    worst = 0.0
    t0 = time.perf_counter()
    for _, part in kernel.iter_compliance(kern, chunks(), "paper", chunk=chunk):
        ok = part.status == verdicts.OK
        worst = max(worst, float(np.max(part.K[:, [0, 1, 2], [0, 1, 2]][ok], initial=0.0)))
    return time.perf_counter() - t0, peak_rss_mb(), worst


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=100_000, help="poses in the batch row")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs per row")
    parser.add_argument("--tolerance", action="store_true", help="also time the tolerance study (10 000 x 100)")
    parser.add_argument("--big", action="store_true", help="also stream 1e7 poses through the kernel")
    parser.add_argument("--atlas-stream", action="store_true",
                        help="also stream a 1e7-pose atlas to zarr (run it alone for its peak RSS)")
    parser.add_argument("--dask", action="store_true", help="also measure the Dask overhead per task")
    parser.add_argument("--sweep", action="store_true", help="also time 10 000 designs x 1 000 poses")
    parser.add_argument("--designs", type=int, default=10_000, help="designs in the sweep row")
    parser.add_argument("--cold", action="store_true",
                        help="only time first use: each row in a fresh process with an empty numba cache")
    parser.add_argument("--pareto", type=int, default=0, metavar="DESIGNS",
                        help="also time the frequency-workspace-compliance Pareto sweep of this many designs")
    parser.add_argument("--calibration", action="store_true",
                        help="only the calibration rows (a five-bar, 200 poses; a 20-joint tree, 500 poses)")
    parser.add_argument("--mechanisms", action="store_true",
                        help="only the generic engine's rows: corpus robots, a plain KKT loop, Mechanism, with beams")
    parser.add_argument("--all", action="store_true",
                        help="every row of the release note in one run: the table, --pareto 100000 and --cold")
    return parser


def main() -> None:
    args = _parser().parse_args()
    if args.calibration:
        calibration_rows()
        return
    if args.mechanisms:
        mechanism_rows(args.repeat)
        loaded_rows()
        calibration_rows()
        return
    if args.cold and not args.all:
        cold_table()
        return
    if args.all:
        args.pareto = args.pareto or 100_000
    h4 = h4pin.load("prototype")
    rng = np.random.default_rng(0)
    poses = centre_pose(h4) + rng.uniform(-1, 1, (args.batch, 4)) * [0.1, 0.1, 0.06, 0.4]
    poses = poses[np.all(np.isfinite(h4.inverse_geometry(poses, on_error="nan")), axis=1)]
    t = speed_timings(h4, poses, args.repeat, 1000 if args.batch >= 100_000 else 200)
    agreement = check_agreement(h4, poses)
    speed_table(t, len(poses), args.repeat, agreement)
    targets(t)
    for option, section in OPTIONAL_SECTIONS:
        if option(args):
            section(args, h4)


def bare_calls(h4: h4pin.H4, x: np.ndarray, repeat: int) -> tuple[float, float, float]:
    """Seconds of one bare compiled call at pose x: of the two independent kernels, the naive
    eq. 30 ported to numba (``independent_kernel.py``) and the same math written for speed by hand
    (``independent_tight.py``: scalar loops, no temporaries, the zero blocks never formed), neither
    sharing code with h4pin; and of h4pin's own one-pose entry (:func:`h4pin.stiffness.pipeline.one`
    through its dispatcher, outputs allocated once, no check and no result object): the floor under
    ``h4pin.compliance(h4, pose)``, which allocates, checks and wraps."""
    args = independent_constants(h4.params)
    independent_compliance(x, *args)
    k_tight = np.empty((8, 8))
    tight_compliance(x, *args, k_tight)
    kern = kernel.prepare(h4.geometry)
    xr = np.array(x)
    xr.setflags(write=False)
    out = (np.empty((8, 8)), np.empty(4), np.empty((4, 8, 8)), False, np.empty(pipeline.NX), False)
    pipeline.one(xr, kern.packed, kern.elements, pipeline.PAPER, *out)
    n = 20_000
    t_ind = best_of(repeat, lambda: [independent_compliance(x, *args) for _ in range(n // 10)]) / (n // 10)
    t_tight = best_of(repeat, lambda: [tight_compliance(x, *args, k_tight) for _ in range(n)]) / n
    t_one = best_of(repeat, lambda: [pipeline.one(xr, kern.packed, kern.elements, pipeline.PAPER, *out)
                                     for _ in range(n)]) / n
    return t_ind, t_tight, t_one


def speed_timings(h4: h4pin.H4, poses: np.ndarray, repeat: int, fatlas_side: int) -> dict:
    """Every row of the main table, in seconds a pose (the kernel rows: a dict by (model, threads));
    ``fatlas_side``: the side of the frequency atlas's grid."""
    n_single = 2000
    few = poses[:n_single]
    t = {"batch": best_of(repeat, lambda: compliance(h4, poses, "paper", method="closed_form")),
         "batch_c": best_of(repeat, lambda: compliance(h4, poses, "consistent", method="closed_form"))}
    best_of(repeat, lambda: compliance(h4, poses, "paper"))  # the default path once, before its rows
    t["single"] = best_of(repeat, lambda: [compliance(h4, x, "paper") for x in few]) / n_single
    t["single_pin"] = best_of(repeat, lambda: [compliance(h4, x, "paper", method="pinocchio")
                                               for x in few[:500]]) / 500
    t["naive"] = best_of(repeat, lambda: [naive_compliance(h4.params, x) for x in few]) / n_single
    t["bare_independent"], t["bare_tight"], t["bare_one"] = bare_calls(h4, few[0], repeat)
    t["statics"] = best_of(1, lambda: [statics.compliance_matrix(h4.geometry, x) for x in few[:200]]) / 200
    t["fd"] = best_of(1, lambda: [deformed.compliance_terms(h4.geometry, x) for x in few[:5]]) / 5
    t["kernel"], t["one"] = kernel_rows(h4, poses, repeat)
    t["default"] = {}
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        t["default"][threads] = best_of(repeat, lambda: compliance(h4, poses, "paper")) / len(poses)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    t["terms"] = best_of(repeat, lambda: compliance(h4, poses, "paper", terms=True)) / len(poses)
    x0 = few[0]
    t["small"] = {n: best_of(repeat, lambda n=n: [compliance(h4, few[:n]) for _ in range(200)]) / 200
                  for n in (1, 10)}
    t["mem_default"], t["mem_terms"] = (
        bytes_per_pose_of(lambda terms=terms: compliance(h4, poses, "paper", terms=terms), len(poses))
        for terms in (False, True))
    t["single_terms"] = best_of(repeat, lambda: [compliance(h4, x0, "paper", terms=True) for _ in range(2000)]) / 2000
    with_el = h4.with_elements(ILLUSTRATIVE)
    numba.set_num_threads(1)
    t["el_batch"] = best_of(repeat, lambda: compliance(with_el, poses, "paper")) / len(poses)
    t["el_off"] = best_of(repeat, lambda: compliance(h4, poses, "paper")) / len(poses)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    t["el_single"] = best_of(repeat, lambda: [compliance(with_el, x, "paper") for x in few[:500]]) / 500
    t["el_numpy"] = best_of(1, lambda: compliance(with_el, few[:100], "paper", method="closed_form")) / 100
    t["atlas"] = atlas_row(h4, repeat)
    t["modes"] = modes_rows(h4, poses, repeat)
    t["fatlas"] = frequency_atlas_row(h4, fatlas_side)
    return t


def check_agreement(h4: h4pin.H4, poses: np.ndarray) -> tuple[float, float, float]:
    """The naive eq. 30 and the pipeline against h4pin's reference (relative), exiting when they
    disagree; and the pipeline's output bytes a pose."""
    few = poses[:50]
    ours = compliance(h4, few, "paper", method="closed_form").matrix
    naive = np.array([naive_compliance(h4.params, x) for x in few])
    args = independent_constants(h4.params)
    independent = np.array([independent_compliance(x, *args) for x in few])
    tight = np.empty((len(few), 8, 8))
    for x, k in zip(few, tight, strict=True):
        tight_compliance(x, *args, k)
    agree = max(np.max(np.abs(ours - a)) for a in (naive, independent, tight)) / np.max(np.abs(ours))
    if agree > 1e-10:
        raise SystemExit(f"an independent eq. 30 (numpy, compiled or hand-tightened) and h4pin disagree: "
                         f"{agree:.1e} relative")
    fast = kernel.compliance_batch(h4.geometry, poses, "paper")
    ref = compliance(h4, poses, "paper", method="closed_form").matrix
    agree_k = float(np.max(np.max(np.abs(fast.K - ref), axis=(1, 2)) / np.max(np.abs(ref), axis=(1, 2))))
    if agree_k > 1e-12:
        raise SystemExit(f"pipeline and h4pin disagree: {agree_k:.1e} relative")
    return agree, agree_k, sum(a.nbytes for a in fast if a is not None) / len(poses)


def _speed_rows(t: dict, n_poses: int) -> list[tuple[str, float]]:
    rows = [
        ("numpy batch (reference), 'paper', incl. inverse geometry", t["batch"] / n_poses),
        ("numpy batch (reference), 'consistent', incl. inverse geometry", t["batch_c"] / n_poses),
        ("h4pin.compliance(h4, poses): default batch path, 1 thread", t["default"][1]),
        ("h4pin.compliance(h4, poses): default batch path, 2 threads", t["default"][2]),
        ("h4pin.compliance(h4, pose): default one-pose path", t["single"]),
        ("h4pin.compliance(h4, pose, method='pinocchio')", t["single_pin"]),
        ("h4pin.compliance, robot with every element kind, batch", t["el_batch"]),
        ("h4pin.compliance, robot with every element kind, one pose", t["el_single"]),
        ("  the same, numpy path (statics route per pose, as before)", t["el_numpy"]),
        ("atlas, 500 x 500 x 3 grid, 'consistent' (derived fields)", t["atlas"]),
        ("naive per-pose numpy eq. 30 (loops, np.cross, inv)", t["naive"]),
        ("  the same compiled by numba (independent kernel), a bare call", t["bare_independent"]),
        ("  the same math written for speed by hand (independent), bare call", t["bare_tight"]),
        ("h4pin's one-pose compiled entry, a bare call (no check, no result)", t["bare_one"]),
        ("validation: Newton-Euler statics route", t["statics"]),
        ("validation: finite-difference route (non-linear)", t["fd"]),
        ("h4pin.compliance(h4, poses, terms=True): batch with terms", t["terms"]),
        ("h4pin.compliance(h4, pose, terms=True): one pose with terms", t["single_terms"]),
        ("h4pin.compliance(h4, poses) for a batch of 1 pose (per call)", t["small"][1]),
        ("h4pin.compliance(h4, poses) for a batch of 10 poses (per call)", t["small"][10]),
    ]
    for (model, threads), secs in t["kernel"].items():
        into = "into out= " in model
        name = model.rpartition(" ")[2]
        label = "pipeline batch into out=" if into else "pipeline batch"
        rows.append((f"{label}, '{name}', {threads} thread{'s' * (threads > 1)}, incl. IGM + verdict", secs))
    rows.append(("kernel, one pose (Kernel call, incl. Python overhead)", t["one"]))
    modes = t["modes"]
    rows += [
        ("h4pin.modes(h4, pose): all frequencies, one pose", modes["twin, one pose"]),
        ("h4pin.modes(h4, poses): batch, all frequencies", modes["twin, batch, all"]),
        ("  the same, the first four frequencies (frequencies(count=4))", modes["twin, batch, first four"]),
        ("h4pin.modes, robot with every element kind, batch", modes["twin, batch, elements"]),
        ("  Pinocchio route (method='pinocchio', as before), one pose", modes["pinocchio, one pose"]),
        ("  Pinocchio route, robot with every element kind", modes["pinocchio, elements"]),
        ("atlas with first frequency, 1e6 poses (per pose)", t["fatlas"]),
    ]
    return rows


def speed_table(t: dict, n_poses: int, repeat: int, agreement: tuple[float, float, float]) -> None:
    """The main table: each row's poses/s, us/pose, against the naive code, the batch and the
    previous release, and the pipeline's share of the cores' peak."""
    agree, agree_k, bytes_per_pose = agreement
    per_pose = t["batch"] / n_poses
    print(f"h4pin compliance speed, {platform.processor() or platform.machine()}, {n_poses} batch poses, "
          f"best of {repeat} (naive vs h4pin: {agree:.1e}, pipeline vs h4pin: {agree_k:.1e} relative), "
          f"load average before: {os.getloadavg()[0]:.2f}\n")
    rows = _speed_rows(t, n_poses)
    peak = peak_flops()
    dgemm = measured_dgemm()
    print(f"| {'path':<64} | {'poses/s':>10} | {'us/pose':>9} | {'vs naive':>8} | {'vs batch':>8} "
          f"| {'before':>9} | {'vs prev.':>8} | {'of peak':>7} |")
    print(f"|{'-' * 66}|{'-' * 12}|{'-' * 11}|{'-' * 10}|{'-' * 10}|{'-' * 11}|{'-' * 10}|{'-' * 9}|")
    for name, secs in rows:
        prev = PREVIOUS.get(name)
        vs_prev = f"{prev / (secs * 1e6):>7.2f}x" if prev else f"{'':>8}"
        before = f"{prev:>9.2f}" if prev else f"{'':>9}"
        hw = ""
        if "pipeline batch" in name and peak:
            threads = int(name.split(" thread")[0].rsplit(" ", 1)[-1])
            hw = f"{KERNEL_FLOPS / secs / (peak * threads):.1%}"
        print(f"| {name:<64} | {1 / secs:>10.0f} | {secs * 1e6:>9.2f} | {t['naive'] / secs:>7.1f}x "
              f"| {per_pose / secs:>7.2f}x | {before} | {vs_prev} | {hw:>7} |")
    print("\n'before' (us/pose) and 'vs prev.': the same row in the previous release (commit 7099350: a scalar and "
          "a lane kernel, element terms in numpy per pose, natural frequencies through Pinocchio), measured on this "
          "machine; the Pinocchio and numpy-element rows above are those routes, still there, measured now.")
    if peak:
        print(f"'of peak': {KERNEL_FLOPS} nominal flops a pose x poses/s / the cores' double-precision peak "
              f"({peak / 1e9:.1f} GFLOP/s a core: 2 FMA pipes x the vector width x 2 x clock; {cpu_summary()}). "
              f"numpy's dgemm reaches {dgemm / 1e9:.1f} GFLOP/s on one core here ({dgemm / peak:.0%} of that peak).")
    floor = 5 * 64 * 8 + 4 * 8 + 8 + 1 + 4 * 8
    print(f"pipeline output without terms: {bytes_per_pose:.0f} bytes/pose (K, q, condition, status); "
          f"h4pin.compliance peak memory a pose: {t['mem_default']:.0f} B, {t['mem_terms']:.0f} B with terms (the "
          f"arrays a result with terms holds: K and 4 terms 2560 B, q, condition, status, pose: {floor} B)")


def targets(t: dict) -> None:
    """The release's speed and memory targets, each met or missed."""
    print("\ntargets:")
    kern = t["kernel"]
    one_core = min(1 / kern["paper", 1], 1 / kern["consistent", 1])
    two_cores = min(1 / kern["paper", 2], 1 / kern["consistent", 2])
    checks = [  # (what, measured, target, unit, True: at least / False: at most)
        ("default batch, 1 core", one_core, 1_200_000, "poses/s", True),
        ("default batch, 2 cores / 1 core", two_cores / one_core, 1.9, "x", True),
        ("  the same into out= (no page faults)", kern["into out= paper", 1] / kern["into out= paper", 2], 1.9, "x",
         True),
        ("one pose, h4pin.compliance", t["single"] * 1e6, 4.0, "us", False),
        ("  / a bare call of the independent kernel", t["single"] / t["bare_independent"], 1.0, "x", False),
        ("  / the hand-tightened independent kernel", t["single"] / t["bare_tight"], 1.0, "x", False),
        ("  / a bare call of h4pin's one-pose entry", t["single"] / t["bare_one"], 1.0, "x", False),
        ("every element kind / elements off, batch", t["el_batch"] / t["el_off"], 2.0, "x", False),
        ("modes, first four frequencies, 1 core", t["modes"]["twin, batch, first four"] * 1e6, 20.0, "us", False),
        ("terms=True batch / default batch", t["terms"] / t["default"][2], 1.3, "x", False),
        ("default batch, memory a pose", t["mem_default"], 600, "B", False),
    ]
    for name, got, want, unit, at_least in checks:
        ok = got >= want if at_least else got <= want
        verdict = "met" if ok else f"MISSED by {abs(got / want - 1):.0%}"
        print(f"  {name:<38} {got:>12,.2f} {unit:<8} {'>=' if at_least else '<='} {want:>12,.2f}   {verdict}")
    print(f"  (numba threads available: {numba.config.NUMBA_NUM_THREADS}, threading layer: "
          f"{numba.threading_layer()})")


def big_section(args: argparse.Namespace, h4: h4pin.H4) -> None:
    n = 10_000_000
    secs, rss, worst = big_stream(h4, n, kernel.CHUNK)
    print(f"\nstreaming {n:.0e} poses in chunks of {kernel.CHUNK}: {secs:.1f} s ({n / secs:,.0f} poses/s), "
          f"peak RSS {rss:.0f} MB (target < 1024 MB: {'met' if rss < 1024 else 'MISSED'}), "
          f"worst K_xx {worst * 1e6:.1f} um/N")


def dask_section(args: argparse.Namespace, h4: h4pin.H4) -> None:
    from h4pin.studies import sweep

    over = sweep.dask_overhead(workers=2)
    print(f"\nDask LocalCluster (2 workers): {over * 1e3:.2f} ms overhead per task")


def sweep_section(args: argparse.Namespace, h4: h4pin.H4) -> None:
    from h4pin.studies import sweep

    print(f"\nsweep: {args.designs} designs x 1000 task poses (+ the volume grid)")
    for label, kwargs in (("1 core", {"threads": 1}), ("2 cores", {"threads": 2}),
                          ("2 Dask workers", {"threads": 1, "workers": 2})):
        secs, evals = sweep.bench(args.designs, **kwargs)
        print(f"  {label:<16} {secs:8.1f} s  {evals / secs:>12,.0f} design-poses/s")
    print("\nsweep per-design overhead (sweep.evaluate with the kernel's compiled call left out; "
          "target <= 20 % of the kernel's time for the 1000 task poses)")
    rows = {"1 thread": [sweep_overhead()]}
    with sweep.Client(2, None) as client:
        rows["2 Dask workers, each"] = list(client.run(sweep_overhead).values())
    for label, results in rows.items():
        for ev, over, k_task in results:
            print(f"  {label:<22} evaluate {ev * 1e3:.3f} ms/design (2728 poses), "
                  f"overhead {over * 1e3:.3f} ms, kernel {k_task * 1e3:.3f} ms (1000 poses): "
                  f"{over / k_task:.0%}")


def all_cold_section(args: argparse.Namespace, h4: h4pin.H4) -> None:
    print()
    cold_table()


#: The optional sections after the main table, in the order they print: (whether the options ask
#: for it, the section).
OPTIONAL_SECTIONS = (
    (lambda a: a.atlas_stream, lambda a, h4: atlas_stream_row()),
    (lambda a: a.big, big_section),
    (lambda a: a.dask, dask_section),
    (lambda a: a.sweep, sweep_section),
    (lambda a: a.tolerance, lambda a, h4: bench_tolerance()),
    (lambda a: a.pareto, lambda a, h4: pareto_row(a.pareto)),
    (lambda a: a.all, all_cold_section),
)


#: The previous release's frequency Pareto: the first frequency at the centre pose only, of at
#: most 200 designs, through the Pinocchio route (its URDF, elastic model and data a design),
#: 120 designs in 2.9 s on this machine.
PREVIOUS_PARETO_MS = 2.9e3 / 120


def pareto_row(n_designs: int) -> None:
    """The sweep with frequencies (each design: the task box's compliance, its workspace volume
    and its first frequency over the centre and 16 corners) on two Dask workers, then the front."""
    import tempfile
    from pathlib import Path

    from h4pin.studies import frequency, sweep

    spec = sweep.Spec(n_designs=n_designs, chunk=256, frequency=True)
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        res = sweep.run(Path(tmp) / "sweep.zarr", spec, workers=2, progress=False)
    seconds = time.perf_counter() - t
    front = frequency.frequency_pareto(res)
    print(f"\nfrequency-workspace-compliance Pareto, {n_designs:,} designs on 2 Dask workers: {seconds:.0f} s, "
          f"{seconds / n_designs * 1e3:.1f} ms a design (17 poses of frequency each; before: "
          f"{PREVIOUS_PARETO_MS:.0f} ms a design for the centre pose alone, at most 200 designs), "
          f"{int(res['reach_all'].sum()):,} reach the task box, {len(front['front'])} on the front")


COLD_STEPS = {
    "import h4pin": "",
    "h4pin.load()": "h4 = h4pin.load()",
    "first single pose, compliance(h4, x)": "h4pin.compliance(h4, x)",
    "first batch of 1000 poses": "h4pin.compliance(h4, xs)",
    "first modes at one pose": "h4pin.modes(h4, x)",
}
COLD_SCRIPT = """
import time, json
t = time.perf_counter(); import numpy as np, h4pin; out = {{'import h4pin': time.perf_counter() - t}}
from h4pin.kinematics.closed_form import centre_pose
for name, code in {steps!r}.items():
    if not code:
        continue
    t = time.perf_counter(); exec(code); out[name] = time.perf_counter() - t
    if name == 'h4pin.load()':
        x = centre_pose(h4); xs = x + np.random.default_rng(0).uniform(-1, 1, (1000, 4)) * [0.05, 0.05, 0.03, 0.2]
print(json.dumps(out))
"""
#: The warm-up of commit 6cc450b (two releases ago) on this machine, idle, measured in the same hour
#: as this release's 126 s and 423 MB: seconds and peak resident MB (the machine's speed drifts by
#: up to 2.5x from day to day: compare with a run of the same day).
PREVIOUS_WARMUP = (166.4, 599.5)


#: Runs ``-c CODE`` or ``-m MODULE ARGS`` and writes its peak resident memory (KB: the process
#: and the children it waited for) to the file $H4PIN_BENCH_RSS at exit.
_RSS_WRAPPER = """
import atexit, os, resource, runpy, sys
def _rss():
    with open(os.environ['H4PIN_BENCH_RSS'], 'w') as f:
        f.write(str(max(resource.getrusage(r).ru_maxrss for r in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))))
atexit.register(_rss)
args = sys.argv[1:]
if args[0] == '-m':
    sys.argv = args[1:]
    runpy.run_module(args[1], run_name='__main__', alter_sys=True)
else:
    sys.argv = ['-c']
    exec(compile(args[1], '<bench>', 'exec'), {'__name__': '__main__'})
"""


def mechanism_rows(repeat: int) -> None:
    """us a configuration of h4pin.mechanism.Mechanism on robots of the corpus: the plain loop a user
    would write (Pinocchio's Jacobians, an SVD of the closures, one dense KKT solve), one
    configuration a call by the Pinocchio route (Mechanism before the compiled path), and a batch
    by the compiled path on one thread and two; the first four frequencies of the batch; and the
    batch with a beam on every link (Mechanism.with_beams)."""
    robots = Path(__file__).resolve().parent.parent / "tests" / "robots"
    print("us a configuration")
    print(f"{'robot':<20}{'nv':>4}{'plain KKT':>11}{'Pinocchio':>11}{'batch 1t':>10}{'batch 2t':>10}"
          f"{'plain/1t':>10}{'plain/2t':>10}{'f1-4 1t':>9}{'f/C':>6}{'beams nv':>10}{'beams 1t':>10}")
    for name in ("5bar_linkage_iso3d", "robot_delta", "cassie_like", "digit_like", "digit_like_2legs", "wl16_like"):
        r = _mechanism_row(robots / name / "robot.urdf", repeat)
        print(f"{name:<20}{r['nv']:>4}{r['plain']:>11.1f}{r['pinocchio']:>11.1f}{r['one']:>10.1f}{r['two']:>10.1f}"
              f"{r['plain'] / r['one']:>10.1f}{r['plain'] / r['two']:>10.1f}{r['freq']:>9.1f}"
              f"{r['freq'] / r['one']:>6.1f}{r['beams_nv']:>10}{r['beams']:>10.1f}")


def loaded_rows() -> None:
    """The loaded robot (h4pin.mechanism.loaded) beside the linear compliance: one equilibrium under
    gravity with its tangent compliance, on corpus robots and the elastic H4, against a linear
    compliance of the same robot (the compiled batch per configuration, one thread); and the H4's
    loaded compliance over poses (h4pin.studies.loaded.sag) against its linear atlas per pose."""
    import warnings

    from h4pin.errors import MechanismWarning
    from h4pin.mechanism import Mechanism
    from h4pin.studies import loaded

    robots = Path(__file__).resolve().parent.parent / "tests" / "robots"
    print("\nloaded equilibrium under gravity + tangent compliance, per configuration (one thread)")
    print(f"{'robot':<20}{'nv':>4}{'loaded ms':>11}{'linear us':>11}{'ratio':>9}{'target':>8}")
    cases = []
    for name in ("5bar_linkage_iso3d", "robot_delta", "cassie_like"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MechanismWarning)
            mech = Mechanism.from_urdf(robots / name / "robot.urdf")
            q = mech.assemble()
        springs = {n: 2e3 if n in mech.actuated else 50.0 for n in list(mech.model.names)[1:]}
        frame = next(f.name for f in mech.model.frames if f.parentJoint == mech.constraint_models[0].joint1_id)
        cases.append((name, mech, q, springs, frame, ()))
    h4 = h4pin.load("prototype")
    em = h4pin.elastic_model(h4)
    cases.append(("elastic H4", em.mechanism, em.configuration(centre_pose(h4)), {}, "D", em.locked))
    for name, mech, q, springs, frame, locked in cases:
        Q = np.tile(q, (256, 1))
        mech.compliance(Q[:2], springs, [frame], locked, method="compiled")

        def one_loaded(mech=mech, q=q, springs=springs, frame=frame) -> None:
            mech.equilibrium(q, springs, gravity=True).compliance([frame])

        load_s = best_of(3, one_loaded)
        lin_s = best_of(3, lambda mech=mech, Q=Q, springs=springs, frame=frame, locked=locked: mech.compliance(
            Q, springs, [frame], locked, method="compiled", threads=1)) / len(Q)
        print(f"{name:<20}{mech.model.nv:>4}{load_s * 1e3:>11.2f}{lin_s * 1e6:>11.1f}{load_s / lin_s:>9.0f}x{'10x':>8}")
    poses = centre_pose(h4) + np.array([[dx, dy, 0.0, 0.0] for dx in (-0.05, 0.05) for dy in (-0.05, 0.05)])
    sag_s = best_of(1, lambda: loaded.sag(h4, poses, 0.5)) / len(poses)
    grid = centre_pose(h4) + np.zeros((10_000, 4))
    lin_s = best_of(3, lambda: h4pin.compliance(h4, grid, "consistent")) / len(grid)
    print(f"H4 loaded compliance over poses (sag, 0.5 kg): {sag_s * 1e3:.0f} ms a pose; its linear atlas "
          f"{lin_s * 1e6:.2f} us a pose: {sag_s / lin_s:,.0f}x (target 10x: missed)")


def calibration_rows(full: bool = True, five_bar: bool = True) -> None:
    """Calibration (h4pin.calibrate) on one core: the five-bar with a beam (the calibration
    experiment's design, 200 poses, 24 parameters), and a humanoid's upper body (example-robot-data's
    TALOS, legs and base locked: a 20-joint tree, markers on both hands, 500 poses, about 100
    parameters: base, markers, offsets, springs and lateral hinges of the torso and arms, six
    links' masses), each fitted from a synthetic tracker session under gravity."""
    import importlib.util

    from h4pin.mechanism import calibration as cal

    spec = importlib.util.spec_from_file_location("calibration_experiment",
                                                  Path(__file__).resolve().parent / "calibration_experiment.py")
    exp = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(exp)
    print("\ncalibration, one core (a synthetic tracker session under gravity, the noise estimated)")
    print(f"{'robot':<34}{'joints':>7}{'samples':>8}{'params':>7}{'seconds':>9}{'target':>8}  error mean (noise)")
    design = exp.five_bar()
    rng = np.random.default_rng(5)
    n = 200
    design["motors"] = rng.uniform(-0.3, 0.3, (n, 2))
    design["loads"] = {"effector": np.c_[rng.normal(0.0, 30.0, (n, 3)), np.zeros((n, 3))]}
    rows = [("five-bar with a beam", design, 5.0)] if five_bar else []
    if full:
        rows.append(("TALOS upper body (20-joint tree)", _upper_body(), 60.0))
    for name, design, target in rows:
        meas, _ = exp.session(design, seed=0)
        start = time.perf_counter()
        c = cal.calibrate(design["mech"], meas, design["parameters"], **exp.fit_options(design))
        seconds = time.perf_counter() - start
        joints = sum(1 for j in range(1, design["mech"].model.njoints)
                     if design["mech"].model.names[j] not in design["mech"].beam_springs)
        err = np.linalg.norm(c.residuals, axis=-1)
        print(f"{name:<34}{joints:>7}{meas.n:>8}{len(c.values):>7}{seconds:>9.1f}{target:>7.0f}s  "
              f"{np.nanmean(err) * 1e3:.3f} mm ({design['noise'] * 1e3:.2f} mm a coordinate)"
              f"{'' if seconds <= target else '  (target missed)'}")


def _upper_body() -> dict:
    """TALOS's upper body as a calibration design (calibration_rows)."""
    import example_robot_data as erd
    import pinocchio as pin

    from h4pin.mechanism import Mechanism

    full = erd.load("talos").model
    lock = [full.getJointId(n) for n in full.names[1:] if n.startswith(("root", "leg_"))]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    mech = Mechanism(model, [], [], name="talos upper body")
    names = list(model.names)[1:]
    body = [n for n in names if n.startswith(("torso", "arm_"))]
    springs = {n: 2e3 if n.startswith("torso") else 500.0 for n in names}
    rng = np.random.default_rng(11)
    n = 500
    lo, hi = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
    mid, half = 0.5 * (lo + hi), 0.3 * (hi - lo)  # the middle 60 % of each joint's range
    q = mid + half * rng.uniform(-1.0, 1.0, (n, model.nq))
    markers = ["gripper_left_base_link", "gripper_right_base_link"]
    prior = {**{f"springs/{j}": (k, 0.3 * k) for j, k in springs.items()},
             **{f"offsets/{j}": (0.0, 0.01) for j in names},
             **{f"lateral/{j}/{a}": (10 * springs[j], 3 * springs[j]) for j in body[2:] for a in "ab"}}
    return {"mech": mech, "markers": markers, "springs": springs, "prior": prior, "noise": 1e-3,
            "parameters": {"base": None, "markers": None, "offsets": body, "springs": body, "lateral": body[2:],
                           "masses": ["torso_2_joint", "arm_left_2_joint", "arm_left_4_joint", "arm_right_2_joint",
                                      "arm_right_4_joint", "head_1_joint"]},
            "configurations": q,
            "loads": {m: np.zeros((n, 6)) for m in markers}}


def _mechanism_row(urdf: Path, repeat: int, n: int = 512) -> dict[str, float]:
    import warnings

    import pinocchio as pin

    from h4pin.errors import H4Error, MechanismWarning
    from h4pin.mechanism import Beam, Mechanism

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        mech = Mechanism.from_urdf(urdf)
        q = mech.assemble()
    model = mech.model
    springs = {model.names[j]: 100.0 for j in range(1, model.njoints)}
    out = mech.constraint_models[0]
    frame = next(f.name for f in model.frames if f.parentJoint == out.joint1_id)
    fid = model.getFrameId(frame)
    d = model.createData()
    k = np.full(model.nv, 100.0)
    cds = [cm.createData() for cm in mech.constraint_models]

    def plain() -> np.ndarray:
        pin.computeJointJacobians(model, d, q)
        pin.updateFramePlacements(model, d)
        for cm, cd in zip(mech.constraint_models, cds, strict=True):
            cm.calc(model, d, cd)
        a = pin.getConstraintsJacobian(model, d, mech.constraint_models, cds)
        _, sv, vt = np.linalg.svd(a, full_matrices=False)
        a = vt[sv > 1e-10 * sv[0]]
        jo = pin.getFrameJacobian(model, d, fid, pin.LOCAL_WORLD_ALIGNED)
        n = a.shape[0]
        sol = np.linalg.solve(np.block([[np.diag(k), a.T], [a, np.zeros((n, n))]]), np.vstack([jo.T, np.zeros((n, 6))]))
        return jo @ sol[:model.nv]

    tube = Beam.tube(0.025, 0.002, E=70e9, G=26e9)
    beams, seen = {}, set()
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint > 0 and f.parentJoint not in seen:
            seen.add(f.parentJoint)
            try:
                mech.with_beams({f.name: tube})
                beams[f.name] = tube
            except H4Error:
                pass
    flex = mech.with_beams(beams)
    Q = np.tile(q, (n, 1))
    mech.compliance(Q[:2], springs, [frame], method="compiled")  # compiled (or loaded) before timing
    mech.modes(Q[:2], springs, method="compiled")
    per = 1e6 / n
    return {"nv": model.nv, "plain": best_of(repeat, lambda: [plain() for _ in range(20)]) * 1e6 / 20,
            "pinocchio": best_of(repeat, lambda: [mech.compliance(q, springs, [frame], method="pinocchio")
                                                  for _ in range(20)]) * 1e6 / 20,
            "one": best_of(repeat, lambda: mech.compliance(Q, springs, [frame], method="compiled", threads=1)) * per,
            "two": best_of(repeat, lambda: mech.compliance(Q, springs, [frame], method="compiled", threads=2)) * per,
            "freq": best_of(repeat, lambda: mech.modes(Q, springs, method="compiled", threads=1)) * per,
            "beams_nv": flex.model.nv,
            "beams": best_of(repeat, lambda: flex.compliance(Q, springs, [frame], method="compiled", threads=1)) * per}


def cold_run(args: list[str], mode: str) -> tuple[float, str, float]:
    """Wall time, stdout and peak resident memory (MB, that process alone and its children) of a
    fresh process with an empty numba cache, ``H4PIN_WARMUP=mode``; ``args``: ``["-c", code]`` or
    ``["-m", module, ...]``."""
    import os
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as cache:
        rss_file = os.path.join(cache, "rss")
        env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(cache, "numba"), H4PIN_WARMUP=mode,
                   H4PIN_BENCH_RSS=rss_file)
        t = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", _RSS_WRAPPER, *args], env=env, capture_output=True, text=True,
                             check=True)
        seconds = time.perf_counter() - t
        with open(rss_file) as f:
            return seconds, out.stdout, int(f.read()) / 1024


def busy(n: int) -> list:
    """n processes spinning on a core each (the warm-up measured beside two busy jobs)."""
    import subprocess
    import sys

    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def cold_table() -> None:
    """First use in fresh processes with an empty cache: h4pin's default (numpy path while a
    warm-up compiles; measured with the warm-up off, so that the row is the call's own time)
    against compiling at first use (``H4PIN_WARMUP=inline``); then the warm-up itself, idle and
    beside two busy processes (seconds, peak resident memory)."""
    import json
    import shutil
    import sys

    cli = shutil.which("h4pin") or str(__import__("pathlib").Path(sys.executable).parent / "h4pin")
    rows = {}
    for mode in ("off", "inline"):
        rows.setdefault("first `h4pin table2` (whole command)", {})[mode] = cold_run(
            ["-c", f"import sys; sys.argv = [{cli!r}, 'table2']\nfrom h4pin.cli import main\ntry:\n    main()\n"
                   "except SystemExit as e:\n    assert not e.code, e"], mode)[0]
        steps = json.loads(cold_run(["-c", COLD_SCRIPT.format(steps=COLD_STEPS)], mode)[1])
        for name, seconds in steps.items():
            rows.setdefault(name, {})[mode] = seconds
    print(f"h4pin first use, {platform.processor() or platform.machine()}, empty numba cache, one fresh process "
          f"per column\n")
    print(f"| {'first use':<45} | {'now (s)':>8} | {'compiling at first use (s)':>27} |")
    print(f"|{'-' * 47}|{'-' * 10}|{'-' * 29}|")
    for name, t in rows.items():
        inline = f"{t['inline']:.2f}" if "inline" in t else "-"
        print(f"| {name:<45} | {t['off']:>8.2f} | {inline:>27} |")
    print(f"\n`h4pin warmup` (compile everything once), empty cache; 6cc450b: {PREVIOUS_WARMUP[0]:.0f} s, "
          f"{PREVIOUS_WARMUP[1]:.0f} MB peak resident (idle); targets <= 60 s, <= 600 MB idle")
    for label, n in (("idle", 0), ("beside two busy processes", 2)):
        jobs = busy(n)
        try:
            seconds, _, rss = cold_run(["-m", "h4pin.warmup", "--quiet"], "inline")
        finally:
            for j in jobs:
                j.kill()
                j.wait()
        print(f"  {label:<28} {seconds:7.1f} s   peak resident {rss:6.0f} MB")


def atlas_row(h4: h4pin.H4, repeat: int) -> float:
    """Seconds per pose of :func:`h4pin.studies.atlas.atlas` over a 500 x 500 x 3 grid at the centre."""
    from h4pin.studies import atlas

    c = centre_pose(h4)
    xs = np.linspace(-0.2, 0.2, 500)
    atlas.atlas(h4, xs[:10], xs[:10], [c[2]], progress=False)
    zs = [c[2] - 0.05, c[2], c[2] + 0.05]
    return best_of(repeat, lambda: atlas.atlas(h4, xs, xs, zs, progress=False)) / (500 * 500 * 3)


def sweep_overhead(n_designs: int = 256, repeat: int = 7) -> tuple[float, float, float]:
    """Seconds per design, one numba thread, best of ``repeat``: the whole
    :func:`h4pin.studies.sweep.evaluate`, its overhead, and the kernel alone over the 1000 task
    poses (into a buffer, as evaluate calls it).

    The overhead is measured directly, not as a difference of two noisy times of about 1 ms
    (they vary by 15 % from run to run on a shared VM, more than the overhead): evaluate runs with
    the kernel's compiled call replaced by one that leaves a stored result in place, so that
    everything else (packing the designs, the Python wrapper, the compiled reduction over real
    K and statuses) runs as it does in a sweep."""
    numba.set_num_threads(1)
    from h4pin.studies import sweep

    spec = sweep.Spec(n_designs=n_designs, chunk=64)
    rows = sweep.designs(spec)
    kerns = [k for k in sweep.kernels(rows) if k is not None]
    poses = np.ascontiguousarray(np.concatenate([spec.task.poses(), spec.volume.poses()]))
    task = np.ascontiguousarray(poses[:1000])
    sweep.evaluate(rows[:4], spec, 1)
    stored = kernel.compliance_batch(kerns[0], poses, spec.model)
    task_buf = kernel.empty_result(len(task), False, False)
    real_empty, real_run = kernel.empty_result, kernel.run_poses

    def overhead_only() -> None:
        kernel.empty_result, kernel.run_poses = (lambda *a: stored), (lambda kern, x, code, res, *a, **k: res)
        try:
            sweep.evaluate(rows, spec, 1)
        finally:
            kernel.empty_result, kernel.run_poses = real_empty, real_run

    def kernel_task() -> None:
        for k in kerns:
            kernel.compliance_batch(k, task, spec.model, task_buf)

    ev = best_of(repeat, lambda: sweep.evaluate(rows, spec, 1)) / len(kerns)
    over = best_of(repeat, overhead_only) / len(kerns)
    k_task = best_of(repeat, kernel_task) / len(kerns)
    return ev, over, k_task


def atlas_stream_row(n_side: int = 1000, n_z: int = 10) -> None:
    """Stream an atlas of n_side^2 x n_z poses into a temporary .zarr store (h4pin.studies.atlas.stream):
    seconds per pose and the peak RSS of this process (the target is < 400 MB for 1e7 poses)."""
    import tempfile
    from pathlib import Path

    from h4pin.studies import atlas

    h4 = h4pin.load()
    xs = np.linspace(-0.35, 0.35, n_side)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        atlas.stream(h4, xs, xs, np.linspace(-0.8, -0.4, n_z), out=Path(tmp) / "a.zarr", progress=False)
        secs = time.perf_counter() - t0
    n = n_side * n_side * n_z
    print(f"\natlas streamed to zarr: {n:.0e} poses in {secs:.1f} s ({secs / n * 1e6:.2f} us/pose, "
          f"{numba.get_num_threads()} threads), peak RSS of this process {peak_rss_mb():.0f} MB")


def bench_tolerance(n_robots: int = 10_000, n_poses: int = 100) -> None:
    """Time the tolerance study (:func:`h4pin.studies.tolerance.study`): robots x poses around the centre."""
    from h4pin.studies import tolerance

    h4 = h4pin.load("prototype")
    rng = np.random.default_rng(0)
    poses = centre_pose(h4) + rng.uniform(-1, 1, (n_poses, 4)) * [0.05, 0.05, 0.05, 0.2]
    t0 = time.perf_counter()
    res = tolerance.study(h4, poses, n_robots=n_robots)
    t = time.perf_counter() - t0
    pairs = n_robots * n_poses
    print(f"\ntolerance study: {n_robots} robots x {n_poses} poses in {t:.1f} s ({t / pairs * 1e6:.1f} us/pair, "
          f"{res.converged.mean() * 100:.2f} % converged)")


if __name__ == "__main__":
    main()
