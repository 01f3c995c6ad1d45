# SPDX-License-Identifier: Apache-2.0
"""Identification against Table II (h4pin.studies.identify) and the fitted variant."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from h4pin import load
from h4pin.cli import app
from h4pin.kinematics.closed_form import CENTRE_Q
from h4pin.stiffness.api import compliance
from h4pin.studies import gap, identify


def built_table(values: dict[str, float]) -> np.ndarray:
    """Table II of a robot built with the values (no linear-scaling shortcut), at p for a force at p'."""
    h4 = load(identify.robot_params(values))
    res = compliance(h4, h4.forward_geometry(CENTRE_Q))
    return res.at([values["p_x"], values["p_y"], values["p_z"]], [values["f_x"], values["f_y"], values["f_z"]])


def test_model_table_equals_a_robot_built_with_the_values():
    rng = np.random.default_rng(7)
    for _ in range(3):
        v = {n: p.lower + rng.uniform(0.1, 0.9) * (p.upper - p.lower) for n, p in identify.PARAMETERS.items()}
        ours, theirs = identify.table(v), built_table(v)
        assert np.max(np.abs(ours - theirs)) < 1e-10 * np.max(np.abs(theirs))


def test_linear_fit_recovers_the_scales_and_their_closed_form_uncertainty():
    """Tilt and axial enter linearly: the fit recovers them from a synthetic table, and its SVD
    uncertainty equals sigma sqrt(diag((A^T A)^-1)) of the linear least squares."""
    truth = {n: p.default for n, p in identify.PARAMETERS.items()} | {"tilt": 3.0, "axial": 1.3, "p_x": 0.03}
    target = built_table(truth)
    sigma = 1e-6
    fit = identify.fit(target, ("tilt", "axial"), sigma=sigma, starts=1, fixed={"p_x": 0.03})
    assert fit.values["tilt"] == pytest.approx(3.0, rel=1e-6)
    assert fit.values["axial"] == pytest.approx(1.3, rel=1e-6)
    assert np.max(np.abs(fit.residual)) < 1e-6
    base = {n: p.default for n, p in identify.PARAMETERS.items()} | {"p_x": 0.03}
    zero = built_table(base | {"tilt": 0.0 + 1e-9, "axial": 1e-9})
    cols = [(built_table(base | {"tilt": 1.0, "axial": 1e-9}) - zero).ravel() / sigma,
            (built_table(base | {"tilt": 1e-9, "axial": 1.0}) - zero).ravel() / sigma]
    a = np.column_stack(cols)
    std = np.sqrt(np.diag(np.linalg.inv(a.T @ a)))
    np.testing.assert_allclose([fit.std["tilt"], fit.std["axial"]], std, rtol=1e-5)
    assert fit.condition == pytest.approx(np.linalg.cond(a * [9.5, 1.5]), rel=1e-5)


def test_measured_match_is_current_and_saturated():
    """FITTED is where the one-point fit lands: re-fitting from it cannot lower the cost, which is
    the floor set by the table's asymmetry (a one-point model is symmetric). It is saturated: more
    parameters than the 6 numbers of the symmetric part, two exactly null directions."""
    m, sigma = gap.MEASURED, gap.noise_from_asymmetry()[0]
    floor = 0.5 * np.sum(((m - m.T) / 2 / sigma) ** 2)
    model = built_table(identify.fitted_values())
    cost = 0.5 * np.sum(((model - m) / sigma) ** 2)
    assert cost - floor < 0.05  # the bounds (axial, ck_dy) cost 0.017 above the floor
    again = identify.fit(m, identify.ONE_POINT_FIT, starts=1, same_point=True, start=identify.FITTED)
    assert cost - again.cost < 1e-3
    assert np.max(np.abs(again.residual)) < 1.5
    for name in ("p_x", "p_y", "axial", "ck_dy"):  # identifiable or on a bound
        assert abs(again.values[name] - identify.FITTED[name]) <= identify.FITTED_ROUNDING[name] * 1.01
    assert len(identify.ONE_POINT_FIT) > len(identify.SYMMETRIC_ENTRIES)
    assert np.sum(again.singular_values < 1e-6 * again.singular_values[0]) >= 2
    # never the default: the stated prototype is far from the measured table
    default = built_table({n: p.default for n, p in identify.PARAMETERS.items()})
    assert np.max(np.abs(default - m)) > 5 * sigma


