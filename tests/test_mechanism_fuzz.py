# SPDX-License-Identifier: Apache-2.0
"""Every sidecar key and every Mechanism argument fed wrong types and values: h4pin only ever
answers with a result or an h4pin.H4Error (never a TypeError, IndexError, UnicodeDecodeError or a
NaN), and the messages name what is wrong."""

from __future__ import annotations

import itertools
import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import run_cli_in_process

from h4pin.errors import H4Error, MalformedURDFError, MechanismWarning, ParameterError
from h4pin.mechanism import Beam, FrameOutput, JointOutput, Mechanism

yaml = pytest.importorskip("yaml")

ROBOT = Path(__file__).parent / "robots" / "5bar_linkage"
BAD = [None, 5, 3.5, math.nan, True, "mot1", "", [], [1, 2], [None], [["a"]], [[1, 2]], [["a", "b", "c"]],
       {"a": 1}, ["3D", 7], [[]], "6d"]


def _good() -> dict:
    return yaml.safe_load((ROBOT / "robot.yaml").read_text())


def _answers(call) -> object:
    """The call's result, or None after an H4Error; anything else fails the test."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MechanismWarning)
            return call()
    except H4Error as exc:
        assert str(exc), "an error with no message"
        return None


@pytest.mark.parametrize(("key", "value"), list(itertools.product(
    ["closed_loop", "type", "name_mot", "joint_name", "joint_type", "beams", "bogus"], BAD)))
def test_every_sidecar_key_with_a_wrong_value(tmp_path, key, value):
    content = _good()
    content[key] = value
    side = tmp_path / "robot.yaml"
    side.write_text(yaml.safe_dump(content))
    mech = _answers(lambda: Mechanism.from_urdf(ROBOT / "robot.urdf", side))
    if mech is not None:  # some values are legal (an empty list of conversions, say)
        assert isinstance(mech, Mechanism)


@pytest.mark.parametrize("text", [b"\xff\xfe\x00binary", b"- just\n- a list\n", b"42", b"", b"closed_loop: [\n",
                                  b"closed_loop: null\ntype: []\n"])
def test_a_sidecar_that_is_not_one(tmp_path, text):
    side = tmp_path / "robot.yaml"
    side.write_bytes(text)
    assert _answers(lambda: Mechanism.from_urdf(ROBOT / "robot.urdf", side)) is None


def test_a_string_name_mot_is_not_read_letter_by_letter(tmp_path):
    content = _good()
    content["name_mot"] = content["name_mot"][0]
    side = tmp_path / "robot.yaml"
    side.write_text(yaml.safe_dump(content))
    with pytest.raises(H4Error, match="name_mot must be a list"):
        Mechanism.from_urdf(ROBOT / "robot.urdf", side)


@pytest.fixture(scope="module")
def five_bar():
    mech = Mechanism.from_urdf(ROBOT / "robot.urdf")
    return mech, mech.assemble()


QS = [None, "x", True, 5, [math.nan] * 6, [0.0] * 3, np.zeros((2, 6)), [math.inf] * 6, {"a": 1}]


@pytest.mark.parametrize(("arg", "value"), [("q", v) for v in QS] + [
    ("tol", v) for v in (0, -1.0, math.nan, math.inf, "1", True, None)] + [
    ("iterations", v) for v in (0, -1, 1.5, True, "3", None)] + [
    ("fixed", v) for v in (5, "nope", [None], [99], [math.nan])])
def test_assemble_with_a_wrong_argument(five_bar, arg, value):
    mech, _ = five_bar
    kwargs = {arg: value}
    q = kwargs.pop("q", None)
    got = _answers(lambda: mech.assemble(q, **kwargs))
    if got is not None:
        assert np.all(np.isfinite(got))


def test_nan_in_q_is_named(five_bar):
    mech, q = five_bar
    bad = q.copy()
    bad[1] = math.nan
    with pytest.raises(H4Error, match=r"q\[1\] is nan"):
        mech.compliance(bad, {n: 1.0 for n in mech.actuated}, [mech.model.frames[-1].name])


@pytest.mark.parametrize(("arg", "value"), [("springs", v) for v in (
    {}, None, [1], {"nope": 1.0}, {"__motors__": -1.0}, {"__motors__": math.nan}, {"__motors__": "a"},
    {"__motors__": [1.0, 2.0]}, {"__motors__": True}, {1: 1.0, "__first__": 2.0})] + [
    ("outputs", v) for v in ([], "nope", 5, [7], [None], FrameOutput("nope"), [JointOutput("nope")])] + [
    ("locked", v) for v in (5, "nope", [None], [math.nan], ["__motor__"])])
def test_compliance_and_modes_with_a_wrong_argument(five_bar, arg, value):
    mech, q = five_bar
    motors = list(mech.actuated)
    if isinstance(value, dict):
        value = {(motors[0] if k == "__first__" else k): v for k, v in value.items()}
        if "__motors__" in value:
            value = {m: value["__motors__"] for m in motors}
    if value == ["__motor__"]:
        value = [motors[0]]
    args = {"springs": {m: 1e3 for m in motors}, "outputs": [mech.model.frames[-1].name], "locked": ()}
    args[arg] = value
    c = _answers(lambda: mech.compliance(q, args["springs"], args["outputs"], args["locked"]))
    if c is not None:
        assert np.all(np.isfinite(c))
    f = _answers(lambda: mech.modes(q, args["springs"], args["locked"]))
    if f is not None:
        assert np.all(np.isfinite(f.frequencies))


def test_modes_without_closures_and_bad_constructor_arguments():
    model = pin.buildModelFromUrdf(str(ROBOT / "robot.urdf"))
    open_tree = Mechanism(model, (), [model.names[1]])
    q = pin.neutral(model)
    springs = {model.names[j]: 10.0 for j in range(1, model.njoints)}
    freq = _answers(lambda: open_tree.modes(q, springs))
    assert freq is None or np.all(np.isfinite(freq.frequencies))
    for args, kwargs in [((None,), {}), ((model, [5]), {}), ((model, (), ["nope"]), {}), ((model, (), [99]), {}),
                         ((model,), {"reference": "x"}), ((model,), {"ranges": (1, 2)}),
                         ((model,), {"springs": {"nope": 1}}), ((model,), {"springs": {model.names[1]: -1}})]:
        assert _answers(lambda a=args, k=kwargs: Mechanism(*a, **k)) is None


# ---------------------------------------------------------------------------------------------
# Issue 48: values that reached SciPy or numpy's linear algebra, were allocated before they were
# refused, or were accepted without a word. Each gives a typed error naming the value (or an
# answer that is finite).

FIVE_3D = Path(__file__).parent / "robots" / "5bar_linkage_iso3d"
LOOP = Path(__file__).parent / "robots" / "synthetic" / "loop.xml"
BEAM_FIELDS = {"E": 70e9, "G": 26e9, "A": 1e-4, "Iy": 1e-9, "Iz": 1e-9, "J": 2e-9}
#: Values for a beam's field or size: out of range either way, non-finite, not numbers.
BEAM_BAD = [0, -1.0, 1e-308, 1e308, 1e200, -1e200, math.nan, math.inf, -math.inf, True, np.True_, 1 + 1j, "70e9",
            None, 10**400, [1.0], np.float64(1e-30)]


@pytest.fixture(scope="module")
def five_3d():
    mech = Mechanism.from_urdf(FIVE_3D / "robot.urdf")
    return mech, mech.assemble()


def _all_springs(mech: Mechanism, k: float = 1e3) -> dict:
    return {n: k for n in list(mech.model.names)[1:]}


@pytest.mark.parametrize(("field", "value"), [(f, v) for f in BEAM_FIELDS for v in BEAM_BAD] + [
    (f, v) for f in BEAM_FIELDS for v in ("low", "high")])
def test_a_beam_refuses_an_implausible_value_at_construction(five_3d, field, value):
    """E, G, A, Iy, Iz, J: outside h4pin.limits.BEAM_RANGES (1e-308, 1e308 made the compliance
    fail with LinAlgError) a ParameterError naming the field and its range; at the edges of the
    ranges the compliance is finite or a typed refusal (an unrestrained motion), never numpy's."""
    from h4pin.limits import BEAM_RANGES

    mech, q = five_3d
    if value in ("low", "high"):
        value = BEAM_RANGES[field][0 if value == "low" else 1]
    try:
        beam = Beam(**{**BEAM_FIELDS, field: value})
    except ParameterError as exc:
        assert f"Beam: {field} " in str(exc) and "\n" not in str(exc)
        if isinstance(value, float) and math.isfinite(value) and value > 0:
            assert "plausible range" in str(exc) and "BEAM_RANGES" in str(exc)
        return
    assert value == math.inf and field not in "EG" or isinstance(value, float) and math.isfinite(value)
    flex = mech.with_beams({"part_3": beam})
    c = _answers(lambda: flex.compliance(q, _all_springs(mech), ["closedloop3D_1B"]))
    assert c is None or np.all(np.isfinite(c))


