#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Speed of h4pin's compliance, printed as a table (nothing here is asserted by the tests).

Rows: the vectorised batch path (eq. 30 with the inverse geometry, model "paper"), the
single-pose path through Pinocchio's Jacobians, a straightforward per-pose numpy implementation
of eq. 30 (loops, np.cross, explicit inverses: what one writes first), and the two validation
routes; then the compiled kernel (:mod:`h4pin.stiffness.kernel`) on 1 and 2 threads, one pose through it,
its memory per pose, and optionally a 1e7-pose streaming run (``--big``), the Dask overhead per
task (``--dask``) and a design sweep of 10 000 designs x 1 000 poses (``--sweep``). The naive
implementation and the kernel are compared to h4pin's result, so the table is only printed if
they agree.

    python scripts/bench.py [--batch 100000] [--repeat 3] [--big] [--dask] [--sweep]
    python scripts/bench.py --cold   # first use after an install: fresh processes, empty numba cache
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import resource
import time

import numba
import numpy as np

import h4pin
from h4pin import verdicts
from h4pin.checks import deformed, statics
from h4pin.description.elements import ILLUSTRATIVE
from h4pin.description.params import LEG_LATERAL, H4Params
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import kernel
from h4pin.stiffness.api import compliance

#: The vector kernel whatever the batch size (kernel.compliance_batch's arguments).
vector_batch = functools.partial(kernel.compliance_batch, vector=True)


def naive_compliance(p: H4Params, pose: np.ndarray) -> np.ndarray:
    """Eq. 30 ("paper" model) for one pose, written plainly with per-bar loops."""
    x, y, z, th = pose
    d = np.array([x, y, z])
    rz = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    zz = np.array([0.0, 0.0, 1.0])
    c = [d + rz @ p.DC[:, k] for k in range(2)]
    q = np.zeros(4)
    A, B, Aij, Bij = [], [], [], []
    for i in range(4):
        k = LEG_LATERAL[i]
        u = p.U[:, i]
        a = np.cross(u, zz)
        b = c[k] + p.DB[:, i] - p.DC[:, k]
        e = b - p.P[:, i]
        rhs = (e @ e + p.r[i] ** 2 - p.l[2 * i] ** 2) / (2 * p.r[i])
        phi = np.arctan2(-e[2], e @ a)
        for sign in (1, -1):
            q[i] = phi + sign * np.arccos(rhs / np.hypot(e @ a, e[2]))
            ai = p.P[:, i] + p.r[i] * (a * np.cos(q[i]) - zz * np.sin(q[i]))
            if u @ np.cross(ai - p.P[:, i], b - ai) > 0:
                break
        A.append(ai)
        B.append(b)
        for s in (1, -1):
            Aij.append(ai + s * p.half_width[i] * u)
            Bij.append(b + s * p.half_width[i] * u)
    m1, m2, m3, m4 = np.zeros((8, 8)), np.zeros((8, 32)), np.zeros((32, 4)), np.zeros((32, 8))
    jx, jq = np.zeros((4, 4)), np.zeros((4, 4))
    lengths = np.zeros(8)
    for i in range(4):
        k = LEG_LATERAL[i]
        w = B[i] - A[i]
        jx[i] = np.r_[w, w @ np.cross(zz, c[k] - d)]
        jq[i, i] = w @ np.cross(p.U[:, i], A[i] - p.P[:, i])
        ri = (p.P[:, i] - A[i]) / np.linalg.norm(p.P[:, i] - A[i])
        wi = w / np.linalg.norm(w)
        for j in range(2):
            n = 2 * i + j
            wij = Bij[n] - Aij[n]
            lengths[n] = np.linalg.norm(wij)
            t = c[k] - Bij[n]
            m1[n, :3] = wij
            m1[n, 3:6] = np.cross(wij, d - c[k] + t)
            m1[n, 6 + k] = np.cross(wij, t)[2]
            m2[n, 3 * n:3 * n + 3] = wij
            m2[n, 24 + n] = lengths[n]
            pij = p.P[:, i] - Aij[n]
            m3[3 * n:3 * n + 3, i] = np.cross(pij, p.U[:, i])
            for j2 in range(2):
                pij2 = p.P[:, i] - Aij[2 * i + j2]
                m4[3 * n:3 * n + 3, 2 * i + j2] = np.cross(pij, ri) * (np.cross(pij2, ri) @ wi)
    m5 = np.vstack([np.zeros((24, 8)), np.eye(8)])
    r = np.zeros((4, 8))
    r[[0, 1, 2, 3], [0, 1, 2, 5]] = 1
    j = np.linalg.inv(jx) @ jq
    jb_inv = np.linalg.inv(m1.T @ np.diag(1 / lengths))
    cc = p.compliances()
    inner = (m3 @ np.diag(cc["control"] + cc["bending"]) @ j.T @ r
             + m4 @ np.diag(np.repeat(cc["torsion"], 2)) @ jb_inv + m5 @ np.diag(cc["tension"]) @ jb_inv)
    return np.linalg.inv(m1) @ m2 @ inner


