# SPDX-License-Identifier: Apache-2.0
"""URDF variants: current, loadable by Pinocchio and yourdfpy, exact round trip, clear errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

import h4pin
from h4pin import H4Params, MalformedURDFError
from h4pin.params import VARIANTS
from h4pin.urdf import params_from_urdf, to_urdf, write_urdf

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted((ROOT / "urdf").glob("h4_*.urdf"))


def test_every_variant_is_shipped_and_current():
    assert {p.stem for p in SHIPPED} == {f"h4_{n}" for n in VARIANTS}
    out = subprocess.run([sys.executable, str(ROOT / "scripts" / "generate_urdf.py"), "--check"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_loads_in_pinocchio_and_yourdfpy(path):
    model = pin.buildModelFromUrdf(str(path))
    # 4 actuators + 16 bar revolutes + free-flyer (7 q, 6 v) + 2 lateral revolutes
    assert (model.nq, model.nv) == (29, 28)
    robot = yourdfpy.URDF.load(str(path))
    assert robot.validate()
    assert {j.type for j in robot.robot.joints} == {"revolute", "floating", "fixed"}


@pytest.mark.parametrize(
    "params",
    [H4Params(), h4pin.symmetric_params(), H4Params(half_width=0.0123456789, kc=1234.5678901234567, l=0.5)],
)
def test_params_round_trip_exactly(params):
    assert params_from_urdf(to_urdf(params)) == params


def test_shipped_file_encodes_its_variant():
    for name, make in VARIANTS.items():
        assert h4pin.load(name).params == make()


def test_inertias_are_plausible(proto):
    """Masses from the stated materials: a carbon bar of section Sb, 0.48 m, at 1600 kg/m^3."""
    masses = {f.name: proto.model.inertias[f.parentJoint].mass for f in proto.model.frames if f.name == "bar_11"}
    assert masses["bar_11"] == pytest.approx(1600 * 28e-6 * 0.48, rel=1e-9)
    total = sum(i.mass for i in proto.model.inertias)
    assert 1.0 < total < 10.0


def _mutate(old: str, new: str, count: int = 1) -> str:
    text = to_urdf(H4Params())
    assert old in text
    return text.replace(old, new, count)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (_mutate('<constraint name="closure_32"', '<constraint name="closure_99"'), "closure_32"),
        (_mutate('<child link="lateral_bar_2"/>\n    <child_origin', '<child link="nowhere"/>\n    <child_origin'),
         "unknown link 'nowhere'"),
        (_mutate(' kc="7400.0"', ""), "'kc'"),
        (_mutate('<link name="D"/>', '<link name="E"/>').replace('<child link="D"/>', '<child link="E"/>'),
         "frame.s. D missing"),
        (_mutate(' Eb="200000000000.0"', ""), "'Eb'"),
        (_mutate("<h4_parameters", "<h4_not_parameters").replace("</h4_parameters>", "</h4_not_parameters>"),
         "h4_parameters"),
        (_mutate('<joint name="actuator_3" type="revolute">', '<joint name="actuator_3" type="continuous">'),
         "actuator_3"),
        (_mutate('<leg index="2" lateral_bar="1" P="0.06 -0.2 0"', '<leg index="2" lateral_bar="1" P="0.06 -0.21 0"'),
         "actuator_2"),
        ("<robot name='x'><link name='a'/>", "not well-formed"),
        ("<sdf/>", "not <robot>"),
    ],
    ids=["missing closure", "unknown frame", "missing kc", "missing named frame", "missing Eb", "no parameters",
         "wrong joint type",
         "tree disagrees", "not xml", "not urdf"],
)
def test_malformed_urdf_is_a_clear_error(text, message, tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(MalformedURDFError, match=message):
        h4pin.load(path)


def test_write_urdf_leaves_no_partial_file(tmp_path):
    target = tmp_path / "h4.urdf"
    write_urdf(H4Params(), target)
    assert params_from_urdf(target.read_text()) == H4Params()
    assert [p.name for p in tmp_path.iterdir()] == ["h4.urdf"]
    with pytest.raises(FileNotFoundError):
        write_urdf(H4Params(), tmp_path / "missing_dir" / "h4.urdf")
    assert not (tmp_path / "missing_dir").exists()


def test_geometry_in_the_tree_matches_the_parameters(proto, centre):
    """Frame positions at the Pinocchio configuration equal the closed-form points."""
    from h4pin import geometry

    q = proto.configuration(centre)
    pin.framesForwardKinematics(proto.model, proto.data, q)
    pts = geometry.points(proto.params, centre, proto.inverse_geometry(centre))
    for i in range(4):
        np.testing.assert_allclose(proto.frame_position(f"P_{i + 1}"), pts.P[i], atol=1e-15)
        np.testing.assert_allclose(proto.frame_position(f"A_{i + 1}"), pts.A[i], atol=1e-14)
        np.testing.assert_allclose(proto.frame_position(f"B_{i + 1}"), pts.B[i], atol=1e-14)
        for j in range(2):
            np.testing.assert_allclose(proto.frame_position(f"B_{i + 1}{j + 1}"), pts.Bij[i, j], atol=1e-14)
            np.testing.assert_allclose(proto.frame_position(f"bar_{i + 1}{j + 1}_end"), pts.Bij[i, j], atol=1e-12)
