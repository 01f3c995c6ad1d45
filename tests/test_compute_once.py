# SPDX-License-Identifier: Apache-2.0
"""Compute once: a viewer or a command asks for the compliance at a pose once, and passes it (and
the deflection made of it) downstream. Each test counts the calls of the compliance functions
the drawing modules reach (a wrapper on every name they are reached by) and checks the drawing
against the same numbers computed independently of the viewer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli_in_process

import h4pin
from h4pin.stiffness import api

ROBOTS = Path(__file__).resolve().parent / "robots"


def _counting(monkeypatch, targets):
    """Wrap ``h4pin.stiffness.api.compliance`` wherever ``targets`` (modules) hold it: the calls."""
    calls = []
    real = api.compliance

    def counted(*args, **kwargs):
        calls.append(np.asarray(args[1] if len(args) > 1 else kwargs.get("pose")).shape)
        return real(*args, **kwargs)

    for module in targets:
        monkeypatch.setattr(module, "compliance", counted)
    return calls


def test_view_with_a_load_computes_the_compliance_once(tmp_path, monkeypatch, capsys, centre):
    """`h4pin view --load ... --out PAGE`: one compliance call for the pose (the ellipsoid and the
    deflected ghost both read it), where the previous release made four."""
    from h4pin.io import viewer
    from h4pin.stiffness import deflection

    calls = _counting(monkeypatch, [api, viewer, deflection])
    code, out, err = run_cli_in_process(["view", "--load", "0", "0", "-10", "--out", str(tmp_path / "v.html")],
                                        monkeypatch, capsys)
    assert code == 0, err
    assert calls == [(4,)], calls
    proto = h4pin.load("prototype")
    k = api.compliance(proto, centre, "paper").matrix  # the CLI's default model, computed here apart
    dd = np.linalg.norm(k[:3, :3] @ [0.0, 0.0, -10.0]) * 1e6
    assert f"true |dD| = {dd:.1f} um" in out


def test_a_mechanism_scene_with_a_load_computes_the_compliance_once(monkeypatch, no_process_left):
    """scene.show(mech, ..., load=): one Mechanism.compliance call (the output's and every joint's
    together), from which the ellipsoid and the ghost are drawn; the drawn ellipsoid's radii are
    those of a separate call for the output alone."""
    from h4pin.mechanism import Mechanism, scene

    five = Mechanism.from_urdf(ROBOTS / "5bar_linkage_iso3d" / "robot.urdf")
    q = five.assemble()
    springs = {"mot1": 2.0e3, "mot2": 3.0e3}
    block = five.compliance(q, springs, ["closedloop3D_1B"])[:3, :3]
    calls = []
    real = Mechanism.compliance

    def counted(self, *args, **kwargs):
        calls.append(len(args[2]))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Mechanism, "compliance", counted)
    with scene.show(five, q, springs, "closedloop3D_1B", load=[0.0, -5.0, 0.0], scale=1.0) as s:
        legend = " ".join(s.legend)
    assert len(calls) == 1 and calls[0] == 1 + five.model.njoints - 1, calls
    radii = np.linalg.eigvalsh(block) * 1e6
    assert f"radii {', '.join(f'{v:.3g}' for v in radii)} um/N" in legend


@pytest.mark.parametrize("model", ["paper", "consistent"])
def test_the_deflection_of_a_given_compliance_equals_the_computed_one(proto, centre, model):
    """deflection(..., result=R) uses R and gives what deflection computes by itself; a result of
    another model is refused by name."""
    from h4pin.stiffness.deflection import deflection

    res = api.compliance(proto, centre, model)
    got, ref = deflection(proto, centre, [1.0, -2.0, 3.0], model, result=res), deflection(proto, centre,
                                                                                          [1.0, -2.0, 3.0], model)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    other = "consistent" if model == "paper" else "paper"
    with pytest.raises(h4pin.ParameterError, match="model"):
        deflection(proto, centre, [1.0, 0.0, 0.0], other, result=res)
