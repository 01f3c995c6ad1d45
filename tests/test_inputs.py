# SPDX-License-Identifier: Apache-2.0
"""The door of every public function (issue 30, "Wrong types reach the inside"): a wrong type
for the robot, a pose, a model name or a flag is a typed h4pin error naming the argument and
what it got (type name and a short repr), never an AttributeError, TypeError, IndexError or
OSError from inside numpy or Pinocchio. Also: ``h4pin.load`` takes the URDF's text."""

from __future__ import annotations

import string
import time
from pathlib import Path

import numpy as np
import pytest

import h4pin
from h4pin.inputs import describe, real_array

H4PIN_DIR = Path(h4pin.__file__).resolve().parent


def refused(call, error: type[Exception], name: str, value=None, *, got: bool = True) -> h4pin.H4Error:
    """``call()`` raises ``error`` (an h4pin error) whose message names ``name`` and, with
    ``got``, the type of ``value``; raised by h4pin itself, with no numpy or Pinocchio
    traceback chained to it."""
    with pytest.raises(h4pin.H4Error) as info:
        call()
    exc = info.value
    assert isinstance(exc, error), f"{type(exc).__name__}: {exc}"
    message = str(exc)
    assert name in message, message
    if got:
        assert type(value).__name__ in message, message
    assert exc.__cause__ is None and (exc.__context__ is None or exc.__suppress_context__), repr(exc.__context__)
    assert Path(info.traceback[-1].path).resolve().is_relative_to(H4PIN_DIR), info.traceback[-1]
    return exc


PARAMS = h4pin.H4Params()
MASKED = np.ma.masked_array([0.0, 0.0, -0.6, 0.0], mask=[True, False, False, False])
#: Not a robot, not a pose: for any argument of a documented type.
WRONG = [None, "prototype", PARAMS, ["a", "b"], {}, {"x": 1.0}, object()]
#: Not a pose (4,) or (N, 4) of real numbers.
WRONG_POSES = [*WRONG[:5], ["0", "0", "-0.6", "0"], np.array([True, False, True, False]), np.ones((3, 4), bool),
               MASKED, np.ma.masked_array(np.zeros((2, 4))), np.array([0.0, 0.0, None, 0.0], dtype=object),
               [0.0, 0.0, None, 0.0], np.array([0.0, 0.0, -0.6, 0.0]) + 0j, np.array(["paper"] * 4), b"\x00" * 32,
               [[0.0, 0.0], [0.0, 0.0, -0.6, 0.0]]]
WRONG_NAMES = [None, np.array(["paper"]), ["paper"], {}, PARAMS, b"paper", 1, True, "no"]
WRONG_FLAGS = ["no", [], "True", 1, 0, np.array([True]), {}, PARAMS]


def ids(value) -> str:
    return type(value).__name__


# ---------------------------------------------------------------------------------------------
# h4pin.compliance (and its result's methods)

COMPLIANCE_CASES = ([("h4", v, h4pin.ParameterError) for v in WRONG + [np.array([True] * 4)]]
                    + [("pose", v, h4pin.PoseError) for v in WRONG_POSES]
                    + [(arg, v, h4pin.ParameterError) for arg in ("model", "method", "on_error") for v in WRONG_NAMES]
                    + [("terms", v, h4pin.ParameterError) for v in WRONG_FLAGS]
                    + [("elements", v, h4pin.ParameterError) for v in ("yes", {}, 1, np.array([True]), PARAMS)])


@pytest.mark.parametrize(("arg", "value", "error"), COMPLIANCE_CASES,
                         ids=[f"{a}-{k}-{type(v).__name__}" for k, (a, v, _) in enumerate(COMPLIANCE_CASES)])
def test_compliance_refuses_wrong_types(proto, centre, arg, value, error):
    args = {"h4": proto, "pose": centre}
    if arg in args:
        args[arg] = value
        call = lambda: h4pin.compliance(args["h4"], args["pose"])  # noqa: E731
    else:
        call = lambda: h4pin.compliance(proto, centre, **{arg: value})  # noqa: E731
    refused(call, error, arg, value, got=not (arg == "pose" and isinstance(value, list) and value and
                                              isinstance(value[0], list)))
    if arg == "pose":  # the batch route with on_error="nan" refuses them too
        refused(lambda: h4pin.compliance(proto, value, on_error="nan"), error, arg, value, got=False)


