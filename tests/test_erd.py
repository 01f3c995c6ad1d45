# SPDX-License-Identifier: Apache-2.0
"""The H4 in example-robot-data (its own RobotLoader, collision pairs from the SRDF, registration)
and in robot_descriptions' loaders (Pinocchio, yourdfpy, MuJoCo).

Against the real packages (``erd`` and ``descriptions`` extras; skipped without them).
"""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import sample_poses

import h4pin
from h4pin.description.params import VARIANTS
from h4pin.io import erd as h4_erd
from h4pin.kinematics.closed_form import centre_pose

ROOT = Path(__file__).resolve().parent.parent


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)


# ----------------------------------------------------------------- registration
def test_names_are_h4_and_every_variant():
    assert h4_erd.NAMES == ("h4", *(f"h4_{v}" for v in VARIANTS))
    assert len(h4_erd.NAMES) == len(VARIANTS) + 1 == 5


def test_loaders_are_example_robot_data_robot_loaders():
    pytest.importorskip("example_robot_data")
    from example_robot_data.robots_loader import ROBOTS, RobotLoader

    assert issubclass(h4_erd.H4Loader, RobotLoader)
    assert h4_erd.register() == h4_erd.NAMES  # explicit, idempotent
    for name in h4_erd.NAMES:
        assert ROBOTS[name] is h4_erd.LOADERS[name] and issubclass(ROBOTS[name], h4_erd.H4Loader)
    assert ROBOTS["h4"].variant == "prototype"
    assert {ROBOTS[f"h4_{v}"].variant for v in VARIANTS} == set(VARIANTS)


def test_import_time_registration_in_a_fresh_interpreter():
    """Documented: example-robot-data has no plug-in hook, so without h4pin imported its load("h4")
    fails with its own "not found" error; ``import h4pin`` registers exactly NAMES."""
    pytest.importorskip("example_robot_data")
    bare = _run("import sys, example_robot_data as e\n"
                "try:\n    e.load('h4')\nexcept ValueError as exc:\n    print('ValueError:', exc)\n"
                "print('h4pin' in sys.modules)")
    assert bare.returncode == 0, bare.stderr
    assert "ValueError: Robot 'h4' not found" in bare.stdout and bare.stdout.strip().endswith("False")
    after = _run("import example_robot_data as e\nbefore = set(e.ROBOTS)\nimport h4pin\n"
                 "print(sorted(set(e.ROBOTS) - before))\nr = e.load('h4')\n"
                 "print(type(r).__name__, len(r.constraint_models), r.model.nq)")
    assert after.returncode == 0, after.stderr
    added, loaded = after.stdout.strip().splitlines()
    assert added == str(sorted(h4_erd.NAMES))
    assert loaded == "RobotWrapper 8 29"


def test_h4pin_imports_without_example_robot_data():
    """With example_robot_data unimportable, h4pin imports, registers nothing, and the loader
    classes raise the extra's error."""
    code = ("import sys\nsys.modules['example_robot_data'] = None\nimport h4pin\nfrom h4pin.io import erd\n"
            "print(erd.available())\ntry:\n    erd.H4Loader\nexcept ImportError as exc:\n"
            "    print(type(exc).__name__, 'h4pin[erd]' in str(exc))")
    out = _run(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "MissingExtraError", "True"]


@pytest.mark.parametrize("doc", ["docs/descriptions.md", "docs/interop.md"])
def test_docs_list_exactly_the_registered_names(doc):
    """Each page's paragraph on example_robot_data.ROBOTS names exactly h4pin.io.erd.NAMES."""
    text = (ROOT / doc).read_text()
    paragraphs = [p for p in text.split("\n\n") if "`example_robot_data.ROBOTS`" in p and "`h4`" in p]
    assert paragraphs, f"{doc}: no paragraph lists the names added to `example_robot_data.ROBOTS`"
    for paragraph in paragraphs:
        assert set(re.findall(r"`(h4(?:_[a-z]+)*)`", paragraph)) - {"h4_description"} == set(h4_erd.NAMES), paragraph


