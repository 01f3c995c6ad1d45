# SPDX-License-Identifier: Apache-2.0
"""Batches of configurations for :class:`h4pin.mechanism.Mechanism`: the route of each call (the
compiled generic path of :mod:`h4pin.mechanism.compiled`, or Pinocchio's), blocks of
configurations over threads, a size estimate before anything is allocated, and assembly over a
list of motor positions by continuation.

``method``: ``"auto"`` (default) takes the compiled path when the model's joints are all of the
kinds it computes and its code is compiled (until then the Pinocchio route, while h4pin's
background warm-up compiles it: :mod:`h4pin._jit`); ``"compiled"`` insists (compiling in the
calling process if needed); ``"pinocchio"`` is the reference route. A configuration the compiled
path flags (a closure off, a near-singular elimination or reduced stiffness, nothing with mass) is
run through the Pinocchio route, whose verdict and message stand, so both routes refuse the same
configurations with the same errors.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin import _jit, limits
from h4pin.errors import H4Error, ParameterError, located
from h4pin.inputs import real_array
from h4pin.mechanism import compiled, engine
from h4pin.mechanism.payload import at_frame

METHODS = ("auto", "compiled", "pinocchio")
GATE = _jit.Gate("generic mechanism path", compiled.batch, step="mechanism")
#: Configurations per block handed to one thread.
BLOCK = 64
#: Bytes a configuration of a batch holds besides its outputs (its copy, status, coupling rows),
#: and configurations a second of the compiled path on one core (measured about 2e4 on the 48-DoF
#: robots of the corpus, one thread; rounded down).
BYTES_PER_CONFIGURATION = 256
#: Each mechanism's compiled tables (read-only once made), by payload; gone with the mechanism.
_TABLES: weakref.WeakKeyDictionary[Any, dict[Any, Any]] = weakref.WeakKeyDictionary()
CONFIGURATIONS_PER_S = 1e4


def check_threads(threads: Any) -> int:
    """``threads`` of a batch: one per core for None, an integer >= 1, capped to
    :data:`h4pin.limits.MAX_THREADS` with a :class:`~h4pin.limits.CappedWarning`."""
    return limits.check_threads(threads, os.cpu_count() or 1)


def configurations(mech: Any, q: Any, what: str = "q") -> tuple[np.ndarray, bool]:
    """``(Q (N, nq), one)``: a configuration (nq,) or a batch (N, nq) of ``mech`` (or of the
    rigid mechanism a beam model lifts), checked at once; ``one`` when a single one was given. A
    batch's size is estimated from its length before anything is copied (a broadcast array of
    10**10 rows is refused, not allocated)."""
    if np.ndim(q) != 2:
        return mech.configuration(q, what)[None], True
    n, nq = len(q), mech.model.nq
    if n == 0:
        raise ParameterError(f"{what}: an empty batch (give at least one configuration)")
    per = BYTES_PER_CONFIGURATION + 8 * nq + 8 * len(mech.couplings) * (mech.model.nv + 1)
    limits.check_size(f"{mech.name}: {limits.fmt_count(n)} configurations", n * per)
    arr = np.array(real_array(q, what, ParameterError, f"configurations, real numbers of shape (N, {nq})"))
    arr = mech.lift(arr)  # a configuration of the rigid mechanism: its beams at 0
    if arr.shape[1] != nq:
        raise ParameterError(f"{what}: configurations of shape (N, {nq}), got shape {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        i, c = bad[0]
        raise ParameterError(f"{what}[{i}][{c}] is {arr[i, c]}: a configuration must be finite")
    return arr, False


def _tables(mech: Any, payload: tuple[int, pin.Inertia] | None = None) -> compiled.Tables | None:
    cache = _TABLES.setdefault(mech, {})
    key = ("tables", None if payload is None else (payload[0], payload[1].mass, *payload[1].lever,
                                                   *payload[1].inertia.reshape(-1)))
    if key not in cache:
        extra = None if payload is None else {payload[0]: payload[1]}
        cache[key] = compiled.tables(mech.model, mech.constraint_models, extra)
    return cache[key]


def _route(mech: Any, method: str, tab: compiled.Tables | None) -> bool:
    """Whether this call takes the compiled path."""
    if method == "pinocchio":
        return False
    if tab is None:
        if method == "compiled":
            raise ParameterError(f"{mech.name}: a joint of a kind the compiled path does not compute (revolute, "
                                 "prismatic, spherical, free-flyer); use method='auto' or 'pinocchio'")
        return False
    if method == "compiled":
        with _jit.compiling():
            return GATE.ready
    return GATE.ready


def _run(mech: Any, tab: compiled.Tables, outs: compiled.Outputs, Q: np.ndarray, k: np.ndarray,
         lock: Sequence[str], n_freq: int, threads: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The compiled path over Q, in blocks over ``threads`` threads."""
    model = mech.model
    working = np.ones(model.nv, dtype=np.bool_)
    for name in lock:
        j = model.joints[model.getJointId(name)]
        working[j.idx_v:j.idx_v + j.nv] = False
    n, m = len(Q), len(outs.row_frame)
    extra, off = coupling_batch(mech, Q)  # off: a coupling that does not hold: the Pinocchio route says so
    comp, freq = np.full((n, m, m), np.nan), np.full((n, n_freq), np.nan)
    status = np.full(n, compiled.FLAGGED, dtype=np.int8)
    args = (*tab, *outs, Q, k, working, extra, engine.CLOSURE_TOL)

    def block(start: int) -> None:
        compiled.batch(*args, start, min(start + BLOCK, n), comp, freq, status)

    starts = range(0, n, BLOCK)
    if threads == 1 or n <= BLOCK:
        for s in starts:
            block(s)
    else:
        with ThreadPoolExecutor(max_workers=min(threads, len(starts))) as pool:
            list(pool.map(block, starts))
    status[off] = compiled.FLAGGED
    return comp, freq, status


