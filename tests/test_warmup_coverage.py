# SPDX-License-Identifier: Apache-2.0
"""The warm-up compiles every signature the commands use (project issue 30: after ``h4pin warmup``
the first ``h4pin atlas`` compiled a second version of a kernel for minutes).

Numba compiles one version of a function per signature, and a signature holds each array's
dtype, dimensions, layout (C or A) and read-only flag: a command that passes one array read-only
where the warm-up passed it writable compiles anew. The slow test warms an empty numba cache up
in one process, runs every command that compiles (tiny grids) in another with the same cache, and
checks that the cache did not change: the same index files with the same signatures, and numba's
own cache log (``NUMBA_DEBUG_CACHE``) saving nothing.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: The compiled entry points the commands call: the gates of :mod:`h4pin._jit` (``kernel.ONE``,
#: ``kernel.BATCH``, ``frequencies.FREQUENCIES``, ``pinocchio.CONFIGURATION``) and the studies'
#: reductions (called directly, without a gate). Name -> (module, function).
ENTRY_POINTS = {
    "kernel.ONE": ("h4pin.stiffness.pipeline", "one"),
    "kernel.BATCH": ("h4pin.stiffness.pipeline", "run"),
    "frequencies.FREQUENCIES": ("h4pin.stiffness.frequencies", "frequencies_run"),
    "pinocchio.CONFIGURATION": ("h4pin.kinematics._compiled", "configuration_packed"),
    "_derived.atlas_fields": ("h4pin.studies._derived", "atlas_fields"),
    "_derived.design_reduce": ("h4pin.studies._derived", "design_reduce"),
}
#: Modules that define gates.
GATE_MODULES = ("h4pin.stiffness.kernel", "h4pin.stiffness.frequencies", "h4pin.kinematics.pinocchio")


def _dispatcher(module: str, function: str):
    return getattr(importlib.import_module(module), function)


def _gates() -> dict[str, list]:
    """Every :class:`h4pin._jit.Gate` of :data:`GATE_MODULES`: ``module.NAME`` -> its functions."""
    from h4pin import _jit

    out = {}
    for name in GATE_MODULES:
        for attr, value in vars(importlib.import_module(name)).items():
            if isinstance(value, _jit.Gate):
                out[f"{name.rsplit('.', 1)[1]}.{attr}"] = list(value.functions)
    return out


def _index_name(module: str, function: str) -> str:
    """The name of numba's index file of an entry point (the same in any cache folder)."""
    return _dispatcher(module, function)._cache._cache_file._index_name


def test_the_list_of_entry_points_holds_every_gate():
    gates = _gates()
    assert set(gates) >= {"kernel.ONE", "kernel.BATCH", "frequencies.FREQUENCIES", "pinocchio.CONFIGURATION"}, gates
    listed = [_dispatcher(*where) for where in ENTRY_POINTS.values()]
    missing = {k: fs for k, fs in gates.items() if not all(any(f is g for g in listed) for f in fs)}
    assert not missing, f"gates the warm-up coverage test does not list (add them to ENTRY_POINTS): {missing}"
    for where in ENTRY_POINTS.values():
        assert _index_name(*where).endswith(".nbi"), where


def snapshot(cache: Path) -> dict[str, list[str]]:
    """The overloads in numba's cache: index file -> the signatures it holds (numba's index is a
    pickled version, then a pickled ``(stamp, {(signature, target): data file})``)."""
    out = {}
    for index in sorted(cache.rglob("*.nbi")):
        with open(index, "rb") as fh:
            pickle.load(fh)
            _, overloads = pickle.loads(fh.read())
        out[str(index.relative_to(cache))] = sorted(str(key[0]) for key in overloads)
    return out


def _entry_cached(snap: dict[str, list[str]], module: str, function: str) -> bool:
    name = _index_name(module, function)
    return any(Path(k).name == name and v for k, v in snap.items())


#: The commands that compile, with tiny grids ({tmp} is a folder of the test's).
COMMANDS = [
    ["atlas", "--x", "-0.1", "0.1", "3", "--y", "-0.1", "0.1", "3", "--out", "{tmp}/a.nc", "--quiet"],
    ["atlas", "--x", "-0.1", "0.1", "20", "--y", "-0.1", "0.1", "20", "--out", "{tmp}/f.zarr", "--quiet",
     "--frequency"],
    ["sweep", "--designs", "4", "--chunk", "2", "--out", "{tmp}/s.zarr", "--quiet"],
    ["sweep", "--designs", "2", "--chunk", "2", "--out", "{tmp}/sf.zarr", "--quiet", "--frequency"],
    ["tolerance", "--robots", "3", "--quiet", "--no-sensitivity"],
    ["modes", "--figure", "{tmp}/m.png", "--grid", "3"],
    ["cycle", "--samples", "16"],
    ["table2"],
]

DRIVER = textwrap.dedent("""
    import sys
    from h4pin import cli

    for argv in {commands!r}:
        sys.argv = ["h4pin", *argv]
        try:
            cli.main()
        except SystemExit as exc:
            if exc.code not in (0, None):
                raise SystemExit(f"h4pin {{' '.join(argv)}} exited {{exc.code}}")
""")


@pytest.mark.slow
def test_commands_compile_nothing_after_the_warmup(tmp_path):
    cache = tmp_path / "numba"
    cache.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(NUMBA_CACHE_DIR=str(cache), H4PIN_WARMUP="inline", MPLBACKEND="Agg")
    warm = subprocess.run([sys.executable, "-m", "h4pin.warmup", "--quiet"], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=1800)
    assert warm.returncode == 0, warm.stderr[-3000:]
    before = snapshot(cache)
    not_cached = [name for name, (m, f) in ENTRY_POINTS.items() if not _entry_cached(before, m, f)]
    assert not not_cached, f"the warm-up left these entry points uncompiled: {not_cached}"

    commands = [[a.format(tmp=out) for a in argv] for argv in COMMANDS]
    run = subprocess.run([sys.executable, "-c", DRIVER.format(commands=commands)], cwd=ROOT,
                         env=dict(env, NUMBA_DEBUG_CACHE="1"), capture_output=True, text=True, timeout=1800)
    assert run.returncode == 0, (run.stdout[-3000:], run.stderr[-3000:])
    after = snapshot(cache)
    saved = [line for line in run.stdout.splitlines() if "data saved" in line or "index saved" in line]
    new = {k: [s for s in v if s not in before.get(k, [])] for k, v in after.items()}
    new = {k: v for k, v in new.items() if v}
    assert not new and not saved, ("the commands compiled signatures the warm-up did not (fix h4pin/warmup.py):\n"
                                   + "\n".join(f"{k}: {v}" for k, v in new.items()) + "\n" + "\n".join(saved[:20]))
    assert after == before
