# SPDX-License-Identifier: Apache-2.0
"""Any closed-loop robot in the viewer (h4pin.mechanism.scene): the deflected shape against a
finite difference of the output's position, the atlas's ellipsoids as stored, a browser render."""

from __future__ import annotations

import base64
import re
import shutil
from pathlib import Path

import matplotlib.image
import numpy as np
import pinocchio as pin
import pytest

from h4pin.errors import ParameterError
from h4pin.mechanism import Mechanism
from h4pin.mechanism import atlas as motor_atlas
from h4pin.mechanism import scene as scene_module

ROBOTS = Path(__file__).resolve().parent / "robots"
TOOL = "closedloop3D_1B"
pytestmark = pytest.mark.usefixtures("no_process_left")


@pytest.fixture(scope="module")
def five_bar() -> Mechanism:
    return Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")


def _objects(page: str) -> dict[str, list]:
    import umsgpack

    out: dict[str, list] = {}
    for blob in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", page):
        msg = umsgpack.unpackb(base64.b64decode(blob))
        out.setdefault(msg["path"], []).append(msg)
    return out


def test_joint_deflection_moves_the_output_by_its_compliance(five_bar):
    """dq from the joints' rows of the compliance: moving the robot along it moves the output's
    origin by C_tt F (central difference) and keeps the loop closed to second order."""
    q = five_bar.assemble()
    springs = motor_atlas.default_springs(five_bar)
    force = np.array([3.0, -2.0, 1.0])
    dq, dy = scene_module.joint_deflection(five_bar, q, springs, TOOL, force)
    C = five_bar.compliance(q, springs, [TOOL])
    np.testing.assert_allclose(dy[:3], C[:3, :3] @ force, rtol=1e-12, atol=1e-18)
    d = five_bar.model.createData()
    fid = five_bar.model.getFrameId(TOOL)

    def at(s):
        pin.framesForwardKinematics(five_bar.model, d, pin.integrate(five_bar.model, q, s * dq))
        return d.oMf[fid].translation.copy()

    eps = 1e-3 / np.abs(dq).max()
    np.testing.assert_allclose((at(eps) - at(-eps)) / (2 * eps), dy[:3], rtol=1e-5, atol=1e-9 * np.abs(dy).max())
    assert max(max(e) for e in five_bar.closure_errors(pin.integrate(five_bar.model, q, eps * dq)).values()) < 1e-5
    with pytest.raises(ParameterError, match="force"):
        scene_module.joint_deflection(five_bar, q, springs, TOOL, [1.0, np.nan, 0.0])


def test_page_holds_the_atlas_ellipsoids_and_the_ghost(five_bar):
    """The page draws one ellipsoid per grid point of status 0, at the stored position, with the
    stored radii (one scale), and the ghost and the arrow of the load."""
    ds = motor_atlas.atlas(five_bar, TOOL, {"mot2": (-0.2, 0.2, 3), "mot1": (-0.2, 0.2, 2)}, progress=False)
    with scene_module.show(five_bar, atlas=ds, load=[0.0, -5.0, 0.0], size=0.01) as scene:
        page = scene.html()
        legend = list(scene.legend)
    objects = _objects(page)
    worst = ds.compliance_max.values.reshape(-1).max()
    pos = ds.position.values.reshape(-1, 3)
    radii = ds.compliance_axes.values.reshape(-1, 3)
    for n in range(6):
        mesh = next(m for m in objects[f"/meshcat/field/{n}"] if m["type"] == "set_object")["object"]["object"]
        drawn = np.diag(np.reshape(mesh["matrix"], (4, 4), order="F"))[:3]
        np.testing.assert_allclose(drawn, np.maximum(radii[n] * 0.01 / worst, 1e-5), rtol=1e-6)
        tf = next(m for m in objects[f"/meshcat/field/{n}"] if m["type"] == "set_transform")["matrix"]
        np.testing.assert_allclose(np.reshape(tf, (4, 4), order="F")[:3, 3], pos[n], rtol=1e-6)
    assert {f"/meshcat/ghost/joints/{n}" for n in list(five_bar.model.names)[1:]} <= set(objects)
    assert "/meshcat/load/shaft" in objects
    assert any("field: 6 of 6" in line for line in legend) and any("red ghost" in line for line in legend)


def test_cli_writes_the_page_of_any_robot(tmp_path, monkeypatch, capsys):
    from conftest import run_cli_in_process

    out = tmp_path / "five.html"
    code, stdout, err = run_cli_in_process(["view", "--robot", str(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf"),
                                            "--output", TOOL, "--load", "0", "-5", "0", "--out", str(out)],
                                           monkeypatch, capsys)
    assert code == 0, err
    assert "red ghost" in stdout and "/meshcat/ghost/joints/mot1" in _objects(out.read_text())
    code, _, err = run_cli_in_process(["view", "--robot", str(out), "--field"], monkeypatch, capsys)
    assert code == 2 and "--field is an option of the H4's view" in err


@pytest.mark.browser
@pytest.mark.skipif(shutil.which("chromium") is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_browser_draws_the_mechanism_and_its_field(five_bar, tmp_path):
    """Headless Chromium renders the page: the sticks, then the atlas's ellipsoids change a
    local region of the picture."""
    q = five_bar.assemble()
    ds = motor_atlas.atlas(five_bar, TOOL, {"mot2": (-0.2, 0.2, 3), "mot1": (-0.2, 0.2, 3)}, progress=False)

    def render(scene, name):
        scene.legend.clear()
        page = scene.write_html(tmp_path / f"{name}.html")
        png = scene_module.screenshot(page, tmp_path / f"{name}.png", size=(800, 600))
        return matplotlib.image.imread(png)[..., :3]

    with scene_module.show(five_bar, q) as bare:
        sticks = render(bare, "sticks")
    with scene_module.show(five_bar, q, atlas=ds, size=0.05) as full:
        field = render(full, "field")
    yellow = (sticks[..., 0] > 0.6) & (sticks[..., 1] > 0.5) & (sticks[..., 2] < 0.3)
    assert yellow.sum() > 20, "the motors (yellow balls) are not drawn"
    changed = np.abs(field - sticks).sum(axis=-1) > 0.1
    assert changed.sum() > 100, f"the field changed only {changed.sum()} pixels"
