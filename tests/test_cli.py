# SPDX-License-Identifier: Apache-2.0
"""The table2 command, the scripts' claims, and one-line errors on the command line."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import h4pin
from h4pin.kinematics.closed_form import CENTRE_Q, centre_pose
from h4pin.stiffness.api import compliance
from h4pin.studies.paper import PAPER_COMPUTED

ROOT = Path(__file__).resolve().parent.parent


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "h4pin.cli", *args], capture_output=True, text=True, cwd=ROOT)


def script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_table2_prints_the_computed_block(proto, centre):
    out = run_cli("table2")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    start = next(n for n, line in enumerate(lines) if line.startswith("h4pin"))
    printed = np.array([[float(v) for v in lines[start + 1 + a].split()[-3:]] for a in range(3)])
    np.testing.assert_allclose(printed, compliance(proto, centre).translational * 1e6, atol=0.051)
    assert "paper, measured" in out.stdout and "%" in out.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [(["table2", "--variant", "nope"], "unknown H4 variant"),
     (["table2", "--variant", "symmetric"], "singular"),
     (["table2", "--urdf", "missing.urdf"], "no URDF file"),
     (["table2", "--model", "exact"], "model must be one of")],
)
def test_cli_errors_are_one_line(args, message):
    out = run_cli(*args)
    assert out.returncode == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert "Traceback" not in out.stderr


def test_gap_factors_are_exact():
    """K is linear in each compliance: I0 divided by the torsion factor gives xx = 40 um/N."""
    sens = script("sensitivity")
    factor = dict((t, f) for t, f, _ in sens.gap_factors())["torsion"]
    h4 = h4pin.load(h4pin.H4Params().replace(I0=h4pin.H4Params().I0 / factor))
    k = compliance(h4, h4.forward_geometry(CENTRE_Q)).translational * 1e6
    assert k[0, 0] == pytest.approx(PAPER_COMPUTED[0, 0], rel=1e-10)
    assert 3 < factor < 6  # docs/parameters.md: a much softer parallelogram tilt closes the gap


def test_naive_eq30_agrees_with_h4pin(proto, poses):
    bench = script("bench")
    for x in poses[:4]:
        k = compliance(proto, x).matrix
        assert np.max(np.abs(bench.naive_compliance(proto.params, x) - k)) < 1e-12 * np.max(np.abs(k))


def test_constrained_dynamics_keeps_the_loops_closed(proto):
    rows = script("constrained_dynamics").simulate(proto, duration=0.05, dt=1e-4, report_every=0.01)
    drift = max(d for _, d, _ in rows)
    moved = np.linalg.norm(rows[-1][2] - centre_pose(proto)[:3])
    assert drift < 1e-7, f"closure drift {drift:.1e} m"
    assert moved > 1e-5  # the torque step does move the robot