@pytest.mark.parametrize(("maker", "value"), [(m, v) for m in ("circle", "tube", "rect") for v in BEAM_BAD])
def test_a_section_size_is_refused_before_its_fourth_power_overflows(maker, value):
    """Beam.circle(1e200), tube(1e200, ...), rect(1e200, 1e200) overflowed (OverflowError)."""
    args = {"circle": lambda v: (v,), "tube": lambda v: (v, 0.001), "rect": lambda v: (v, v)}[maker](value)
    with pytest.raises(ParameterError) as info:
        getattr(Beam, maker)(*args, E=70e9, G=26e9)
    assert "\n" not in str(info.value) and ("Beam" in str(info.value))


def _urdf_with(tmp_path: Path, old: str, new: str) -> Path:
    text = (FIVE_3D / "robot.urdf").read_text()
    assert old in text
    (tmp_path / "robot.urdf").write_text(text.replace(old, new, 1))
    (tmp_path / "robot.yaml").write_text((FIVE_3D / "robot.yaml").read_text())
    return tmp_path / "robot.urdf"


#: (text of the five-bar's URDF, the same with ``{v}`` for a number, the element and attribute named).
URDF_NUMBERS = [('<origin xyz="0 -0.18000000000000015987', '<origin xyz="{v} -0.18000000000000015987', "<origin xyz>"),
                ('rpy="1.570796326794896558 -1.570796326794896336 0"', 'rpy="{v} -1.570796326794896336 0"',
                 "<origin rpy>"),
                ('<child link="part_4" />\n    <axis xyz="0 0 1" />',
                 '<child link="part_4" />\n    <axis xyz="0 {v} 1" />', "<axis xyz"),
                ('<mass value="', '<mass value="{v}" x="', "<mass value"),
                ('<inertia ixx="', '<inertia ixx="{v}" x="', "<inertia"),
                ('<limit effort="1"', '<limit lower="{v}" upper="1" effort="1"', "<limit lower")]


