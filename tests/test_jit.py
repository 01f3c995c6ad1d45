# SPDX-License-Identifier: Apache-2.0
"""First use without the compiler (h4pin._jit): the interpreted twins equal the compiled
functions, and a process with an empty numba cache answers at once, on the numpy path and the
twins, with the warm numbers and without compiling anything."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from numba import njit

import h4pin
from h4pin import _jit
from h4pin.kinematics import _compiled
from h4pin.kinematics import pinocchio as kin
from h4pin.kinematics.closed_form import centre_pose

ROOT = Path(__file__).resolve().parent.parent
VARIANTS = h4pin.VARIANTS


def _poses(h4, n=4):
    c = centre_pose(h4)
    return [c + np.array([0.03 * np.cos(k), 0.03 * np.sin(k), 0.01 * k, 0.1 * (k - 1)]) for k in range(n)]


@pytest.mark.parametrize("variant", VARIANTS)
def test_configuration_twin_equals_compiled(variant):
    """The twin of the configuration fills the same Pinocchio configuration (and closes the loops)."""
    h4 = h4pin.load(variant)
    twin = _jit.interpreted(_compiled.configuration_packed)
    assert twin is not _compiled.configuration_packed and not hasattr(twin, "signatures")
    floats, ints = kin.configuration_pack(h4)
    for x in _poses(h4):
        st = kin.state(h4, x)
        args = [np.ascontiguousarray(a, dtype=float) for a in st]
        compiled = _compiled.configuration_packed(h4.index.q_neutral.copy(), *args, floats, ints)
        interpreted = twin(h4.index.q_neutral.copy(), *args, floats, ints)
        assert np.max(np.abs(interpreted - compiled)) < 1e-12


COLD = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np, h4pin
from h4pin.kinematics import _compiled
from h4pin.stiffness import pipeline
h4 = h4pin.load()
x = h4pin.kinematics.closed_form.centre_pose(h4)
xs = x + np.array([[0.02 * k, -0.01 * k, 0.005 * k, 0.05 * k] for k in range(5)])
one = h4pin.compliance(h4, x)
batch = h4pin.compliance(h4, xs, "consistent", terms=True)
pin = h4pin.compliance(h4, x, method="pinocchio")
bad = h4pin.compliance(h4, np.array([[0, 0, -2.0, 0], x]), on_error="nan")
compiled = [f.__name__ for f in (_compiled.configuration_packed, pipeline.one, pipeline.run) if f.signatures]
print(json.dumps({"seconds": time.perf_counter() - t0, "one": one.matrix.tolist(), "batch": batch.matrix.tolist(),
                  "tension": batch.terms["tension"].tolist(), "pin": pin.matrix.tolist(), "q0": h4.q0.tolist(),
                  "status": bad.status.tolist(), "compiled": compiled}))
"""


