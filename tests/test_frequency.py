# SPDX-License-Identifier: Apache-2.0
"""The first-frequency map and the frequency/workspace Pareto front (h4pin.studies.frequency)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("xarray")

from kkt import constraint_rows, mass_matrix, nullspace_frequencies, spring_vector  # noqa: E402

import h4pin  # noqa: E402
from h4pin import verdicts  # noqa: E402
from h4pin.elastic import modes  # noqa: E402
from h4pin.elastic.modal import mass_model  # noqa: E402
from h4pin.mechanism import Payload
from h4pin.studies import frequency  # noqa: E402


def _independent_first(h4, poses: np.ndarray, payload_kg: float = 0.0) -> np.ndarray:
    """The first natural frequency (Hz) at each pose by plain Pinocchio and scipy (tests/kkt.py):
    crba of the elastic model with its link inertias (a point ``payload_kg`` added to the body of
    frame D), the springs, and the generalized eigenproblem on the null space of the closures
    and the locked actuators. Nothing of h4pin.vibration, the compiled twin or h4pin.elastic.modal's
    solve."""
    em = h4pin.elastic_model(h4)
    model = pin.Model(mass_model(em))  # the URDF's inertias, each forearm on its actuator's spring
    if payload_kg:
        frame = model.frames[model.getFrameId("D")]
        model.inertias[frame.parentJoint] += pin.Inertia(payload_kg, frame.placement.translation, np.zeros((3, 3)))
    k = spring_vector(model, em.stiffness)
    out = []
    for x in poses:
        q = em.configuration(x)
        a, d = constraint_rows(model, em.constraint_models, q, em.locked)
        out.append(nullspace_frequencies(a, k, mass_matrix(model, d, q))[0])
    return np.array(out)


def test_map_is_mirror_symmetric_and_refuses_what_the_robot_cannot_reach(proto, centre):
    """The prototype is symmetric about the x-z plane at theta = 0 (its K has zero y couplings
    at the centre): the first frequency at (x, y) equals the one at (x, -y). Poses out of reach
    are NaN with their verdict, and every reachable point equals the independent route
    (crba and the closures' null space, tests/kkt.py) to 1e-10."""
    ys = np.array([-0.06, 0.0, 0.06])
    xs = np.array([-0.08, 0.0, 0.08, 0.9])
    ds = frequency.frequency_map(proto, xs, ys, progress=False)
    f, status = ds.first_frequency.values, ds.status.values
    assert np.all(status[:, :3] == verdicts.OK) and np.all(status[:, 3] == verdicts.UNREACHABLE)
    assert np.all(np.isnan(f[:, 3])) and np.all(np.isfinite(f[:, :3]))
    np.testing.assert_allclose(f[0, :3], f[2, :3], rtol=1e-9)
    gy, gx = np.meshgrid(ys, xs[:3], indexing="ij")
    grid = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, centre[2]), np.zeros(gx.size)], axis=1)
    np.testing.assert_allclose(f[:, :3].ravel(), _independent_first(proto, grid), rtol=1e-10)
    assert np.nanmax(f) / np.nanmin(f) > 1.1  # the map is not flat (29 to 36 Hz here)


def test_payload_lowers_the_first_frequency_everywhere(proto, centre):
    """With and without a 0.5 kg point payload at D: each equals the independent route (1e-10),
    and the payload lowers it."""
    poses = centre + np.array([[0.0, 0.0, 0.0, 0.0], [0.05, -0.03, 0.02, 0.2]])
    bare, _ = frequency.first_frequency(proto, poses)
    loaded, _ = frequency.first_frequency(proto, poses, Payload(0.5))
    np.testing.assert_allclose(bare, _independent_first(proto, poses), rtol=1e-10)
    np.testing.assert_allclose(loaded, _independent_first(proto, poses, 0.5), rtol=1e-10)
    assert np.all(loaded < bare)


def test_pareto_front_is_the_non_dominated_designs():
    """On synthetic sweep results (frequencies given), every front design is dominated by none,
    and every other design is dominated by a front one (brute force)."""
    rng = np.random.default_rng(3)
    n = 40
    freq, vol = rng.uniform(20, 60, n), rng.uniform(1, 9, n)
    front = set(frequency.pareto_indices(freq, vol).tolist())

    def dominated(i):
        return any(freq[j] >= freq[i] and vol[j] >= vol[i] and (freq[j] > freq[i] or vol[j] > vol[i])
                   for j in range(n))

    assert front == {i for i in range(n) if not dominated(i)}


@pytest.mark.slow  # a whole command in a subprocess, 8 s; the modes CLI's errors stay in the default run
def test_cli_prints_the_modes_and_writes_the_map(tmp_path, proto, centre):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    png = tmp_path / "f.png"
    out = subprocess.run([sys.executable, "-m", "h4pin.cli", "modes", "--payload", "0.5", "--figure", str(png),
                          "--grid", "3", "--span", "0.1"], capture_output=True, text=True, cwd=root, timeout=120)
    assert out.returncode == 0, out.stderr
    rows = [line.split() for line in out.stdout.splitlines() if line.split() and line.split()[0].isdigit()]
    ref = modes(proto, centre, Payload(0.5)).frequencies[:4]
    np.testing.assert_allclose([float(r[1]) for r in rows], ref, atol=0.051)
    assert png.is_file() and png.stat().st_size > 1000
    for args, message in ((["--payload", "-1"], "--payload must be a finite mass >= 0"),
                          (["--count", "0"], "--count must be >= 1"),
                          (["--figure", str(tmp_path / "m.txt")], "--figure"),
                          (["--pose", "0", "0", "-2", "0"], "cannot reach")):
        bad = subprocess.run([sys.executable, "-m", "h4pin.cli", "modes", *args], capture_output=True, text=True,
                             cwd=root, timeout=120)
        assert bad.returncode == 2 and message in bad.stderr and len(bad.stderr.strip().splitlines()) == 1, bad.stderr
    assert not (tmp_path / "m.txt").exists()
