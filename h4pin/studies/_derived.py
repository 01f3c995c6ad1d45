# SPDX-License-Identifier: Apache-2.0
"""Compiled derived quantities of the compliance of eq. 30 (Company, Pierrot, Fauroux, ICRA 2005)
for the studies: the atlas (:mod:`h4pin.studies.atlas`) and the design sweep
(:mod:`h4pin.studies.sweep`) reduce the kernel's K (N, 8, 8) and J (N, 4, 4) here, in numba,
instead of calling ``np.linalg.eigvalsh`` and ``np.linalg.cond`` on stacks of small matrices.

* :func:`sym3_eigvals`: the eigenvalues of a symmetric 3x3 matrix by cyclic Jacobi rotations with
  a relative stopping test (an off-diagonal entry is dropped once it is below 1e-17 of the
  geometric mean of its two diagonal entries), so the eigenvalues of a positive definite matrix
  keep their relative accuracy even when it is ill-conditioned (Demmel and Veselic, 1992);
* :func:`cond4`: the 2-norm condition number of a 4x4 matrix by a one-sided (Hestenes) Jacobi SVD
  on its rows: the singular values are the norms of the rows once they are mutually orthogonal.
  Rows are rotated (not columns) because J = Jx^-1 Jq of eq. 8 mixes units by row (m/rad for
  x, y, z, rad/rad for theta): the one-sided Jacobi SVD is insensitive to that scaling;
* :func:`atlas_fields`: per pose, compliance_max (m/N), isotropy (1), stiffness_z (N/m) and
  cond_J (1), NaN where the status is not 0, in parallel over the poses (``prange``);
* :func:`design_reduce`: per design, the count of task poses with status 0, the worst
  compliance over them (m/N) and the count of volume-grid poses with status 0.

Every function is ``nogil`` and cached on disk (``cache=True``); ``tests/test_atlas.py`` holds
them to numpy (``eigvalsh``, ``cond``) and to exact references.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Sweeps of :func:`sym3_eigvals` and :func:`cond4` at most (3x3 and 4x4 Jacobi converge
#: quadratically: 4 to 6 sweeps reach round-off).
MAX_SWEEPS = 12
#: Relative size below which an off-diagonal entry of :func:`sym3_eigvals` counts as zero (each
#: rotation sets its entry to exactly 0, so the others fall below this in a few sweeps).
_TINY = 1e-17
_TINY2 = _TINY * _TINY
#: Relative size below which two rows of :func:`singular_values4` count as orthogonal: their
#: inner product is recomputed from the rows, so it stalls at round-off (about 1e-16).
_TINY_ROWS = 2.2e-16
_TINY_ROWS2 = _TINY_ROWS * _TINY_ROWS


@njit(cache=True, nogil=True, inline="always")
def _jacobi_t(app, aqq, apq):
    """tan of the Jacobi angle that zeroes apq (the smaller root, |t| <= 1)."""
    theta = (aqq - app) / (2.0 * apq)
    if abs(theta) > 1e150:  # theta^2 would overflow
        return 0.5 / theta
    t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
    return t if theta >= 0.0 else -t


@njit(cache=True, nogil=True, inline="always")
def _jacobi_pair(app, aqq, apq, apr, aqr):
    """The Jacobi rotation of the pair (p, q) that zeroes apq (set it to 0 after): the new app,
    aqq, apr, aqr (apr, aqr: rows p and q of the third column r) and whether it rotated (an apq
    negligible against app and aqq is dropped without rotating)."""
    if apq == 0.0 or apq * apq <= _TINY2 * abs(app * aqq):
        return app, aqq, apr, aqr, False
    t = _jacobi_t(app, aqq, apq)
    c = 1.0 / np.sqrt(t * t + 1.0)
    s = t * c
    return app - t * apq, aqq + t * apq, c * apr - s * aqr, s * apr + c * aqr, True


@njit(cache=True, nogil=True)
def sym3_eigvals(a00, a01, a02, a11, a12, a22):
    """The eigenvalues (ascending) of the symmetric 3x3 matrix [[a00, a01, a02], [., a11, a12],
    [., ., a22]] by cyclic Jacobi rotations; any unit (that of the entries)."""
    for _ in range(MAX_SWEEPS):
        a00, a11, a02, a12, r01 = _jacobi_pair(a00, a11, a01, a02, a12)  # pair (0, 1); third index 2
        a01 = 0.0
        a00, a22, a01, a12, r02 = _jacobi_pair(a00, a22, a02, a01, a12)  # pair (0, 2); third index 1
        a02 = 0.0
        a11, a22, a01, a02, r12 = _jacobi_pair(a11, a22, a12, a01, a02)  # pair (1, 2); third index 0
        a12 = 0.0
        rotated = r01 or r02 or r12
        if not rotated:
            break
    lo, mid, hi = a00, a11, a22
    if lo > mid:
        lo, mid = mid, lo
    if mid > hi:
        mid, hi = hi, mid
    if lo > mid:
        lo, mid = mid, lo
    return lo, mid, hi


@njit(cache=True, nogil=True, inline="always")
def _orthogonalize_rows(x, nrm):
    """Rotate the rows of the 4x4 ``x`` in place until they are mutually orthogonal (one-sided
    Jacobi); their norms are then the singular values. ``nrm`` (4,) is scratch: the squared row
    norms, updated by each rotation (a' = a - t g, b' = b + t g) instead of recomputed."""
    for i in range(4):
        nrm[i] = x[i, 0] * x[i, 0] + x[i, 1] * x[i, 1] + x[i, 2] * x[i, 2] + x[i, 3] * x[i, 3]
    for _ in range(MAX_SWEEPS):
        rotated = False
        for i in range(3):
            for j in range(i + 1, 4):
                alpha, beta = nrm[i], nrm[j]
                gamma = x[i, 0] * x[j, 0] + x[i, 1] * x[j, 1] + x[i, 2] * x[j, 2] + x[i, 3] * x[j, 3]
                if not (gamma * gamma > _TINY_ROWS2 * (alpha * beta)):  # orthogonal (or NaN)
                    continue
                t = _jacobi_t(alpha, beta, gamma)
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(4):
                    xi, xj = x[i, k], x[j, k]
                    x[i, k] = c * xi - s * xj
                    x[j, k] = s * xi + c * xj
                nrm[i] = alpha - t * gamma
                nrm[j] = beta + t * gamma
                rotated = True
        if not rotated:
            break
    for i in range(4):  # exact norms of the final rows
        nrm[i] = x[i, 0] * x[i, 0] + x[i, 1] * x[i, 1] + x[i, 2] * x[i, 2] + x[i, 3] * x[i, 3]


@njit(cache=True, nogil=True)
def singular_values4(a):
    """The singular values (descending) of the 4x4 matrix ``a`` (any unit) by a one-sided Jacobi
    SVD on its rows (``a`` is not changed; NaN in, NaN out)."""
    x = a.copy()
    nrm = np.empty(4)
    _orthogonalize_rows(x, nrm)
    return np.sort(np.sqrt(nrm))[::-1]


@njit(cache=True, nogil=True, inline="always")
def _cond4(a, x, nrm):
    """:func:`cond4` with ``x`` (4, 4) and ``nrm`` (4,) as scratch."""
    for i in range(4):
        for k in range(4):
            x[i, k] = a[i, k]
    _orthogonalize_rows(x, nrm)
    hi, lo = 0.0, np.inf
    for i in range(4):
        if not (nrm[i] == nrm[i]):
            return np.nan
        hi = max(hi, nrm[i])
        lo = min(lo, nrm[i])
    return np.inf if lo == 0.0 else np.sqrt(hi) / np.sqrt(lo)


@njit(cache=True, nogil=True)
def cond4(a):
    """The 2-norm condition number sigma_max / sigma_min of the 4x4 matrix ``a`` (inf if it is
    singular, NaN if it holds a NaN), by the one-sided Jacobi SVD of :func:`singular_values4`."""
    return _cond4(a, np.empty((4, 4)), np.empty(4))


@njit(cache=True, nogil=True, inline="always")
def _ktt_eigvals(K, p):
    """Eigenvalues (ascending) of the symmetric part of K[p, :3, :3]."""
    return sym3_eigvals(K[p, 0, 0], 0.5 * (K[p, 0, 1] + K[p, 1, 0]), 0.5 * (K[p, 0, 2] + K[p, 2, 0]),
                        K[p, 1, 1], 0.5 * (K[p, 1, 2] + K[p, 2, 1]), K[p, 2, 2])


#: Poses per parallel block of :func:`atlas_fields` (one scratch array per block).
_BLOCK = 1024


@njit(cache=True, nogil=True, parallel=True)
def atlas_fields(K, J, status, compliance_max, isotropy, stiffness_z, cond_J):
    """The atlas' derived quantities of N poses, in parallel over the poses.

    Args:
        K: (N, 8, 8) compliance of eq. 30 (SI; K_tt = K[:, :3, :3] in m/N).
        J: (N, 4, 4) J = Jx^-1 Jq of eq. 8.
        status: (N,) int8 verdicts; the outputs are NaN where it is not 0.
        compliance_max, isotropy, stiffness_z, cond_J: (N,) float64 outputs: the largest
            eigenvalue of the symmetric part of K_tt (m/N), smallest over largest (1), 1 / K_zz
            (N/m), the 2-norm condition number of J (1).
    """
    n = status.shape[0]
    for b in prange((n + _BLOCK - 1) // _BLOCK):
        x = np.empty((4, 4))
        nrm = np.empty(4)
        for p in range(b * _BLOCK, min(n, (b + 1) * _BLOCK)):
            if status[p] != 0:
                compliance_max[p] = np.nan
                isotropy[p] = np.nan
                stiffness_z[p] = np.nan
                cond_J[p] = np.nan
                continue
            lo, _, hi = _ktt_eigvals(K, p)
            compliance_max[p] = hi
            isotropy[p] = lo / hi
            stiffness_z[p] = 1.0 / K[p, 2, 2]
            cond_J[p] = _cond4(J[p], x, nrm)


@njit(cache=True, nogil=True, inline="always")
def _ktt_bound(K, p):
    """An upper bound on the largest eigenvalue of the symmetric part A of K[p, :3, :3]: the
    smaller of Gershgorin's (max_a A_aa + sum_b |A_ab|) and Wolkowicz and Styan's
    (m + sqrt(2/3 |A - m I|_F^2), m = trace / 3; 1980), the latter summed from A - m I so that no
    cancellation makes it smaller than it is; loosened by 1e-12 for round-off."""
    a00, a11, a22 = K[p, 0, 0], K[p, 1, 1], K[p, 2, 2]
    a01, a02, a12 = 0.5 * (K[p, 0, 1] + K[p, 1, 0]), 0.5 * (K[p, 0, 2] + K[p, 2, 0]), 0.5 * (K[p, 1, 2] + K[p, 2, 1])
    gersh = max(a00 + abs(a01) + abs(a02), max(a11 + abs(a01) + abs(a12), a22 + abs(a02) + abs(a12)))
    m = (a00 + a11 + a22) / 3.0
    d0, d1, d2 = a00 - m, a11 - m, a22 - m
    ws = m + np.sqrt((2.0 / 3.0) * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)))
    bound = min(gersh, ws)
    return bound + 1e-12 * abs(bound)


@njit(cache=True, nogil=True)
def design_reduce(K, status, n_task):
    """One design's reductions over its task poses (rows ``:n_task``) and its volume grid (rows
    ``n_task:``): (task poses with status 0, the worst compliance over them in m/N -- the largest
    eigenvalue of the symmetric part of K_tt, NaN if none --, grid poses with status 0).

    The eigenvalues are only computed where they can matter: starting from the pose with the
    largest diagonal entry, a pose whose upper bound on the largest eigenvalue (:func:`_ktt_bound`)
    is not above the worst found so far is skipped (its largest eigenvalue cannot be the worst):
    about 4 eigenvalue problems a design of 1 000 task poses instead of 1 000."""
    n_ok = 0
    top, first = -np.inf, -1
    for p in range(n_task):
        if status[p] == 0:
            n_ok += 1
            for a in range(3):
                if K[p, a, a] > top:
                    top, first = K[p, a, a], p
    worst = np.nan
    if n_ok:
        worst = _ktt_eigvals(K, first)[2] if first >= 0 else -np.inf
        for p in range(n_task):
            if status[p] != 0 or p == first:
                continue
            if _ktt_bound(K, p) <= worst:
                continue
            worst = max(worst, _ktt_eigvals(K, p)[2])
    n_grid = 0
    for p in range(n_task, status.shape[0]):
        if status[p] == 0:
            n_grid += 1
    return n_ok, worst, n_grid