@pytest.mark.parametrize(("old", "new", "named"), URDF_NUMBERS, ids=[c[2] for c in URDF_NUMBERS])
@pytest.mark.parametrize("value", ["1e308", "-1e308", "nan", "inf", "-inf", "1e3000", "x", "0x10"])
def test_a_urdf_number_pinocchio_would_choke_on_is_named(tmp_path, old, new, named, value):
    """A URDF origin of 1e308 reached SciPy ("Residuals are not finite"): every number of the
    tree is a finite number, an origin within 1 km; the refusal names the element and attribute.
    A value within the checks (a mass of 1e308, say) is read."""
    path = _urdf_with(tmp_path, old, new.format(v=value))
    got = _answers(lambda: Mechanism.from_urdf(path))
    if got is None:
        with pytest.raises(MalformedURDFError) as info:
            Mechanism.from_urdf(path)
        assert named in str(info.value) and "robot.urdf" in str(info.value) and "\n" not in str(info.value)
    else:
        assert value in ("1e308", "-1e308") and named not in ("<origin xyz>",), "an origin of 1e308 was read"


def _mjcf_with(tmp_path: Path, old: str, new: str) -> Path:
    text = LOOP.read_text()
    assert old in text
    (tmp_path / "loop.xml").write_text(text.replace(old, new, 1))
    return tmp_path / "loop.xml"


MJCF_NUMBERS = [('<body name="rocker" pos="0.5 0 0">', '<body name="rocker" pos="{v} 0 0">', "body 'rocker': pos"),
                ('anchor="0.3 0.1 0"', 'anchor="{v} 0.1 0"', "(connect): anchor"),
                ('<joint name="crank" type="hinge" axis="0 0 1"', '<joint name="crank" type="hinge" axis="{v} 0 1"',
                 "joint 'crank': axis"),
                ('<site name="tip" pos="0.3 0.1 0"/>', '<site name="tip" pos="{v} 0.1 0"/>', "site 'tip': pos"),
                ('<key qpos="0.1 0.3', '<key qpos="{v} 0.3', "keyframe 0: qpos")]


