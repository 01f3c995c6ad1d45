# SPDX-License-Identifier: Apache-2.0
"""Impossible sizes, unreachable schedulers and absurd values are refused at once (project issue
30, h4pin.limits): a typed error (the CLI: exit 2 and one line ``error: ...``, no traceback)
naming the size or the value and the limit or the range, in seconds, before any large
allocation and without writing anything."""

from __future__ import annotations

import http.server
import re
import socket
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli_in_process

import h4pin
from h4pin import limits
from h4pin.errors import ParameterError

run_cli = run_cli_in_process  # tests/conftest.py


def assert_refused(argv: list[str], words: list[str], monkeypatch, capsys, seconds: float = 15.0) -> str:
    started = time.monotonic()
    code, _, err = run_cli(argv, monkeypatch, capsys)
    lines = [line for line in err.splitlines() if not line.startswith("h4pin: first run")]
    assert code == 2, (argv, err)
    assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], (argv, w, lines[0])
    assert time.monotonic() - started < seconds, argv
    return lines[0]


# --- sizes ------------------------------------------------------------------------------------


def test_compliance_of_a_billion_pose_view_is_refused_before_any_copy(proto, centre):
    view = np.broadcast_to(centre, (10**9, 4))
    started = time.monotonic()
    with pytest.raises(limits.TooLargeError) as info:
        h4pin.compliance(proto, view)
    assert time.monotonic() - started < 2.0
    message = str(info.value)
    assert isinstance(info.value, h4pin.ParameterError)
    assert "1,000,000,000 poses" in message and "GiB" in message and limits.MEMORY_ENV in message
    assert "\n" not in message


def test_the_memory_limit_is_the_users_to_raise(proto, centre, monkeypatch):
    view = np.broadcast_to(centre, (200_000, 4))
    monkeypatch.setenv(limits.MEMORY_ENV, "1MiB")
    with pytest.raises(limits.TooLargeError, match=r"over the limit of 1\.0 MiB \(H4PIN_MEMORY_LIMIT=1MiB"):
        h4pin.compliance(proto, view)
    monkeypatch.setenv(limits.MEMORY_ENV, "1TiB")
    assert h4pin.compliance(proto, view).matrix.shape == (200_000, 8, 8)


@pytest.mark.parametrize(("text", "value"), [("123", 123), ("8GiB", 8 * 2**30), ("8 G", 8e9), ("1.5e9", 1.5e9),
                                             ("512MiB", 2**29), ("0", None), ("none", None)])
def test_memory_limit_parses_bytes_and_units(monkeypatch, text, value):
    monkeypatch.setenv(limits.MEMORY_ENV, text)
    assert limits.memory_limit()[0] == value


@pytest.mark.parametrize("text", ["lots", "-5", "8 parsecs", "nan"])
def test_a_bad_memory_limit_is_named(monkeypatch, text):
    monkeypatch.setenv(limits.MEMORY_ENV, text)
    with pytest.raises(ParameterError, match=limits.MEMORY_ENV):
        limits.check_size("x", 1.0)


def test_the_default_limit_is_a_share_of_the_available_memory(monkeypatch):
    monkeypatch.delenv(limits.MEMORY_ENV, raising=False)
    avail = limits.available_memory()
    if avail is None:
        pytest.skip("this system does not say how much memory is available")
    limit, source = limits.memory_limit()
    assert limit == pytest.approx(limits.MEMORY_FRACTION * avail, rel=0.2)  # memory moves meanwhile
    assert "available" in source


def test_a_time_limit_refuses_a_long_job(monkeypatch):
    from h4pin.studies import sweep

    spec = sweep.Spec(n_designs=1_000_000)
    sweep.check_size(spec)  # fits in memory, no time limit by default
    monkeypatch.setenv(limits.TIME_ENV, "10min")
    with pytest.raises(limits.TooLargeError, match="over the time limit of 10 min"):
        sweep.check_size(spec)