def test_empty_cache_answers_without_compiling(tmp_path, proto, centre):
    """With an empty numba cache (and no background warm-up), loading, one pose, a batch with
    terms, the Pinocchio path and a refused pose compile nothing and equal the compiled results."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), H4PIN_WARMUP="off", PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", COLD], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["compiled"] == []
    xs = centre + np.array([[0.02 * k, -0.01 * k, 0.005 * k, 0.05 * k] for k in range(5)])
    ref_one = h4pin.compliance(proto, centre, method="kernel").matrix
    ref = h4pin.compliance(proto, xs, "consistent", method="kernel", terms=True)
    ref_pin = h4pin.compliance(proto, centre, method="pinocchio").matrix
    for key, want in (("one", ref_one), ("batch", ref.matrix), ("tension", ref.terms["tension"]), ("pin", ref_pin)):
        assert np.max(np.abs(np.array(got[key]) - want)) <= 1e-12 * np.max(np.abs(want)), key
    assert np.max(np.abs(np.array(got["q0"]) - proto.q0)) < 1e-12
    assert got["status"] == [1, 0]


READY = ("from h4pin.kinematics import _compiled; from h4pin.stiffness import pipeline; from h4pin import _jit; "
         "print(all(_jit._ready_one(f) for f in (_compiled.configuration_packed, pipeline.one)))")


def test_warmup_compiles_every_gated_function():
    """The warm-up's steps compile every function a gate waits for (else a process would stay on
    the fallback for good): run in this process, every gate is ready afterwards, each step
    reported once, in order."""
    from h4pin import warmup
    from h4pin.kinematics import pinocchio as kin
    from h4pin.mechanism import batch
    from h4pin.stiffness import frequencies, kernel

    seen: list[str] = []
    warmup.compile_all(lambda name, seconds: seen.append(name))
    assert seen == [warmup.NAMES[key] for key in warmup.KEYS]
    gates = [kin.CONFIGURATION, kernel.ONE, kernel.BATCH, frequencies.FREQUENCIES, batch.GATE]
    assert warmup.gates() == gates  # the list the test suite's own warm-up checks (tests/conftest.py)
    for gate in gates:
        assert all(f.signatures for f in gate.functions), gate.name
        assert gate.step in warmup.KEYS, gate.name


def test_warmup_compiles_the_calling_step_first():
    """A background warm-up started by a gate compiles that gate's step (and the loaded robot it
    needs) before the others, and every step once; the process is started with ``--first``."""
    from h4pin import warmup

    assert warmup.order() == list(warmup.KEYS) == warmup.order("no such step")
    for key in warmup.KEYS:
        got = warmup.order(key)
        assert sorted(got) == sorted(warmup.KEYS), key
        assert got.index(key) <= 1, key  # first, or right after the robot it needs
    assert warmup.order("mechanism")[0] == "mechanism"
    assert warmup.order("frequencies")[:2] == ["configuration", "frequencies"]
    assert warmup.with_needs(["studies", "one"]) == ["configuration", "studies", "one"]
    names = [warmup.NAMES[key] for key in warmup.order("mechanism")]
    assert names[0].startswith("any mechanism") and len(names) == len(warmup.KEYS)


def test_background_start_names_the_first_step(monkeypatch):
    """``start_background(step)`` starts ``python -m h4pin.warmup --first step`` (once)."""
    from h4pin import _jit

    calls = []
    monkeypatch.setattr(_jit, "_started", False)
    monkeypatch.setattr(_jit, "running", lambda: False)
    monkeypatch.setattr(_jit, "mode", lambda: "background")
    monkeypatch.setattr(_jit.subprocess, "Popen", lambda args, **kw: calls.append(args))
    assert _jit.start_background("mechanism") is True
    assert _jit.start_background("one") is False  # one warm-up per process
    assert len(calls) == 1 and calls[0][-2:] == ["--first", "mechanism"] and "h4pin.warmup" in calls[0]


@pytest.mark.slow
def test_background_warmup_fills_the_cache(tmp_path):
    """A first call with an empty cache starts one warm-up process, which fills the cache in
    order of first need: a new process soon finds the configuration and the one-pose kernel
    there (the warm-up is then stopped: the whole of it takes minutes)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), H4PIN_WARMUP="background", PYTHONPATH=str(ROOT))

    def ready() -> bool:
        out = subprocess.run([sys.executable, "-c", READY], env=env, capture_output=True, text=True, timeout=60,
                             check=True)
        return out.stdout.strip() == "True"

    assert not ready()
    first = ("import h4pin, numpy as np; h4pin.compliance(h4pin.load(), np.array([0, 0, -0.5, 0.0])); "
             "from h4pin import _jit; print(_jit.lock_path())")
    out = subprocess.run([sys.executable, "-c", first], env=env, capture_output=True, text=True, timeout=60,
                         check=True)
    lock = Path(out.stdout.strip())
    try:
        deadline = time.monotonic() + 300
        while not ready():
            assert time.monotonic() < deadline, "the warm-up did not compile its first steps within 300 s"
            time.sleep(2)
    finally:
        deadline = time.monotonic() + 30
        while not lock.exists() and time.monotonic() < deadline:  # the warm-up holds it while it compiles
            time.sleep(0.2)
        try:
            os.kill(int(lock.read_text()), signal.SIGTERM)
        except (OSError, ValueError):
            pass


