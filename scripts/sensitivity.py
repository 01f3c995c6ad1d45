#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Which unstated or uncertain parameter moves Table II, and what closes the gap to the paper.

At q_i = 45 deg, sweeps each parameter the paper leaves out or may have rounded (half-width h,
position of C_k, polar moment I0, stressed forearm fraction, the spring values kc, E, Eb) and
prints/plots the four Table II entries (xx, yy, zz, xz in um/N) against it. Then, for each spring
family, the closed-form factor on its compliance that brings xx to the paper's 40 um/N (K is
linear in each compliance), and what the other entries become with it.

    python scripts/sensitivity.py [--out docs/sensitivity.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import h4pin  # noqa: E402
from h4pin.files import save_figure
from h4pin.kinematics.closed_form import CENTRE_Q
from h4pin.stiffness.api import TERMS, compliance  # noqa: E402
from h4pin.studies.paper import PAPER_COMPUTED, PAPER_MEASURED  # noqa: E402

ENTRIES = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xz": (0, 2)}
BASE = h4pin.H4Params()


def _dc(dx: float = 0.0, dy: float = 0.0) -> np.ndarray:
    dc = BASE.DC.copy()
    dc[0] += dx
    dc[1] += np.array([-dy, dy])
    return dc


#: name -> (x label, values, params for a value, value of the default)
SWEEPS = {
    "half-width h": ("h [mm]", np.array([4, 6, 10, 20, 30, 40, 50]) * 1e-3,
                     lambda v: BASE.replace(half_width=v), BASE.half_width[0]),
    "C_k along x": ("x offset of C_1, C_2 [mm]", np.linspace(-40, 40, 9) * 1e-3,
                    lambda v: BASE.replace(DC=_dc(dx=v)), 0.0),
    "C_k along y": ("|y| of C_k - 60 mm [mm]", np.linspace(-40, 40, 9) * 1e-3,
                    lambda v: BASE.replace(DC=_dc(dy=v)), 0.0),
    "I0": ("I0 / I", np.array([0.25, 0.5, 1, 2, 3, 4]),
           lambda v: BASE.replace(I0=v * BASE.I), BASE.I0[0] / BASE.I[0]),
    "stressed forearm": ("stressed fraction of r", np.linspace(0.5, 1.0, 6),
                         lambda v: BASE.replace(forearm_stressed_fraction=v), 1.0),
    "kc": ("kc / 7.4e3 N.m/rad", np.array([0.5, 0.75, 1, 1.5, 2]),
           lambda v: BASE.replace(kc=v * BASE.kc), 1.0),
    "E (forearms)": ("E / 70 GPa (G = 0.4 E)", np.array([0.5, 0.75, 1, 1.5, 2]),
                     lambda v: BASE.replace(E=v * BASE.E, G=v * BASE.G), 1.0),
    "Eb (bars)": ("Eb / 200 GPa", np.array([0.25, 0.5, 1, 2]), lambda v: BASE.replace(Eb=v * BASE.Eb), 1.0),
}


def table_entries(params: h4pin.H4Params, model: str = "paper") -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The 3x3 block (um/N) and the per-term blocks at q_i = 45 deg."""
    h4 = h4pin.load(params)
    res = compliance(h4, h4.forward_geometry(CENTRE_Q), model)
    return res.translational * 1e6, {t: v[:3, :3] * 1e6 for t, v in res.terms.items()}


def sweep() -> dict[str, np.ndarray]:
    """For each sweep, an array (n values, 4 entries) in um/N."""
    out = {}
    total = sum(len(v[1]) for v in SWEEPS.values())
    with tqdm(total=total, desc="sensitivity", unit="case") as bar:
        for name, (_, values, make, _) in SWEEPS.items():
            rows = []
            for v in values:
                k, _ = table_entries(make(v))
                rows.append([k[ENTRIES[e]] for e in ENTRIES])
                bar.update()
            out[name] = np.array(rows)
    return out


def gap_factors() -> list[tuple[str, float, np.ndarray]]:
    """Factor on each term's compliance that gives xx = 40 um/N, and the four entries then."""
    k, terms = table_entries(BASE)
    out = []
    for t in TERMS:
        factor = 1.0 + (PAPER_COMPUTED[0, 0] - k[0, 0]) / terms[t][0, 0]
        scaled = k + (factor - 1.0) * terms[t]
        out.append((t, factor, np.array([scaled[ENTRIES[e]] for e in ENTRIES])))
    return out


def plot(results: dict[str, np.ndarray], path: Path) -> None:
    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5), sharey=True)
    colours = dict(zip(ENTRIES, ("C0", "C1", "C2", "C3"), strict=True))
    for ax, (name, (label, values, _, default)) in zip(axes.flat, SWEEPS.items(), strict=True):
        scale = 1e3 if "mm" in label else 1.0
        for n, e in enumerate(ENTRIES):
            ax.plot(values * scale, results[name][:, n], "o-", color=colours[e], label=f"K_{e}")
            ax.axhline(PAPER_COMPUTED[ENTRIES[e]], color=colours[e], ls="--", lw=0.8)
        ax.axvline(default * scale, color="k", ls=":", lw=0.8)
        ax.set_title(name)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("compliance [um/N]")
    axes[0, 0].legend(title="solid: h4pin, dashed: paper", fontsize=8)
    fig.suptitle("H4 prototype at q_i = 45 deg: Table II entries vs the parameters the paper does not give "
                 "(dotted: h4pin default)")
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "docs" / "sensitivity.png",
                        help="figure to write (PNG)")
    args = parser.parse_args()
    if not args.out.parent.is_dir():
        raise SystemExit(f"error: folder {args.out.parent} does not exist")
    results = sweep()
    header = "".join(f"{e:>8}" for e in ENTRIES)
    paper = "".join(f"{PAPER_COMPUTED[ENTRIES[e]]:8.1f}" for e in ENTRIES)
    measured = "".join(f"{PAPER_MEASURED[ENTRIES[e]]:8.1f}" for e in ENTRIES)
    print(f"\n{'Table II entries [um/N]':<40}{header}")
    print(f"{'paper, computed':<40}{paper}\n{'paper, measured':<40}{measured}")
    for name, (label, values, _, default) in SWEEPS.items():
        print(f"\n{name} ({label})")
        scale = 1e3 if "mm" in label else 1.0
        for v, row in zip(values, results[name], strict=True):
            mark = "  <- default" if np.isclose(v, default) else ""
            print(f"  {v * scale:<38.3g}" + "".join(f"{x:8.1f}" for x in row) + mark)
    print("\nScale one spring family's compliance until xx = 40 um/N (paper, computed):")
    print(f"  {'term':<12}{'factor':>8}" + header)
    for t, factor, row in gap_factors():
        print(f"  {t:<12}{factor:8.2f}" + "".join(f"{x:8.1f}" for x in row))
    print(f"\nwrote {args.out}")
    plot(results, args.out)


if __name__ == "__main__":
    main()