def size_cases(tmp: Path) -> list[tuple[list[str], list[str]]]:
    return [
        (["tolerance", "--robots", "100000000"], ["100,000,000 robots", "GiB", "H4PIN_MEMORY_LIMIT"]),
        (["cycle", "--samples", "100000000"], ["100,000,000 samples", "TiB", "H4PIN_MEMORY_LIMIT"]),
        (["modes", "--figure", str(tmp / "m.png"), "--grid", "100000"], ["10,000,000,000 poses", "H4PIN_MEMORY_LIMIT"]),
        (["sweep", "--designs", "1000000000000", "--out", str(tmp / "s.zarr")],
         ["1,000,000,000,000 designs", "H4PIN_MEMORY_LIMIT", "years"]),
        (["atlas", "--x", "-1", "1", "100000", "--y", "-1", "1", "100000", "--z-range", "-1", "0", "1000", "--out",
          str(tmp / "a.zarr")], ["10,000,000,000,000 poses", "H4PIN_MEMORY_LIMIT"]),
    ]


def test_cli_refuses_impossible_sizes_in_one_line(tmp_path, monkeypatch, capsys):
    for argv, words in size_cases(tmp_path):
        assert_refused(argv, words, monkeypatch, capsys)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_the_studies_refuse_sizes_before_they_allocate(proto):
    from h4pin.studies import atlas, cycle, frequency, sweep, tolerance

    for call in (lambda: tolerance.study(proto, n_robots=10**8),
                 lambda: cycle.run(proto, 0.5, samples=10**8),
                 lambda: frequency.frequency_map(proto, np.zeros(10**5), np.zeros(10**5)),
                 lambda: sweep.designs(sweep.Spec(n_designs=10**12)),
                 lambda: atlas.atlas(proto, np.zeros(10**5), np.zeros(10**5), np.zeros(10**3), progress=False)):
        started = time.monotonic()
        with pytest.raises(limits.TooLargeError):
            call()
        assert time.monotonic() - started < 5.0


# --- schedulers -------------------------------------------------------------------------------


@pytest.fixture
def http_server():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


@pytest.fixture
def closed_port() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"127.0.0.1:{port}"


@pytest.mark.parametrize("which", ["http_server", "closed_port"])
def test_a_scheduler_that_is_not_dask_is_refused_in_seconds(which, request, tmp_path, monkeypatch, capsys):
    address = request.getfixturevalue(which)
    # an HTTP server takes the handshake's timeout (5 s) to be refused: one form of its address
    for shown in ([f"tcp://{address}"] if which == "http_server" else [address, f"tcp://{address}"]):
        line = assert_refused(["sweep", "--designs", "4", "--out", str(tmp_path / "s.zarr"), "--scheduler", shown],
                              ["cannot reach a Dask scheduler", shown], monkeypatch, capsys, seconds=10.0)
        assert ("no Dask handshake" in line) == (which == "http_server")
    assert not (tmp_path / "s.zarr").exists()


def test_a_dask_scheduler_passes_the_check():
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    from h4pin.studies.sweep import check_scheduler

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        started = time.monotonic()
        check_scheduler(cluster.scheduler_address)
        check_scheduler(cluster.scheduler_address.removeprefix("tcp://"))
        assert time.monotonic() - started < 2.0


# --- values -----------------------------------------------------------------------------------


def value_cases(tmp: Path) -> list[tuple[list[str], list[str]]]:
    return [
        (["view", "--load", "1e300", "0", "0", "--out", str(tmp / "v.html")], ["--load = 1e+300 N", "1e+06"]),
        (["view", "--exaggeration", "1e300", "--out", str(tmp / "v.html")], ["--exaggeration = 1e+300", "1e+06"]),
        (["view", "--mode", "1", "--payload", "1e12", "--out", str(tmp / "v.html")], ["--payload = 1e+12 kg", "1000"]),
        (["modes", "--payload", "1e12"], ["--payload = 1e+12 kg", "[0, 1000] kg"]),
        (["cycle", "--payload", "1e12"], ["--payload = 1e+12 kg", "[0, 1000] kg"]),
        (["cycle", "--time", "1e-9"], ["--time = 1e-09 s", "[0.001, 1e+06] s"]),
    ]