def test_compliance_accepts_numpy_scalars_and_ints(proto, centre):
    """numpy's bool and str pass for a flag and a name; integer poses are real numbers."""
    ref = h4pin.compliance(proto, centre, "consistent", terms=True)
    got = h4pin.compliance(proto, centre, np.str_("consistent"), terms=np.True_, method=np.str_("auto"))
    np.testing.assert_array_equal(got.matrix, ref.matrix)
    assert isinstance(got.terms, dict) and got.terms.keys() == ref.terms.keys()  # computed now: terms was True
    np.testing.assert_array_equal(h4pin.compliance(proto, centre, elements=np.False_).matrix,
                                  h4pin.compliance(proto, centre, elements=False).matrix)
    with pytest.raises(h4pin.UnreachablePoseError):  # int pose: the door lets it in, the robot cannot take it
        h4pin.compliance(proto, np.array([0, 0, 0, 0]))
    np.testing.assert_array_equal(h4pin.compliance(proto, centre.astype(np.float32)).pose, centre.astype(np.float32))


@pytest.mark.parametrize("value", [*WRONG_POSES[:5], np.array([True, False, True]), MASKED[:3],
                                   np.array([0.0, None, 0.0]), np.array([1j, 0, 0])], ids=ids)
def test_result_methods_refuse_wrong_types(proto, centre, value):
    res = h4pin.compliance(proto, centre)
    refused(lambda: res.deflection(value), h4pin.LoadError, "load", value)
    refused(lambda: res.at(value), h4pin.ParameterError, "offset", value)
    if value is not None:  # load_at=None: at the offset
        refused(lambda: res.at([0.0, 0.0, 0.0], value), h4pin.ParameterError, "load_at", value)


# ---------------------------------------------------------------------------------------------
# h4pin.modes, h4pin.elastic_model

MODES_CASES = ([("robot", v, h4pin.ParameterError) for v in WRONG + [np.array([True] * 4)]]
               + [("pose", v, h4pin.PoseError) for v in WRONG_POSES if not isinstance(v, list) or v[0] != [0.0, 0.0]]
               + [("method", v, h4pin.ParameterError) for v in WRONG_NAMES]
               + [("link_inertias", v, h4pin.ParameterError) for v in [*WRONG_FLAGS, None]]
               + [("payload", v, h4pin.ParameterError) for v in ("x", {}, 1.0, PARAMS)]
               + [("data", v, h4pin.ParameterError) for v in ("x", {}, 1.0, PARAMS, "ROBOT_DATA")])


@pytest.mark.parametrize(("arg", "value", "error"), MODES_CASES,
                         ids=[f"{a}-{k}-{type(v).__name__}" for k, (a, v, _) in enumerate(MODES_CASES)])
def test_modes_refuses_wrong_types(proto, centre, arg, value, error):
    got = True
    if isinstance(value, str) and value == "ROBOT_DATA":  # a pin.Data, of the rigid model
        value, got = proto.data, False
    args = {"robot": proto, "pose": centre}
    if arg in args:
        args[arg] = value
        call = lambda: h4pin.modes(args["robot"], args["pose"])  # noqa: E731
    else:
        call = lambda: h4pin.modes(proto, centre, **{arg: value})  # noqa: E731
    refused(call, error, arg, value, got=got)


@pytest.mark.parametrize("value", [*WRONG, np.array([True] * 4), h4pin.H4Geometry], ids=ids)
def test_elastic_model_refuses_wrong_types(value):
    refused(lambda: h4pin.elastic_model(value), h4pin.ParameterError, "h4", value)


# ---------------------------------------------------------------------------------------------
# h4pin.load, h4pin.Elements

#: (argument, value, what the message names, the type name it shows).
LOAD_CASES = ([("source", v, "source", type(v).__name__)
               for v in (None, 1, 3.5, True, ["prototype"], {}, np.array(["prototype"]), np.array([True]), object())]
              + [("springs", v, "springs", type(v).__name__) for v in ("no", [], ["kc"], 1.0)]
              + [("springs", {"kc": v}, "springs['kc']", type(v).__name__)
                 for v in (True, "1e5", None, np.ma.masked_array([1e5] * 4), 1e5j, [True, False, True, True])]
              + [("springs", {1: 2.0}, "springs", "int")]
              + [("elements", v, "elements", type(v).__name__) for v in ("no", [], 1.0, PARAMS)]
              + [("elements", {1: 0.0}, "elements", "int"),
                 ("elements", {"revolute_tilt": True}, "revolute_tilt", "bool"),
                 ("elements", {"revolute_tilt": np.array([True, False])}, "revolute_tilt", "ndarray"),
                 ("elements", {"ball_radial": "1e-8"}, "ball_radial", "str")]
              + [("bar_clearance", v, "bar_clearance", type(v).__name__)
                 for v in (True, "0.01", None, np.array([0.01]), [0.01], -1.0, np.nan, 1j)])


