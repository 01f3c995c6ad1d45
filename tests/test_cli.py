# SPDX-License-Identifier: Apache-2.0
"""The table2 command, the scripts' claims, and one-line errors on the command line."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import typer.main
from conftest import run_cli_in_process

import h4pin
from h4pin import cli
from h4pin.kinematics.closed_form import CENTRE_Q, centre_pose
from h4pin.stiffness.api import compliance
from h4pin.studies.paper import PAPER_COMPUTED

ROOT = Path(__file__).resolve().parent.parent


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "h4pin.cli", *args], capture_output=True, text=True, cwd=ROOT)


def script(name: str):
    """Script ``scripts/<name>.py`` as a module, its folder on ``sys.path`` as when Python runs it
    (``bench.py`` imports ``independent_kernel.py`` beside it)."""
    folder = str(ROOT / "scripts")
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, folder)
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(folder)
    return module


def test_table2_prints_the_computed_block(proto, centre):
    out = run_cli("table2")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    start = next(n for n, line in enumerate(lines) if line.startswith("h4pin"))
    printed = np.array([[float(v) for v in lines[start + 1 + a].split()[-3:]] for a in range(3)])
    np.testing.assert_allclose(printed, compliance(proto, centre).translational * 1e6, atol=0.051)
    assert "paper, measured" in out.stdout and "%" in out.stdout


def test_table2_gap_rows_line_up_with_the_tables(proto):
    """Every cell of the gap block ends in the column its header and the tables above end in,
    relative gaps and the absolute ones (where the paper's entry is 0, in um/N) alike."""
    from h4pin.studies.table2 import report

    lines = report(proto).splitlines()
    head = lines.index(next(line for line in lines if line.startswith("gap to paper computed")))
    ends = [m.end() for m in re.finditer(r"F[xyz]", lines[head])]
    table = lines[next(n for n, line in enumerate(lines) if line.startswith("h4pin")) + 1]
    assert [m.end() for m in re.finditer(r"-?\d+\.\d", table)] == ends
    for row in lines[head + 1:head + 4]:
        cells = list(re.finditer(r"[+-]\d+(\.\d)?%?", row))
        assert [m.end() for m in cells] == ends, row
        assert all(m.group().endswith("%") or m.group() == "+0.0" for m in cells), row  # 0 in the paper: ours is 0


@pytest.mark.parametrize(
    ("args", "message"),
    [(["table2", "--variant", "nope"], "Invalid value for '--variant': 'nope' is not one of 'prototype', "),
     (["table2", "--variant", "symmetric"], "singular"),
     (["table2", "--urdf", "missing.urdf"], "no URDF file"),
     (["table2", "--model", "exact"], "Invalid value for '--model': 'exact' is not one of 'paper', 'consistent'."),
     (["export", "--out", "h4.xml", "--mjcf", "h4.xml"], "No such option: --mjcf"),
     (["export"], "Missing option '--out'.")],
)
def test_cli_errors_are_one_line(args, message):
    out = run_cli(*args)
    assert out.returncode == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert "Traceback" not in out.stderr


def test_gap_factors_are_exact():
    """K is linear in each compliance: I0 divided by the torsion factor gives xx = 40 um/N."""
    sens = script("sensitivity")
    factor = dict((t, f) for t, f, _ in sens.gap_factors())["torsion"]
    h4 = h4pin.load(h4pin.H4Params().replace(I0=h4pin.H4Params().I0 / factor))
    k = compliance(h4, h4.forward_geometry(CENTRE_Q)).translational * 1e6
    assert k[0, 0] == pytest.approx(PAPER_COMPUTED[0, 0], rel=1e-10)
    assert 3 < factor < 6  # docs/parameters.md: a much softer parallelogram tilt closes the gap


def test_naive_eq30_agrees_with_h4pin(proto, poses):
    bench = script("bench")
    for x in poses[:4]:
        k = compliance(proto, x).matrix
        assert np.max(np.abs(bench.naive_compliance(proto.params, x) - k)) < 1e-12 * np.max(np.abs(k))


def test_hand_tightened_eq30_agrees_with_h4pin(proto, poses):
    """The bench's hand-tightened independent kernel (its reductions of the naive products are
    algebra, not shared code) gives h4pin's K."""
    naive, tight = script("independent_kernel"), script("independent_tight")
    args = naive.constants(proto.params)
    for x in poses[:4]:
        k = compliance(proto, x, method="closed_form").matrix
        got = np.full((8, 8), np.nan)
        tight.tight_compliance(np.ascontiguousarray(x, dtype=float), *args, got)
        assert np.max(np.abs(got - k)) < 1e-12 * np.max(np.abs(k))


def test_constrained_dynamics_keeps_the_loops_closed(proto):
    rows = script("constrained_dynamics").simulate(proto, duration=0.05, dt=1e-4, report_every=0.01)
    drift = max(d for _, d, _ in rows)
    moved = np.linalg.norm(rows[-1][2] - centre_pose(proto)[:3])
    assert drift < 1e-7, f"closure drift {drift:.1e} m"
    assert moved > 1e-5  # the torque step does move the robot


COMMANDS = typer.main.get_command(cli.app).commands


def test_cli_reference_is_generated_from_the_cli():
    """docs/cli.md is h4pin.cli.reference() (its first line says how to regenerate it): every
    command, and every option of each once."""
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert text == cli.reference(), f"docs/cli.md is stale; regenerate it: {cli.REGENERATE}"
    assert cli.REGENERATE in text.splitlines()[0]
    for name, command in COMMANDS.items():
        assert text.count(f"\n## h4pin {name}\n") == 1, name
        section = text.split(f"\n## h4pin {name}\n")[1].split("\n## ")[0].splitlines()
        for param in command.params:
            if not param.hidden:
                opt = param.opts[0]
                assert sum(line.startswith((f"- `{opt} ", f"- `{opt}`")) for line in section) == 1, (name, opt)


def test_one_convention_over_the_commands():
    """--model defaults to 'paper' (as h4pin.compliance; cycle aside); outputs are --out, --figure or --figures
    (the old names, removed in 0.2, are refused) with --overwrite; --quiet wherever a progress bar runs; --payload is
    one shape (KG, >= 0)."""
    import inspect

    assert inspect.signature(compliance).parameters["model"].default == "paper"
    for name, command in COMMANDS.items():
        params = {p.name: p for p in command.params}
        visible = {opt for p in command.params if not p.hidden for opt in p.opts}
        if "model" in params:  # cycle: cli.CYCLE_MODEL, until its dynamics take the paper model
            assert params["model"].default == ("consistent" if name == "cycle" else "paper"), name
        assert not visible & set(REMOVED), name
        writes = bool(visible & {"--out", "--figure", "--figures"})
        assert ("--overwrite" in visible) == writes, name
        assert ("--quiet" in visible) == (name in ("view", "tolerance", "atlas", "sweep", "warmup")), name
        if "payload" in params:
            assert params["payload"].metavar == "KG", name
    hidden = {opt for c in COMMANDS.values() for p in c.params if p.hidden for opt in p.opts}
    assert hidden == set()


run_main = run_cli_in_process  # tests/conftest.py


@pytest.mark.parametrize("command", [name for name, c in COMMANDS.items() if any(p.name == "model" for p in c.params)])
def test_a_wrong_model_is_a_usage_error_naming_the_choices(command, monkeypatch, capsys):
    code, _, err = run_main([command, "--model", "exact"], monkeypatch, capsys)
    assert code == 2
    assert err == "error: Invalid value for '--model': 'exact' is not one of 'paper', 'consistent'.\n"


#: The options renamed in 0.1 (deprecated for one release) and removed in 0.2 (CHANGELOG.md).
REMOVED = {"view": "--html", "export": "--mjcf", "modes": "--map", "sweep": "--pareto"}


@pytest.mark.parametrize("command", sorted(REMOVED))
def test_the_old_option_names_are_gone(command, tmp_path, monkeypatch, capsys):
    """An option renamed in 0.1 is refused in 0.2, in one line naming it."""
    code, _, err = run_main([command, REMOVED[command], str(tmp_path / "x")], monkeypatch, capsys)
    assert code == 2 and err.startswith(f"error: No such option: {REMOVED[command]}") and err.count("\n") == 1


#: Each command that writes a file: its arguments (small and quick), the option and name of the file.
WRITERS = {
    "export": (["export"], "--out", "notes.txt"),
    "atlas": (["atlas", "--x", "-0.1", "0.1", "2", "--y", "0", "0.1", "2", "--quiet"], "--out", "user.nc"),
    "modes": (["modes", "--grid", "2", "--span", "0.1"], "--figure", "user.png"),
    "tolerance": (["tolerance", "--robots", "2", "--no-sensitivity", "--quiet"], "--figure", "user.png"),
    "view": (["view"], "--out", "notes.txt"),
}
#: The optional package a command needs to write its file (the oldest-Pinocchio CI run has none).
EXTRAS = {"export": "mujoco", "atlas": "xarray"}
#: A user's file of each kind (the PNG and NetCDF ones start as those formats do).
USER_FILES = {".txt": b"a user's own notes\n", ".png": b"\x89PNG\r\n\x1a\nnot h4pin's",
              ".nc": b"\x89HDF\r\n\x1a\nnot h4pin's"}


@pytest.mark.parametrize("command", [c if c == "export" else pytest.param(c, marks=pytest.mark.slow)
                                     for c in WRITERS])  # the slow ones spawn a study or a viewer (9-60 s)
def test_a_user_file_is_kept_unless_overwrite(command, tmp_path):
    """An existing file h4pin did not write: exit 2, one line naming it, the file byte for byte as
    it was; --overwrite replaces it; a file h4pin wrote is replaced without --overwrite."""
    args, option, name = WRITERS[command]
    target = tmp_path / name
    user = USER_FILES[target.suffix]
    target.write_bytes(user)
    refused = run_cli(*args, option, str(target))
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr == (f"error: {option} {target} exists and h4pin did not write it: give another path, or "
                              "--overwrite to replace it\n")
    assert target.read_bytes() == user and [p.name for p in tmp_path.iterdir()] == [name]

    if command in EXTRAS and importlib.util.find_spec(EXTRAS[command]) is None:
        pytest.skip(f"needs the {EXTRAS[command]} package to write it (not installed)")
    first = run_cli(*args, option, str(target), "--overwrite")
    assert first.returncode == 0, first.stderr
    assert target.read_bytes() != user and f"wrote {target}" in first.stdout
    inode = target.stat().st_ino
    again = run_cli(*args, option, str(target))
    assert again.returncode == 0, again.stderr
    assert target.stat().st_ino != inode and f"wrote {target}" in again.stdout  # a new file, renamed into place
    assert "Traceback" not in refused.stderr + first.stderr + again.stderr


def test_h4pin_tells_its_own_files(tmp_path):
    """The markers: a text file's digest comment (a page, an MJCF, a URDF), a PNG text chunk; a
    text file h4pin wrote and the user then edited, the files the project ships (no marker: a
    copy a user edits is theirs), a file of the same format h4pin did not write, a link, a FIFO
    or a missing file are not h4pin's."""
    import os

    from matplotlib.figure import Figure

    from h4pin.files import save_figure, write_text, written_by_h4pin

    assert not written_by_h4pin(ROOT / "urdf" / "h4_prototype.urdf")
    assert not written_by_h4pin(ROOT / "mjcf" / "h4_prototype.xml")
    page = write_text(tmp_path / "page.txt", "\n <!DOCTYPE html><html><body></body></html>")
    assert page.read_text().startswith("\n <!DOCTYPE html><!-- written by h4pin, unchanged if sha256 ")
    assert written_by_h4pin(page)
    urdf = write_text(tmp_path / "r.urdf", (ROOT / "urdf" / "h4_prototype.urdf").read_text())
    assert urdf.read_text().split("?>", 1)[1].startswith("<!-- written by h4pin") and written_by_h4pin(urdf)
    urdf.write_text(urdf.read_text().replace('kc="7400.0"', 'kc="7500.0"', 1))  # the user edits it
    assert not written_by_h4pin(urdf)
    fig = Figure()
    fig.subplots().plot([0, 1])
    assert written_by_h4pin(save_figure(fig, tmp_path / "f.png"))
    fig = Figure()
    fig.subplots().plot([0, 1])
    fig.savefig(tmp_path / "g.png")  # matplotlib's own
    (tmp_path / "link.png").symlink_to(tmp_path / "f.png")
    (tmp_path / "notes.txt").write_text("<!DOCTYPE html> my page")
    os.mkfifo(tmp_path / "fifo.xml")
    for other in ("g.png", "link.png", "notes.txt", "missing.png", "fifo.xml"):
        assert not written_by_h4pin(tmp_path / other), other


def test_odd_output_paths_are_one_line_refusals(tmp_path, monkeypatch, capsys):
    """A FIFO at the output path (it would block a writer forever), an empty name, a name too
    long for the file system and a user's edited copy of an h4pin file: exit 2, one line, nothing
    written or replaced."""
    import os

    from conftest import run_cli_in_process

    fifo = tmp_path / "pipe.xml"
    os.mkfifo(fifo)
    edited = tmp_path / "mine.xml"
    from h4pin.files import write_text

    write_text(edited, "<?xml version='1.0'?>\n<mujoco/>\n")
    edited.write_text(edited.read_text() + "<!-- my notes -->\n")
    before = edited.read_text()
    for out, match in ((fifo, "neither a file nor a folder"), ("", "give a file name"),
                       (tmp_path / ("x" * 300 + ".xml"), "File name too long"), (edited, "h4pin did not write it")):
        code, _, err = run_cli_in_process(["export", "--out", str(out)], monkeypatch, capsys)
        assert code == 2 and match in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert edited.read_text() == before