def compliance(mech: Any, Q: np.ndarray, one: bool, stiff: dict[str, Any], outs: list[Any], lock: tuple[str, ...],
               method: str, threads: int) -> np.ndarray:
    """(N, m, m) compliance of ``outs`` at each configuration of Q (:meth:`Mechanism.compliance`)."""
    model = mech.model
    tab = _tables(mech)
    arrays = compiled.outputs(model, outs)
    rows = len(arrays.row_frame)
    if len(Q) > 1:
        limits.check_size(f"{mech.name}: compliance of {len(Q):,} configurations",
                          len(Q) * 8 * rows * rows * 2, len(Q) / CONFIGURATIONS_PER_S)
    if _route(mech, method, tab):
        comp, _, status = _run(mech, tab, arrays, Q, engine.stiffness_vector(model, stiff), lock, 0, threads)
    else:
        comp, status = np.full((len(Q), rows, rows), np.nan), np.full(len(Q), compiled.FLAGGED, dtype=np.int8)
    for i in np.flatnonzero(status != compiled.OK):
        try:
            check_couplings(mech, Q[i])
            comp[i] = engine.compliance_matrix(model, mech.constraint_models, Q[i], locked=lock, stiffness=stiff,
                                               outputs=outs, data=mech.data, extra_rows=coupling_rows(mech, Q[i]))
        except H4Error as exc:
            raise located(exc, None if one else f"configuration {i}") from None
    return comp


def check_couplings(mech: Any, q: np.ndarray) -> None:
    """UnassembledError when a joint coupling of ``mech`` does not hold at q."""
    for c in mech.couplings:
        r = c.residual_row(mech.model, q)[0]
        if not abs(r) <= engine.CLOSURE_TOL:
            raise engine.UnassembledError(f"coupling of {c.joint1!r} does not hold at q: error {abs(r):.3e}")


def coupling_batch(mech: Any, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows (N, r, nv), off (N,))``: the couplings' rows at each configuration of Q (N, nq),
    computed over the whole batch at once (:meth:`JointCoupling.residual_rows
    <h4pin.mechanism.couplings.JointCoupling.residual_rows>`), and where one does not hold."""
    extra = np.zeros((len(Q), len(mech.couplings), mech.model.nv))
    off = np.zeros(len(Q), dtype=bool)
    for r, c in enumerate(mech.couplings):
        res, _ = c.residual_rows(mech.model, Q, extra[:, r])
        off |= ~(np.abs(res) <= engine.CLOSURE_TOL)
    return extra, off


def coupling_rows(mech: Any, q: np.ndarray) -> np.ndarray | None:
    """The couplings' rows (r, nv) at q, or None without couplings."""
    if not mech.couplings:
        return None
    return np.array([c.residual_row(mech.model, q)[1] for c in mech.couplings])


def payload_inertia(model: pin.Model, payload: Any) -> tuple[int, pin.Inertia] | None:
    """``(joint id, inertia in that joint's frame)`` of ``(frame, h4pin.mechanism.Payload)``."""
    if payload is None:
        return None
    _, body, f = at_frame(model, payload)
    inertia = pin.Inertia(float(body.mass), np.asarray(body.com, dtype=float), np.asarray(body.inertia, dtype=float))
    return int(f.parentJoint), f.placement.act(inertia)


def frequencies(mech: Any, Q: np.ndarray, stiff: dict[str, Any], lock: tuple[str, ...], payload: Any,
                method: str, threads: int, one_config: Any) -> np.ndarray:
    """(N, m) natural frequencies (Hz, ascending, NaN past a configuration's last) at each
    configuration of Q; ``one_config(q)`` is the Pinocchio route's frequencies at one q."""
    model = mech.model
    pay = payload_inertia(model, payload)
    tab = _tables(mech, pay)
    limits.check_size(f"{mech.name}: natural frequencies of {len(Q):,} configurations",
                      len(Q) * 8 * (model.nv + 1) * 2, 3 * len(Q) / CONFIGURATIONS_PER_S)
    rows: list[np.ndarray | None] = [None] * len(Q)
    if _route(mech, method, tab):
        arrays = compiled.outputs(model, [])
        _, freq, status = _run(mech, tab, arrays, Q, engine.stiffness_vector(model, stiff), lock, model.nv, threads)
        for i in np.flatnonzero(status == compiled.OK):
            rows[i] = freq[i][np.isfinite(freq[i])]
    for i, row in enumerate(rows):
        if row is None:
            try:
                rows[i] = one_config(Q[i])
            except H4Error as exc:
                raise located(exc, f"configuration {i}") from None
    out = np.full((len(Q), max(len(r) for r in rows)), np.nan)
    for i, r in enumerate(rows):
        out[i, :len(r)] = r
    return out