@pytest.mark.parametrize(("arg", "value", "name", "type_name"), LOAD_CASES,
                         ids=[f"{a}-{k}-{t}" for k, (a, _, _, t) in enumerate(LOAD_CASES)])
def test_load_refuses_wrong_types(arg, value, name, type_name):
    call = (lambda: h4pin.load(value)) if arg == "source" else (lambda: h4pin.load("prototype", **{arg: value}))
    exc = refused(call, h4pin.ParameterError, name, got=False)
    assert arg in str(exc) and type_name in str(exc), str(exc)


@pytest.mark.parametrize("source", ["x" * 5000, "a\0b", "h4_" + "é" * 300 + ".urdf", b"nope", Path("missing.urdf"),
                                    "<robot/>", b"<robot/>", " \n <robot name='x'></robot>", b"<\xff\xfe>",
                                    "<?xml version='1.0'?>\n<robot name='h4'>", b"\x00<robot/>"],
                         ids=lambda s: type(s).__name__ + str(len(str(s))))
def test_load_refuses_bad_sources_with_h4_errors(source):
    """Long names (once ``OSError: File name too long``), NUL bytes, missing paths, XML text that is
    not an H4: each an h4pin error, none leaking from the file system or the XML readers."""
    with pytest.raises(h4pin.H4Error) as info:
        h4pin.load(source)
    assert isinstance(info.value, (h4pin.ParameterError, h4pin.URDFNotFoundError, h4pin.MalformedURDFError))
    assert len(str(info.value)) < 600


def test_load_takes_the_urdf_text(proto, centre, poses):
    """The prototype's URDF text (str or bytes, after white space) is the prototype."""
    text = proto.urdf
    path = h4pin.robot.variant_path("prototype")
    for source in (text, "\n  " + text, text.encode(), bytearray(text.encode()), "\ufeff" + text):
        robot = h4pin.load(source)
        assert robot.source == "URDF text" and robot.urdf == text
        for x in (centre, poses[0]):
            np.testing.assert_array_equal(h4pin.compliance(robot, x).matrix, h4pin.compliance(proto, x).matrix)
    assert h4pin.load(path).source == str(path) == h4pin.load(str(path).encode()).source
    assert h4pin.load(b"prototype").source == str(path)
    again = h4pin.load(text, springs={"kc": proto.geometry.springs["kc"] * 2}, elements=h4pin.Elements(shaft_tilt=1e-6))
    assert again.elements.on("shaft_tilt")
    np.testing.assert_array_equal(again.geometry.springs["kc"], 2 * proto.geometry.springs["kc"])


ELEMENT_VALUES = [True, np.True_, [True, False], np.array([True, True]), "1e-8", None, np.ma.masked_array([0.0, 1e-8]),
                  np.array([None, 1e-8]), 1e-8j, np.array(["paper"]), {}, PARAMS, [[1e-8], [1e-8, 1e-8]]]


@pytest.mark.parametrize("field", ["revolute_tilt", "ball_radial", "central_EI", "forearm_out_EI"])
@pytest.mark.parametrize("value", ELEMENT_VALUES, ids=ids)
def test_elements_refuse_wrong_types(field, value):
    refused(lambda: h4pin.Elements(**{field: value}), h4pin.ParameterError, field, value,
            got=not isinstance(value, list) or isinstance(value[0], bool))


def test_elements_still_take_numbers():
    # integers are numbers too (within the plausible ranges: ball_radial 0 or up to 1e-2 m/N)
    el = h4pin.Elements(revolute_tilt=1, ball_radial=np.zeros(8, dtype=np.int32), central_EI=[200, np.inf],
                        shaft_tilt=np.float32(1e-6))
    assert el.revolute_tilt.dtype == np.float64 and el.on("revolute_tilt") and el.on("central_EI")
    assert el.ball_radial.dtype == np.float64 and not el.on("ball_radial")