@pytest.mark.parametrize(("old", "new", "named"), MJCF_NUMBERS, ids=[c[2] for c in MJCF_NUMBERS])
@pytest.mark.parametrize("value", ["nan", "1e308", "inf", "-nan", "5e3"])
def test_a_mjcf_number_that_is_not_finite_is_named(tmp_path, old, new, named, value):
    """An MJCF ``anchor`` or ``pos`` of nan compiled in MuJoCo and reached SciPy: refused at
    read time naming the element and attribute (MuJoCo refuses some itself: a typed error too);
    a position beyond 1 km too. An axis of 1e308 is MuJoCo's to normalise: read."""
    pytest.importorskip("mujoco")
    path = _mjcf_with(tmp_path, old, new.format(v=value))
    if "axis" in named and value in ("1e308", "5e3"):  # read, or refused by the check of the two readers
        assert _answers(lambda: Mechanism.from_mjcf(path)) is None or value == "5e3"
        return
    with pytest.raises(MalformedURDFError) as info:
        Mechanism.from_mjcf(path)
    assert "loop.xml" in str(info.value) and "\n" not in str(info.value)
    assert named in str(info.value) or "MuJoCo cannot read it" in str(info.value), info.value


DOCS = Path(__file__).parent.parent / "docs" / "mechanisms.md"


def test_the_sidecar_snippet_of_the_docs_is_read(tmp_path):
    """docs/mechanisms.md's ``beams: {part_3: {E: 70e9, G: 26e9, d: 0.02}}`` (YAML 1.1 read 70e9
    as text): its beam is Beam.circle(0.02, 70e9, 26e9)."""
    import re

    snippet = re.search(r"A sidecar may carry the beams \(.*?\): `(beams:.*?)`", DOCS.read_text(), re.S).group(1)
    snippet = " ".join(snippet.split())
    assert snippet == "beams: {part_3: {E: 70e9, G: 26e9, d: 0.02}}"
    (tmp_path / "robot.yaml").write_text((FIVE_3D / "robot.yaml").read_text() + snippet + "\n")
    mech = Mechanism.from_urdf(FIVE_3D / "robot.urdf", tmp_path / "robot.yaml")
    want = Mechanism.from_urdf(FIVE_3D / "robot.urdf").with_beams({"part_3": Beam.circle(0.02, 70e9, 26e9)})
    assert mech.beam_springs == want.beam_springs and len(mech.beam_springs) == 6


@pytest.mark.parametrize(("text", "value"), [("70e9", 70e9), ("7E10", 7e10), ("+70e9", 70e9), ("1.5e9", 1.5e9),
                                             ("70_000e6", 70e9), ("7.0e+10", 7e10), ("70000000000", 70e9)])
def test_sidecar_numbers_are_read_as_users_write_them(tmp_path, text, value):
    (tmp_path / "robot.yaml").write_text((FIVE_3D / "robot.yaml").read_text() +
                                         f"beams: {{part_3: {{E: {text}, G: 26e9, A: 1e-4, Iy: 1e-9, Iz: 1e-9, "
                                         "J: 2e-9}}\n")
    mech = Mechanism.from_urdf(FIVE_3D / "robot.urdf", tmp_path / "robot.yaml")
    want = Mechanism.from_urdf(FIVE_3D / "robot.urdf").with_beams({"part_3": Beam(value, 26e9, 1e-4, 1e-9, 1e-9,
                                                                                  2e-9)})
    assert mech.beam_springs == want.beam_springs


@pytest.mark.parametrize(("extra", "key"), [("name_mot: ['mot2', 'mot1']\n", "name_mot"),
                                            ("type: ['3d']\n", "type"),
                                            ("beams: {part_3: {E: 70e9, G: 26e9, d: 0.02, d: 0.03}}\n", "d"),
                                            ("beams: {part_3: {d: 0.02, E: 1, G: 1}, part_3: {d: 0.01, E: 1, G: 1}}\n",
                                             "part_3")])
