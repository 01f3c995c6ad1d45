#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The hostile inputs of issue 48 run one by one, each in its own process with a timeout, and
their outcomes counted by category (nothing here is asserted by the tests; ``tests/test_hostile_files.py``
and ``tests/test_mechanism_fuzz.py`` hold the same inputs).

Each case says what it expects: ``refuse`` (a typed :mod:`h4pin.errors` error, one line on the
CLI with exit status 2, or a warning where a value is capped) or ``answer`` (a finite result).
The outcome of a case is one of:

* ``hang``: still running at the timeout (a FIFO read forever), or out of the probe's memory
  limit (a device read without bound);
* ``untyped``: a Python error that is no :class:`h4pin.H4Error` (a ``TypeError``, ``KeyError``,
  ``MemoryError``, ...), or a CLI traceback;
* ``accepted``: a value that should be refused went through without a word;
* ``typed``: refused with a typed error (or said with an h4pin warning);
* ``answered``: an ``answer`` case gave a finite result (``refused`` if it gave a typed error).

    python scripts/hostile_probe.py [--timeout 30] [--only WORD] [-v]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
ROBOTS = HERE / "tests" / "robots"
FIVE_BAR = ROBOTS / "5bar_linkage_iso3d"
MEMORY = 4 << 30  # the address space of a case: a device read without bound ends here

# What a Python case runs in: its expression's value is checked finite.
PRELUDE = """
import functools, json, math, os, sys, warnings
import numpy as np
from pathlib import Path
from h4pin.errors import H4Error
from h4pin.mechanism import Beam, Mechanism
T = Path(sys.argv[1]); FIVE = Path(sys.argv[2])
OUT = "closedloop3D_1B"
M = functools.lru_cache(lambda: Mechanism.from_urdf(FIVE / "robot.urdf"))
Q = functools.lru_cache(lambda: M().assemble())
def S(k=1e3):
    return {n: k for n in list(M().model.names)[1:]}
def beam(field, value):
    values = {"E": 70e9, "G": 26e9, "A": 1e-4, "Iy": 1e-9, "Iz": 1e-9, "J": 2e-9, field: value}
    flex = M().with_beams({"part_3": Beam(**values)})
    return flex.compliance(flex.assemble(), S(), [OUT])
def finite(x):
    if isinstance(x, (Mechanism, Path)):
        return True
    if hasattr(x, "frequencies"):
        x = x.frequencies
    return bool(np.all(np.isfinite(np.asarray(x, dtype=float))))
"""

RUNNER = PRELUDE + """
def _out(kind, text=""):
    print("PROBE " + json.dumps([kind, " ".join(str(text).split())[:300]]), flush=True)
try:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = eval(sys.argv[3])
    said = [w for w in caught if w.category.__module__.startswith("h4pin")]
    if said:
        _out("warned", said[0].message)
    elif finite(value):
        _out("returned", type(value).__name__)
    else:
        _out("nonfinite", type(value).__name__)
except H4Error as exc:
    _out("typed" if "\\n" not in str(exc).strip() else "untyped", f"{type(exc).__name__}: {exc}")
except BaseException as exc:
    _out("untyped", f"{type(exc).__name__}: {exc}")
"""


