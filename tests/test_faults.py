# SPDX-License-Identifier: Apache-2.0
"""No silent wrong answer, no stuck or unrecoverable job: URDF edits and CLI arguments that must
each give their typed one-line error before any work, and sweeps and atlases killed at several
moments (SIGKILL) that resume to the result of an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli_in_process

import h4pin
from h4pin import cli

ROOT = Path(__file__).resolve().parent.parent

ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="upper"><visual><geometry><mesh filename="package://nowhere/upper.stl"/></geometry></visual></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""


def edit(old: str, new: str, count: int = 1):
    def apply(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, count)
    return apply


#: URDF edits: (id, edit of the prototype's text, error class, words of the message).
URDF_CASES = [
    ("zero actuator axis", edit('<axis xyz="0 -1.0 0"/>', '<axis xyz="0 0 0"/>'), h4pin.MalformedURDFError,
     "zero <axis"),
    ("axis not numbers", edit('<axis xyz="0 -1.0 0"/>', '<axis xyz="0 one 0"/>'), h4pin.MalformedURDFError,
     "not a list of numbers"),
    ("negative mass", edit('<mass value="6.7858401317539565"/>', '<mass value="-6.8"/>'), h4pin.MalformedURDFError,
     "negative <mass"),
    ("inertia not PSD", edit('ixx="0.1561025973642233"', 'ixx="-0.2"'), h4pin.MalformedURDFError,
     "not positive semi-definite"),
    ("swapped limits", edit('<limit lower="-1.0" upper="2.0"', '<limit lower="2.5" upper="2.0"'),
     h4pin.MalformedURDFError, "above upper"),
    ("NaN origin", edit('<origin xyz="-0.2 -0.06 0" rpy="0 0 0"/>', '<origin xyz="nan -0.06 0" rpy="0 0 0"/>'),
     h4pin.MalformedURDFError, "finite numbers"),
    ("infinite rpy", edit('<origin xyz="-0.2 -0.06 0" rpy="0 0 0"/>', '<origin xyz="-0.2 -0.06 0" rpy="0 inf 0"/>'),
     h4pin.MalformedURDFError, "finite numbers"),
    ("duplicate joint", edit('<joint name="A_1_frame"', '<joint name="actuator_1"'), h4pin.MalformedURDFError,
     "two <joint> elements are named 'actuator_1'"),
    ("duplicate link", edit('<link name="A_1"/>', '<link name="forearm_1"/>'), h4pin.MalformedURDFError,
     "two <link> elements are named 'forearm_1'"),
    ("foreign robot with a missing mesh", lambda _: ARM, h4pin.MalformedURDFError, "not an H4"),
    ("not XML", lambda t: t[: len(t) // 2], h4pin.MalformedURDFError, ""),
    ("missing frame", edit('<link name="A_1"/>', '<link name="A_one"/>'), h4pin.MalformedURDFError, ""),
]


@pytest.mark.parametrize(("edit_text", "error", "words"), [c[1:] for c in URDF_CASES], ids=[c[0] for c in URDF_CASES])
def test_urdf_edits_give_their_typed_error(tmp_path, proto, edit_text, error, words, capfd):
    path = tmp_path / "edited.urdf"
    path.write_text(edit_text(proto.urdf))
    with pytest.raises(error, match=None) as info:
        h4pin.load(path)
    message = str(info.value)
    assert words in message and str(path) in message and "\n" not in message
    assert "Error:" not in capfd.readouterr().err  # refused before Pinocchio's C++ parser complains


def test_ur5_is_refused_for_not_being_an_h4():
    erd = pytest.importorskip("example_robot_data")
    try:
        path = erd.getModelPath("/ur_description/urdf/ur5_robot.urdf") + "/ur_description/urdf/ur5_robot.urdf"
    except Exception:  # noqa: BLE001 - the data package is optional
        pytest.skip("example-robot-data's UR5 files are not installed")
    with pytest.raises(h4pin.MalformedURDFError, match="not an H4"):
        h4pin.load(path)


@pytest.mark.parametrize(("springs", "words"), [({"kc": -1}, "springs['kc']"), ({"E": [1, 2]}, "springs['E']"),
                                                ({"forearm_stressed_fraction": 1.5}, "at most 1"),
                                                ({"Sb": np.nan}, "springs['Sb']")])
def test_bad_spring_overrides_blame_the_argument(springs, words):
    with pytest.raises(h4pin.ParameterError) as info:
        h4pin.load("prototype", springs=springs)
    assert words in str(info.value) and ".urdf" not in str(info.value)


#: CLI arguments: (argv, words of the one-line error). Each exits 2 before any work, writes nothing.
def cli_cases(tmp: Path) -> list[tuple[list[str], str]]:
    folder = tmp / "folder"
    folder.mkdir()
    (folder / "mine.txt").write_text("a user's file")
    a_file = tmp / "file.txt"
    a_file.write_text("x")
    (tmp / "folder.zarr").mkdir()
    (tmp / "folder.zarr" / "data.bin").write_bytes(b"not an atlas")
    return [
        (["sweep", "--workers", "0", "--out", str(tmp / "s.zarr")], "--workers must be >= 1"),
        (["sweep", "--out", str(folder)], "is not a zarr store"),
        (["sweep", "--out", str(a_file)], "is a file"),
        (["sweep", "--out", str(tmp / "no" / "s.zarr")], "does not exist"),
        (["sweep", "--out", str(tmp / "s.zarr"), "--figure", str(tmp / "p.txt")], "must end in .png"),
        (["sweep", "--out", str(tmp / "s.zarr"), "--urdf-dir", str(tmp / "nowhere")], "does not exist"),
        (["sweep", "--out", str(tmp / "s.zarr"), "--scheduler", "tcp://127.0.0.1:9"], "cannot reach a Dask"),
        (["atlas", "--out", str(tmp / "a.txt")], "must end in .nc or .zarr"),
        (["atlas", "--out", str(a_file.parent / "x" / "a.nc")], "does not exist"),
        (["atlas", "--out", str(folder)], "must end in .nc or .zarr"),
        (["atlas", "--out", str(tmp / "folder.zarr")], "is not a zarr store"),
        (["atlas", "--out", str(tmp / "a.nc"), "--figures", str(tmp / "nowhere")], "does not exist"),
        (["atlas", "--out", str(tmp / "a.nc"), "--x", "-1", "1", "100000", "--y", "-1", "1", "100000",
          "--z-range", "-1", "0", "1000"], "GiB"),
        (["atlas", "--out", str(tmp / "a.nc"), "--x", "-1", "1", "0"], "N >= 1"),
        (["view", "--host", "999.1.1.1"], "cannot listen there"),
        (["view", "--host", "8.8.8.8"], "cannot listen there"),
        (["view", "--out", str(tmp / "no" / "v.html")], "does not exist"),
        (["view", "--out", str(folder)], "is a folder"),
        (["tolerance", "--sigma", "forearm=1e9"], "not a manufacturing tolerance"),
        (["tolerance", "--sigma", "forearm=-1"], "must be finite and >= 0"),
        (["tolerance", "--sigma", "bogus=1e-4"], "unknown tolerance"),
        (["tolerance", "--robots", "0"], "--robots must be >= 1"),
        (["tolerance", "--figure", str(tmp / "t.txt")], "must end in .png"),
        (["export", "--out", str(folder)], "is a folder"),
        (["atlas", "--out", "/proc/atlas.nc"], "cannot write in /proc"),
        (["sweep", "--out", "/proc/s.zarr"], "cannot write in /proc"),
        (["view", "--out", "/proc/v.html"], "cannot write in /proc"),
        (["tolerance", "--figure", "/proc/t.png"], "cannot write in /proc"),
        (["export", "--out", "/proc/h4.xml"], "cannot write in /proc"),
        (["table2", "--variant", "nope"], "Invalid value for '--variant'"),
        (["table2", "--model", "exact"], "Invalid value for '--model'"),
    ]


run_cli = run_cli_in_process  # tests/conftest.py


def test_cli_errors_before_any_work(tmp_path, monkeypatch, capsys):
    cases = cli_cases(tmp_path)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    for argv, words in cases:
        started = time.monotonic()
        code, _, err = run_cli(argv, monkeypatch, capsys)
        lines = [line for line in err.splitlines() if not line.startswith("h4pin: first run")]
        assert code == 2, (argv, err)
        assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], (argv, err)
        assert time.monotonic() - started < 8.0, argv  # refused up front: no computation, no 30 s timeout
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing written
    assert len(cases) >= 25


def test_first_run_says_it_compiles(monkeypatch, capsys, tmp_path):
    """With an empty numba cache the kernel is not cached, and a command that compiles it in the
    foreground says so on stderr before it starts (one line); --help, table2 (which does not
    wait for the compiler) and cached runs say nothing."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    code = "from h4pin.stiffness import kernel; print(kernel.cached())"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    from h4pin.stiffness import kernel

    monkeypatch.setattr(kernel, "cached", lambda: False)
    cli.note_first_compile(["atlas"])
    assert "first run: compiling" in capsys.readouterr().err
    cli.note_first_compile(["atlas", "--help"])
    cli.note_first_compile(["table2"])  # starts on the numpy path (h4pin._jit)
    monkeypatch.setattr(kernel, "cached", lambda: True)
    cli.note_first_compile(["atlas"])
    assert capsys.readouterr().err == ""


