# SPDX-License-Identifier: Apache-2.0
"""The README and the docs/ pages run as written: their Python blocks, and (on the README and the
guides that hold what it once said) their shell lines and their printed sample output.

The pages: ``README.md`` and every ``docs/*.md`` for the Python blocks; ``README.md`` and
:data:`GUIDES` (docs/ pages whose code came from the README) for the shell and console blocks. The
rules, so that a page can be rewritten without touching this file:

* each ```` ```python ```` block runs alone, in a fresh namespace (a reader copies one block, not
  the page: a block that needs a robot, a pose or an import says so itself), in a fresh folder (the
  files it writes land there) that links the checkout's ``tests/`` folder (its robots: a path such
  as ``tests/robots/...`` reads as from the checkout's root), under umask 077. Afterwards every
  :class:`h4pin.io.viewer.Scene` left in the namespace is closed, no process it started may still
  run, and every file it wrote is mode 0644. Exceptions, each named with its reason:
  :data:`NOT_RUN` (a block that starts a server it leaves running), :data:`NEEDS` (a block of an
  optional package: skipped when that package is not installed), :data:`CONTINUES` (a block on a
  page this project's docs rules do not own, which runs after the page's blocks before it, in
  their namespace).
* ```` ```bash ```` blocks: each line is a command; a trailing ``# comment`` documents it. ``&&``
  chains run step by step. ``h4pin`` (also ``.venv/bin/h4pin``) runs as ``<this python> -m
  h4pin.cli``; ``python``, ``python3`` and ``.venv/bin/python`` run as this interpreter. Steps not
  run, by rule (the test is reported as skipped with the reason):

  - environment set-up, ``python3 -m venv`` and ``pip install``: they need the network, and the
    tests already run in the environment they make;
  - the test suite itself (``python -m pytest``);
  - the documentation site's build (``python -m sphinx``): ``tests/test_docs.py`` builds it;
  - a server: ``h4pin view`` without ``--html``, unless its comment says it fails ``(exit N)`` with
    N != 0 (it then fails before any server starts; a time limit guards against a hang).

  A comment ``(exit N)`` sets the expected exit status (default 0). A comment ``# error: A ... B``
  requires each fragment (A, B) on stderr.
* ```` ```console ```` blocks: ``$ command`` lines run as above, and the lines after each, up to
  the next ``$``, must equal the command's standard output (trailing spaces aside).
* Other blocks (```` ```text ````, ```` ```xml ````, untagged) are not run.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import re
import shlex
import signal
import stat
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: The guides in docs/ that hold code the README once carried (their blocks run by the same rules).
GUIDES = ("first_use.md", "tour.md", "viewer.md", "studies.md", "motion.md", "build_in_code.md", "loaded.md",
          "calibration.md")
PAGES = (README, *(ROOT / "docs" / name for name in GUIDES))
FENCE = re.compile(r"^(?P<fence>`{3,}|~{3,})\s*(?P<info>[^\s`]*)")


class Block(NamedTuple):
    lang: str
    line: int  # page line of the block's first content line (1-based)
    text: str
    page: str = "README.md"


def blocks(text: str, page: str = "README.md") -> list[Block]:
    """Fenced code blocks of a Markdown text, with their info word (``""`` if untagged)."""
    out, lines, n = [], text.splitlines(), 0
    while n < len(lines):
        m = FENCE.match(lines[n])
        if not m:
            n += 1
            continue
        fence, start = m["fence"], n + 1
        end = start
        while end < len(lines) and not lines[end].startswith(fence):
            end += 1
        out.append(Block(m["info"].lower(), start + 1, "\n".join(lines[start:end]), page))
        n = end + 1
    return out


def page_name(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


ALL = [b for path in PAGES for b in blocks(path.read_text(encoding="utf-8"), page_name(path))]
#: Every page whose ```python blocks run, each block alone.
PYTHON_PAGES = (README, *sorted((ROOT / "docs").glob("*.md")))
PYTHON = [b for path in PYTHON_PAGES for b in blocks(path.read_text(encoding="utf-8"), page_name(path))
          if b.lang == "python"]
#: Blocks not run, by (page, a fragment of the block): the reason.
NOT_RUN = {
    ("docs/interop.md", "v.initViewer()"): "starts meshcat's own server (meshcat.Visualizer()) and leaves it "
                                           "running, as an interactive session does",
}
#: The packages of h4pin's optional extras (pyproject.toml): a block that imports one is skipped
#: where it is not installed (the core install: CI's oldest-Pinocchio run); any other import runs.
OPTIONAL = frozenset({"mujoco", "example_robot_data", "robot_descriptions", "toolbox_parallel_robots", "yaml",
                      "xarray", "zarr", "dask", "distributed", "h5netcdf", "h5py", "sphinx"})
#: Blocks of an optional package they do not import, by (page, a fragment of the block): the module;
#: skipped without it (a block's own imports are read from it: :func:`imported`).
NEEDS = {
    ("docs/interop.md", "interop.toolbox()"): "toolbox_parallel_robots",
}
#: Blocks that continue the page's blocks before them, by (page, a fragment of the block): the reason.
CONTINUES: dict = {}


def listed(table: dict, b: Block):
    """The value of table for block b (a key whose fragment is in the block), or None."""
    return next((v for (page, fragment), v in table.items() if page == b.page and fragment in b.text), None)


def imported(b: Block) -> list[str]:
    """The top-level packages a block imports (``import a.b``, ``from a.b import c``: ``a``)."""
    names = []
    for node in ast.walk(ast.parse(b.text)):
        if isinstance(node, ast.Import):
            names += [alias.name.split(".")[0] for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module.split(".")[0])
    return sorted(set(names))


def block_id(b: Block) -> str:
    number = [c for c in PYTHON if c.page == b.page].index(b) + 1
    return f"{b.page}:{b.line} #{number}"


class Command(NamedTuple):
    where: str  # <page>:<line>
    text: str  # the command as written (no comment)
    comment: str
    expected_stdout: str | None  # console blocks only


def split_comment(line: str) -> tuple[str, str]:
    """A shell line without its trailing ``# comment``, and the comment."""
    quote = None  # a '#' starting a word outside quotes starts the comment
    for n, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (n == 0 or line[n - 1].isspace()):
            return line[:n].strip(), line[n + 1:].strip()
    return line.strip(), ""