def test_a_sidecar_key_given_twice_is_refused(tmp_path, extra, key):
    """YAML keeps the last of two equal keys without a word: h4pin refuses, naming it and its line."""
    (tmp_path / "robot.yaml").write_text((FIVE_3D / "robot.yaml").read_text() + extra)
    with pytest.raises(MalformedURDFError, match=rf"robot.yaml, line \d+: .*the key '{key}' is given twice"):
        Mechanism.from_urdf(FIVE_3D / "robot.urdf", tmp_path / "robot.yaml")


@pytest.mark.parametrize("call", ["assemble_2e12", "assemble_1e9", "compliance_1e10", "modes_1e9", "list_batch"])
def test_a_batch_is_estimated_from_its_shape_before_it_is_copied(five_3d, monkeypatch, call):
    """A broadcast (2e12, 2) motor array gave MemoryError: 3.64 TiB; (1e10, nq) to compliance
    373 GiB, (1e9, nq) to modes 37 GiB; the 1e9 assembly refusal took 51 s: each is now refused
    by its estimate, from its shape, in well under a second."""
    import time

    from h4pin.limits import TooLargeError

    mech, q = five_3d
    monkeypatch.setenv("H4PIN_MEMORY_LIMIT", "1GiB")
    springs = _all_springs(mech)
    calls = {"assemble_2e12": lambda: mech.assemble(motors=np.broadcast_to(np.zeros(2), (2 * 10**12, 2))),
             "assemble_1e9": lambda: mech.assemble(motors=np.broadcast_to(np.zeros(2), (10**9, 2))),
             "compliance_1e10": lambda: mech.compliance(np.broadcast_to(q, (10**10, len(q))), springs,
                                                        ["closedloop3D_1B"]),
             "modes_1e9": lambda: mech.modes(np.broadcast_to(q, (10**9, len(q))), springs),
             "list_batch": lambda: mech.compliance([q] * 10**7, springs, ["closedloop3D_1B"])}
    start = time.perf_counter()
    with pytest.raises(TooLargeError, match="would need about"):
        calls[call]()
    assert time.perf_counter() - start < 5.0


@pytest.mark.parametrize(("option", "value"), [("bogus", 1), ("timestep", "x"), ("timestep", True),
                                               ("timestep", 1e6), ("timestep", math.nan), ("timestep", -1.0),
                                               ("timestep", 0.0), ("timestep", None), ("timestep", 1 + 1j),
                                               ("damping", -1.0), ("damping", 2.0), ("damping", "x"),
                                               ("damping", math.inf), ("damping", False), ("locked", None),
                                               ("locked", 5), ("locked", ["nope"]), ("sites", 5), ("sites", [1]),
                                               ("sites", ["nope"]), ("name", 5), ("name", math.nan),
                                               ("solref", "x"), ("solref", [1, 2, 3]), ("solref", [math.nan, 1]),
                                               ("solref", True), ("solimp", [1, 2, 3]), ("solimp", None),
                                               ("solimp", {"a": 1}), ("solimp", [0.9] * 4 + [1 + 1j])])
def test_a_bad_export_option_is_named_and_nothing_is_written(five_3d, tmp_path, option, value):
    """to_mjcf(timestep='x') and to_mjcf(bogus=1) gave TypeError; timestep=1e6 was written; a
    name, solref or solimp of the wrong kind reached MuJoCo's bindings (TypeError)."""
    pytest.importorskip("mujoco")
    mech, q = five_3d
    with pytest.raises(ParameterError) as info:
        mech.to_mjcf(tmp_path / "out.xml", _all_springs(mech), q, **{option: value})
    assert option in str(info.value) and "\n" not in str(info.value)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("threads", [0, -1, True, 1.5, "2", np.int64(0), -(10**30)])
def test_threads_that_are_not_a_count_are_refused(five_3d, threads):
    mech, q = five_3d
    springs = _all_springs(mech)
    for call in (lambda: mech.compliance(np.array([q, q]), springs, ["closedloop3D_1B"], threads=threads),
                 lambda: mech.modes(np.array([q, q]), springs, threads=threads)):
        with pytest.raises(ParameterError, match="threads"):
            call()


def test_threads_beyond_the_maximum_are_capped_with_a_warning(five_3d):
    from h4pin.limits import MAX_THREADS, CappedWarning

    mech, q = five_3d
    springs = _all_springs(mech)
    want = mech.compliance(np.array([q, q]), springs, ["closedloop3D_1B"], threads=1)
    with pytest.warns(CappedWarning, match=f"threads = 1e\\+18 capped to {MAX_THREADS}"):
        got = mech.compliance(np.array([q, q]), springs, ["closedloop3D_1B"], threads=10**18)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    with pytest.warns(CappedWarning):
        assert np.all(np.isfinite(mech.modes(np.array([q, q]), springs, threads=10**18).frequencies))