def test_bad_values_in_results_and_poses(proto, centre):
    """A NaN offset, a complex pose and a NaN pose with on_error='nan' each get their typed answer."""
    res = h4pin.compliance(proto, centre)
    with pytest.raises(h4pin.ParameterError, match="finite"):
        res.at([0.0, 0.0, np.nan])
    with pytest.raises(h4pin.ParameterError, match="real numbers"):
        res.at([0.0, 1j, 0.0])
    with pytest.raises(h4pin.PoseError, match="real numbers"):
        h4pin.compliance(proto, centre + 1e-3j)
    with pytest.raises(h4pin.PoseError, match="real numbers"):
        proto.inverse_geometry([0.0, 0.0, -0.6, 1j])
    one = h4pin.compliance(proto, [np.nan, 0.0, -0.6, 0.0], on_error="nan")
    assert one.status == 5 and not one.valid and np.all(np.isnan(one.matrix))
    with pytest.raises(h4pin.PoseError, match="non-finite"):
        h4pin.compliance(proto, [np.nan, 0.0, -0.6, 0.0])


def test_help_shows_flags_without_a_value(monkeypatch, capsys):
    for command in ("table2", "atlas", "sweep"):
        code, out, _ = run_cli([command, "--help"], monkeypatch, capsys)
        assert code == 0 and "<bool>" not in out and "BOOLEAN" not in out
    code, out, _ = run_cli(["table2", "--help"], monkeypatch, capsys)
    assert "--measured-match " in out


