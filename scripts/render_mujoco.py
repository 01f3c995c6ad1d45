#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Render a shipped MuJoCo model offscreen, at its keyframe q0, from its camera: docs/mujoco.png.

    python scripts/render_mujoco.py [--variant prototype] [--gl egl|osmesa] [--out docs/mujoco.png]

MuJoCo picks its OpenGL back end when it is imported, from MUJOCO_GL: this script sets it to
``--gl`` (default egl, the one that works headless with Mesa's libEGL; osmesa needs libOSMesa).
Needs the ``mujoco`` extra. The PNG is written atomically (h4pin.files).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"


def render(variant: str, out: Path, width: int = 640, height: int = 480) -> Path:
    """Render mjcf/h4_<variant>.xml at its keyframe from its camera into the PNG ``out``."""
    import matplotlib.image
    import mujoco

    from h4pin.files import write_atomic
    from h4pin.io.mjcf import CAMERA, KEYFRAME, mjcf_path

    model = mujoco.MjModel.from_xml_path(str(mjcf_path(variant)))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(KEYFRAME).id)
    mujoco.mj_forward(model, data)
    renderer = mujoco.Renderer(model, height, width)
    try:
        renderer.update_scene(data, camera=CAMERA)
        image = renderer.render()
    finally:
        renderer.close()
    return write_atomic(out, lambda tmp: matplotlib.image.imsave(tmp, image, format="png"))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="prototype")
    parser.add_argument("--gl", default="egl", choices=["egl", "osmesa", "glfw"], help="MuJoCo's OpenGL back end")
    parser.add_argument("--out", type=Path, default=DOCS / "mujoco.png")
    args = parser.parse_args()
    os.environ["MUJOCO_GL"] = args.gl
    if args.gl != "glfw":
        os.environ["PYOPENGL_PLATFORM"] = args.gl
    try:
        print(f"wrote {render(args.variant, args.out)}")
    except Exception as exc:  # no OpenGL context: say which back end failed and how
        print(f"error: rendering with MUJOCO_GL={args.gl} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
