# SPDX-License-Identifier: Apache-2.0
"""The meshcat viewer: numbers drawn, a real browser render, CLI errors, no process left behind."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import matplotlib.image
import numpy as np
import pinocchio as pin
import pytest

from h4pin import viewer
from h4pin.deflection import deflected_configuration
from h4pin.stiffness import compliance

ROOT = Path(__file__).resolve().parent.parent
needs_chromium = pytest.mark.skipif(shutil.which("chromium") is None,
                                    reason="needs Debian's chromium (apt-get install chromium)")


def our_processes(pattern: str) -> list[int]:
    """PIDs of processes whose command line contains ``pattern`` (read from /proc)."""
    out = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="ignore")
        except OSError:
            continue
        if pattern in cmd and int(pid) != os.getpid():
            out.append(int(pid))
    return out


@pytest.fixture(autouse=True)
def no_server_left_behind():
    before = set(our_processes("meshcat.servers.zmqserver"))
    yield
    assert set(our_processes("meshcat.servers.zmqserver")) <= before, "a meshcat server was left running"
    assert not our_processes("h4pin-chromium-"), "a Chromium process was left running"


def test_ellipsoid_axes_are_deflection_directions(proto, poses):
    """Along each axis a unit force deflects D parallel to it, by the radius (m/N)."""
    for x in poses[:4]:
        k = compliance(proto, x, "consistent").translational
        radii, axes = viewer.ellipsoid_axes(k)
        assert np.linalg.det(axes) == pytest.approx(1.0)
        for r, a in zip(radii, axes.T, strict=True):
            d = k @ a
            assert np.linalg.norm(d) == pytest.approx(r, rel=1e-12)
            assert abs(d @ a) / np.linalg.norm(d) == pytest.approx(1.0, abs=1e-12)


def test_ghost_moves_d_by_the_exaggerated_deflection(proto, poses):
    x, force, factor = poses[2], np.array([3.0, -2.0, -10.0]), 500.0
    q = deflected_configuration(proto, x, force, scale=factor)
    pin.framesForwardKinematics(proto.model, proto.data, q)
    moved = proto.frame_position("D") - x[:3]
    np.testing.assert_allclose(moved, factor * compliance(proto, x, "consistent").translational @ force, rtol=1e-12)


def test_scene_legend_states_the_scales(proto, centre):
    with viewer.show(proto, centre, load=[0, 0, -10], scale=2.0, exaggeration=100.0) as scene:
        text = " ".join(scene.legend)
    assert "1 um/N drawn as 2 mm" in text and "x100" in text


def _render(scene: viewer.Scene, tmp: Path, name: str) -> np.ndarray:
    html = scene.write_html(tmp / f"{name}.html")
    return matplotlib.image.imread(viewer.screenshot(html, tmp / f"{name}.png", size=(800, 600)))[..., :3]


@pytest.mark.browser
@needs_chromium
def test_browser_draws_the_robot_and_the_ellipsoid(proto, centre, tmp_path):
    """Headless Chromium renders the page: robot pixels, and the ellipsoid changes only a small,
    green region of the picture."""
    with viewer.Scene(proto) as bare:
        bare.pose(centre)
        robot = _render(bare, tmp_path, "robot")
        bare.ellipsoid(centre, scale=2.0)
        bare.legend.clear()  # compare the 3-D scene only
        both = _render(bare, tmp_path, "both")
    orange = (robot[..., 0] > 0.6) & (robot[..., 1] > 0.25) & (robot[..., 1] < 0.6) & (robot[..., 2] < 0.3)
    assert orange.sum() > 500, "the forearms (orange) are not drawn"
    changed = np.abs(both - robot).sum(axis=-1) > 0.1
    assert changed.sum() > 200, f"the ellipsoid changed only {changed.sum()} pixels"
    assert changed.mean() < 0.05, "the change is not local"
    new = both[changed]
    assert np.mean((new[:, 1] > new[:, 0]) & (new[:, 1] > new[:, 2])) > 0.5, "the changed pixels are not green"
    rows, cols = np.nonzero(changed)
    assert rows.mean() > 0.5 * robot.shape[0], "the ellipsoid is not at the plate, below the actuators"


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "h4pin.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=120)


def test_cli_writes_a_self_contained_page(tmp_path):
    out = run_cli("view", "--html", str(tmp_path / "h4.html"), "--load", "0", "0", "-10", "--field")
    assert out.returncode == 0, out.stderr
    page = (tmp_path / "h4.html").read_text()
    assert "h4pin-legend" in page and "x100" in out.stdout and "field: 50 of 50 poses" in out.stdout
    assert "http://" not in page.split("<script")[0]  # nothing to fetch before the inlined scripts
    assert [p.name for p in tmp_path.iterdir()] == ["h4.html"]


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--pose", "0", "0", "-0.9", "0"], "cannot reach"),
     (["--variant", "symmetric"], "singular"),
     (["--pose", "0", "0"], "requires 4 arguments"),
     (["--load", "0", "0", "x"], "Invalid value for '--load'"),
     (["--model", "exact"], "model must be one of")],
)
def test_cli_bad_input_is_one_line_and_writes_nothing(tmp_path, args, message):
    target = tmp_path / "h4.html"
    out = run_cli("view", "--html", str(target), *args)
    assert out.returncode == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not target.exists() and list(tmp_path.iterdir()) == []


def test_cli_server_stops_cleanly_on_ctrl_c():
    """Without --html: the URL is printed, and SIGINT stops the command and its meshcat server."""
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-m", "h4pin.cli", "view"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        deadline = time.monotonic() + 60
        line = ""
        while "meshcat: http" not in line and time.monotonic() < deadline:
            line = proc.stdout.readline()
        assert "meshcat: http" in line, proc.stderr.read() if proc.poll() is not None else "no URL printed"
        assert our_processes("meshcat.servers.zmqserver"), "no meshcat server is running"
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0
        assert "stopped" in proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