# ---------------------------------------------------------------------------------------------
# Real kills: a sweep and an atlas as subprocesses, SIGKILL at several moments, then resumed.


def h4pin_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "h4pin.cli", *args]


def run_to_end(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def kill_after(args: list[str], cwd: Path, seconds: float) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    time.sleep(seconds)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


@pytest.mark.slow
def test_sweep_killed_at_any_moment_resumes_to_the_same_result(tmp_path):
    zarr = pytest.importorskip("zarr")
    args = ["sweep", "--designs", "512", "--chunk", "32", "--quiet"]
    whole = run_to_end(h4pin_cmd(*args, "--out", "whole.zarr"), tmp_path)
    assert whole.returncode == 0, whole.stderr
    ref = zarr.open_group(str(tmp_path / "whole.zarr"), mode="r")
    for k, delay in enumerate((0.3, 1.2, 2.5, 4.0)):
        out = f"killed{k}.zarr"
        kill_after(h4pin_cmd(*args, "--out", out), tmp_path, delay)
        # whatever the kill left resumes (or starts anew): never "a different sweep"
        again = run_to_end(h4pin_cmd(*args, "--out", out), tmp_path)
        assert again.returncode == 0, (delay, again.stderr)
        got = zarr.open_group(str(tmp_path / out), mode="r")
        for name in ("designs", "valid", "reach_all", "worst", "volume", "task_ok", "done"):
            np.testing.assert_array_equal(got[name][:], ref[name][:], err_msg=f"{name} after a kill at {delay} s")
    assert not [p for p in tmp_path.iterdir() if "h4pin-tmp" in p.name]  # no stale temporary folder left


@pytest.mark.slow
def test_atlas_killed_while_saving_leaves_nothing_behind(tmp_path):
    args = ["atlas", "--x", "-0.2", "0.2", "301", "--y", "-0.2", "0.2", "301", "--quiet"]
    whole = run_to_end(h4pin_cmd(*args, "--out", "whole.zarr"), tmp_path)
    assert whole.returncode == 0, whole.stderr
    from h4pin.mechanism.store import open_store as open_atlas

    ref = open_atlas(tmp_path / "whole.zarr")
    for k, delay in enumerate((0.5, 2.0, 3.0)):
        out = f"killed{k}.zarr"
        kill_after(h4pin_cmd(*args, "--out", out), tmp_path, delay)
        assert not (tmp_path / out).exists() or (tmp_path / out / "zarr.json").exists()  # all or nothing
        again = run_to_end(h4pin_cmd(*args, "--out", out), tmp_path)
        assert again.returncode == 0, again.stderr
        got = open_atlas(tmp_path / out)
        for name in ref.data_vars:
            np.testing.assert_array_equal(got[name].values, ref[name].values)
    assert not [p for p in tmp_path.iterdir() if "h4pin-tmp" in p.name]


def dead_pid() -> int:
    """A pid that no process has (the highest pid the kernel hands out, plus one)."""
    return int(Path("/proc/sys/kernel/pid_max").read_text()) + 1


def test_what_a_kill_during_a_save_leaves_is_removed_by_the_next_save(tmp_path, proto):
    """A save killed half-way leaves ``.NAME.h4pin-tmp-PID-*`` beside its target (its process is
    dead): the next write to that target removes it; a live process's temporary is kept."""
    from h4pin.files import write_text
    from h4pin.mechanism import store
    from h4pin.studies import atlas

    ds = atlas.atlas(proto, [0.0, 0.01], [0.0], [-0.6], progress=False)
    for name in ("a.zarr", "a.nc", "page.html"):
        stale = tmp_path / f".{name}.h4pin-tmp-{dead_pid()}-abc"
        stale.mkdir()
        (stale / "half-written").write_bytes(b"x" * 100)
        alive = tmp_path / f".{name}.h4pin-tmp-{os.getpid()}-def"
        alive.write_text("another save, still running")
        if name == "page.html":
            write_text(tmp_path / name, "<html></html>")
        else:
            store.save(ds, tmp_path / name)
            np.testing.assert_array_equal(store.open_store(tmp_path / name).status.values, ds.status.values)
        assert not stale.exists() and alive.exists()
        alive.unlink()


def test_an_unfinished_sweep_store_names_the_option_that_replaces_it(tmp_path):
    """What a kill left before stores were created whole (a bare zarr group, no h4pin_store tag)
    is not taken for h4pin's: refused, naming --overwrite, which starts the sweep over."""
    zarr = pytest.importorskip("zarr")
    from h4pin.studies import sweep

    store = tmp_path / "old.zarr"
    zarr.open_group(str(store), mode="w")
    spec = sweep.Spec(n_designs=4, chunk=2)
    with pytest.raises(h4pin.ParameterError, match="h4pin did not write it: give another path, or --overwrite"):
        sweep.run(store, spec, progress=False)
    assert sweep.run(store, spec, stop_after=0, progress=False, overwrite=True)["done"].tolist() == [False, False]


@pytest.mark.parametrize(("command", "hidden"), [("atlas", "xarray"), ("sweep", "zarr")])
def test_a_command_whose_extra_is_missing_names_it(tmp_path, command, hidden):
    """Without the 'studies' extra (its module hidden), h4pin atlas / sweep say which extra to
    install, in one line, exit 2, nothing written."""
    out_path = str(tmp_path / ("o.nc" if command == "atlas" else "o.zarr"))
    code = (f"import sys; sys.modules[{hidden!r}] = None; from h4pin import cli; "
            f"sys.argv = ['h4pin', {command!r}, '--out', {out_path!r}, '--quiet']; cli.main()")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)))
    lines = [line for line in out.stderr.splitlines() if not line.startswith("h4pin: first run")]
    assert out.returncode == 2 and len(lines) == 1, out.stderr
    assert "pip install 'h4pin[studies]'" in lines[0] and hidden in lines[0]
    assert not list(tmp_path.iterdir())