def fixtures(tmp: Path) -> None:
    """The hostile files: FIFOs, a folder, text, foreign stores, odd URDFs and MJCFs."""
    os.mkfifo(tmp / "fifo")
    os.mkfifo(tmp / "fifo.xml")
    os.mkfifo(tmp / "mesh.stl")
    (tmp / "folder").mkdir()
    (tmp / "text.nc").write_text("not a store\n")
    (tmp / "text.zarr").write_text("not a store\n")
    urdf = (FIVE_BAR / "robot.urdf").read_text()
    side = (FIVE_BAR / "robot.yaml").read_text()
    (tmp / "trunc.urdf").write_text(urdf[: len(urdf) // 2])
    (tmp / "trunc.yaml").write_text(side)
    k = urdf.index('<origin xyz="', urdf.index("<joint")) + len('<origin xyz="')
    (tmp / "huge.urdf").write_text(urdf[:k] + "1e308 " + urdf[urdf.index(" ", k) + 1:])
    (tmp / "huge.yaml").write_text(side)
    latin = urdf.replace('<robot name="onshape">', '<robot name="onshap\u00e9">', 1)
    (tmp / "latin.urdf").write_bytes(('<?xml version="1.0" encoding="ISO-8859-1"?>\n' + latin).encode("latin-1"))
    (tmp / "latin.yaml").write_text(side)
    (tmp / "twice.yaml").write_text(side + "name_mot: ['mot2', 'mot1']\n")
    (tmp / "docs.yaml").write_text(side + "beams: {part_3: {E: 70e9, G: 26e9, d: 0.02}}\n")
    odd = tmp / os.fsdecode(b"caf\xe9")
    odd.mkdir()
    shutil.copy(FIVE_BAR / "robot.urdf", odd / "robot.urdf")
    shutil.copy(FIVE_BAR / "robot.yaml", odd / "robot.yaml")
    loop = (ROBOTS / "synthetic" / "loop.xml").read_text()
    (tmp / "nan_anchor.xml").write_text(loop.replace('anchor="0.3 0.1 0"', 'anchor="nan 0.1 0"'))
    (tmp / "nan_pos.xml").write_text(loop.replace('<body name="rocker" pos="0.5 0 0">',
                                                  '<body name="rocker" pos="nan 0 0">'))
    (tmp / "mesh.xml").write_text(loop.replace("<worldbody>", f'<asset><mesh name="m" file="{tmp}/mesh.stl"/>'
                                               "</asset>\n  <worldbody>"))
    (tmp / "include.xml").write_text(loop.replace("<worldbody>", f'<include file="{tmp}/fifo.xml"/>\n  <worldbody>'))
    import numpy as np
    import xarray as xr
    import zarr

    zarr.open_group(str(tmp / "foreign.zarr"), mode="w").attrs["x"] = 1
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(tmp / "foreign.nc", engine="h5netcdf")


#: The Python cases, by class of issue 48: name -> an expression; ``M()`` is the five-bar (read
#: once), ``Q()`` its assembly, ``S()`` a spring on every joint, ``OUT`` its output frame, ``T``
#: the fixtures' folder, ``FIVE`` the five-bar's, ``beam(field, value)`` a beam on ``part_3`` with
#: one field changed, its compliance computed.
PY = {
    "hang": {
        "from_urdf(FIFO)": "Mechanism.from_urdf(T / 'fifo', FIVE / 'robot.yaml')",
        "from_urdf(sidecar=FIFO)": "Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'fifo')",
        "from_mjcf(FIFO)": "Mechanism.from_mjcf(T / 'fifo.xml')",
        "from_mjcf(<mesh file=FIFO>)": "Mechanism.from_mjcf(T / 'mesh.xml')",
        "from_mjcf(<include file=FIFO>)": "Mechanism.from_mjcf(T / 'include.xml')",
        "from_urdf(/dev/zero)": "Mechanism.from_urdf('/dev/zero', FIVE / 'robot.yaml')",
        "from_urdf(sidecar=/dev/zero)": "Mechanism.from_urdf(FIVE / 'robot.urdf', '/dev/zero')",
        "from_mjcf(/dev/zero)": "Mechanism.from_mjcf('/dev/zero')",
        "from_urdf(folder)": "Mechanism.from_urdf(T / 'folder', FIVE / 'robot.yaml')",
    },
    "untyped": {
        **{f"Beam({f}={v})": f"beam({f!r}, {v})" for f in ("E", "G", "A", "Iy", "Iz", "J")
           for v in ("1e-308", "1e308")},
        "Beam.tube(1e200)": "Beam.tube(1e200, 1e199, 70e9, 26e9)",
        "Beam.circle(1e200)": "Beam.circle(1e200, 70e9, 26e9)",
        "Beam.rect(1e200, 1e200)": "Beam.rect(1e200, 1e200, 70e9, 26e9)",
        "URDF origin 1e308": "Mechanism.from_urdf(T / 'huge.urdf').assemble()",
        "MJCF anchor nan": "Mechanism.from_mjcf(T / 'nan_anchor.xml').assemble()",
        "MJCF pos nan": "Mechanism.from_mjcf(T / 'nan_pos.xml').assemble()",
        "Latin-1 URDF": "Mechanism.from_urdf(T / 'latin.urdf')",
        "from_urdf(None)": "Mechanism.from_urdf(None)",
        "from_urdf(5)": "Mechanism.from_urdf(5)",
        "from_urdf(bytes)": "Mechanism.from_urdf(bytes(FIVE / 'robot.urdf'))",
        "from_mjcf(None)": "Mechanism.from_mjcf(None)",
        "assemble motors (2e12, 2)": "M().assemble(motors=np.broadcast_to(np.zeros(2), (2 * 10**12, 2)))",
        "compliance (1e10, nq)": "M().compliance(np.broadcast_to(Q(), (10**10, len(Q()))), S(), [OUT])",
        "modes (1e9, nq)": "M().modes(np.broadcast_to(Q(), (10**9, len(Q()))), S())",
        "assemble motors (1e9, 2)": "M().assemble(motors=np.broadcast_to(np.zeros(2), (10**9, 2)))",
        "to_mjcf(timestep='x')": "M().to_mjcf(T / 'o.xml', S(), timestep='x')",
        "to_mjcf(bogus=1)": "M().to_mjcf(T / 'o.xml', S(), bogus=1)",
    },
    "accepted": {
        "compliance threads=10**18": "M().compliance(np.array([Q(), Q()]), S(), [OUT], threads=10**18)",
        "modes threads=10**18": "M().modes(np.array([Q(), Q()]), S(), threads=10**18)",
        "compliance complex q": "M().compliance(Q() + 1j, S(), [OUT])",
        "compliance complex batch": "M().compliance(np.array([Q(), Q()]) + 0j, S(), [OUT])",
        "modes complex q": "M().modes(Q() + 1j, S())",
        "assemble complex q": "M().assemble(M().reference + 0.5j)",
        "assemble complex motors": "M().assemble(motors=[0.1 + 1j, 0.2])",
        "assemble motors True": "M().assemble(motors=[True, 0.0])",
        "configuration complex": "M().configuration(M().reference + 1j)",
        "spring True (compliance)": "M().compliance(Q(), {**S(), 'mot1': True}, [OUT])",
        "spring True (modes)": "M().modes(Q(), {**S(), 'mot1': True})",
        "spring True (Mechanism)": "Mechanism(M().model, M().constraint_models, M().actuated, springs={'mot1': True})",
        "to_mjcf(timestep=1e6)": "M().to_mjcf(T / 'o3.xml', S(), timestep=1e6)",
        "to_mjcf(timestep=True)": "M().to_mjcf(T / 'o4.xml', S(), timestep=True)",
        "sidecar key twice": "Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'twice.yaml')",
    },
    "also": {
        "docs sidecar beams (70e9)": "Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'docs.yaml')",
        "non-UTF-8 folder": "Mechanism.from_urdf(T / os.fsdecode(b'caf\\xe9') / 'robot.urdf')",
        "with_beams({})": "M().with_beams({})",
    },
}
#: The CLI cases: name -> the arguments of ``h4pin`` (``{T}``: the fixtures' folder, ``{F}``: the five-bar's).
CLI = {
    "hang": {
        "atlas --sidecar FIFO": "atlas --robot {F}/robot.urdf --sidecar {T}/fifo --output OUT --out {T}/a.nc --quiet",
        "export --sidecar FIFO": "export --robot {F}/robot.urdf --sidecar {T}/fifo --elastic --out {T}/e.xml",
        "view --atlas FIFO": "view --robot {F}/robot.urdf --atlas {T}/fifo --out {T}/v.html",
        "export --robot FIFO.xml": "export --robot {T}/fifo.xml --elastic --out {T}/e.xml",
    },
    "untyped": {f"view --atlas {n}": f"view --robot {{F}}/robot.urdf --atlas {{T}}/{n} --out {{T}}/v.html"
                for n in ("foreign.zarr", "text.nc", "foreign.nc", "text.zarr")},
    "accepted": {
        "atlas --motor 1e300": "atlas --robot {F}/robot.urdf --output OUT --motor mot1=-1e300:1e300:5 --count 2 "
                               "--out {T}/m.nc --quiet",
        **{f"atlas --threads {t}": f"atlas --robot {{F}}/robot.urdf --output OUT --count 2 --threads {t} "
                                   f"--out {{T}}/t{t}.nc --quiet" for t in ("0", "-1", "1000000")},
        "export --timestep 1e6": "export --robot {F}/robot.urdf --elastic --spring mot1=100 --spring mot2=100 "
                                 "--timestep 1e6 --out {T}/ts.xml",
    },
    "also": {"export truncated --elastic": "export --robot {T}/trunc.urdf --sidecar {F}/robot.yaml --elastic "
                                           "--out {T}/tr.xml"},
}
#: The cases that should answer (a finite result), not refuse.
ANSWER = {"Latin-1 URDF", "docs sidecar beams (70e9)", "non-UTF-8 folder", "with_beams({})"}


def cases() -> list[tuple[str, str, str, str, object]]:
    """(class, name, expect, kind, what): kind ``py`` (what: an expression, :data:`PY`) or ``cli``
    (what: the arguments of ``h4pin``, :data:`CLI`), in the order of the issue's classes."""
    out = []
    for cls in ("hang", "untyped", "accepted", "also"):
        for kind, table in (("py", PY), ("cli", CLI)):
            for name, what in table.get(cls, {}).items():
                what = what.replace("OUT", "closedloop3D_1B").split() if kind == "cli" else what
                out.append((cls, name, "answer" if name in ANSWER else "refuse", kind, what))
    return out


def run_case(case: tuple, tmp: Path, timeout: float) -> tuple[str, str]:
    """The outcome of one case (module docstring) and a word of detail."""
    cls, name, expect, kind, what = case
    env = dict(os.environ, H4PIN_WARMUP="off", PYTHONPATH=str(HERE))
    env.pop("H4PIN_MEMORY_LIMIT", None)
    if kind == "py":
        argv = [sys.executable, "-c", RUNNER, str(tmp), str(FIVE_BAR), what]
    else:
        argv = [sys.executable, "-m", "h4pin.cli",
                *(a.replace("{T}", str(tmp)).replace("{F}", str(FIVE_BAR)) for a in what)]

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))

    proc = subprocess.Popen(argv, cwd=tmp, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, start_new_session=True, preexec_fn=limit)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return "hang", f"no answer in {timeout:g} s"
    out, err = stdout.decode(errors="replace"), stderr.decode(errors="replace")
    if kind == "py":
        lines = [json.loads(line[6:]) for line in out.splitlines() if line.startswith("PROBE ")]
        if not lines:
            return "untyped", (err.strip().splitlines() or [f"exit {proc.returncode}"])[-1][:200]
        got, detail = lines[-1]
        if got == "untyped" and detail.startswith("MemoryError") and proc.returncode == 0 and "zero" in name:
            return "hang", f"read without bound ({detail[:60]})"
        if got == "returned":
            return ("answered" if expect == "answer" else "accepted"), detail
        if got == "warned":
            return ("answered" if expect == "answer" else "typed"), f"warning: {detail}"
        if got == "typed":
            return ("refused" if expect == "answer" else "typed"), detail
        if got == "nonfinite":
            return "untyped", f"a non-finite {detail}"
        return "untyped", detail
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("h4pin: first run")]
    if proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "):
        return ("refused" if expect == "answer" else "typed"), lines[0][:200]
    if proc.returncode == 0:
        warned = [ln for ln in lines if "warning" in ln.lower()]
        if warned and expect != "answer":
            return "typed", warned[0][:200]
        return ("answered" if expect == "answer" else "accepted"), (out.strip().splitlines() or [""])[-1][:200]
    return "untyped", f"exit {proc.returncode}, {len(lines)} lines: " + (lines[-1] if lines else "")[:160]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds a case may take")
    parser.add_argument("--only", default=None, help="run only the cases whose name holds this")
    parser.add_argument("-v", "--verbose", action="store_true", help="one line per case")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="h4pin-probe-"))
    try:
        fixtures(tmp)
        table: dict[str, Counter] = {}
        todo = [c for c in cases() if args.only is None or args.only in c[1]]
        for case in todo:
            start = time.monotonic()
            outcome, detail = run_case(case, tmp, args.timeout)
            table.setdefault(case[0], Counter())[outcome] += 1
            if args.verbose:
                print(f"{case[0]:9} {case[1]:34} {outcome:9} {time.monotonic() - start:5.1f} s  {detail}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    kinds = ("hang", "untyped", "accepted", "typed", "answered", "refused")
    print(f"\n{'class (issue 48)':18}" + "".join(f"{k:>10}" for k in kinds) + f"{'cases':>8}")
    total = Counter()
    for cls, counts in table.items():
        total.update(counts)
        print(f"{cls:18}" + "".join(f"{counts[k]:10}" for k in kinds) + f"{sum(counts.values()):8}")
    print(f"{'all':18}" + "".join(f"{total[k]:10}" for k in kinds) + f"{sum(total.values()):8}")


if __name__ == "__main__":
    main()
