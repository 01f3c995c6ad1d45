#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Term-by-term report of Table II with the elements eq. 30 neglects (h4pin.stiffness.elements).

At q_i = 45 deg, with illustrative element data (orders of magnitude of bearings, ball joints,
the URDF's 8 mm aluminium plate rods, actuator shafts and motor mounts, not prototype data; the
same value for every element of a kind; see h4pin.description.elements.ILLUSTRATIVE), or with the elements
written in a URDF (``--urdf``: ``<h4_revolute>``, ``<h4_ball>``, ``<h4_plate_bar>``,
``<h4_actuator shaft_tilt>``, ``<h4_base>``, see h4pin.stiffness.elements): each term's xx, yy, zz, xz in
um/N and its share; each element's shape against the two shapes of eq. 30 (docs/gap.md); and the
element compliance (or rigidity EI, GJ) of every element of that kind that would make its term's
xx 1 um/N (each term is linear in its compliance, inversely so in a rigidity).

    python scripts/elements_report.py [--urdf my_h4.urdf]
"""

from __future__ import annotations

import argparse

import numpy as np

import h4pin
from h4pin.description import elements as el
from h4pin.kinematics.closed_form import centre_pose
from h4pin.studies import gap

US = 1e6
UNITS = el.UNITS
STIFFNESS = {"m/N": "N/m", "rad/(N.m)": "N.m/rad"}


def _values(v: np.ndarray) -> str:
    if np.all(v == v[0]):
        return f"{v[0]:.3g}"
    return "[" + " ".join(f"{x:.3g}" for x in v) + "]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urdf", help="an H4 URDF with <h4_revolute>/<h4_ball> elements (default: the prototype "
                                       "with illustrative elements)")
    args = parser.parse_args()
    h4 = h4pin.load(args.urdf or "prototype")
    elements = h4.elements if args.urdf else el.ILLUSTRATIVE
    pose = centre_pose(h4)
    terms = h4pin.compliance(h4, pose, "consistent", elements=elements, terms=True).terms
    entries = {t: m[[0, 1, 2, 0], [0, 1, 2, 2]] for t, m in terms.items()}  # Table II entries xx, yy, zz, xz
    total = sum(entries.values())
    print(f"Elements ({'from ' + args.urdf if args.urdf else 'illustrative'}): "
          + ", ".join(f"{n} = {_values(getattr(elements, n))} {UNITS[n]}" for n in el.ELEMENTS))
    print(f"\n{'term':<18}" + "".join(f"{e:>9}" for e in gap.ENTRIES) + "   share of xx   yy/xx  zz/xx  xz/xx")
    for name, v in entries.items():
        has_xx = abs(v[0]) > 1e-9 * np.abs(total).max()
        ratios = "  ".join(f"{x / v[0]:5.3f}" for x in v[1:]) if has_xx else "  (no xx)"
        print(f"{name:<18}" + "".join(f"{x * US:9.3f}" for x in v) + f"{v[0] / total[0]:12.1%}   " + ratios)
    print(f"{'total':<18}" + "".join(f"{x * US:9.3f}" for x in total))
    base = {"control": terms["control"][:3, :3], "torsion": terms["torsion"][:3, :3]}
    print("\nElement shape vs the two shapes of eq. 30 (axial, tilt), and the compliance (rigidity EI, GJ) of every "
          "element of the kind for which its term alone has xx = 1 um/N:")
    for name in el.ELEMENTS:
        if name not in terms:
            print(f"  {name:<16} off")
            continue
        coef, res = gap.in_span(base | {name: terms[name][:3, :3]}, name, ("control", "torsion"))
        values = getattr(elements, name)
        c = float(np.mean(values[np.isfinite(values)]))  # a common factor on every element of the kind
        xx = entries[name][0]
        unit = UNITS[name]
        if abs(xx) <= 1e-9 * abs(total[0]):
            need = "none: no xx at this pose"
        elif name in el.RIGIDITIES:
            need = f"{c * xx / 1e-6:.2e} {unit}"
        else:
            need = f"{c * 1e-6 / xx:.2e} {unit} (stiffness {xx / (c * 1e-6):.2e} {STIFFNESS[unit]})"
        kind = "inside the two-shape cone" if res < 1e-6 and np.all(coef >= -1e-9 * np.abs(coef).max()) else (
            "in their plane, outside the cone" if res < 1e-6 else f"outside their plane (residual {res:.2f})")
        print(f"  {name:<16} {kind:<36} {need}")


if __name__ == "__main__":
    main()
