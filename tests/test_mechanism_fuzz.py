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

from h4pin.errors import H4Error, MechanismWarning
from h4pin.mechanism import FrameOutput, JointOutput, Mechanism

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
