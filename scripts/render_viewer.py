#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Render the viewer's page in headless Chromium to docs/viewer.png (the README's picture).

The prototype at its centre pose with its compliance ellipsoid, the ghost under 10 N down, and
the ellipsoid field over the workspace grid. Needs Debian's ``chromium``.

    python scripts/render_viewer.py [--out docs/viewer.png]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import h4pin
from h4pin.io import viewer
from h4pin.mechanism.scene import screenshot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "docs" / "viewer.png")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")
    with tempfile.TemporaryDirectory() as tmp, viewer.show(h4, load=[0.0, 0.0, -10.0], field=True) as scene:
        page = scene.write_html(Path(tmp) / "h4.html")
        png = screenshot(page, Path(tmp) / "h4.png", size=(1000, 750))
        shutil.move(png, args.out)  # the temporary folder may be on another file system
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