@pytest.mark.parametrize("case", ["q complex", "batch complex", "modes complex", "assemble complex", "motors complex",
                                  "motors True", "motors np.True_", "spring True", "spring np.True_",
                                  "spring complex", "spring [True]", "Mechanism spring True", "configuration complex",
                                  "batch with a True"])
def test_complex_numbers_and_bools_are_not_numbers_here(five_3d, case):
    """Complex positions lost their imaginary part and True was a spring of 1 N.m/rad or a motor
    at 1 rad, without a word: refused, naming the argument."""
    mech, q = five_3d
    springs = _all_springs(mech)
    calls = {
        "q complex": (lambda: mech.compliance(q + 1j, springs, ["closedloop3D_1B"]), "q"),
        "batch complex": (lambda: mech.compliance(np.array([q, q]) + 0j, springs, ["closedloop3D_1B"]), "q"),
        "modes complex": (lambda: mech.modes(q.astype(complex), springs), "q"),
        "assemble complex": (lambda: mech.assemble(mech.reference + 0.5j), "q"),
        "motors complex": (lambda: mech.assemble(motors=np.array([0.1 + 1j, 0.2])), "motors"),
        "motors True": (lambda: mech.assemble(motors=[True, 0.0]), "motors"),
        "motors np.True_": (lambda: mech.assemble(motors=[[0.0, np.True_]]), "motors"),
        "spring True": (lambda: mech.compliance(q, {**springs, "mot1": True}, ["closedloop3D_1B"]), "mot1"),
        "spring np.True_": (lambda: mech.modes(q, {**springs, "mot1": np.True_}), "mot1"),
        "spring complex": (lambda: mech.compliance(q, {**springs, "mot1": 1 + 0j}, ["closedloop3D_1B"]), "mot1"),
        "spring [True]": (lambda: mech.compliance(q, {**springs, "mot1": [True]}, ["closedloop3D_1B"]), "mot1"),
        "Mechanism spring True": (lambda: Mechanism(mech.model, mech.constraint_models, mech.actuated,
                                                    springs={"mot1": True}), "mot1"),
        "configuration complex": (lambda: mech.configuration(q + 1j), "q"),
        "batch with a True": (lambda: mech.compliance([list(q), [True, *q[1:]]], springs, ["closedloop3D_1B"]), "q"),
    }
    call, name = calls[case]
    with pytest.raises(ParameterError) as info:
        call()
    assert name in str(info.value) and "\n" not in str(info.value)
    assert "complex" in str(info.value) or "bool" in str(info.value)


@pytest.mark.parametrize("grid", [(-1e300, 1e300, 5), (0.0, 100.0, 3), (-70.0, 0.0, 2), [0.0, 1e3], [math.pi * 21]])
def test_a_motor_grid_beyond_ten_turns_is_refused(five_3d, grid):
    """``atlas --motor NAME=-1e300:1e300:5`` answered "ok" at 1e300 rad: a revolute motor's grid
    and assembly stay within h4pin.limits.RANGES["motor angle"] (ten turns either way)."""
    pytest.importorskip("xarray")
    from h4pin.limits import ImplausibleValueError
    from h4pin.mechanism import atlas

    mech, _ = five_3d
    with pytest.raises(ImplausibleValueError, match=r"grid 'mot1' = .* rad is outside the plausible range "
                                                    r"\[-62.83\d*, 62.83\d*\] rad"):
        atlas.motor_axes(mech, {"mot1": grid})
    values = np.linspace(*grid) if isinstance(grid, tuple) else np.asarray(grid)
    motors = np.zeros((len(values), len(mech.actuated)))
    motors[:, list(mech.actuated).index("mot1")] = values
    with pytest.raises(ImplausibleValueError, match="motors: 'mot1'"):
        mech.assemble(motors=motors)


def test_the_motor_atlas_refuses_threads_before_any_work(five_3d, monkeypatch):
    pytest.importorskip("xarray")
    from h4pin.mechanism import atlas

    mech, _ = five_3d
    monkeypatch.setattr(Mechanism, "assemble", lambda *a, **k: pytest.fail("assembled before the refusal"))
    for threads in (0, -1, 2.5):
        with pytest.raises(ParameterError, match="threads"):
            atlas.atlas(mech, "closedloop3D_1B", threads=threads, progress=False)


