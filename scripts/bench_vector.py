# SPDX-License-Identifier: Apache-2.0
"""Poses per second of the scalar batch kernel (kernel._batch) and the lane-vector kernel
(vector._run, threaded by vector._vbatch) on 1 and 2 threads, timed alternately (best of --repeat), the one-pose times,
and with --asm the instruction mix of both compiled batch functions.

Default path: model "paper", no terms, inverse geometry and every verdict included; poses around
the prototype's workspace centre (as scripts/bench.py), all reachable.
"""

from __future__ import annotations

import argparse
import collections
import functools
import os
import re
import time

import numba
import numpy as np

import h4pin
from h4pin.kinematics.closed_form import centre_pose
from h4pin.stiffness import kernel, packed, vector

#: The vector kernel whatever the batch size (kernel.compliance_batch's arguments).
vector_batch = functools.partial(kernel.compliance_batch, vector=True)

FMA = ("vfmadd", "vfnmadd", "vfmsub", "vfnmsub")
scalar = functools.partial(kernel.compliance_batch, vector=False)  # the one-pose-at-a-time kernel


def poses_of(h4: h4pin.H4, n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    x = centre_pose(h4) + rng.uniform(-1, 1, (n, 4)) * [0.1, 0.1, 0.06, 0.4]
    return x[np.all(np.isfinite(h4.inverse_geometry(x, on_error="nan")), axis=1)]


def rates(kern: kernel.Kernel, x: np.ndarray, repeat: int) -> dict[tuple[str, int], float]:
    """Poses/s per (kernel, threads), the two kernels alternating run by run."""
    out = {}
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        best = {"scalar": np.inf, "vector": np.inf}
        for _ in range(repeat):
            for name, f in (("scalar", scalar), ("vector", vector_batch)):
                t0 = time.perf_counter()
                f(kern, x, "paper")
                best[name] = min(best[name], time.perf_counter() - t0)
        for name, t in best.items():
            out[name, threads] = len(x) / t
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


def one_pose(kern: kernel.Kernel, x: np.ndarray, repeat: int, n: int = 20_000) -> dict[str, float]:
    """Seconds per call for one pose: the scalar one-pose kernel, and both batch functions on a
    (1, 4) batch."""
    p = np.ascontiguousarray(x[0])
    one = np.ascontiguousarray(x[:1])
    calls = {"scalar one-pose (Kernel.__call__)": lambda: kern(p),
             "scalar batch, N = 1": lambda: kernel.compliance_batch(kern, one),
             "vector batch, N = 1": lambda: vector_batch(kern, one)}
    out = {}
    for name, f in calls.items():
        f()
        best = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            for _ in range(n):
                f()
            best = min(best, (time.perf_counter() - t0) / n)
        out[name] = best
    return out


def instruction_mix(kern: kernel.Kernel) -> dict[str, collections.Counter]:
    """Static instruction counts of uncached copies of both batch functions (numba gives no
    assembly for code loaded from its cache)."""
    x = np.zeros((2, 4)) + [0.0, 0.0, -0.6, 0.0]
    res = kernel._empty(2, False, False)
    out = {}
    for name, fn, args in (
            ("kernel._batch", kernel._batch, (x, kern.packed, 0, res.K, res.q, res.condition, res.status,
                                              packed.NO_TERMS_N, False, packed.NO_J_N, False, 256)),
            ("vector._run", vector._run, (x, 0, 2, kern.packed, 0, res.K, res.q, res.condition, res.status,
                                          packed.NO_TERMS_N, False, packed.NO_J_N, False))):
        opts = {k: v for k, v in fn.targetoptions.items() if k not in ("cache", "nopython")}
        fresh = numba.njit(**opts)(fn.py_func)
        fresh(*args)
        asm = "\n".join(fresh.inspect_asm(s) for s in fresh.signatures)
        c: collections.Counter = collections.Counter()
        for m in re.finditer(r"^\s+([a-z][a-z0-9]*)\s+([^\n]*)", asm, re.M):
            op, operands = m.group(1), m.group(2)
            reg = "zmm" if "zmm" in operands else "ymm" if "ymm" in operands else "xmm" if "xmm" in operands else ""
            if not reg:
                continue
            if op.startswith(FMA):
                kind = "fma"
            elif op in ("vmulpd", "vmulsd"):
                kind = "mul"
            elif op in ("vaddpd", "vaddsd", "vsubpd", "vsubsd"):
                kind = "add/sub"
            elif op in ("vdivpd", "vdivsd"):
                kind = "div"
            elif op in ("vsqrtpd", "vsqrtsd"):
                kind = "sqrt"
            elif op.startswith(("vblendm", "vblendv")) or op.startswith("vcmp"):
                kind = "cmp/blend"
            else:
                kind = "other"
            width = reg if op.endswith("pd") or reg in ("ymm", "zmm") else "scalar"
            if op.endswith("sd"):
                width = "scalar"
            c[kind, width] += 1
        c["total", ""] = sum(c.values())
        out[name] = c
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=100_000, help="poses per batch")
    parser.add_argument("--repeat", type=int, default=5, help="best of this many runs")
    parser.add_argument("--asm", action="store_true", help="also print the instruction mix (compiles twice)")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")
    kern = kernel.prepare(h4.geometry)
    x = poses_of(h4, args.batch)
    a, b = scalar(kern, x), vector_batch(kern, x)  # load or compile once
    if not np.array_equal(a.status, b.status):
        raise SystemExit("the two kernels give different verdicts")
    r = rates(kern, x, args.repeat)
    load = os.getloadavg()
    print(f"N = {len(x)}, model paper, best of {args.repeat}, alternated; load average {load[0]:.2f} "
          f"{load[1]:.2f} {load[2]:.2f}; numba threads available {numba.config.NUMBA_NUM_THREADS}")
    print(f"{'threads':>7} | {'scalar poses/s':>15} | {'vector poses/s':>15} | {'vector/scalar':>13}")
    for threads in (1, 2):
        s, v = r["scalar", threads], r["vector", threads]
        print(f"{threads:>7} | {s:>15,.0f} | {v:>15,.0f} | {v / s:>13.2f}")
    print(f"2 threads / 1 thread: scalar {r['scalar', 2] / r['scalar', 1]:.2f}, "
          f"vector {r['vector', 2] / r['vector', 1]:.2f}")
    for name, t in one_pose(kern, x, args.repeat).items():
        print(f"one pose, {name}: {t * 1e6:.2f} us")
    if args.asm:
        for name, c in instruction_mix(kern).items():
            print(f"{name}: " + ", ".join(f"{k[0]} {k[1]}".strip() + f" {v}" for k, v in sorted(c.items())))


if __name__ == "__main__":
    main()
