# SPDX-License-Identifier: Apache-2.0
"""Sphinx configuration of h4pin's site: the guides of docs/ (Markdown, through MyST), the API
reference from the docstrings (autodoc, napoleon: Google style), and the gallery of examples/
(sphinx-gallery, run at every build). One command builds it, warnings as errors:

    python -m sphinx -W -b html docs docs/_build/html

Nothing is fetched: no intersphinx, no remote theme assets (furo ships its own)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # this checkout's h4pin, before any installed one

# The gallery runs h4pin in this process. With numba's cache not yet full it takes the numpy path
# and the interpreted twins (the same numbers to round-off) and starts no background warm-up, so
# a build compiles nothing and leaves no process behind; H4PIN_WARMUP=inline compiles instead.
if os.environ.get("H4PIN_WARMUP") != "inline":
    os.environ["H4PIN_WARMUP"] = "off"
os.environ.setdefault("MPLBACKEND", "Agg")

import h4pin  # noqa: E402

project = "h4pin"
author = "h4pin contributors"
copyright = "h4pin contributors, Apache-2.0"
release = h4pin.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "auto_examples/*.ipynb", "auto_examples/*.py",
                    "auto_examples/*.zip", "auto_examples/*.md5", "auto_examples/*.json"]

# Guides being written: in the navigation (after `motion` in index.md's toctree) when their page
# exists, and no warning while it does not.
OPTIONAL_GUIDES = ("loaded", "calibration")
OPTIONAL_AFTER = "cycle\nmotion\n```"


def optional_guides(app, docname, source):
    """index.md's toctree, with each of :data:`OPTIONAL_GUIDES` whose page exists."""
    if docname != "index":
        return
    present = "".join(f"{name}\n" for name in OPTIONAL_GUIDES if (DOCS / f"{name}.md").is_file())
    if OPTIONAL_AFTER not in source[0]:
        raise RuntimeError(f"docs/index.md: the toctree that takes {OPTIONAL_GUIDES} no longer ends in "
                           f"{OPTIONAL_AFTER!r}")
    source[0] = source[0].replace(OPTIONAL_AFTER, OPTIONAL_AFTER[:-3] + present + "```", 1)


def setup(app):
    app.connect("source-read", optional_guides)

# -- MyST: the guides are GitHub-flavoured Markdown; their links to sections (page.md#heading)
# resolve through heading anchors.
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 4

# -- autodoc / napoleon
autodoc_default_options = {"undoc-members": False, "show-inheritance": True,
                           "member-order": "bysource"}
autodoc_typehints = "description"
autodoc_class_signature = "separated"
autoclass_content = "class"
autodoc_preserve_defaults = True
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_attr_annotations = True
napoleon_use_ivar = True  # a class's "Attributes:" as fields, not a second description of its dataclass fields

# -- sphinx-gallery: examples/ run at every build, each in seconds.
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": str(DOCS / "auto_examples"),
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "write_computation_times": False,  # no sg_execution_times file beside the guides
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "min_reported_time": 0,
    "within_subsection_order": "FileNameSortKey",
    "show_memory": False,
    "abort_on_example_error": True,
    "capture_repr": ("_repr_html_", "__repr__"),
}

# -- HTML
html_theme = "furo"
html_title = f"h4pin {release}"
html_static_path: list[str] = []
html_show_sourcelink = True
html_last_updated_fmt = None
pygments_style = "sphinx"
pygments_dark_style = "monokai"

# Re-exported names are documented where they are defined and under h4pin's public name, so a
# short name in a signature (ParameterError, Elements) has two targets: Sphinx links the first.
suppress_warnings = ["ref.python"]
