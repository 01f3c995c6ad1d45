# SPDX-License-Identifier: Apache-2.0
"""The documentation site (docs/conf.py): its API pages cover the package, it builds with
warnings as errors (the gallery of examples/ run), and its pages show in a browser."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import h4pin

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
#: What the API reference must document (the issue's list): the generic engine's modules and the
#: H4's packages.
MODULES = {"h4pin", *(f"h4pin.mechanism.{m}" for m in ("core", "engine", "assembly", "batch", "beams", "couplings",
                                                       "payload", "sidecar", "mjcf_reader", "mjcf_writer", "store",
                                                       "atlas", "scene")),
           "h4pin.description", "h4pin.kinematics", "h4pin.stiffness", "h4pin.elastic", "h4pin.studies", "h4pin.io",
           "h4pin.plots"}
SITE_PACKAGES = ("sphinx", "furo", "myst_parser", "sphinx_gallery")


def documented_modules() -> set[str]:
    return {m for page in (DOCS / "api").glob("*.md")
            for m in re.findall(r"^\.\. automodule:: (\S+)", page.read_text(encoding="utf-8"), re.M)}


def test_the_api_pages_cover_the_package():
    """Every module of the list above has an automodule, and each documented module imports."""
    documented = documented_modules()
    assert MODULES <= documented, sorted(MODULES - documented)
    for name in documented:
        assert importlib.util.find_spec(name) is not None, name
    index = (DOCS / "api" / "index.md").read_text(encoding="utf-8")
    assert all(f"\n{page.stem}\n" in index for page in (DOCS / "api").glob("*.md") if page.stem != "index")


def test_every_guide_is_in_the_navigation():
    """Each page of docs/ is in a toctree of the index (or is the index), but the two guides
    being written, which conf.py adds when they exist."""
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^([a-z_]+(?:/[a-z_]+)?)$", index, re.M))
    pages = {p.stem for p in DOCS.glob("*.md")} - {"index"}
    assert pages - {"loaded", "calibration"} <= listed, sorted(pages - listed)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built by the README's command (warnings as errors), into a temporary folder."""
    missing = [name for name in SITE_PACKAGES if importlib.util.find_spec(name) is None]
    if missing:
        pytest.skip(f"needs the docs extra (pip install '.[docs]'): {', '.join(missing)} not installed")
    out = tmp_path_factory.mktemp("site")
    env = {k: v for k, v in os.environ.items() if k != "H4PIN_WARMUP"}  # conf.py's own choice
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-b", "html", "-d", str(out / ".doctrees"),
                           str(DOCS), str(out / "html")], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-5000:]
    return out / "html"


@pytest.mark.slow  # a whole build of the site, examples run (a minute or two)
def test_the_site_builds_with_every_public_name(site):
    """The build has every page, an API entry for each of h4pin.__all__, and the gallery's pages
    with the examples' output (their figures included)."""
    for page in ("index.html", "first_use.html", "build_in_code.html", "cli.html", "api/h4pin.html",
                 "api/mechanism.html", "auto_examples/index.html", "changelog.html"):
        assert (site / page).is_file(), page
    api = (site / "api" / "h4pin.html").read_text(encoding="utf-8")
    missing = [name for name in h4pin.__all__ if f'id="h4pin.{name}"' not in api]
    assert not missing, missing
    examples = sorted((ROOT / "examples").glob("plot_*.py"))
    assert len(examples) >= 7
    for example in examples:
        page = (site / "auto_examples" / f"{example.stem}.html").read_text(encoding="utf-8")
        assert "Total running time of the script" in page, example.name
    assert list((site / "_images").glob("sphx_glr_plot_*"))


def ink(png: Path) -> tuple[float, int]:
    """(share of pixels that are not white, number of dark, text-coloured pixels) of a screenshot."""
    import matplotlib.pyplot as plt

    rgb = plt.imread(png)[..., :3]
    not_white = float(np.mean(rgb.min(axis=-1) < 0.95))
    dark = int(np.sum(rgb.max(axis=-1) < 0.35))
    return not_white, dark


@pytest.mark.slow
@pytest.mark.browser
@pytest.mark.skipif(shutil.which("chromium") is None, reason="needs Debian's chromium (apt-get install chromium)")
@pytest.mark.parametrize("page", ["index.html", "api/h4pin.html"])
def test_pages_render_in_a_browser(site, page, tmp_path):
    """Headless Chromium draws the page with content: not a blank page, and text on it."""
    from h4pin.mechanism.scene import screenshot

    png = screenshot(site / page, tmp_path / "page.png", size=(1200, 900))
    not_white, dark = ink(png)
    assert not_white > 0.05, f"{page}: {not_white:.1%} of the screenshot is not white"
    assert dark > 2000, f"{page}: {dark} text-coloured pixels"
