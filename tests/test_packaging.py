# SPDX-License-Identifier: Apache-2.0
"""The repository stands alone: its licence, its links, its sdist, and the files it writes."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import re
import shutil
import stat
import subprocess
import sys
import tarfile
import warnings
from pathlib import Path

import numpy as np
import pytest

import h4pin
from h4pin.kinematics.closed_form import centre_pose

ROOT = Path(__file__).resolve().parent.parent
#: sha256 of the Apache License 2.0 as published at https://www.apache.org/licenses/LICENSE-2.0.txt
APACHE_2_SHA256 = "cfc7749b96f63bd31c3c42b5c471bf756814053e847c10f3eb003417bc523d30"
SKIP_DIRS = {".git", ".venv", "venv", "build", "dist", "__pycache__", ".pytest_cache", ".ruff_cache",
             "_build", "auto_examples"}  # the last two: the documentation site's build (git-ignored)
TEXT_SUFFIXES = {".py", ".md", ".toml", ".urdf", ".txt", ".cfg", ".yaml", ".yml", ""}


def repo_files() -> list[Path]:
    out = []
    for dirpath, dirnames, filenames in os.walk(ROOT):
        dirnames[:] = [d for d in dirnames
                       if d not in SKIP_DIRS and not d.startswith(".venv") and not d.endswith(".egg-info")]
        out += [Path(dirpath) / f for f in filenames if f != ".git"]  # a worktree's .git file
    return sorted(out)


def text_files() -> list[Path]:
    return [p for p in repo_files() if p.suffix in TEXT_SUFFIXES and p.name != "LICENSE"]


def test_license_is_apache_2_as_the_headers_say():
    assert hashlib.sha256((ROOT / "LICENSE").read_bytes()).hexdigest() == APACHE_2_SHA256
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert re.search(r'^license = "Apache-2.0"$', pyproject, re.M)
    assert re.search(r'^license-files = \["LICENSE"\]$', pyproject, re.M)
    sources = [p for p in repo_files() if p.suffix == ".py" or p.parent.name == ".ci"]
    assert len(sources) > 20
    for path in sources:
        head = path.read_text(encoding="utf-8").splitlines()[:3]
        assert "# SPDX-License-Identifier: Apache-2.0" in head, path.relative_to(ROOT)


def test_nothing_refers_outside_the_repository():
    """No machine path and no citation of notes kept outside the repository."""
    words = ["H4-" + "NOTES", "../" + "shared", "shared" + "/H4", "/" + "work/", "/" + "home/", "/" + "Users/"]
    pattern = re.compile("|".join(map(re.escape, words)))
    bad = {}
    for path in text_files():
        rel = path.relative_to(ROOT).as_posix()
        hits = [n + 1 for n, line in enumerate(path.read_text(encoding="utf-8").splitlines()) if pattern.search(line)]
        if hits:
            bad[rel] = hits
    assert not bad, f"references outside the repository (file: lines): {bad}"


def test_markdown_links_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    assert {p.name for p in pages} >= {"README.md", "conventions.md", "parameters.md", "errata.md"}
    for page in pages:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text(encoding="utf-8")):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            assert (page.parent / target.split("#")[0]).exists(), f"{page.name}: broken link {target}"


def test_scripts_write_world_readable_files(tmp_path):
    """The sensitivity figure is written 0644 even under umask 077 (mkstemp alone gives 0600)."""
    spec = importlib.util.spec_from_file_location("sensitivity", ROOT / "scripts" / "sensitivity.py")
    sens = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sens)
    results = {name: np.ones((len(values), len(sens.ENTRIES))) for name, (_, values, _, _) in sens.SWEEPS.items()}
    old = os.umask(0o077)
    try:
        sens.plot(results, tmp_path / "s.png")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "s.png").stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["s.png"]


def run(args: list[str], cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def unpacked_sdist(tmp_path_factory) -> Path:
    """The sdist, built by hatchling (the build backend, no network) and unpacked."""
    builders = pytest.importorskip("hatchling.builders.sdist", reason="needs hatchling (the test extra)")
    out = tmp_path_factory.mktemp("sdist")
    (archive,) = builders.SdistBuilder(str(ROOT)).build(directory=str(out), versions=["standard"])
    with tarfile.open(archive) as tar:
        tar.extractall(out, filter="data")
    (top,) = [p for p in out.iterdir() if p.is_dir()]
    return top


def test_sdist_carries_the_repository(unpacked_sdist):
    have = {p.relative_to(unpacked_sdist).as_posix() for p in unpacked_sdist.rglob("*") if p.is_file()}
    for need in ("LICENSE", "README.md", "pyproject.toml", "docs/conventions.md", "docs/parameters.md",
                 "docs/errata.md", "docs/sensitivity.png", "urdf/h4_prototype.urdf", "urdf/h4_symmetric.urdf",
                 "scripts/generate_urdf.py", "scripts/reproduce_table2.py", "tests/conftest.py",
                 "h4pin/cli/__init__.py"):
        assert need in have, need
    for folder in ("h4pin", "scripts", "tests", "urdf", "docs"):
        ours = {p.name for p in (ROOT / folder).iterdir() if p.is_file() and p.suffix != ".pyc"}
        theirs = {Path(p).name for p in have if p.startswith(folder + "/") and p.count("/") == 1}
        assert ours == theirs, folder
    assert "License-Expression: Apache-2.0" in (unpacked_sdist / "PKG-INFO").read_text()


@pytest.mark.slow  # the unpacked sdist compiles in its own, empty cache (a minute)
def test_scripts_work_from_the_unpacked_sdist(unpacked_sdist, tmp_path):
    top = unpacked_sdist
    check = run([str(top / "scripts" / "generate_urdf.py"), "--check"], tmp_path, top)
    assert check.returncode == 0, check.stderr
    from h4pin.description.params import VARIANTS

    assert check.stdout.count("up to date: urdf/h4_") == len(VARIANTS) * 2  # URDF + Extended-URDF sidecar
    assert check.stdout.count("up to date: srdf/h4_") == len(VARIANTS)
    table = run([str(top / "scripts" / "reproduce_table2.py")], tmp_path, top)
    here = run(["-m", "h4pin.cli", "table2"], tmp_path, ROOT)
    assert table.returncode == 0 and here.returncode == 0, table.stderr + here.stderr
    assert table.stdout == here.stdout and "(shipped h4_prototype.urdf)" in table.stdout
    dyn = run([str(top / "scripts" / "constrained_dynamics.py"), "--duration", "0.002", "--dt", "0.001"], tmp_path, top)
    assert dyn.returncode == 0, dyn.stderr
    for name in ("bench", "sensitivity", "render_viewer"):
        helped = run([str(top / "scripts" / f"{name}.py"), "--help"], tmp_path, top)
        assert helped.returncode == 0 and "usage:" in helped.stdout, helped.stderr
    assert list(tmp_path.iterdir()) == []


def resolve(dotted: str) -> object:
    """The object a dotted name ``h4pin.x.y`` names: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:n]))
        except ImportError:
            continue
        for attr in parts[n:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def test_every_cited_h4pin_name_exists():
    """Every ``h4pin.<name>`` the package's docstrings, the scripts, docs/ and the README cite
    resolves (e.g. ``h4pin.compliance``, which once existed only in ``h4pin.stiffness.api``)."""
    sources = [*sorted((ROOT / "h4pin").rglob("*.py")), *sorted((ROOT / "scripts").glob("*.py")),
               *sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
    cited = set()
    for path in sources:
        cited |= {m.rstrip(".") for m in re.findall(r"\bh4pin\.[A-Za-z_][\w.]*", path.read_text(encoding="utf-8"))}
    assert {"h4pin.compliance", "h4pin.load", "h4pin.mechanism.scene.Scene"} <= cited
    from h4pin.extras import MissingExtraError

    missing = []
    for name in sorted(cited):
        try:
            with warnings.catch_warnings():  # an old name cited by its own deprecation message resolves, warning
                warnings.simplefilter("ignore", DeprecationWarning)
                resolve(name)
        except MissingExtraError:  # defined, made from an optional extra this install lacks
            continue
        except (ImportError, AttributeError):
            missing.append(name)
    assert not missing, f"cited but not defined: {missing}"


@pytest.mark.slow  # a copied install in a private mount namespace, 7 s
def test_a_read_only_install_imports_and_computes(tmp_path):
    """With the package folder and $HOME read-only (a system or container install), h4pin imports
    and computes: numba's cache goes to a per-user temporary folder, the per-user cache folder
    under $HOME being read-only too (read-only bind mounts in a private mount namespace; skipped
    where the machine does not allow one)."""
    if shutil.which("unshare") is None:
        pytest.skip("needs the unshare command (util-linux)")
    copy, home = tmp_path / "site", tmp_path / "home"
    home.mkdir()
    shutil.copytree(ROOT / "h4pin", copy / "h4pin", ignore=shutil.ignore_patterns("__pycache__"))
    for data in ("urdf", "srdf"):
        shutil.copytree(ROOT / data, copy / data)
    cache = tmp_path / "tmp"
    cache.mkdir()
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import h4pin, numpy as np; "
            "from h4pin.kinematics.closed_form import centre_pose; h = h4pin.load(); "
            "assert h4pin.__file__.startswith(sys.argv[1]); "
            "r = h4pin.compliance(h, centre_pose(h), method='closed_form'); print(r.translational[0, 0]); "
            "from h4pin import _numba_cache; print(_numba_cache.configure())")
    script = (f"mount --bind -o ro {copy} {copy} && mount --bind -o ro {home} {home} && "
              f"HOME={home} TMPDIR={cache} {sys.executable} -c \"{code}\" {copy}")
    out = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True, timeout=300,
                         env={k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")})
    if out.returncode != 0 and "Traceback" not in out.stderr:  # unshare or mount refused: Python never ran
        pytest.skip(f"no private read-only mounts here: {out.stderr.strip()}")
    assert out.returncode == 0, out.stderr
    kxx, folder = out.stdout.split()
    assert float(kxx) == pytest.approx(h4pin.compliance(h4pin.load(), centre_pose(h4pin.load())).translational[0, 0])
    assert folder.startswith(str(cache)) and any(Path(folder).iterdir())  # compiled code cached there