def test_with_no_beams_is_the_mechanism_itself(five_3d):
    mech, _ = five_3d
    assert mech.with_beams({}) is mech
    with pytest.raises(ParameterError, match="beams: a mapping"):
        mech.with_beams([])


@pytest.mark.parametrize(("argv", "word"), [
    (["atlas", "--motor", "mot1=-1e300:1e300:5"], "grid 'mot1' = -1e+300 rad is outside the plausible range"),
    (["atlas", "--motor", "mot1=0:100:2"], "grid 'mot1' = 100 rad is outside the plausible range"),
    (["atlas", "--threads", "0"], "--threads must be a count >= 1"),
    (["atlas", "--threads", "-1"], "--threads must be a count >= 1"),
    (["export", "--elastic", "--spring", "mot1=100", "--spring", "mot2=100", "--timestep", "1e6"],
     "timestep = 1e+06 s is outside the plausible range"),
    (["export", "--elastic", "--spring", "mot1=100", "--timestep", "nan"], "timestep"),
])
def test_the_cli_refuses_what_it_accepted_without_a_word(tmp_path, monkeypatch, capsys, argv, word):
    """One line on stderr, exit 2, nothing written."""
    out = ["--out", str(tmp_path / ("a.nc" if argv[0] == "atlas" else "e.xml"))]
    extra = ["--output", "closedloop3D_1B", "--quiet", "--count", "2"] if argv[0] == "atlas" else []
    code, _, err = run_cli_in_process([argv[0], "--robot", str(FIVE_3D / "robot.urdf"), *argv[1:], *extra, *out],
                                      monkeypatch, capsys)
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("h4pin: first run")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and word in lines[0], err
    assert not list(tmp_path.iterdir())


def test_the_cli_caps_threads_with_a_one_line_warning(tmp_path, monkeypatch, capsys):
    from h4pin.limits import MAX_THREADS

    code, out, err = run_cli_in_process(["atlas", "--robot", str(FIVE_3D / "robot.urdf"), "--output",
                                         "closedloop3D_1B", "--count", "2", "--threads", "1000000", "--quiet", "--out",
                                         str(tmp_path / "a.nc")], monkeypatch, capsys)
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("h4pin: first run")]
    assert code == 0 and lines == [f"warning: --threads 1000000 capped to {MAX_THREADS} (h4pin.limits.MAX_THREADS)"]
    assert (tmp_path / "a.nc").exists()


#: Values no argument should take whole (with those of BAD above): numbers past the floats,
#: complex, masked, an object, a slice, large and wrong-shaped arrays.
HOSTILE = [None, 5, -1, 0, "x", "", True, math.nan, math.inf, 1e300, -1e300, [1], [1, 2, 3], {"a": 1}, 1 + 1j, b"x",
           object(), [[1, 2]], ["nope"], (0.1, 1.0, 3.0), np.zeros((2, 2)), np.array(["a"]), 10**400, [None],
           [math.nan] * 5, np.ma.masked_array([1.0], mask=[True]), np.zeros(10**5), slice(1), [True] * 5,
           ["mot1", "mot1"], "mot1", [0]]