def shell_commands() -> list[Command]:
    out = []
    for b in ALL:
        if b.lang not in ("bash", "sh", "shell"):
            continue
        for k, line in enumerate(b.text.splitlines()):
            text, comment = split_comment(line)
            if text:
                out.append(Command(f"{b.page}:{b.line + k}", text, comment, None))
    return out


def console_commands() -> list[Command]:
    out = []
    for b in ALL:
        if b.lang != "console":
            continue
        lines = b.text.splitlines()
        starts = [k for k, line in enumerate(lines) if line.startswith("$ ")]
        for a, k in enumerate(starts):
            stop = starts[a + 1] if a + 1 < len(starts) else len(lines)
            text, comment = split_comment(lines[k][2:])
            out.append(Command(f"{b.page}:{b.line + k}", text, comment, "\n".join(lines[k + 1:stop])))
    return out


def argv(step: str) -> tuple[list[str] | None, str]:
    """The step as an argv for this environment, or None and the rule that skips it."""
    words = shlex.split(step)
    prog = words[0].removeprefix(".venv/bin/")
    if prog == "pip" or (prog.startswith("python") and words[1:3] == ["-m", "venv"]):
        return None, "sets up an environment (needs the network; the tests run in that environment)"
    if prog.startswith("python") and words[1:3] == ["-m", "pytest"]:
        return None, "runs the test suite itself"
    if prog.startswith("python") and words[1:3] == ["-m", "sphinx"]:
        return None, "builds the documentation site (tests/test_docs.py builds it)"
    if prog == "h4pin":
        return [sys.executable, "-m", "h4pin.cli", *words[1:]], ""
    if prog in ("python", "python3"):
        return [sys.executable, *words[1:]], ""
    return words, ""


def expected_status(comment: str) -> int:
    m = re.search(r"\(exit (\d+)\)", comment)
    return int(m[1]) if m else 0


def starts_a_server(args: list[str], comment: str) -> bool:
    writes = "--html" in args or "--out" in args  # a page written, no server
    return args[2:4] == ["h4pin.cli", "view"] and not writes and expected_status(comment) == 0


def run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: os.umask(0o077))
    try:
        out, err = proc.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=30)
        pytest.fail(f"{' '.join(args)} did not finish in 300 s: {err}")
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