def best_of(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


#: The previous release's table (README before this release, this machine), us/pose, by row name.
PREVIOUS = {
    "numpy batch (reference), 'paper', incl. inverse geometry": 13.3,
    "h4pin.compliance(h4, poses): default batch path": 0.50,
    "h4pin.compliance(h4, pose): default one-pose path": 7.24,
    "h4pin.compliance(h4, pose, method='pinocchio')": 35.7,
    "h4pin.compliance, robot with all 11 elements, one pose": 1220.0,
    "atlas, 500 x 500 x 3 grid, 'consistent' (derived fields)": 1.10,
    "naive per-pose numpy eq. 30 (loops, np.cross, inv)": 1927.0,
    "h4pin.compliance(h4, poses, terms=True): batch with terms": 0.88,
    "h4pin.compliance(h4, pose, terms=True): one pose with terms": 8.7,
    "h4pin.compliance(h4, poses) for a batch of 1 pose (per call)": 19.0,
    "h4pin.compliance(h4, poses) for a batch of 10 poses (per call)": 34.0,
    "scalar kernel batch, 'paper', 1 thread, incl. IGM + verdict": 1.47,
    "vector kernel batch, 'paper', 1 thread, incl. IGM + verdict": 0.943,
    "vector kernel batch, 'consistent', 1 thread, incl. IGM + verdict": 0.947,
    "vector kernel batch, 'paper', 2 threads, incl. IGM + verdict": 0.482,
    "vector kernel batch, 'consistent', 2 threads, incl. IGM + verdict": 0.484,
    "kernel, one pose (Kernel call, incl. Python overhead)": 4.0,
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
    """Seconds per pose of the kernel batch per (model, threads), and of one pose."""
    kern = kernel.prepare(h4.geometry)
    kernel.compliance_batch(kern, poses[:10], vector=False)  # load (or compile) once
    times = {}
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        for model in ("paper", "consistent"):
            run = lambda m=model: kernel.compliance_batch(kern, poses, m, vector=False)  # noqa: E731
            times[model, threads] = best_of(repeat, run) / len(poses)
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        for model in ("paper", "consistent"):
            run = lambda m=model: vector_batch(kern, poses, m)  # noqa: E731
            run()
            times["vector " + model, threads] = best_of(repeat, run) / len(poses)
    out = vector_batch(kern, poses)
    best = {1: np.inf, 2: np.inf}
    for _ in range(repeat):  # into the same arrays (no page faults), 1 and 2 threads alternating
        for threads in (1, 2):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            t0 = time.perf_counter()
            vector_batch(kern, poses, "paper", out)
            best[threads] = min(best[threads], (time.perf_counter() - t0) / len(poses))
    for threads, t in best.items():
        times["vector, into out=, paper", threads] = t
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    x = poses[0]
    kern(x)
    n_one = 20_000
    t_one = best_of(repeat, lambda: [kern(x) for _ in range(n_one)]) / n_one
    return times, t_one


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


def main() -> None:
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
    args = parser.parse_args()
    if args.cold:
        cold_table()
        return
    h4 = h4pin.load("prototype")
    rng = np.random.default_rng(0)
    poses = centre_pose(h4) + rng.uniform(-1, 1, (args.batch, 4)) * [0.1, 0.1, 0.06, 0.4]
    poses = poses[np.all(np.isfinite(h4.inverse_geometry(poses, on_error="nan")), axis=1)]
    n_single = 2000
    few = poses[:n_single]

    t_batch = best_of(args.repeat, lambda: compliance(h4, poses, "paper", method="closed_form"))
    t_batch_c = best_of(args.repeat, lambda: compliance(h4, poses, "consistent", method="closed_form"))
    t_default = best_of(args.repeat, lambda: compliance(h4, poses, "paper")) / len(poses)
    t_single = best_of(args.repeat, lambda: [compliance(h4, x, "paper") for x in few]) / n_single
    t_single_pin = best_of(args.repeat, lambda: [compliance(h4, x, "paper", method="pinocchio")
                                                 for x in few[:500]]) / 500
    t_naive = best_of(args.repeat, lambda: [naive_compliance(h4.params, x) for x in few]) / n_single
    t_statics = best_of(1, lambda: [statics.compliance_matrix(h4.geometry, x) for x in few[:200]]) / 200
    t_fd = best_of(1, lambda: [deformed.compliance_terms(h4.geometry, x) for x in few[:5]]) / 5
    t_kernel, t_one = kernel_rows(h4, poses, args.repeat)
    t_terms = best_of(args.repeat, lambda: compliance(h4, poses, "paper", terms=True)) / len(poses)
    x0 = few[0]
    t_small = {n: best_of(args.repeat, lambda n=n: [compliance(h4, few[:n]) for _ in range(200)]) / 200
               for n in (1, 10)}
    mem_default, mem_terms = (bytes_per_pose_of(lambda t=t: compliance(h4, poses, "paper", terms=t), len(poses))
                              for t in (False, True))
    t_single_terms = best_of(args.repeat, lambda: [compliance(h4, x0, "paper", terms=True) for _ in range(2000)]) / 2000
    with_el = h4.with_elements(ILLUSTRATIVE)
    t_el_batch = best_of(args.repeat, lambda: compliance(with_el, few, "paper")) / n_single
    t_el_single = best_of(args.repeat, lambda: [compliance(with_el, x, "paper") for x in few[:500]]) / 500
    t_atlas = atlas_row(h4, args.repeat)

    ours = compliance(h4, few[:50], "paper", method="closed_form").matrix
    naive = np.array([naive_compliance(h4.params, x) for x in few[:50]])
    agree = np.max(np.abs(ours - naive)) / np.max(np.abs(ours))
    if agree > 1e-10:
        raise SystemExit(f"naive eq. 30 and h4pin disagree: {agree:.1e} relative")
    fast = kernel.compliance_batch(h4.geometry, poses, "paper")
    ref = compliance(h4, poses, "paper", method="closed_form").matrix
    agree_k = float(np.max(np.max(np.abs(fast.K - ref), axis=(1, 2)) / np.max(np.abs(ref), axis=(1, 2))))
    if agree_k > 1e-12:
        raise SystemExit(f"kernel and h4pin disagree: {agree_k:.1e} relative")
    bytes_per_pose = sum(a.nbytes for a in fast if a is not None) / len(poses)

    per_pose = t_batch / len(poses)
    print(f"h4pin compliance speed, {platform.processor() or platform.machine()}, {len(poses)} batch poses, "
          f"best of {args.repeat} (naive vs h4pin: {agree:.1e}, kernel vs h4pin: {agree_k:.1e} relative), "
          f"load average before: {os.getloadavg()[0]:.2f}\n")
    rows = [
        ("numpy batch (reference), 'paper', incl. inverse geometry", per_pose),
        ("numpy batch (reference), 'consistent', incl. inverse geometry", t_batch_c / len(poses)),
        ("h4pin.compliance(h4, poses): default batch path", t_default),
        ("h4pin.compliance(h4, pose): default one-pose path", t_single),
        ("h4pin.compliance(h4, pose, method='pinocchio')", t_single_pin),
        ("h4pin.compliance, robot with all 11 elements, batch", t_el_batch),
        ("h4pin.compliance, robot with all 11 elements, one pose", t_el_single),
        ("atlas, 500 x 500 x 3 grid, 'consistent' (derived fields)", t_atlas),
        ("naive per-pose numpy eq. 30 (loops, np.cross, inv)", t_naive),
        ("validation: Newton-Euler statics route", t_statics),
        ("validation: finite-difference route (non-linear)", t_fd),
    ]
    rows += [
        ("h4pin.compliance(h4, poses, terms=True): batch with terms", t_terms),
        ("h4pin.compliance(h4, pose, terms=True): one pose with terms", t_single_terms),
        ("h4pin.compliance(h4, poses) for a batch of 1 pose (per call)", t_small[1]),
        ("h4pin.compliance(h4, poses) for a batch of 10 poses (per call)", t_small[10]),
    ]
    for (model, threads), t in t_kernel.items():
        kind, _, name = model.rpartition(" ")
        label = ("vector kernel batch into out=" if "out=" in kind else "vector kernel batch" if kind
                 else "scalar kernel batch")
        rows.append((f"{label}, '{name}', {threads} thread{'s' * (threads > 1)}, incl. IGM + verdict", t))
    rows.append(("kernel, one pose (Kernel call, incl. Python overhead)", t_one))
    peak = peak_flops()
    dgemm = measured_dgemm()
    print(f"| {'path':<64} | {'poses/s':>10} | {'us/pose':>9} | {'vs naive':>8} | {'vs batch':>8} "
          f"| {'vs prev.':>8} | {'of peak':>7} |")
    print(f"|{'-' * 66}|{'-' * 12}|{'-' * 11}|{'-' * 10}|{'-' * 10}|{'-' * 10}|{'-' * 9}|")
    for name, t in rows:
        prev = PREVIOUS.get(name)
        vs_prev = f"{prev / (t * 1e6):>7.2f}x" if prev else f"{'':>8}"
        hw = ""
        if "kernel batch" in name and peak:
            threads = int(name.split(" thread")[0].rsplit(" ", 1)[-1])
            hw = f"{KERNEL_FLOPS / t / (peak * threads):.1%}"
        print(f"| {name:<64} | {1 / t:>10.0f} | {t * 1e6:>9.2f} | {t_naive / t:>7.1f}x | {per_pose / t:>7.2f}x "
              f"| {vs_prev} | {hw:>7} |")
    print("\n'vs prev.': the same row in the previous release's table (README, same machine).")
    if peak:
        print(f"'of peak': {KERNEL_FLOPS} nominal flops a pose x poses/s / the cores' double-precision peak "
              f"({peak / 1e9:.1f} GFLOP/s a core: 2 FMA pipes x the vector width x 2 x clock; {cpu_summary()}). "
              f"numpy's dgemm reaches {dgemm / 1e9:.1f} GFLOP/s on one core here ({dgemm / peak:.0%} of that peak).")
    floor = 5 * 64 * 8 + 4 * 8 + 8 + 1 + 4 * 8
    print(f"kernel output without terms: {bytes_per_pose:.0f} bytes/pose (K, q, condition, status); "
          f"h4pin.compliance peak memory a pose: {mem_default:.0f} B, {mem_terms:.0f} B with terms (the arrays a "
          f"result with terms holds: K and 4 terms 2560 B, q, condition, status, pose: {floor} B)")

    print("\ntargets:")
    one_core = min(1 / t_kernel["vector paper", 1], 1 / t_kernel["vector consistent", 1])
    two_cores = min(1 / t_kernel["vector paper", 2], 1 / t_kernel["vector consistent", 2])
    checks = [  # (what, measured, target, unit, True: at least / False: at most)
        ("vector batch, 1 core", one_core, 1_200_000, "poses/s", True),
        ("vector batch, 2 cores / 1 core", two_cores / one_core, 1.9, "x", True),
        ("  the same into out= (no page faults)",
         t_kernel["vector, into out=, paper", 1] / t_kernel["vector, into out=, paper", 2], 1.9, "x", True),
        ("one pose, h4pin.compliance", t_single * 1e6, 4.0, "us", False),
        ("one pose via Pinocchio", t_single_pin * 1e6, 50.0, "us", False),
        ("terms=True batch / default batch", t_terms / t_default, 1.3, "x", False),
        ("terms=True batch, memory a pose", mem_terms, 2560, "B", False),
        ("default batch, memory a pose", mem_default, 600, "B", False),
    ]
    for name, got, want, unit, at_least in checks:
        ok = got >= want if at_least else got <= want
        verdict = "met" if ok else f"MISSED by {abs(got / want - 1):.0%}"
        print(f"  {name:<36} {got:>12,.2f} {unit:<8} {'>=' if at_least else '<='} {want:>12,.2f}   {verdict}")
    print(f"  (numba threads available: {numba.config.NUMBA_NUM_THREADS}, threading layer: "
          f"{numba.threading_layer()})")

    if args.atlas_stream:
        atlas_stream_row()
    if args.big:
        n = 10_000_000
        secs, rss, worst = big_stream(h4, n, kernel.CHUNK)
        print(f"\nstreaming {n:.0e} poses in chunks of {kernel.CHUNK}: {secs:.1f} s ({n / secs:,.0f} poses/s), "
              f"peak RSS {rss:.0f} MB (target < 1024 MB: {'met' if rss < 1024 else 'MISSED'}), "
              f"worst K_xx {worst * 1e6:.1f} um/N")
    if args.dask or args.sweep:
        from h4pin.studies import sweep

        if args.dask:
            over = sweep.dask_overhead(workers=2)
            print(f"\nDask LocalCluster (2 workers): {over * 1e3:.2f} ms overhead per task")
        if args.sweep:
            print(f"\nsweep: {args.designs} designs x 1000 task poses (+ the volume grid)")
            for label, kwargs in (("1 core", {"threads": 1}), ("2 cores", {"threads": 2}),
                                  ("2 Dask workers", {"threads": 1, "workers": 2})):
                secs, evals = sweep.bench(args.designs, **kwargs)
                print(f"  {label:<16} {secs:8.1f} s  {evals / secs:>12,.0f} design-poses/s")
            print("\nsweep per-design overhead (sweep.evaluate with the kernel's compiled call left out; "
                  "target <= 20 % of the kernel's time for the 1000 task poses)")
            rows = {"1 thread": [sweep_overhead()]}
            with sweep._client(2, None) as client:
                rows["2 Dask workers, each"] = list(client.run(sweep_overhead).values())
            for label, results in rows.items():
                for ev, over, k_task in results:
                    print(f"  {label:<22} evaluate {ev * 1e3:.3f} ms/design (2728 poses), "
                          f"overhead {over * 1e3:.3f} ms, kernel {k_task * 1e3:.3f} ms (1000 poses): "
                          f"{over / k_task:.0%}")
    if args.tolerance:
        bench_tolerance()


COLD_STEPS = {
    "import h4pin": "",
    "h4pin.load()": "h4 = h4pin.load()",
    "first single pose, compliance(h4, x)": "h4pin.compliance(h4, x)",
    "first batch of 1000 poses": "h4pin.compliance(h4, xs)",
    "first pose on the Pinocchio path": "h4pin.compliance(h4, x, method='pinocchio')",
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


def cold_run(args: list[str], mode: str) -> tuple[float, str]:
    """Wall time and stdout of a fresh process with an empty numba cache, ``H4PIN_WARMUP=mode``."""
    import os
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, H4PIN_WARMUP=mode)
        t = time.perf_counter()
        out = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, check=True)
        return time.perf_counter() - t, out.stdout


def cold_table() -> None:
    """First use in fresh processes with an empty cache: h4pin's default (numpy path and
    interpreted twins while a warm-up compiles; measured with the warm-up off, so that the row is
    the call's own time) against compiling at first use (``H4PIN_WARMUP=inline``, before)."""
    import json
    import shutil
    import sys

    cli = shutil.which("h4pin") or str(__import__("pathlib").Path(sys.executable).parent / "h4pin")
    rows = {}
    for mode in ("off", "inline"):
        rows.setdefault("first `h4pin table2` (whole command)", {})[mode] = cold_run(
            ["-c", f"import sys; sys.argv = [{cli!r}, 'table2']; from h4pin.cli import main; main()"], mode)[0]
        steps = json.loads(cold_run(["-c", COLD_SCRIPT.format(steps=COLD_STEPS)], mode)[1])
        for name, seconds in steps.items():
            rows.setdefault(name, {})[mode] = seconds
    warm = cold_run(["-m", "h4pin.warmup", "--quiet"], "inline")[0]
    rows["`h4pin warmup` (compile everything, once)"] = {"off": warm}
    print(f"h4pin first use, {platform.processor() or platform.machine()}, empty numba cache, one fresh process "
          f"per column\n")
    print(f"| {'first use':<45} | {'now (s)':>8} | {'compiling at first use (s)':>27} |")
    print(f"|{'-' * 47}|{'-' * 10}|{'-' * 29}|")
    for name, t in rows.items():
        inline = f"{t['inline']:.2f}" if "inline" in t else "-"
        print(f"| {name:<45} | {t['off']:>8.2f} | {inline:>27} |")


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
    kerns = [k for k in sweep._kernels(rows) if k is not None]
    poses = np.ascontiguousarray(np.concatenate([spec.task.poses(), spec.volume.poses()]))
    task = np.ascontiguousarray(poses[:1000])
    sweep.evaluate(rows[:4], spec, 1)
    stored = kernel.compliance_batch(kerns[0], poses, spec.model)
    task_buf = kernel._empty(len(task), False, False)
    real_empty, real_run = kernel._empty, kernel._run

    def overhead_only() -> None:
        kernel._empty, kernel._run = (lambda *a: stored), (lambda kern, x, code, res, *a, **k: res)
        try:
            sweep.evaluate(rows, spec, 1)
        finally:
            kernel._empty, kernel._run = real_empty, real_run

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