def _surfaces(mech: Mechanism, q: np.ndarray, tmp: Path) -> dict:
    """Every argument of the mechanism's public calls, each alone hostile (the others good)."""
    pytest.importorskip("xarray")
    from h4pin.mechanism import Payload, atlas

    s, out, urdf = _all_springs(mech), ["closedloop3D_1B"], FIVE_3D / "robot.urdf"
    small = {"mot1": (0, 0.1, 2), "mot2": (0, 0.1, 2)}
    return {
        "from_urdf actuated": lambda v: Mechanism.from_urdf(urdf, actuated=v),
        "from_urdf free_flyer": lambda v: Mechanism.from_urdf(urdf, free_flyer=v),
        "from_mjcf actuated": lambda v: Mechanism.from_mjcf(LOOP, actuated=v),
        "assemble q": lambda v: mech.assemble(v),
        "assemble motors": lambda v: mech.assemble(motors=v),
        "assemble fixed": lambda v: mech.assemble(fixed=v),
        "assemble tol": lambda v: mech.assemble(tol=v),
        "assemble iterations": lambda v: mech.assemble(iterations=v),
        "compliance q": lambda v: mech.compliance(v, s, out),
        "compliance springs": lambda v: mech.compliance(q, v, out),
        "compliance a spring": lambda v: mech.compliance(q, {**s, "mot1": v}, out),
        "compliance outputs": lambda v: mech.compliance(q, s, v),
        "compliance locked": lambda v: mech.compliance(q, {k: x for k, x in s.items() if k != "mot1"}, out, v),
        "compliance free_root": lambda v: mech.compliance(q, s, out, free_root=v),
        "compliance method": lambda v: mech.compliance(q, s, out, method=v),
        "compliance threads": lambda v: mech.compliance(np.array([q, q]), s, out, threads=v),
        "modes payload": lambda v: mech.modes(q, s, payload=v),
        "modes payload body": lambda v: mech.modes(q, s, payload=("closedloop3D_1B", v)),
        "Payload mass": lambda v: Payload(v),
        "with_beams": lambda v: mech.with_beams(v),
        "with_beams a beam": lambda v: mech.with_beams({"part_3": v}),
        "Beam to": lambda v: Beam(1, 1, 1, 1, 1, 1, to=v),
        "Beam carry": lambda v: Beam(1, 1, 1, 1, 1, 1, carry=v),
        "to_mjcf path": lambda v: mech.to_mjcf(v, s, q),
        "to_mjcf springs": lambda v: mech.to_mjcf(tmp / "o.xml", v, q),
        "to_mjcf q": lambda v: mech.to_mjcf(tmp / "o.xml", s, v),
        "closure_errors": lambda v: mech.closure_errors(v),
        "motor_axes grid": lambda v: atlas.motor_axes(mech, {"mot1": v}),
        "motor_axes count": lambda v: atlas.motor_axes(mech, count=v),
        "default_springs": lambda v: atlas.default_springs(mech, v),
        "atlas output": lambda v: atlas.atlas(mech, v, small, progress=False),
        "atlas axes": lambda v: atlas.atlas(mech, "closedloop3D_1B", v, progress=False),
        "atlas chunk": lambda v: atlas.atlas(mech, "closedloop3D_1B", small, chunk=v, progress=False),
        "atlas out": lambda v: atlas.atlas(mech, "closedloop3D_1B", small, out=v, progress=False),
    }


SURFACES = ["from_urdf actuated", "from_urdf free_flyer", "from_mjcf actuated", "assemble q", "assemble motors",
            "assemble fixed", "assemble tol", "assemble iterations", "compliance q", "compliance springs",
            "compliance a spring", "compliance outputs", "compliance locked", "compliance free_root",
            "compliance method", "compliance threads", "modes payload", "modes payload body", "Payload mass",
            "with_beams", "with_beams a beam", "Beam to", "Beam carry", "to_mjcf path", "to_mjcf springs",
            "to_mjcf q", "closure_errors", "motor_axes grid", "motor_axes count", "default_springs", "atlas output",
            "atlas axes", "atlas chunk", "atlas out"]


@pytest.mark.parametrize("surface", SURFACES)
def test_every_argument_answers_or_refuses_in_one_typed_line(five_3d, tmp_path, monkeypatch, surface):
    """Each argument of the public calls, fed every hostile value: a result (finite numbers) or an
    H4Error of one line, never a TypeError, OverflowError, LinAlgError or a message over lines
    (a value's multi-line repr)."""
    pytest.importorskip("mujoco")
    mech, q = five_3d
    call = _surfaces(mech, q, tmp_path)[surface]
    monkeypatch.chdir(tmp_path)  # an atlas's out given as text lands here
    wrong = []
    for value in HOSTILE:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                got = call(value)
        except H4Error as exc:
            if not str(exc) or "\n" in str(exc):
                wrong.append(f"{value!r:.40}: a message over lines: {exc!s:.80}")
            continue
        except Exception as exc:  # noqa: BLE001 - what this test is for
            wrong.append(f"{value!r:.40}: {type(exc).__name__}: {exc!s:.80}")
            continue
        arr = getattr(got, "frequencies", got)
        if isinstance(arr, np.ndarray) and arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
            wrong.append(f"{value!r:.40}: a non-finite answer")
    assert not wrong, "\n".join(wrong)