def test_cache_stamp_covers_the_modules_compiled_code_depends_on(tmp_path, monkeypatch):
    """numba stamps a cached function with its own file; h4pin's stamp adds every module its
    compiled code inlines or freezes constants of. In a copy of the package: editing the element
    schema's codes (description/elements.py), the packed layouts (packed.py) or the singular
    threshold (verdicts.py) changes the stamp of the compiled pipeline, and not that of the
    compiled configuration (kinematics/_compiled.py), which imports nothing of h4pin; and the
    dispatchers of this process carry the stamp."""
    import shutil

    from h4pin import _numba_cache
    from h4pin.stiffness import pipeline

    src = Path(_numba_cache.__file__).resolve().parent
    names = {p.relative_to(src).as_posix() for p in _numba_cache.sources(src / "stiffness" / "pipeline.py")}
    assert {"stiffness/packed.py", "verdicts.py", "description/elements.py", "stiffness/pipeline.py"} <= names
    for f in (pipeline.run, pipeline.one):
        assert f._cache._cache_file._source_stamp == _numba_cache.stamp(src / "stiffness" / "pipeline.py")

    copy = tmp_path / "h4pin"
    shutil.copytree(src, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(_numba_cache, "_ROOT", copy)
    _numba_cache._imports.cache_clear()
    files = {"pipeline": copy / "stiffness" / "pipeline.py", "closure": copy / "kinematics" / "_compiled.py"}
    before = {k: _numba_cache.stamp(f) for k, f in files.items()}
    for edited in ("description/elements.py", "stiffness/packed.py", "verdicts.py"):
        path = copy / edited
        path.write_text(path.read_text() + "\n# edited\n")
        after = {k: _numba_cache.stamp(f) for k, f in files.items()}
        assert after["pipeline"] != before["pipeline"], edited
        assert after["closure"] == before["closure"], edited
        before = after
    _numba_cache._imports.cache_clear()


def test_isolated_warmup_runs_a_process_a_group():
    """``compile_all(isolate=True)`` (``h4pin warmup``, the background warm-up) runs the steps in
    :func:`h4pin.warmup.order`, a child process for each run of one group, and passes each step's
    progress on; a child that fails raises, naming its step. (The cache is full here: the
    test above compiled everything, so each child only loads.)"""
    from h4pin import warmup

    for first in (None, *warmup.KEYS):
        runs = warmup.chunks(first)
        assert [k for run in runs for k in run] == warmup.order(first)
        assert all(len({warmup.GROUPS[k] for k in run}) == 1 for run in runs)
        assert all(warmup.GROUPS[a[-1]] != warmup.GROUPS[b[0]] for a, b in zip(runs[:-1], runs[1:], strict=True))
    seen = []
    warmup.compile_all(lambda name, secs: seen.append(name), "mechanism", isolate=True)
    assert seen == [warmup.NAMES[k] for k in warmup.order("mechanism")]
    with pytest.raises(RuntimeError, match="(?s)nosuch.*failed.*unknown step"):
        warmup.run_child(["nosuch"], None)


def test_sigterm_ends_the_warmup_and_its_child(tmp_path):
    """A SIGTERM to the warm-up (what a test or a user sends its lock holder) ends the child
    process compiling a group too, and releases the lock: nothing keeps compiling behind it."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), H4PIN_WARMUP="inline", PYTHONPATH=str(ROOT))
    lock = tmp_path / "warmup.lock"
    parent = subprocess.Popen([sys.executable, "-m", "h4pin.warmup", "--lock", str(lock), "--quiet"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    children = Path(f"/proc/{parent.pid}/task/{parent.pid}/children")
    try:
        deadline = time.monotonic() + 120
        kids: list[int] = []
        while not kids:
            if not children.exists():
                pytest.skip("this kernel does not list a process's children in /proc")
            kids = [int(k) for k in children.read_text().split()]
            assert time.monotonic() < deadline and parent.poll() is None, "the warm-up started no child"
            time.sleep(0.2)
        parent.send_signal(signal.SIGTERM)
        assert parent.wait(timeout=60) == 128 + signal.SIGTERM
        for kid in kids:
            assert not Path(f"/proc/{kid}").exists() or "Z" in Path(f"/proc/{kid}/stat").read_text().split()[2]
        assert not lock.exists()
    finally:
        if parent.poll() is None:
            parent.kill()


@njit
def _callee(a, i):  # pragma: no cover - compiled
    s = 0.0
    for k in range(a.shape[0]):
        s += a[k] * (k + i)
    return s


@njit
def _plain_caller(a):  # pragma: no cover - compiled
    return _callee(a, 1) + _callee(a, 2)


@_jit.link_as_compiled
@njit
def _linked_caller(a):  # pragma: no cover - compiled
    return _callee(a, 1) + _callee(a, 2)


def test_link_as_compiled_links_callees_as_they_were_optimised():
    """A function marked by ``_jit.link_as_compiled`` calls its callees' compiled code as it is
    (their definitions stay in its module, called), where numba's own build inlines them and
    optimises them again; both give the same number as numpy."""
    a = np.linspace(-1.0, 2.0, 7)
    want = float(np.sum(a * (np.arange(7) + 1)) + np.sum(a * (np.arange(7) + 2)))
    assert _plain_caller(a) == pytest.approx(want, rel=1e-15)
    assert _linked_caller(a) == _plain_caller(a)

    def callees_defined(f):
        ir = f.overloads[f.signatures[0]].library.get_llvm_str()
        return [line for line in ir.splitlines() if line.startswith("define") and "7_callee" in line]

    assert len(callees_defined(_linked_caller)) == 2  # one version per literal second argument
    assert callees_defined(_plain_caller) == []


def test_link_as_compiled_hooks_numba_once():
    """The hook wraps numba's method once, however many functions are marked."""
    from numba.core import codegen

    hook = codegen.CPUCodeLibrary._optimize_final_module
    assert getattr(hook, "_h4pin_hook", False)
    plain = _plain_caller.py_func
    assert _jit.link_as_compiled(plain) is plain  # a plain function (NUMBA_DISABLE_JIT): returned as is
    assert _jit.link_as_compiled(_callee) is _callee  # marking another function hooks nothing again
    assert codegen.CPUCodeLibrary._optimize_final_module is hook


REINSTALLED = r"""
import sys, h4pin
from h4pin import _numba_cache
from h4pin.kinematics import pinocchio as kin
assert h4pin.__file__.startswith(sys.argv[1]), h4pin.__file__
before = kin.CONFIGURATION.cached()
if sys.argv[2] == "compile":
    h4pin.load()  # H4PIN_WARMUP=inline: compiles the configuration into the cache
print(before, kin.CONFIGURATION.cached(), _numba_cache.folder())
"""


@pytest.mark.slow  # two pip installs of the package and one compile of the configuration (about 40 s)
def test_a_reinstall_of_the_same_source_finds_the_compiled_kernels(tmp_path):
    """``pip install`` of this source into a folder, the configuration compiled there, then the
    same source installed again (``--upgrade``: the package's folder replaced, and with it
    anything cached beside the code): the second install finds the compiled configuration in the
    per-user cache (its gate is cached before anything runs), and compiles nothing."""
    import importlib.util

    if importlib.util.find_spec("pip") is None or importlib.util.find_spec("hatchling") is None:
        pytest.skip("needs pip and hatchling (the test extra) to install the package")
    target, cache = tmp_path / "site", tmp_path / "cache"
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--no-index",
           "--target", str(target)]
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(XDG_CACHE_HOME=str(cache), PYTHONPATH=str(target), H4PIN_WARMUP="inline")

    def install(*extra):
        out = subprocess.run([*pip, *extra, str(ROOT)], cwd=tmp_path, env=env, capture_output=True, text=True,
                             timeout=300)
        assert out.returncode == 0, out.stderr

    def run(action):
        out = subprocess.run([sys.executable, "-c", REINSTALLED, str(target), action], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        before, after, folder = out.stdout.split()
        return before == "True", after == "True", folder

    install()
    marker = target / "h4pin" / "first-install"
    marker.write_text("")
    assert run("compile") == (False, True, str(cache / "h4pin" / "numba"))  # a fresh cache, then compiled
    assert not any((target / "h4pin").rglob("*.nbi"))  # nothing beside the code
    install("--upgrade")
    assert not marker.exists()  # the package's folder was replaced
    assert run("look") == (True, True, str(cache / "h4pin" / "numba"))  # found before any call
