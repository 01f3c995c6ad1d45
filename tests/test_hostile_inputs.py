# SPDX-License-Identifier: Apache-2.0
"""Hostile inputs at the new surfaces (Elements, Payload, the elastic cycle's arguments, the CLI):
each gives a typed h4pin error naming the problem, or a finite answer; never a bare numpy or
Python error, a NaN result, or a numpy RuntimeWarning printed before the refusal."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import run_cli_in_process

import h4pin
from h4pin.description.elements import COUNTS, ELEMENTS, RIGIDITIES
from h4pin.elastic.modal import Payload
from h4pin.errors import H4Error
from h4pin.studies import elastic_cycle

#: Values no argument should take whole: non-finite, negative, huge, tiny, text, bools, None,
#: wrong shapes and containers, an int beyond the floats, complex, masked, an object.
HOSTILE = [math.nan, math.inf, -math.inf, -1.0, 1e300, -1e300, 1e-300, "x", "1.0", b"1", True, None, [1, 2],
           np.zeros((2, 2)), 10**400, 1 + 1j, {"a": 1}, np.ma.masked_array([1.0], mask=[True]), object(),
           np.array(["a"]), [math.nan] * 8, np.zeros(10**6)]


def answer(call):
    """The call's result, or the H4Error it raised; anything else (or a RuntimeWarning) fails."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            return call()
        except H4Error as exc:
            assert str(exc) and "\n" not in str(exc).strip(), repr(exc)
            return exc


def is_nan_input(value, sizes: tuple[int, ...] = (1,)) -> bool:
    """Whether ``value`` is real numbers of an accepted size holding a NaN (then the refusal must
    say NaN; one of another size or type is refused for that, and may not show its values)."""
    if not isinstance(value, (float, list, np.ndarray)) or isinstance(value, np.ma.MaskedArray):
        return False
    arr = np.asarray(value)
    return arr.dtype.kind == "f" and arr.size in sizes and bool(np.isnan(arr).any())


