# SPDX-License-Identifier: Apache-2.0
"""Numbers in docs/ that the code computes, read from the page and computed again (issue 50).

Each test finds its sentence on the page (a rewrite that drops it fails here, as a number that stops
matching does) and compares the number printed with the code's value now, to the printed rounding.
Speed figures are not computed here (they belong to one recorded bench run, cited on the page): for
them the tests check that the text around a table says what the table says.
"""

from __future__ import annotations

import inspect
import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import h4pin
from h4pin.errors import InterferenceError, MechanismWarning, ParameterError, SingularPoseError
from h4pin.kinematics.closed_form import centre_pose

DOCS = Path(__file__).resolve().parent.parent / "docs"


def page(name: str) -> str:
    """A docs page with its line breaks and runs of spaces as single spaces."""
    return re.sub(r"\s+", " ", (DOCS / name).read_text(encoding="utf-8"))


def find(pattern: str, text: str) -> re.Match:
    m = re.search(pattern, text)
    assert m, f"the page no longer says: {pattern}"
    return m


def rounds_to(value: float, printed: str) -> bool:
    """``value`` printed with as many decimals as ``printed`` has gives ``printed``."""
    decimals = len(printed.partition(".")[2])
    return abs(value - float(printed)) <= 0.5 * 10.0 ** -decimals + 1e-12


# --- validation.md: the symmetric variant at its centre


def test_the_symmetric_centre_is_singular_to_round_off():
    row = find(r"\| `symmetric` variant at its centre \| `SingularPoseError`: [^|]*cond ≥ (1e\d+) [^|]*`inf` through "
               r"Pinocchio's", page("validation.md"))
    bound = float(row[1])
    h4 = h4pin.load("symmetric")
    x = centre_pose(h4)
    for method in ("auto", "closed_form"):  # the compiled route and the numpy one
        with pytest.raises(SingularPoseError) as err:
            h4pin.compliance(h4, x, method=method)
        cond = float(re.search(r"cond = (\S+) >=", str(err.value))[1])
        assert cond >= bound, (method, cond)
    with pytest.raises(SingularPoseError, match=r"cond = inf >="):
        h4pin.compliance(h4, x, method="pinocchio")
    batch = h4pin.compliance(h4, x[None], on_error="nan")
    assert batch.condition[0] >= bound


# --- parameters.md: the parallelograms' half width h


def table_ii(half_width: float) -> np.ndarray:
    h4 = h4pin.load(h4pin.H4Params(half_width=half_width))
    return h4pin.compliance(h4, centre_pose(h4)).translational


def test_half_width_moves_table_ii_as_the_page_says():
    text = page("parameters.md")
    limit = find(r"It must stay below (\d+) mm: at \1 mm the bars interpenetrate at the centre pose "
                 r"\(`InterferenceError`\), and above it the plate-side ball joints of legs 1 and 4 \(`ball_radius` "
                 r"5 mm\) collide \(refused at load\)", text)
    moves = find(r"From (\d+) to (\d+) mm Table II moves by at most ([\d.]+) % from its value at (\d+) mm "
                 r"\(([\d.]+) % at (\d+) mm\)", text)
    ref = table_ii(float(moves[4]) * 1e-3)
    entries = np.abs(ref) > 1e-6 * np.abs(ref).max()  # the y couplings are zero by symmetry

    def change(h_mm: float) -> float:  # percent, the largest over Table II's entries
        return 100 * np.max(np.abs(table_ii(h_mm * 1e-3) - ref)[entries] / np.abs(ref[entries]))

    lo, hi = int(moves[1]), int(moves[2])
    worst = max(change(h) for h in np.arange(lo, hi + 0.5, 1.0))  # every mm
    assert rounds_to(worst, moves[3]), worst
    assert rounds_to(change(float(moves[6])), moves[5])
    stop = float(limit[1])
    assert h4pin.H4Params().ball_radius == 0.005
    table_ii((stop - 0.1) * 1e-3)
    with pytest.raises(InterferenceError):
        table_ii(stop * 1e-3)
    with pytest.raises(ParameterError, match="ball joints of legs 1 and 4 collide"):
        h4pin.load(h4pin.H4Params(half_width=(stop + 0.1) * 1e-3))


# --- errata.md: which entry point defaults to which model


def test_the_models_defaults_are_the_entry_points():
    from h4pin.cli.cycle import cycle
    from h4pin.cli.table2 import table2
    from h4pin.cli.view import view
    from h4pin.io import viewer

    def default(fn):
        value = inspect.signature(fn).parameters["model"].default
        return getattr(value, "default", value)  # a typer option's default

    entry = {"`h4pin.compliance`": h4pin.compliance, "`h4pin table2`": table2, "`h4pin view`": view,
             "`h4pin.io.viewer.show`": viewer.show, "`h4pin cycle`": cycle}
    head = find(r'\| \| `model="paper"` \(default of ([^)]*)\) \| `model="consistent"` \(default of ([^)]*)\) \|',
                page("errata.md"))
    named = {}
    for model, cell in zip(("paper", "consistent"), head.groups(), strict=True):
        for name in re.findall(r"`[^`]+`", cell):
            named[name] = model
    assert set(named) == set(entry), named
    assert {name: default(fn) for name, fn in entry.items()} == named


# --- mechanisms.md: the five-bar with aluminium links