def test_cli_refuses_absurd_values_in_one_line(tmp_path, monkeypatch, capsys):
    for argv, words in value_cases(tmp_path):
        assert_refused(argv, words, monkeypatch, capsys)
    assert list(tmp_path.iterdir()) == []


def test_values_inside_the_ranges_pass():
    for kind, (lo, hi, _, _) in limits.RANGES.items():
        for v in (lo, hi, 0.5 * (lo + hi)):
            assert limits.check_range(kind, v, kind) == v
        for v in (hi * 10 if hi > 0 else 1.0, float("inf"), float("nan")):
            with pytest.raises(limits.ImplausibleValueError, match=kind):
                limits.check_range(kind, v, kind)


def test_cycle_refuses_an_absurd_period_and_payload(proto):
    from h4pin.studies import cycle

    with pytest.raises(limits.ImplausibleValueError, match=r"period = 1e-09 s .*\[0\.001, 1e\+06\] s"):
        cycle.run(proto, 1e-9)
    with pytest.raises(limits.ImplausibleValueError, match=r"payload = 1e\+12 kg"):
        cycle.run(proto, 0.5, 1e12)


def test_the_api_refuses_absurd_loads_payloads_and_drawing_factors(proto, centre):
    """The same ranges as the CLI's at the API's own doors: a deflection under 1e300 N, a 1e12 kg
    payload's frequencies, a drawn exaggeration of 1e300 are ImplausibleValueErrors naming the
    argument, not pages of inf (and a load inside the range still computes)."""
    from h4pin.io import viewer

    res = h4pin.compliance(proto, centre)
    with pytest.raises(limits.ImplausibleValueError, match=r"load: force F = 1e\+300 N .*\[-1e\+06, 1e\+06\] N"):
        res.deflection(np.array([1e300, 0.0, 0.0]))
    with pytest.raises(limits.ImplausibleValueError, match=r"load: torque T, t1, t2 = -1e\+09 N.m"):
        res.deflection(np.r_[0.0, 0.0, 10.0, -1e9, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(res.deflection(np.array([1e5, 0.0, 0.0])), 1e5 * res.matrix[:, 0], rtol=1e-15)
    with pytest.raises(limits.ImplausibleValueError, match=r"payload mass = 1e\+12 kg"):
        h4pin.modes(proto, centre, h4pin.Payload(1e12))
    for kwargs, word in (({"exaggeration": 1e300}, "exaggeration = 1e+300"), ({"scale": 1e300}, "scale = 1e+300"),
                         ({"load": [1e300, 0.0, 0.0]}, "load: force F = 1e+300")):
        with pytest.raises(limits.ImplausibleValueError, match=re.escape(word)):
            viewer.show(proto, centre, **kwargs)  # refused before any server starts


def test_a_spring_of_1e_300_is_refused_at_load_and_by_the_studies(proto, centre):
    """A robot cannot be built with a spring outside the ranges (load, URDF text, pickling all go
    through H4's constructor); the studies that take parameters instead of a robot check them."""
    from h4pin.studies import atlas, frequency

    with pytest.raises(limits.ImplausibleValueError, match=r"springs: .*'kc' = 1e-300 N.m/rad .*\[1e-06, 1e\+25\]"):
        h4pin.load("prototype", springs={"kc": 1e-300})
    with pytest.raises(limits.ImplausibleValueError, match=r"'E' = 1e\+300 Pa"):
        h4pin.load("prototype", springs={"E": 1e300})
    with pytest.raises(limits.ImplausibleValueError, match="'kc' = 1e-300"):
        h4pin.load(proto.urdf.replace('kc="7400.0"', 'kc="1e-300"', 1))
    soft = h4pin.H4Params(kc=1e-300)
    with pytest.raises(limits.ImplausibleValueError, match=r"'kc' = 1e-300 N.m/rad .*\[1e-06, 1e\+25\]"):
        limits.check_springs(soft)
    for call in (lambda: frequency.first_frequency(soft, centre),
                 lambda: atlas.atlas(soft, [0.0], [0.0], [centre[2]], progress=False)):
        with pytest.raises(limits.ImplausibleValueError, match="kc"):
            call()
    limits.check_springs(h4pin.load("prototype"))  # the shipped robots are within the ranges
    limits.check_springs(h4pin.H4Params())


def test_a_urdf_with_a_1e_300_spring_is_refused_by_the_cli(proto, tmp_path, monkeypatch, capsys):
    assert proto.urdf.count('kc="7400.0"') == 4
    path = tmp_path / "soft.urdf"
    path.write_text(proto.urdf.replace('kc="7400.0"', 'kc="1e-300"', 1))
    assert_refused(["modes", "--urdf", str(path)], ["'kc' = 1e-300", str(path)], monkeypatch, capsys)
    assert_refused(["table2", "--urdf", str(path)], ["'kc' = 1e-300"], monkeypatch, capsys)


def test_a_sweep_refuses_actuator_stiffness_bounds_out_of_range():
    from h4pin.studies import sweep

    bounds = dict(sweep.BOUNDS, kc=(1e-300, 1e4))
    with pytest.raises(limits.ImplausibleValueError, match="kc"):
        sweep.Spec(bounds=bounds)


def test_a_zero_frequency_is_a_named_warning(proto, centre, monkeypatch):
    from h4pin.studies import frequency

    class Zero:
        first = np.zeros(2)
        status = np.zeros(2, dtype=np.int8)

    monkeypatch.setattr(frequency, "modes", lambda *a, **k: Zero())
    with pytest.warns(limits.NonFiniteResultWarning, match="2 of 2 results are not finite"):
        frequency.first_frequency(proto, np.tile(centre, (2, 1)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        monkeypatch.undo()
        f, status = frequency.first_frequency(proto, np.tile(centre, (2, 1)))
        assert np.all(np.isfinite(f) & (f > 0))


def test_elements_have_plausible_ranges_everywhere_they_enter():
    """Element data outside h4pin.limits.ELEMENT_RANGES are refused where Elements are made, where
    a URDF is read and where a pickle is loaded; an unknown kind names the kinds; 0 and inf (off)
    pass."""
    import pickle

    import h4pin
    from h4pin.description.elements import Elements
    from h4pin.limits import ImplausibleValueError

    for kwargs, match in (({"forearm_out_EI": 1e-300}, r"forearm 1: forearm_out_EI = 1e-300 N.m\^2 is outside"),
                          ({"revolute_tilt": 1e300}, r"revolute_tilt = 1e\+300"),
                          ({"ball_radial": [0.0] * 7 + [0.5]}, r"bar 42: ball_radial = 0.5 m/N"),
                          ({"central_EI": [1e13, np.inf]}, "central_EI = 1e\\+13")):
        with pytest.raises(ImplausibleValueError, match=match):
            Elements(**kwargs)
    with pytest.raises(h4pin.ParameterError, match="no element kind 'bogus' .*forearm_out_EI"):
        Elements(bogus=1)
    assert Elements(revolute_tilt=0.0, forearm_out_EI=np.inf).off
    h4 = h4pin.load("prototype")
    text = h4.urdf.replace('stressed_fraction="1.0"/>', 'stressed_fraction="1.0" out_EI="1e-30"/>')
    with pytest.raises(ImplausibleValueError, match=r"forearm link 'forearm_1' .*out_EI.* 1e-30"):
        h4pin.load(text)
    # a pickle rebuilds its elements through the constructor: what it carries is checked like new data
    good = Elements(forearm_out_EI=1120.0)
    assert pickle.loads(pickle.dumps(good)).allclose(good)
    func, (values,) = good.__reduce__()
    values["forearm_out_EI"] = np.full(4, 1e-30)  # as a pickle written by another version could hold
    with pytest.raises(ImplausibleValueError):
        func(values)


def test_payloads_are_typed_and_ranged():
    from h4pin.limits import ImplausibleValueError
    from h4pin.mechanism import Payload

    with pytest.raises(h4pin_errors().ParameterError, match="not text"):
        Payload("0.5")
    for args, match in (((0.5, (1e8, 0, 0)), "payload com = 1e\\+08 m"), ((1e12,), "payload mass = 1e\\+12 kg"),
                        ((0.5, (0, 0, 0), np.eye(3) * 1e30), "principal moments\\) = 1e\\+30")):
        with pytest.raises(ImplausibleValueError, match=match):
            Payload(*args)
    assert Payload(0.5, (0.01, 0.0, 0.02)).mass == 0.5


def test_mechanism_outputs_are_checked():
    import math

    from h4pin.mechanism import FrameOutput, JointOutput

    err = h4pin_errors().ParameterError
    with pytest.raises(err, match="scale must be a finite non-zero number, got nan"):
        JointOutput("mot1", math.nan)
    with pytest.raises(err, match="rows must be indices 0 to 5, got \\(7,\\)"):
        FrameOutput("D", rows=(7,))
    with pytest.raises(err, match="reference must be pin.LOCAL"):
        FrameOutput("D", reference="bogus")


def h4pin_errors():
    import h4pin.errors

    return h4pin.errors


def test_the_new_batch_paths_estimate_their_size_and_time(monkeypatch):
    """h4pin.modes over a billion (broadcast) poses and the elastic cycle with a billion samples
    or a stop of 1e9 s are refused in a line before allocating; a 1 ms cycle's 600 000-sample stop
    is in the time estimate (H4PIN_TIME_LIMIT=10 refuses it at once); a 1e-9 s period and a robot
    given by name are typed errors."""
    import h4pin
    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.limits import ImplausibleValueError, TooLargeError
    from h4pin.studies import elastic_cycle as ec

    h4 = h4pin.load("prototype")
    with pytest.raises(TooLargeError, match="modes: 1,000,000,000 poses"):
        h4pin.modes(h4, np.broadcast_to(centre_pose(h4), (10**9, 4)))
    with pytest.raises(TooLargeError, match="elastic cycle: 1,000,000,000 samples"):
        ec.run(h4, samples=10**9)
    with pytest.raises(TooLargeError, match="of the stop"):
        ec.run(h4, hold=1e9)
    with pytest.raises(ImplausibleValueError, match="period = 1e-09 s"):
        ec.run(h4, period=1e-9)
    with pytest.raises(h4pin.ParameterError, match="must be an h4pin.H4"):
        ec.run("prototype")
    monkeypatch.setenv("H4PIN_TIME_LIMIT", "10")
    with pytest.raises(TooLargeError, match="600,000 of the stop"):
        ec.run(h4, period=0.001, hold=1.5, samples=400)


def test_memory_limit_zero_in_any_spelling_and_scheduler_schemes(monkeypatch):
    """H4PIN_MEMORY_LIMIT 0, 0.0 or 0e0 all mean no limit; a scheduler address in a scheme h4pin
    cannot use (tls://, ws://) or without a usable port is refused at once, naming it."""
    from h4pin import limits
    from h4pin.studies import sweep

    for text in ("0", "0.0", "0e0"):
        monkeypatch.setenv("H4PIN_MEMORY_LIMIT", text)
        assert limits.memory_limit()[0] is None
    monkeypatch.setenv("H4PIN_MEMORY_LIMIT", "8GiB")
    assert limits.memory_limit()[0] == 8 * 2**30
    for address, match in (("tls://127.0.0.1:8786", "over tcp:// only .not tls://"), ("ws://127.0.0.1:8786", "not ws://"),
                           ("tcp://127.0.0.1:port", "port must be a number"), ("", "an address such as")):
        with pytest.raises(h4pin_errors().ParameterError, match=match):
            sweep.check_scheduler(address)


def test_a_sweep_chunk_larger_than_memory_is_refused():
    """--chunk sets the zarr chunk, held whole while it is written: 1e12 designs a chunk is
    refused in a line (before: a MemoryError asking for 44 TiB)."""
    from h4pin.limits import TooLargeError
    from h4pin.studies import sweep

    with pytest.raises(TooLargeError, match="in chunks of 1,000,000,000,000"):
        sweep.check_size(sweep.Spec(n_designs=1000, chunk=10**12))
    sweep.check_size(sweep.Spec(n_designs=1000, chunk=64))
