# SPDX-License-Identifier: Apache-2.0
"""Table II of the paper: translational compliance at the workspace centre (q_i = 45 deg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from h4pin.robot import H4, urdf_dir
from h4pin.stiffness import TERMS, compliance

#: Table II of the paper, um/N (erratum 5: the print says m/N). Rows: displacement x, y, z;
#: columns: force along x, y, z.
PAPER_COMPUTED = np.array([[40.0, 0.0, 21.0], [0.0, 21.0, 0.0], [21.0, 0.0, 19.0]])
PAPER_MEASURED = np.array([[51.0, 0.0, 11.0], [-3.0, 15.0, -1.0], [15.0, 0.0, 9.0]])
CENTRE_Q = np.full(4, np.pi / 4)


def centre_pose(h4: H4) -> np.ndarray:
    """The pose with all actuators at 45 deg (the paper's measurement pose)."""
    return h4.forward_geometry(CENTRE_Q)


def source_label(h4: H4) -> str:
    """Where the robot came from, as a reader can use it: a shipped file by its name (its folder
    depends on the installation), anything else as given."""
    path = Path(h4.source)
    if path.is_absolute() and path.parent == urdf_dir().resolve():
        return f"shipped {path.name}"
    return h4.source


def report(h4: H4, model: str = "paper") -> str:
    """Text report: our 3x3 block (um/N) beside the paper's, per-term split and relative gaps."""
    pose = centre_pose(h4)
    res = compliance(h4, pose, model)
    exact = res.translational * 1e6
    ours = np.round(exact, 1) + 0.0  # for display; + 0.0 turns -0.0 into 0.0
    lines = [f"H4 compliance at q_i = 45 deg, pose D = ({', '.join(f'{v * 1e3:.2f}' for v in pose[:3])}) mm, "
             f"theta = {pose[3]:.3f} rad, model '{model}' ({source_label(h4)})", ""]
    rows = "xyz"

    def block(title: str, m: np.ndarray) -> list[str]:
        out = [f"{title:<28}" + "".join(f"{'F' + c:>9}" for c in rows)]
        for a in range(3):
            out.append(f"{'  d' + rows[a] + ' [um/N]':<28}" + "".join(f"{m[a, b]:9.1f}" for b in range(3)))
        return out

    lines += block("h4pin", ours) + [""]
    lines += block("paper, computed", PAPER_COMPUTED) + [""]
    lines += block("paper, measured", PAPER_MEASURED) + [""]
    lines.append(f"{'gap to paper computed':<28}" + "".join(f"{'F' + c:>9}" for c in rows))
    for a in range(3):
        cells = []
        for b in range(3):
            ref = PAPER_COMPUTED[a, b]
            cells.append(f"{(exact[a, b] - ref) / ref * 100:8.0f}%" if ref else f"{ours[a, b] - ref:+8.1f} ")
        lines.append(f"{'  d' + rows[a]:<28}" + "".join(cells))
    lines += ["", "per-term split [um/N]:  " + "  ".join(f"{t:>9}" for t in TERMS)]
    for a, b in ((0, 0), (1, 1), (2, 2), (0, 2)):
        lines.append(f"  d{rows[a]}/F{rows[b]}{'':<16}" + "  ".join(f"{res.terms[t][a, b] * 1e6:9.2f}" for t in TERMS))
    lines += ["", "The gap to the paper comes from prototype data the paper does not give (half-width, C_k, "
              "section shapes);", "defaults are not tuned to the table. See scripts/sensitivity.py for what closes it."]
    return "\n".join(lines)
