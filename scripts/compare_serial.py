#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The H4 beside a serial arm: largest translational compliance over a comparable workspace.

Both robots are sampled on the same box of tool positions: 0.2 m x 0.2 m in x, y (11 x 11) at
three heights 5 cm apart, centred on the H4's workspace centre (``h4pin.kinematics.closed_form.centre_pose``,
theta = 0) and on the UR5's tool point at q = (0, -90, 90, -90, -90, 0) deg (elbow up, tool
pointing down; the tool keeps that orientation over the box, by inverse kinematics).

- H4: ``h4pin.stiffness.api.compliance(h4, poses, on_error="nan")`` (model 'consistent').
- UR5 (example-robot-data): ``h4pin.studies.serial.serial_compliance`` at ``tool0`` with
  ``h4pin.studies.serial.UR5_JOINT_STIFFNESS`` -- ASSUMED joint stiffness, see that constant and
  docs/interop.md; the arm's numbers scale as 1/k.

Prints min / median / max of the largest eigenvalue (um/N) and plots maps at mid height and the
distributions to docs/serial_vs_h4.png. Needs the ``erd`` extra (example-robot-data-loaders).

    python scripts/compare_serial.py [--out docs/serial_vs_h4.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import h4pin  # noqa: E402
from h4pin.files import save_figure
from h4pin.kinematics.closed_form import centre_pose  # noqa: E402
from h4pin.stiffness.api import compliance  # noqa: E402
from h4pin.studies.serial import UR5_JOINT_STIFFNESS, serial_compliance  # noqa: E402

SPAN, N, HEIGHTS = 0.2, 11, (-0.05, 0.0, 0.05)
UR5_START = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])


def offsets() -> np.ndarray:
    """(len(HEIGHTS), N, N, 3) offsets of the sampled tool positions, m."""
    g = np.linspace(-SPAN / 2, SPAN / 2, N)
    return np.array([[[(x, y, z) for x in g] for y in g] for z in HEIGHTS])


def h4_largest(h4: h4pin.H4) -> np.ndarray:
    """Largest eigenvalue (um/N) of the H4's translational block over the box (NaN where unreachable)."""
    c = centre_pose(h4)
    off = offsets().reshape(-1, 3)
    poses = np.tile(c, (len(off), 1))
    poses[:, :3] += off
    res = compliance(h4, poses, "consistent", on_error="nan")
    tt = res.translational
    out = np.full(len(poses), np.nan)
    ok = np.all(np.isfinite(tt), axis=(1, 2))
    out[ok] = np.linalg.eigvalsh(tt[ok])[:, -1] * 1e6
    return out.reshape(offsets().shape[:3])


def ik(model, data, fid, target: pin.SE3, q: np.ndarray, iters: int = 200) -> np.ndarray | None:
    """Damped least-squares inverse kinematics of the frame's placement; None if it does not converge."""
    for _ in range(iters):
        pin.framesForwardKinematics(model, data, q)
        err = pin.log6(data.oMf[fid].actInv(target)).vector
        if np.linalg.norm(err) < 1e-12:
            return q
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        q = pin.integrate(model, q, jac.T @ np.linalg.solve(jac @ jac.T + 1e-10 * np.eye(6), err))
    return None


def ur5_largest() -> tuple[np.ndarray, np.ndarray]:
    """Largest eigenvalue (um/N) of the UR5's translational block over the box, and its centre (m)."""
    import example_robot_data

    robot = example_robot_data.load("ur5")
    model, data = robot.model, robot.data
    fid = model.getFrameId("tool0")
    pin.framesForwardKinematics(model, data, UR5_START)
    start = data.oMf[fid].copy()
    off = offsets()
    out = np.full(off.shape[:3], np.nan)
    for h in range(off.shape[0]):
        q = UR5_START.copy()
        for iy in range(N):
            row = range(N) if iy % 2 == 0 else range(N - 1, -1, -1)  # snake: each start is a neighbour
            for ix in row:
                target = pin.SE3(start.rotation, start.translation + off[h, iy, ix])
                sol = ik(model, data, fid, target, q)
                if sol is None:
                    continue
                q = sol
                res = serial_compliance(model, data, q, fid, UR5_JOINT_STIFFNESS)
                out[h, iy, ix] = np.linalg.eigvalsh(res.translational)[-1] * 1e6
    return out, start.translation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default = Path(__file__).resolve().parent.parent / "docs" / "serial_vs_h4.png"
    parser.add_argument("--out", type=Path, default=default, help="figure to write (PNG)")
    args = parser.parse_args()
    h4 = h4pin.load("prototype")
    a = h4_largest(h4)
    b, ur5_centre = ur5_largest()
    for name, v in (("H4 prototype", a), ("UR5 (assumed joint k)", b)):
        f = v[np.isfinite(v)]
        print(f"{name:24s} largest translational compliance over the box [um/N]: "
              f"min {f.min():6.1f}  median {np.median(f):6.1f}  max {f.max():6.1f}  ({f.size}/{v.size} poses)")
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6), layout="constrained")
    ext = [-SPAN / 2 * 1e3, SPAN / 2 * 1e3, -SPAN / 2 * 1e3, SPAN / 2 * 1e3]
    vmax = np.nanmax([np.nanmax(a[1]), np.nanmax(b[1])])
    for axis, v, title in ((ax[0], a[1], "H4 prototype (centre of its workspace)"),
                           (ax[1], b[1], f"UR5, tool down at ({', '.join(f'{c * 1e3:.0f}' for c in ur5_centre)}) mm")):
        im = axis.imshow(v, origin="lower", extent=ext, vmin=0, vmax=vmax, cmap="viridis")
        axis.set_title(title, fontsize=10)
        axis.set_xlabel("dx [mm]")
        axis.set_ylabel("dy [mm]")
    fig.colorbar(im, ax=ax[:2], label="largest translational compliance [um/N]")
    bins = np.linspace(0, vmax * 1.05, 40)
    ax[2].hist(a[np.isfinite(a)], bins=bins, alpha=0.7, label="H4 prototype")
    ax[2].hist(b[np.isfinite(b)], bins=bins, alpha=0.7, label="UR5 (assumed joint stiffness)")
    ax[2].set_xlabel("largest translational compliance [um/N]")
    ax[2].set_ylabel("poses")
    ax[2].set_title(f"{SPAN * 1e3:.0f} x {SPAN * 1e3:.0f} mm box, 3 heights 50 mm apart", fontsize=10)
    ax[2].legend(fontsize=9)
    fig.suptitle("Largest eigenvalue of the 3x3 translational compliance (mid-height maps; all heights at right)")
    save_figure(fig, args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