def test_noise_from_the_antisymmetric_part_by_hand():
    """a_xy - a_yx = 3, a_xz - a_zx = -4, a_yz - a_zy = 1 um/N: sigma^2 = (9 + 16 + 1) / 6."""
    sigma, dof = identify.noise_from_antisymmetry()
    assert dof == 3 and sigma == pytest.approx(np.sqrt(26.0 / 6.0) * 1e-6, rel=1e-12)
    data, noise = identify.symmetric_data()
    np.testing.assert_allclose(data * 1e6, [51, 15, 9, -1.5, 13, -0.5], atol=1e-12)
    np.testing.assert_allclose(noise[3:], noise[:3] / np.sqrt(2.0), rtol=1e-15)


def test_model_selection_numbers_are_consistent():
    """chi^2, dof and AIC of each candidate recomputed from its fitted values through the table of
    the robot built with them; a leave-one-out prediction is never better than the in-sample fit
    of the same entry (the entry left out no longer pulls the fit)."""
    candidates = {k: identify.CANDIDATES[k] for k in ("point", "point_xz+tilt+axial")}
    rows = identify.select(candidates, starts=3, loo_starts=2)
    assert [r.aic for r in rows] == sorted(r.aic for r in rows)
    data, noise = identify.symmetric_data()
    for r in rows:
        v = {n: p.default for n, p in identify.PARAMETERS.items()} | r.values
        v |= {"f_x": v["p_x"], "f_y": v["p_y"], "f_z": v["p_z"]}
        t = built_table(v)
        sym = np.array([0.5 * (t[i, j] + t[j, i]) for i, j in identify.SYMMETRIC_ENTRIES])
        z = (sym - data) / noise
        assert r.chi2 == pytest.approx(np.sum(z**2), rel=1e-6)
        assert r.dof == 6 - r.k and r.aic == pytest.approx(r.chi2 + 2 * r.k)
        assert np.all(np.abs(r.loo) >= np.abs(z) - 1e-6)
        assert set(r.at_bound) <= set(r.names)
    # the smaller set does not meet the table within its noise: chi^2 far above its dof
    assert all(r.chi2 > 3 * r.dof for r in rows)


def test_computed_table_is_met_within_rounding_by_the_robot_quantities():
    """Started in the region found by the gap sweep (C_k ~ (30, 20) mm, tilt ~4.5), the fit of the
    computed table meets all entries within rounding (checked on a robot built with the values)."""
    start = {"ck_dx": 0.03, "ck_dy": 0.015, "tilt": 4.5}
    fit = identify.fit(gap.COMPUTED, identify.COMPUTED_FIT, starts=1, start=start)
    built = built_table(fit.values)
    assert np.max(np.abs(built - gap.COMPUTED)) <= gap.ROUNDING
    assert len(fit.singular_values) == 5 and fit.singular_values[-1] < 1e-6 * fit.singular_values[0]  # 4 data


def test_cli_table2_fitted_prints_the_four_tables():
    out = CliRunner().invoke(app, ["table2", "--measured-match"])
    assert out.exit_code == 0, out.output
    h4 = load("measured_match")
    at_p = compliance(h4, h4.forward_geometry(CENTRE_Q)).at(identify.fitted_point()) * 1e6
    row = next(line for line in out.output.splitlines() if line.strip().startswith("dx"))
    numbers = [float(v) for v in row.split()[1:]]
    assert len(numbers) == 12
    np.testing.assert_allclose(numbers[3:6], np.round(at_p[0], 1), atol=1e-9)
    np.testing.assert_allclose(numbers[9:12], gap.MEASURED[0] * 1e6)


def test_fitted_is_a_named_variant_never_the_default():
    """The shipped h4_measured_match.urdf is the robot identify.fitted_params() builds; load() and the
    package import stay the prototype and do not import the identification (scipy.optimize)."""
    import subprocess
    import sys

    import h4pin

    assert "measured_match" in h4pin.VARIANTS
    shipped, built = load("measured_match"), load(identify.fitted_params())
    x = shipped.forward_geometry(CENTRE_Q)
    np.testing.assert_allclose(compliance(shipped, x).matrix, compliance(built, x).matrix, rtol=1e-12, atol=0)
    assert load().source.endswith("h4_prototype.urdf")
    assert not np.allclose(compliance(load(), x).translational, compliance(shipped, x).translational, rtol=0.05)
    code = "import sys, h4pin; print('h4pin.studies.identify' in sys.modules, 'scipy.optimize' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
