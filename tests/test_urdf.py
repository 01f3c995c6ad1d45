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
from h4pin.description.params import VARIANTS
from h4pin.description.reader import params_from_urdf
from h4pin.description.urdf import to_urdf, write_urdf
from h4pin.studies.variants import GENERATORS

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


@pytest.mark.parametrize("params", [H4Params(), h4pin.symmetric_params(), h4pin.toleranced_params(),
                                    H4Params(half_width=0.0123456789, kc=1234.5678901234567, l=0.5)])
def test_params_round_trip(params):
    """params -> URDF -> model -> params: equal to round-off (1e-15 m; geometry goes through
    Pinocchio's forward kinematics, so not bit for bit)."""
    assert params_from_urdf(to_urdf(params)).allclose(params, atol=1e-15)


def test_shipped_file_encodes_its_variant():
    for name, make in GENERATORS.items():
        assert h4pin.load(name).params.allclose(make(), atol=1e-15)


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
        (_mutate('<constraint name="closure_32" type="point">\n    <parent link="bar_32"/>',
                 '<constraint name="closure_32" type="point">\n    <parent link="bar_31"/>'),
         "bar 32"),
        (_mutate('<child link="lateral_bar_2"/>\n    <child_origin', '<child link="nowhere"/>\n    <child_origin'),
         "unknown link 'nowhere'"),
        (_mutate('<h4_actuator kc="7400.0"/>', ""), "'kc' of the actuated joint 'actuator_1'"),
        (_mutate('<link name="D"/>', '<link name="E"/>').replace('<child link="D"/>', '<child link="E"/>'),
         "not an H4: it has no frame D"),
        (_mutate(' Eb="200000000000.0"', ""), "'Eb' of the bar link 'bar_11'"),
        (_mutate(' Sb="2.8e-05"', ' Sb="-2.8e-05"', 3), "bar link 'bar_11'.*'Sb' = -2.8e-05"),
        (_mutate('<h4pin format="2" units="SI"/>', '<h4pin format="2" units="mm"/>'), "only SI"),
        (_mutate('<h4pin format="2" units="SI"/>', '<h4pin format="7" units="SI"/>'), "format=.7.. is unknown"),
        (_mutate('<constraint name="closure_11" type="point">', '<constraint name="closure_11" type="6d">'),
         "closure_11.*type '6d'"),
        (_mutate('<constraint name="closure_12"', '<constraint name="closure_11"'), "two <constraint> elements"),
        (_mutate('<joint name="actuator_3" type="revolute">', '<joint name="actuator_3" type="prismatic">'),
         "forearm 3"),
        (_mutate('<h4pin format="2" units="SI"/>', '<h4_parameters format="1"/>'), "format 1"),
        ("<robot name='x'><link name='a'/>", "not well-formed"),
        ("<sdf/>", "not <robot>"),
    ],
    ids=["closure on the wrong bar", "unknown link", "missing kc", "missing named frame", "missing Eb",
         "negative Sb", "units", "format", "closure type", "duplicate closure", "wrong joint type", "old format",
         "not xml", "not urdf"],
)
def test_malformed_urdf_is_a_clear_error(text, message, tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(MalformedURDFError, match=message) as info:
        h4pin.load(path)
    assert str(path) in str(info.value)  # the message names the file


@pytest.mark.parametrize(("data", "message"), [(b"\x89PNG\r\n\x1a\n\0\0", "binary"),
                                               (to_urdf(H4Params()).encode("utf-16-le"), "binary"),
                                               ("<robot name='\xe9'/>".encode("latin-1"), "not UTF-8")])
def test_binary_or_non_utf8_files_are_refused(tmp_path, data, message):
    path = tmp_path / "bad.urdf"
    path.write_bytes(data)
    with pytest.raises(MalformedURDFError, match=message):
        h4pin.load(path)


def test_a_urdf_in_utf16_with_its_byte_order_mark_is_the_same_robot(tmp_path):
    """UTF-16 (its byte-order mark says so) is XML text as UTF-8 is: the same robot
    (h4pin.mechanism.urdf_reader.decode, shared with Mechanism.from_urdf)."""
    path = tmp_path / "h4.urdf"
    path.write_bytes(to_urdf(H4Params()).encode("utf-16"))
    assert h4pin.load(path).params == h4pin.load(H4Params()).params


def test_existing_file_is_a_path_and_names_are_variants(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "myrobot.urdf").write_text(to_urdf(H4Params(half_width=0.03)))
    assert h4pin.load("myrobot.urdf").params.half_width[0] == pytest.approx(0.03)
    (tmp_path / "prototype").write_text(to_urdf(H4Params(half_width=0.02)))  # an existing file wins
    assert h4pin.load("prototype").params.half_width[0] == pytest.approx(0.02)
    with pytest.raises(h4pin.URDFNotFoundError):
        h4pin.load("missing.urdf")
    with pytest.raises(h4pin.ParameterError, match="measured_match, prototype, symmetric, toleranced"):
        h4pin.load("protoype")


def test_write_urdf_leaves_no_partial_file(tmp_path):
    target = tmp_path / "h4.urdf"
    write_urdf(H4Params(), target)
    assert params_from_urdf(target.read_text()).allclose(H4Params())
    assert [p.name for p in tmp_path.iterdir()] == ["h4.urdf"]
    assert target.stat().st_mode & 0o777 == 0o644
    with pytest.raises(FileNotFoundError):
        write_urdf(H4Params(), tmp_path / "missing_dir" / "h4.urdf")
    assert not (tmp_path / "missing_dir").exists()


def test_geometry_in_the_tree_matches_the_parameters(proto, centre):
    """Frame positions at the Pinocchio configuration equal the closed-form points."""
    from h4pin.kinematics import closed_form as geometry

    q = proto.configuration(centre)
    pin.framesForwardKinematics(proto.model, proto.data, q)
    pts = geometry.points(proto.geometry, proto.state(centre))
    for i in range(4):
        np.testing.assert_allclose(proto.frame_position(f"P_{i + 1}"), pts.P[i], atol=1e-15)
        np.testing.assert_allclose(proto.frame_position(f"A_{i + 1}"), pts.A[i], atol=1e-14)
        np.testing.assert_allclose(proto.frame_position(f"B_{i + 1}"), pts.B[i], atol=1e-14)
        for j in range(2):
            np.testing.assert_allclose(proto.frame_position(f"B_{i + 1}{j + 1}"), pts.Bij[i, j], atol=1e-14)
            np.testing.assert_allclose(proto.frame_position(f"bar_{i + 1}{j + 1}_end"), pts.Bij[i, j], atol=1e-12)