# ----------------------------------------------------------------- loading
@pytest.mark.parametrize("name", h4_erd.NAMES)
def test_example_robot_data_loads_the_h4(name):
    erd = pytest.importorskip("example_robot_data")
    variant = "prototype" if name == "h4" else name[3:]
    robot, q0, urdf, srdf = erd.load_full(name)
    assert isinstance(robot, pin.RobotWrapper)
    h4 = h4pin.load(variant)
    assert Path(urdf).read_text() == h4.urdf and robot.urdf == urdf
    assert Path(srdf).parent.name == "srdf" and Path(urdf).parent.name == "urdf"
    # q0 from the SRDF: the configuration of the reference pose, to the 1e-12 the SRDF keeps,
    # within a micrometre of the centre (all actuators at 45 deg).
    np.testing.assert_allclose(q0, h4.configuration(h4_erd.reference_pose(h4)), rtol=0, atol=1e-11)
    np.testing.assert_allclose(h4_erd.reference_pose(h4), centre_pose(h4), rtol=0, atol=5e-7)
    # robot.q0 is the SRDF group state, quaternion normalised (readParamsFromSrdf)
    np.testing.assert_allclose(robot.model.referenceConfigurations["q0"], q0, rtol=0, atol=1e-12)
    # The closures come with it and close at q0, on the wrapper's own model and data.
    assert len(robot.constraint_models) == 8
    pin.forwardKinematics(robot.model, robot.data, q0)
    gaps = []
    for cm, cd in zip(robot.constraint_models, robot.constraint_datas, strict=True):
        cm.calc(robot.model, robot.data, cd)
        gaps.append(np.linalg.norm(cd.c1Mc2.translation))
    assert max(gaps) < 1e-11
    # And they are the closures: moving one actuator alone opens them.
    q = q0.copy()
    q[robot.model.joints[robot.model.getJointId("actuator_1")].idx_q] += 0.01
    pin.forwardKinematics(robot.model, robot.data, q)
    robot.constraint_models[0].calc(robot.model, robot.data, robot.constraint_datas[0])
    assert np.linalg.norm(robot.constraint_datas[0].c1Mc2.translation) > 1e-4
    # example-robot-data's RobotLoader made the collision pairs: h4pin's.
    assert _pairs(robot.collision_model) == _pairs(h4.collision_model)


def test_q0_is_the_rounded_centre_not_the_exact_one():
    """docs/interop.md: load("h4")'s q0 is the configuration of the centre pose rounded to 1e-6,
    [0, 0, -0.588139 m, 0] (to 4e-13), 2.1e-6 rad from the exact centre's configuration (the
    actuators 1.4e-6 rad from 45 deg, the plate 4.9e-7 m from the exact centre)."""
    erd = pytest.importorskip("example_robot_data")
    _, q0, _, _ = erd.load_full("h4")
    h4 = h4pin.load("prototype")
    np.testing.assert_array_equal(h4_erd.reference_pose(h4), [0.0, 0.0, -0.588139, 0.0])
    np.testing.assert_allclose(q0, h4.configuration([0.0, 0.0, -0.588139, 0.0]), rtol=0, atol=1.2e-12)  # 4.0e-13 x 3
    exact = h4.configuration(centre_pose(h4))
    step = pin.difference(h4.model, exact, q0)  # rad for the angles, m for the plate's translation
    plate = h4.model.joints[h4.model.getJointId("plate")].idx_v
    angles = np.delete(step, range(plate, plate + 3))
    act = [h4.model.joints[h4.model.getJointId(n)].idx_v for n in h4.actuated_joint_names]
    # Measured 2.1e-6 rad (any joint), 1.4e-6 rad (each actuator), 4.9e-7 m (plate): bounds /3 and x3.
    assert 7e-7 < np.max(np.abs(angles)) < 6.3e-6
    assert np.all((4.6e-7 < np.abs(step[act])) & (np.abs(step[act]) < 4.2e-6))
    assert 1.6e-7 < np.max(np.abs(step[plate:plate + 3])) < 1.5e-6


# ----------------------------------------------------------------- collision pairs
def _pairs(geometry: pin.GeometryModel) -> set[frozenset[str]]:
    names = [g.name for g in geometry.geometryObjects]
    return {frozenset((names[p.first], names[p.second])) for p in geometry.collisionPairs}


