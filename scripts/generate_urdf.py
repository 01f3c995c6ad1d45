#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Write the shipped URDF variants, urdf/h4_<name>.urdf, from h4pin.VARIANTS.

With each URDF: its Extended-URDF sidecar urdf/h4_<name>.yaml (closures and motors for Gepetto's
loader, see h4pin.io.interop), its SRDF srdf/h4_<name>.srdf (reference configuration q0, for
example-robot-data's loaders, see h4pin.io.erd) and its MuJoCo model mjcf/h4_<name>.xml
(h4pin.io.mjcf, written through MuJoCo's MjSpec; skipped, with a note, when MuJoCo is not
installed).

Run after changing h4pin/description/params.py, h4pin/description/urdf.py or h4pin/io/mjcf.py;
tests/test_urdf.py and tests/test_mjcf.py fail while the committed files are not current. ``--check``
only reports stale files (exit 1 if any). MuJoCo's XML writer lays a file out a little differently
from one version to another, so ``--check`` compares an MJCF's text only when the installed MuJoCo
is the one named in the file (tests/test_mjcf.py compares the compiled models otherwise); write
the shipped files with the newest MuJoCo.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from h4pin.description.urdf import to_urdf, write_text_atomic
from h4pin.files import same_generated_text
from h4pin.studies.variants import GENERATORS

URDF_DIR = Path(__file__).resolve().parent.parent / "urdf"
SRDF_DIR = URDF_DIR.parent / "srdf"
MJCF_DIR = URDF_DIR.parent / "mjcf"


def sidecar_files() -> dict[Path, str]:
    """The Extended-URDF sidecars urdf/h4_<name>.yaml, generated from the URDFs' closures."""
    from h4pin import load
    from h4pin.io.interop import extended_urdf_yaml

    return {URDF_DIR / f"h4_{name}.yaml": extended_urdf_yaml(load(make()), f"h4_{name}.urdf")
            for name, make in GENERATORS.items()}


def srdf_files() -> dict[Path, str]:
    """The SRDFs srdf/h4_<name>.srdf with the reference configuration q0 (example-robot-data layout)."""
    from h4pin import load
    from h4pin.io.erd import srdf

    return {SRDF_DIR / f"h4_{name}.srdf": srdf(load(make()), f"h4_{name}") for name, make in GENERATORS.items()}


def mjcf_files() -> dict[Path, str]:
    """The MuJoCo models mjcf/h4_<name>.xml (h4pin.io.mjcf.to_mjcf), named h4_<name>; empty, with a
    note on stderr, when MuJoCo is not installed."""
    from h4pin import load
    from h4pin.extras import MissingExtraError
    from h4pin.io.mjcf import to_mjcf

    try:
        return {MJCF_DIR / f"h4_{name}.xml": to_mjcf(load(make()), f"h4_{name}") for name, make in GENERATORS.items()}
    except MissingExtraError as exc:
        print(f"skipped mjcf/: {exc}", file=sys.stderr)
        return {}


def mjcf_to_check(files: dict[Path, str]) -> dict[Path, str]:
    """The MJCF files whose text ``--check`` compares: those written by the installed MuJoCo (or
    missing); the others are reported and left to tests/test_mjcf.py."""
    from h4pin.io.mjcf import writer_version

    out = {}
    for path, text in files.items():
        shipped = writer_version(path.read_text()) if path.is_file() else None
        mine = writer_version(text)
        if shipped is not None and shipped != mine:
            print(f"not compared: {path.relative_to(URDF_DIR.parent)} (written by MuJoCo {shipped}, this is {mine})")
            continue
        out[path] = text
    return out


def check_or_write(files: dict[Path, str], check: bool) -> list[Path]:
    """Write each stale file atomically (unless ``check``); returns the stale ones. A file is
    current when it says what the generator writes now, numbers to round-off
    (:func:`h4pin.files.same_generated_text`: their last digits follow the CPU)."""
    stale = []
    for path, text in files.items():
        if path.is_file() and same_generated_text(path.read_text(), text):
            print(f"up to date: {path.relative_to(URDF_DIR.parent)}")
            continue
        stale.append(path)
        if not check:
            path.parent.mkdir(exist_ok=True)
            write_text_atomic(path, text, mark=False)  # shipped: no marker (a user's edited copy is theirs)
            print(f"wrote {path.relative_to(URDF_DIR.parent)}")
    return stale


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report stale files, write nothing")
    args = parser.parse_args()
    urdfs = {URDF_DIR / f"h4_{name}.urdf": to_urdf(make(), f"h4_{name}") for name, make in GENERATORS.items()}
    stale = check_or_write(urdfs, args.check)
    stale += check_or_write(sidecar_files(), args.check)
    stale += check_or_write(srdf_files(), args.check)
    mjcf = mjcf_files()
    stale += check_or_write(mjcf_to_check(mjcf) if args.check else mjcf, args.check)
    if args.check and stale:
        print("stale: " + ", ".join(str(p.relative_to(URDF_DIR.parent)) for p in stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
