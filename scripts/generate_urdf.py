#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Write the shipped URDF variants, urdf/h4_<name>.urdf, from h4pin.VARIANTS.

Run after changing h4pin/params.py or h4pin/urdf.py; tests/test_urdf.py fails while the
committed files are not current. ``--check`` only reports stale files (exit 1 if any).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from h4pin.params import VARIANTS
from h4pin.urdf import to_urdf, write_text_atomic

URDF_DIR = Path(__file__).resolve().parent.parent / "urdf"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report stale files, write nothing")
    args = parser.parse_args()
    stale = []
    for name, make in VARIANTS.items():
        path = URDF_DIR / f"h4_{name}.urdf"
        text = to_urdf(make(), path.stem)
        if path.is_file() and path.read_text() == text:
            print(f"up to date: {path.relative_to(URDF_DIR.parent)}")
            continue
        stale.append(path)
        if not args.check:
            write_text_atomic(path, text)
            print(f"wrote {path.relative_to(URDF_DIR.parent)}")
    if args.check and stale:
        print("stale: " + ", ".join(str(p.relative_to(URDF_DIR.parent)) for p in stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