def _touching(h4, geometry: pin.GeometryModel, q: np.ndarray) -> set[frozenset[str]]:
    """The link pairs with a pair of geometries in collision at q (Pinocchio/coal)."""
    data, gdata = h4.model.createData(), geometry.createData()
    pin.computeCollisions(h4.model, data, geometry, gdata, q, False)
    link = [h4.model.frames[g.parentFrame].name for g in geometry.geometryObjects]
    return {frozenset((link[p.first], link[p.second])) for k, p in enumerate(geometry.collisionPairs)
            if gdata.collisionResults[k].isCollision()}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_collision_pairs_are_example_robot_datas(variant):
    """example-robot-data's own RobotLoader on the shipped files (addAllCollisionPairs, then
    removeCollisionPairs with the SRDF) gives h4pin.load's pairs."""
    pytest.importorskip("example_robot_data")
    from example_robot_data.robots_loader import RobotLoader

    class Plain(RobotLoader):  # example-robot-data's code only
        model_path, path, urdf_subpath, srdf_subpath = str(ROOT), "", "urdf", "srdf"
        urdf_filename, srdf_filename, ref_posture = f"h4_{variant}.urdf", f"h4_{variant}.srdf", "q0"

    theirs = Plain().robot.collision_model
    h4 = h4pin.load(variant)
    mine = h4.collision_model
    assert _pairs(mine) == _pairs(theirs)
    n = mine.ngeoms
    everything = pin.GeometryModel(theirs)
    everything.addAllCollisionPairs()
    assert (n, len(everything.collisionPairs), len(mine.collisionPairs)) == (55, 1396, 1148)
    assert len(h4.disabled_collisions) == 38


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_disabled_pairs_touch_and_checked_pairs_do_not(variant):
    """At q0 and at 12 sampled poses: no checked pair is in collision, and every disabled link pair
    is (links joined by a joint, or meeting at a universal or ball joint's centre)."""
    h4 = h4pin.load(variant)
    everything = pin.GeometryModel(h4.collision_model)
    everything.addAllCollisionPairs()
    disabled = {frozenset((d.link1, d.link2)) for d in h4.disabled_collisions}
    for q in [h4.q0, *(h4.configuration(x) for x in sample_poses(h4, 12, seed=4))]:
        assert _touching(h4, h4.collision_model, q) == set()
        assert _touching(h4, everything, q) == disabled


def test_adjacent_pairs_are_joined_by_a_joint(proto):
    """The "Adjacent" pairs are the (parent, child) links of the URDF's joints with geometry on both
    sides, as yourdfpy reads the file; the others are the closures' links and the universal joints'
    ends (forearm_i, bar_ij)."""
    yourdfpy = pytest.importorskip("yourdfpy")
    urdf = yourdfpy.URDF.load(str(h4pin.robot.variant_path("prototype")), build_scene_graph=False,
                              load_meshes=False)
    solid = {name for name, link in urdf.link_map.items() if link.collisions}
    joined = {frozenset((j.parent, j.child)) for j in urdf.robot.joints
              if j.type != "floating" and {j.parent, j.child} <= solid}
    by_reason = {}
    for d in proto.disabled_collisions:
        by_reason.setdefault(d.reason, set()).add(frozenset((d.link1, d.link2)))
    assert by_reason["Adjacent"] == joined
    closures = {frozenset((f"bar_{i}{j}", f"lateral_bar_{1 if i < 3 else 2}")) for i in range(1, 5) for j in (1, 2)}
    universal = {frozenset((f"forearm_{i}", f"bar_{i}{j}")) for i in range(1, 5) for j in (1, 2)}
    assert by_reason["Always"] == closures | universal
    assert set(by_reason) == {"Adjacent", "Always"}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_shipped_srdf_is_the_generated_one(variant):
    h4 = h4pin.load(variant)
    assert (ROOT / "srdf" / f"h4_{variant}.srdf").read_text() == h4_erd.srdf(h4, f"h4_{variant}")


def test_wheel_installs_example_robot_data_layout(tmp_path):
    """The wheel carries urdf/ and srdf/ under share/example-robot-data/robots/h4_description."""
    wheel_builder = pytest.importorskip("hatchling.builders.wheel")
    builder = wheel_builder.WheelBuilder(str(ROOT))
    wheel = Path(next(iter(builder.build(directory=str(tmp_path), versions=["standard"]))))
    names = zipfile.ZipFile(wheel).namelist()
    data = [n.split(".data/data/", 1)[1] for n in names if ".data/data/" in n]
    for variant in VARIANTS:
        for sub, ext in (("urdf", "urdf"), ("urdf", "yaml"), ("srdf", "srdf")):
            assert f"share/example-robot-data/robots/h4_description/{sub}/h4_{variant}.{ext}" in data
            assert f"h4pin/{sub}/h4_{variant}.{ext}" in names
    for module in ("__init__", *(f"h4_{v}_description" for v in VARIANTS)):
        assert f"h4pin/descriptions/{module}.py" in names


