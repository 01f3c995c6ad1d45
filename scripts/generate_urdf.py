#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Write the shipped URDF variants, urdf/h4_<name>.urdf, from h4pin.VARIANTS.

With each URDF: its Extended-URDF sidecar urdf/h4_<name>.yaml (closures and motors for Gepetto's
loader, see h4pin.io.interop) and its SRDF srdf/h4_<name>.srdf (reference configuration q0, for
example-robot-data's loaders, see h4pin.io.erd).

Run after changing h4pin/description/params.py or h4pin/description/urdf.py; tests/test_urdf.py fails while the
committed files are not current. ``--check`` only reports stale files (exit 1 if any).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from h4pin.description.urdf import to_urdf, write_text_atomic
from h4pin.studies.variants import GENERATORS

URDF_DIR = Path(__file__).resolve().parent.parent / "urdf"
SRDF_DIR = URDF_DIR.parent / "srdf"


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


def check_or_write(files: dict[Path, str], check: bool) -> list[Path]:
    """Write each stale file atomically (unless ``check``); returns the stale ones."""
    stale = []
    for path, text in files.items():
        if path.is_file() and path.read_text() == text:
            print(f"up to date: {path.relative_to(URDF_DIR.parent)}")
            continue
        stale.append(path)
        if not check:
            path.parent.mkdir(exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            tmp.write_text(text)
            tmp.replace(path)
            print(f"wrote {path.relative_to(URDF_DIR.parent)}")
    return stale


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report stale files, write nothing")
    args = parser.parse_args()
    stale = []
    for name, make in GENERATORS.items():
        path = URDF_DIR / f"h4_{name}.urdf"
        text = to_urdf(make(), path.stem)
        if path.is_file() and path.read_text() == text:
            print(f"up to date: {path.relative_to(URDF_DIR.parent)}")
            continue
        stale.append(path)
        if not args.check:
            write_text_atomic(path, text)
            print(f"wrote {path.relative_to(URDF_DIR.parent)}")
    stale += check_or_write(sidecar_files(), args.check)
    stale += check_or_write(srdf_files(), args.check)
    if args.check and stale:
        print("stale: " + ", ".join(str(p.relative_to(URDF_DIR.parent)) for p in stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