def test_messages_are_short():
    """What it got: the type and a repr cut to a line (a URDF's text, a big array)."""
    assert describe(None) == "NoneType None"
    assert len(describe("x" * 10_000)) < 80 and len(describe(np.zeros((100, 100)))) < 160
    assert "\n" not in describe(np.zeros((5, 5)))
    with pytest.raises(h4pin.PoseError, match="masked array"):
        real_array(np.ma.masked_array([1.0]), "pose")
    assert real_array(np.arange(3), "x").dtype == np.float64


# ---------------------------------------------------------------------------------------------
# Fuzz: random wrong types and sizes into every argument of every public function


def _random_value(rng: np.random.Generator, proto: h4pin.H4):
    """Something random, mostly of a wrong type or size."""
    kind = int(rng.integers(16))
    if kind == 0:
        return [None, True, False, np.True_, 0, 1, -7, 3.5, np.nan, np.inf, 1j, object()][int(rng.integers(12))]
    if kind == 1:
        letters = string.ascii_letters + string.digits + "<>/._ \n\0é"
        return "".join(rng.choice(list(letters), int(rng.integers(0, 30))))
    if kind == 2:
        return bytes(rng.integers(0, 256, int(rng.integers(0, 20)), dtype=np.uint8))
    if kind == 3:
        return [str(v) for v in rng.normal(size=int(rng.integers(0, 6)))]
    if kind == 4:
        return {str(k): float(v) for k, v in enumerate(rng.normal(size=int(rng.integers(0, 3))))}
    if kind == 5:
        return [PARAMS, proto, h4pin.Elements(), {1, 2}, (), [], {}, Path("nowhere.urdf")][int(rng.integers(8))]
    shape = tuple(int(n) for n in rng.integers(0, 6, int(rng.integers(0, 4))))
    if rng.random() < 0.4:
        shape = (*shape[:1], 4) if rng.random() < 0.5 else (4,)
    base = np.asarray(rng.normal(size=shape) * 0.3)
    dtype = [bool, np.int8, np.uint16, np.float32, np.complex128, object, "U5", "S3", np.float64, np.float64][kind - 6]
    if dtype is object:
        arr = base.astype(object)
        if arr.size:
            arr.flat[int(rng.integers(arr.size))] = None
        return arr
    arr = (base > 0) if dtype is bool else base.astype(dtype)
    if kind == 14:  # a masked array
        return np.ma.masked_array(arr, mask=rng.random(shape) < 0.5)
    if kind == 15 and arr.size:
        arr.flat[int(rng.integers(arr.size))] = [np.nan, np.inf, -np.inf][int(rng.integers(3))]
    return arr.tolist() if rng.random() < 0.2 else arr


def test_fuzz_every_failure_is_an_h4pin_error(proto, centre):
    """200 seeded calls, one random argument each: any failure is an h4pin.H4Error (never an
    AttributeError, TypeError, IndexError, OSError, ... from inside)."""
    rng = np.random.default_rng(30)
    res = h4pin.compliance(proto, centre)
    targets = {
        "compliance": (lambda **a: h4pin.compliance(**{"h4": proto, "pose": centre, **a}),
                       ("h4", "pose", "model", "elements", "on_error", "method", "terms")),
        "modes": (lambda **a: h4pin.modes(**{"robot": proto, "pose": centre, **a}),
                  ("robot", "pose", "payload", "method", "link_inertias", "data")),
        "elastic_model": (lambda **a: h4pin.elastic_model(**a), ("h4",)),
        "load": (lambda **a: h4pin.load(**a), ("source", "springs", "elements", "bar_clearance")),
        "Elements": (lambda **a: h4pin.Elements(**a), ("revolute_radial", "ball_radial", "lateral_GJ", "shaft_tilt")),
        "deflection": (lambda **a: res.deflection(**a), ("load",)),
        "at": (lambda **a: res.at(**{"offset": np.zeros(3), **a}), ("offset", "load_at")),
    }
    names = sorted(targets)
    started, failures, kinds = time.monotonic(), [], set()
    for case in range(200):
        name = names[int(rng.integers(len(names)))]
        call, args = targets[name]
        arg = args[int(rng.integers(len(args)))]
        value = _random_value(rng, proto)
        try:
            call(**{arg: value})
        except h4pin.H4Error as exc:
            kinds.add(type(exc).__name__)
        except Exception as exc:  # noqa: BLE001 - what the test is about
            failures.append(f"#{case} {name}({arg}={describe(value)}): {type(exc).__name__}: {exc}")
    assert not failures, "\n".join(failures)
    assert {"ParameterError", "PoseError"} <= kinds
    assert time.monotonic() - started < 10.0
