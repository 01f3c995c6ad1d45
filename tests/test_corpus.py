# SPDX-License-Identifier: Apache-2.0
"""Every closed-loop robot of the corpus (tests/robots/corpus.yaml: Gepetto's example-parallel-
robots, read as their authors' loader reads them) through h4pin.mechanism.Mechanism: it loads, its
motors are the sidecar's, it assembles by default inside its ranges, and its compliance and
natural frequencies agree with independent routes built from Pinocchio's frame Jacobians and the
sidecar's own closure definitions (tests/kkt.py, shared with tests/test_mechanism.py):

* compliance: the KKT system ``[[K, Aᵀ], [A, 0]]`` (A: each closure's rows, 3-D as the world gap
  of the two frames' origins, 6-D as frame 2's motion relative to frame 1 in frame 1's axes; the
  locked joints as identity rows), solved densely for the output's Jacobian;
* frequencies: scipy's generalized eigenproblem ``Nᵀ K N x = w² Nᵀ M N x`` on the null space N of
  A (scipy.linalg.null_space), its finite eigenvalues.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from kkt import constraint_rows, kkt_compliance, mass_matrix, spring_vector

from h4pin.errors import MechanismWarning
from h4pin.mechanism import Mechanism
from h4pin.mechanism.engine import UnassembledError

yaml = pytest.importorskip("yaml")
scipy_linalg = pytest.importorskip("scipy.linalg")

HERE = Path(__file__).parent / "robots"
CORPUS = yaml.safe_load((HERE / "corpus.yaml").read_text())["robots"]
#: The robots whose own files do not close from their reference with any start the trust-region
#: solver finds (eight random starts tried: 0.096-0.120 m and 0.0427-0.0431 m), with the residual it
#: reaches from the reference (m): measured, stated, checked.
OPEN = {"kangaroo_like": 0.117, "kangaroo_like_2legs": 0.0431}


def _mechanism(entry: dict) -> Mechanism:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        return Mechanism.from_urdf(HERE / entry["urdf"], HERE / entry["sidecar"], free_flyer=entry["free_flyer"])


def _springs(mech: Mechanism) -> dict[str, float]:
    """A spring on every joint but the free-flyer root, motors stiffer, values varied."""
    out = {}
    for j in range(1, mech.model.njoints):
        name = mech.model.names[j]
        if name in mech.free_flyers:
            continue
        out[name] = (2e3 if name in mech.actuated else 50.0) * (1.0 + 0.1 * (j % 7))
    return out


def _assembled_in_range(mech: Mechanism) -> np.ndarray:
    """The default assembly, checked closed (1e-9) and inside the file's ranges."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        q = mech.assemble()
    assert max(max(e) for e in mech.closure_errors(q).values()) <= 1e-9
    lo, hi = mech.ranges
    ranged = np.isfinite(lo)
    assert np.all((q[ranged] >= lo[ranged] - 1e-12) & (q[ranged] <= hi[ranged] + 1e-12))
    return q


@pytest.mark.parametrize("entry", CORPUS, ids=[e["name"] for e in CORPUS])
def test_corpus_robot(entry):
    mech = _mechanism(entry)
    side = yaml.safe_load((HERE / entry["sidecar"]).read_text())
    assert set(mech.actuated) == set(side["name_mot"])
    assert len(mech.constraint_models) == len(side["closed_loop"])
    if entry["name"] in OPEN:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MechanismWarning)
            with pytest.raises(UnassembledError, match="off by") as err:
                mech.assemble()
        off = float(str(err.value).split("off by ")[1].split()[0])
        assert off == pytest.approx(OPEN[entry["name"]], rel=0.05)
        return
    q = _assembled_in_range(mech)

    springs = _springs(mech)
    model = mech.model
    out_frame = side["closed_loop"][0][0]
    C = mech.compliance(q, springs, [out_frame])

    A, d = constraint_rows(model, mech.constraint_models, q, mech.free_flyers)
    k = spring_vector(model, springs)
    jo = pin.getFrameJacobian(model, d, model.getFrameId(out_frame), pin.LOCAL_WORLD_ALIGNED)
    want = kkt_compliance(A, k, jo)  # on the independent rows of A (a redundant closure set has dependent rows)
    np.testing.assert_allclose(C, want, rtol=0, atol=1e-9 * np.abs(want).max())

    # natural frequencies: the first four against the generalized eigenproblem on null(A)
    n = scipy_linalg.null_space(A, rcond=1e-10)  # the KKT route's rank threshold
    mass = mass_matrix(model, d, q)
    lam = scipy_linalg.eigvals(n.T @ np.diag(k) @ n, n.T @ mass @ n)
    lam = np.sort(lam[np.isfinite(lam)].real)
    lam = lam[lam > 0]
    got = mech.modes(q, springs).frequencies
    m = min(4, len(got))
    np.testing.assert_allclose(got[:m], np.sqrt(lam[:m]) / (2 * np.pi), rtol=1e-7)


@pytest.mark.slow
def test_corpus_timings_table():
    """The corpus as docs/mechanisms.md's table gives it: each robot loads, and a compliance call
    costs milliseconds (printed with -s; no time is asserted)."""
    rows = []
    for entry in CORPUS:
        mech = _mechanism(entry)
        if entry["name"] in OPEN:
            rows.append((entry["name"], len(mech.constraint_models), len(mech.actuated), mech.model.nv, None))
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MechanismWarning)
            q = mech.assemble()
        springs = _springs(mech)
        out = yaml.safe_load((HERE / entry["sidecar"]).read_text())["closed_loop"][0][0]
        t = time.perf_counter()
        for _ in range(5):
            mech.compliance(q, springs, [out])
        rows.append((entry["name"], len(mech.constraint_models), len(mech.actuated), mech.model.nv,
                     (time.perf_counter() - t) / 5 * 1e3))
    for r in rows:
        print(f"{r[0]:<24}{r[1]:>4}{r[2]:>4}{r[3]:>5}  {'-' if r[4] is None else f'{r[4]:.2f} ms'}")
    assert len(rows) == len(CORPUS)