def in_plane_worst(c: np.ndarray) -> float:
    """um/N, the largest eigenvalue of the tool's translational block in the linkage's plane (x, z)."""
    t = c[np.ix_([0, 2], [0, 2])]
    return float(np.linalg.eigvalsh(0.5 * (t + t.T))[-1]) * 1e6


def test_five_bar_beam_figures_are_the_walk_throughs():
    from h4pin.mechanism import Beam, Mechanism

    text = page("mechanisms.md")
    at_q = find(r"at the `q` above has a worst compliance in the linkage's plane \(x, z\) of ([\d.]+) µm/N; aluminium "
                r"links of that tube bring it to ([\d.]+) µm/N \(\+(\d+) %\); out of the plane, where rigid links give "
                r"nothing, they give ([\d.]+) µm/N", text)
    start = find(r"\(`five_bar.assemble\(\)`, ([\d.]+) → ([\d.]+) µm/N there\)", text)
    code = find(r'tube = (Beam\.tube\([^)]*\)).*?flex = five_bar\.with_beams\((\{[^}]*\})\)', text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MechanismWarning)
        five_bar = Mechanism.from_urdf(DOCS.parent / "tests/robots/5bar_linkage_iso3d/robot.urdf")
    tube = eval(code[1], {"Beam": Beam})  # the page's own tube and links
    flex = five_bar.with_beams(eval(code[2], {"tube": tube}))
    springs, tool = {"mot1": 2.0e3, "mot2": 3.0e3}, ["closedloop3D_1B"]
    for q, printed in ((five_bar.assemble(pin.neutral(five_bar.model) + 0.05), at_q), (five_bar.assemble(), start)):
        rigid, links = five_bar.compliance(q, springs, tool), flex.compliance(q, springs, tool)
        assert rounds_to(in_plane_worst(rigid), printed[1]), in_plane_worst(rigid)
        assert rounds_to(in_plane_worst(links), printed[2]), in_plane_worst(links)
        if printed is at_q:
            assert rounds_to(100 * (in_plane_worst(links) / in_plane_worst(rigid) - 1), printed[3])
            assert rounds_to(links[1, 1] * 1e6, printed[4]), links[1, 1]
            assert abs(rigid[1, 1]) < 1e-12  # rigid links: nothing out of the plane


# --- speed: the text says what the recorded table says


def table_rows(text: str, first_cell: str) -> list[list[str]]:
    return [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
            if line.startswith(f"| {first_cell}")]


def test_mechanisms_speed_text_agrees_with_its_table():
    raw = (DOCS / "mechanisms.md").read_text(encoding="utf-8")
    rows = [r for name in ("5bar_linkage_iso3d", "robot_delta", "cassie_like", "digit_like", "digit_like_2legs",
                           "wl16_like") for r in table_rows(raw, name + " ") if r[2].endswith(" µs")]
    assert len(rows) == 6
    us = lambda cell: float(cell.removesuffix(" µs"))  # noqa: E731
    ratios = []
    for r in rows:
        assert r[6] == f"{us(r[2]) / us(r[4]):.0f}×", r  # plain / batch on one thread
        assert r[8] == f"{us(r[7]) / us(r[4]):.1f}×", r  # frequencies / compliance
        ratios.append(int(r[6].removesuffix("×")))
    span = f"{min(ratios)}–{max(ratios)}×"
    assert f"The plain loop is {span} slower than the batch on one thread" in page("mechanisms.md")
    assert f"it is {span} faster than the plain Pinocchio + numpy KKT loop" in page("motion.md")


def test_performance_text_agrees_with_its_table():
    raw = (DOCS / "performance.md").read_text(encoding="utf-8")
    default = table_rows(raw, "`h4pin.compliance(h4, poses)`, default batch, 1 thread / 2 threads")[0][1]
    one, two = default.split(" / ")
    terms = table_rows(raw, "`compliance(..., terms=True)`, batch, 2 threads")[0][1]
    m = find(r"`terms=True` ([\d.]+)× the default batch on the same two threads \(([\d.]+) / ([\d.]+) µs", page(
        "performance.md"))
    assert (m[2], m[3]) == (terms, two)
    assert m[1] == f"{float(terms) / float(two):.1f}"
    modes = table_rows(raw, "`h4pin.modes(h4, poses)`, all frequencies")[0][1].split(" / ")[0]
    assert f"20 µs a pose on one core (the 16 frequencies: {modes} µs in the recorded run of" in page("modes.md")
    assert float(modes) == pytest.approx(20, abs=0.5)  # "about 20 µs" in modes.md and motion.md
    for name in ("modes.md", "motion.md"):
        assert "about 30 µs" not in page(name) and "About 30 µs" not in page(name)


def test_motor_atlas_time_per_point_agrees_with_the_grids_time():
    m = find(r"Time: about ([\d.]+) ms a grid point on the 14-DoF delta .*? the (\d+) × (\d+) grid of the command "
             r"above in ([\d.]+) s", page("mechanisms.md"))
    per_point = float(m[4]) / (int(m[2]) * int(m[3])) * 1e3
    assert abs(per_point - float(m[1])) <= 0.1, per_point
    assert "--motor mot1_rod1=-0.3:0.3:21 --motor mot1_rod2=-0.3:0.3:21" in page("mechanisms.md")