def generated(seed: int, n: int) -> list:
    """``n`` random hostile values: magnitudes over 600 decades, signs, NaN and inf sprinkled, in
    scalars and arrays of random lengths."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        size = int(rng.integers(0, 10))
        v = np.sign(rng.normal(size=size)) * 10.0 ** rng.uniform(-300, 300, size)
        v[rng.random(size) < 0.2] = rng.choice([np.nan, np.inf, -np.inf])
        out.append(float(v[0]) if size == 1 else v)
    return out


def elements_cases() -> list[tuple[str, object]]:
    return [(name, v) for name in (*ELEMENTS, "bogus") for v in HOSTILE] + \
        [(name, v) for name, v in zip(np.resize(ELEMENTS, 40), generated(1, 40), strict=True)]


@pytest.mark.parametrize(("name", "value"), elements_cases())
def test_elements_answer_or_refuse(name, value):
    got = answer(lambda: h4pin.Elements(**{name: value}))
    if isinstance(got, H4Error):
        assert name in str(got)
        if name != "bogus" and is_nan_input(value, (1, COUNTS.get(name, 1))):
            assert "nan" in str(got).lower(), got
        return
    arr = getattr(got, name)
    assert arr.shape == (COUNTS[name],) and not np.isnan(arr).any()
    assert np.all(arr > 0) if name in RIGIDITIES else np.all((arr >= 0) & np.isfinite(arr))


def test_elements_refuse_positional_values():
    with pytest.raises(h4pin.ParameterError, match="by name"):
        h4pin.Elements(1e-8)


PAYLOAD_EXTRA = [[0, 0, math.nan], [1e300, 0, 0], np.eye(3) * 1e300, np.eye(3) * math.nan, -np.eye(3),
                 np.diag([1.0, 1.0, 5.0]), [[0, 0, 0]] * 3]


@pytest.mark.parametrize(("field", "value"), [(f, v) for f in ("mass", "com", "inertia")
                                              for v in HOSTILE + PAYLOAD_EXTRA])
def test_payload_answers_or_refuses(field, value):
    got = answer(lambda: Payload(**{"mass": 1.0, field: value}))
    if isinstance(got, H4Error):
        assert "payload" in str(got)
        if is_nan_input(value, {"mass": (1,), "com": (3,), "inertia": (9,)}[field]):
            assert "nan" in str(got).lower(), got
        return
    assert math.isfinite(got.mass) and got.com.shape == (3,) and got.inertia.shape == (3, 3)
    assert np.all(np.isfinite(got.spatial()))


#: The elastic cycle's arguments, each alone hostile (the others cheap: 8 samples, no hold).
CYCLE_ARGS = ("period", "payload", "samples", "damping", "hold", "tool", "motion", "heading", "theta", "length",
              "height", "rise", "overlap", "check", "centre", "bogus")


@pytest.mark.parametrize(("arg", "value"), [(a, v) for a in CYCLE_ARGS for v in HOSTILE[:17]])
def test_elastic_cycle_refuses_before_computing(proto, monkeypatch, arg, value):
    """Every hostile argument of the elastic cycle is refused (naming it, or the pose of the cycle
    it makes unreachable) before the motion is computed (springs_along is never reached), or it
    is a value it can take (an angle that only turns the stroke, a tiny hold): then the answer is
    finite."""
    reached = []
    real = elastic_cycle.springs_along
    monkeypatch.setattr(elastic_cycle, "springs_along", lambda *a, **k: (reached.append(1), real(*a, **k))[1])
    kwargs = {"samples": 8, "hold": 0.0, arg: value}
    got = answer(lambda: elastic_cycle.run(proto, **kwargs))
    if isinstance(got, H4Error):
        assert not reached, "refused after the motion was computed"
        assert arg in str(got) or isinstance(got, h4pin.PoseError) and "the cycle leaves the workspace" in str(got), got
        if is_nan_input(value, (3,) if arg in ("tool", "centre") else (1,)) and arg != "bogus":
            assert "nan" in str(got).lower(), got
        return
    assert reached and not isinstance(value, (str, bytes, dict, complex)) and value is not math.nan, (arg, value)
    for series in (got.quasi_static, got.dynamic, got.rest, got.residual):
        assert np.all(np.isfinite(series))


def test_the_cycle_answers_with_bounds_and_names_unknown_options(proto):
    with pytest.raises(h4pin.ParameterError, match="no cycle option 'legth'; the options are centre, length"):
        elastic_cycle.run(proto, samples=8, hold=0.0, legth=0.3)
    with pytest.raises(h4pin.ParameterError, match=r"damping = 10 s is outside the plausible range \[0, 1\] s"):
        elastic_cycle.run(proto, samples=8, damping=10.0)
    with pytest.raises(h4pin.ParameterError, match=r"elastic cycle: 8 samples and 1e\+300 of the stop"):
        elastic_cycle.run(proto, samples=8, hold=1e300)
    with pytest.raises(h4pin.ParameterError, match=r"elastic cycle: 1e\+300 samples"):
        elastic_cycle.run(proto, samples=10**400)


#: Refusals of the command line over inputs that make numpy warn if computed: (argv, a word of the message).
CLI_REFUSALS = [
    (["modes", "--pose", "nan", "0", "-0.6", "0"], "nan"),
    (["modes", "--pose", "1e300", "0", "-0.6", "0"], "cannot reach"),
    (["modes", "--pose", "0", "0", "-1e300", "0"], "cannot reach"),
    (["modes", "--pose", "0", "0", "-0.6", "1e300"], "1e+300 rad"),
    (["modes", "--payload", "nan"], "nan"),
    (["view", "--pose", "1e300", "0", "-0.6", "0", "--out", "{tmp}/v.html"], "cannot reach"),
    (["view", "--load", "nan", "0", "0", "--out", "{tmp}/v.html"], "nan"),
    (["cycle", "--time", "nan"], "nan"),
    (["cycle", "--payload", "1e300"], "payload"),
]


@pytest.mark.parametrize(("argv", "word"), CLI_REFUSALS)
def test_a_cli_refusal_is_the_one_line(tmp_path, monkeypatch, capsys, argv, word):
    """With every warning shown (as ``python -W default``), stderr is exactly the one error line:
    no RuntimeWarning of numpy before it."""
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.filterwarnings("ignore", category=DeprecationWarning)  # third-party imports (zmq) of `view`
        code, out, err = run_cli_in_process(argv, monkeypatch, capsys)
    lines = [line for line in err.splitlines() if not line.startswith("h4pin: first run")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert word in lines[0].lower() and "Warning" not in err, err
    assert not list(tmp_path.iterdir())


def test_a_failed_allocation_is_one_line_with_the_limit_off(monkeypatch, capsys):
    """H4PIN_MEMORY_LIMIT=0 (no estimate refuses): an allocation that fails anyway is one line,
    exit 2, naming memory and the variable."""
    from h4pin.studies import cycle

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setenv("H4PIN_MEMORY_LIMIT", "0")
    monkeypatch.setattr(cycle, "cycle_dynamics", no_memory)
    code, out, err = run_cli_in_process(["cycle", "--samples", "8"], monkeypatch, capsys)
    lines = [line for line in err.splitlines() if not line.startswith("h4pin: first run")]
    assert code == 2 and len(lines) == 1 and "out of memory" in lines[0] and "H4PIN_MEMORY_LIMIT" in lines[0], err


def test_the_elastic_part_of_a_cycle_is_estimated_before_the_rigid_one_runs(monkeypatch, capsys):
    """cycle --elastic: the elastic cycle's motion and stop (10 kB a sample, 400,000 samples here:
    4 GB) are refused up front when the rigid cycle alone (1.25 GB) would fit."""
    monkeypatch.setenv("H4PIN_MEMORY_LIMIT", "2GiB")
    code, _, err = run_cli_in_process(["cycle", "--samples", "100000", "--elastic"], monkeypatch, capsys)
    lines = [line for line in err.splitlines() if not line.startswith("h4pin: first run")]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("error: elastic cycle: 100,000 samples and 300,000 of the stop would need about 3.7 GiB")


def test_a_sweep_task_box_is_counted_not_made():
    """A task box of 1e16 poses is refused by its estimate, without making its poses."""
    from h4pin.limits import TooLargeError
    from h4pin.studies import sweep

    spec = sweep.Spec(n_designs=4, chunk=2, task=sweep.Task(counts=(10**4,) * 4))
    with pytest.raises(TooLargeError, match="sweep: 4 designs in chunks of 2 would need about"):
        sweep.check_size(spec)