def check_written_files(folder: Path) -> None:
    """Everything written under ``folder`` (under umask 077) is mode 0644."""
    modes = {}
    for dirpath, _, filenames in os.walk(folder):  # not into the link to tests/
        for name in filenames:
            path = Path(dirpath) / name
            if not path.is_symlink():
                modes[str(path.relative_to(folder))] = oct(stat.S_IMODE(path.stat().st_mode))
    assert all(m == "0o644" for m in modes.values()), modes


def test_the_readme_has_what_these_tests_check():
    """The rules above find the README's blocks (a rewrite that breaks them fails here): its
    Table II sample, its Python examples, and in the guides the commands it once carried."""
    readme = [b for b in ALL if b.page == "README.md"]
    assert len([b for b in readme if b.lang == "python"]) >= 2, "no ```python blocks in the README"
    assert any(c.text == ".venv/bin/h4pin table2" and c.where.startswith("README.md:") for c in console_commands()), \
        "no `$ .venv/bin/h4pin table2` sample in the README"
    assert {b.page for b in PYTHON} >= {"README.md", "docs/tour.md", "docs/viewer.md", "docs/mechanisms.md"}
    runnable = [c for c in shell_commands() if any(argv(s)[0] for s in c.text.split("&&"))]
    assert len(runnable) >= 3


@pytest.mark.parametrize("block", PYTHON, ids=block_id)
def test_python_block_runs_alone(block, tmp_path, monkeypatch, no_process_left):
    from h4pin.io import viewer

    if (reason := listed(NOT_RUN, block)) is not None:
        pytest.skip(f"not run: {reason}")
    for module in (*imported(block), *filter(None, [listed(NEEDS, block)])):
        if module in OPTIONAL and importlib.util.find_spec(module) is None:
            pytest.skip(f"needs {module} (an optional extra), not installed here")
    before = [b for b in PYTHON if b.page == block.page and b.line < block.line] if listed(CONTINUES, block) else []
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tests").symlink_to(ROOT / "tests", target_is_directory=True)
    namespace: dict = {"__name__": "__readme__"}
    old = os.umask(0o077)
    try:
        for b in (*before, block):
            code = compile("\n" * (b.line - 1) + b.text, str(ROOT / b.page), "exec")  # tracebacks name page lines
            exec(code, namespace)
    finally:
        os.umask(old)
        for value in list(namespace.values()):
            if isinstance(value, viewer.Scene):
                value.close()
    check_written_files(tmp_path)


def test_the_exceptions_name_blocks_that_exist():
    """Each entry of NOT_RUN, NEEDS and CONTINUES names one block (a rewrite that drops it fails here)."""
    for table in (NOT_RUN, NEEDS, CONTINUES):
        for page, fragment in table:
            assert len([b for b in PYTHON if b.page == page and fragment in b.text]) == 1, (page, fragment)


@pytest.mark.parametrize("command", shell_commands(), ids=lambda c: f"{c.where} {c.text}")
def test_shell_lines_run(command, tmp_path, no_process_left):
    ran = []
    for step in command.text.split("&&"):
        args, rule = argv(step.strip())
        if args is None:
            continue
        if starts_a_server(args, command.comment):
            rule = "starts a server (h4pin view without --html)"
            continue
        out = run(args, tmp_path)
        assert out.returncode == expected_status(command.comment), (step, out.stdout, out.stderr)
        if command.comment.startswith("error:"):
            for fragment in filter(None, (f.strip() for f in command.comment.split("(exit")[0].split("..."))):
                assert fragment in out.stderr, (fragment, out.stderr)
        ran.append(step)
    if not ran:
        pytest.skip(f"not run by rule: {rule}")
    check_written_files(tmp_path)


@pytest.mark.parametrize("command", console_commands(), ids=lambda c: f"{c.where} {c.text}")
def test_printed_samples_match_the_commands(command, tmp_path, no_process_left):
    args, rule = argv(command.text)
    assert args is not None, f"a console sample must be runnable ({rule})"
    out = run(args, tmp_path)
    assert out.returncode == expected_status(command.comment), out.stderr
    printed = [line.rstrip() for line in out.stdout.rstrip("\n").splitlines()]
    sample = [line.rstrip() for line in command.expected_stdout.rstrip("\n").splitlines()]
    assert printed == sample, "README sample differs from the output:\n" + "\n".join(printed)