# ----------------------------------------------------------------- robot_descriptions
def _frames(model: pin.Model, q: np.ndarray) -> dict[str, np.ndarray]:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return {f.name: data.oMf[k].homogeneous for k, f in enumerate(model.frames)}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_description_modules(variant):
    from importlib import import_module

    from h4pin.descriptions import MODULES

    module = import_module(f"h4pin.descriptions.{MODULES[variant]}")
    assert Path(module.URDF_PATH).read_text() == h4pin.load(variant).urdf
    assert Path(module.SRDF_PATH).read_text() == (ROOT / "srdf" / f"h4_{variant}.srdf").read_text()
    assert Path(module.URDF_PATH).parent.parent == Path(module.REPOSITORY_PATH) == Path(module.PACKAGE_PATH)
    assert Path(module.MJCF_PATH).name == f"h4_{variant}.xml" and Path(module.MJCF_PATH).parent.name == "mjcf"


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_robot_descriptions_loaders(variant):
    """robot_descriptions' own Pinocchio and yourdfpy loaders load each module by name (after
    register_robot_descriptions) and agree with h4pin.load: nq, nv, every frame at q0 (Pinocchio);
    every link at the neutral configuration and the legs' links at q0 (yourdfpy, which keeps a
    floating joint at its origin)."""
    pytest.importorskip("robot_descriptions")
    from robot_descriptions.loaders.pinocchio import load_robot_description as load_pinocchio

    from h4pin.descriptions import MODULES, register_robot_descriptions

    assert set(register_robot_descriptions()) == set(MODULES.values())
    h4 = h4pin.load(variant)
    robot = load_pinocchio(MODULES[variant])
    assert (robot.model.nq, robot.model.nv) == (h4.model.nq, h4.model.nv) == (29, 28)
    assert robot.model.names.tolist() == h4.model.names.tolist()
    theirs, mine = _frames(robot.model, h4.q0), _frames(h4.model, h4.q0)
    assert theirs.keys() == mine.keys()
    for name in mine:
        np.testing.assert_allclose(theirs[name], mine[name], rtol=0, atol=1e-14, err_msg=name)

    yourdfpy_loader = pytest.importorskip("robot_descriptions.loaders.yourdfpy")
    urdf = yourdfpy_loader.load_robot_description(MODULES[variant], build_scene_graph=True, load_meshes=False)
    assert urdf.num_dofs == h4.model.nv
    neutral = _frames(h4.model, pin.neutral(h4.model))
    for link in urdf.link_map:
        np.testing.assert_allclose(urdf.get_transform(link, "base_link"), neutral[link], rtol=0, atol=1e-12,
                                   err_msg=link)
    revolute = [n for n in urdf.actuated_joint_names if urdf.joint_map[n].type == "revolute"]
    cfg = [h4.q0[h4.model.joints[h4.model.getJointId(n)].idx_q] for n in revolute]
    urdf.update_cfg(dict(zip(revolute, cfg, strict=True)))
    legs = [link for link in urdf.link_map if link.startswith(("forearm_", "bar_", "A_"))]
    assert len(legs) > 30
    for link in legs:
        np.testing.assert_allclose(urdf.get_transform(link, "base_link"), mine[link], rtol=0, atol=1e-12,
                                   err_msg=link)


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_robot_descriptions_mujoco_loader(variant):
    """robot_descriptions' MuJoCo loader loads each module's MJCF: nq, nv, the 8 closures, the 4
    motors, and h4pin.io.mjcf.qpos(h4, q0) puts every frame's site where Pinocchio puts it."""
    pytest.importorskip("robot_descriptions")
    mujoco = pytest.importorskip("mujoco")
    from h4pin.descriptions import MODULES, paths, register_robot_descriptions

    if not Path(paths(variant).MJCF_PATH).is_file():
        pytest.skip(f"needs {paths(variant).MJCF_PATH} (scripts/generate_urdf.py writes it with MuJoCo installed)")
    register_robot_descriptions()
    from robot_descriptions.loaders.mujoco import load_robot_description as load_mujoco

    from h4pin.io.mjcf import qpos

    model = load_mujoco(MODULES[variant])
    h4 = h4pin.load(variant)
    assert (model.nq, model.nv, model.neq, model.nu) == (h4.model.nq, h4.model.nv, 8, 4)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos(h4, h4.q0)
    mujoco.mj_kinematics(model, data)
    mine = _frames(h4.model, h4.q0)
    checked = 0
    for k in range(model.nsite):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, k)
        if name in mine:
            np.testing.assert_allclose(data.site_xpos[k], mine[name][:3, 3], rtol=0, atol=1e-12, err_msg=name)
            checked += 1
    assert checked >= 19  # D, C_k, A_ij, B_ij at least
