# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures: the shipped robots, the centre pose, a deterministic set of poses, and a
check that a test leaves none of the processes it started running."""

from __future__ import annotations

import os
import re
import signal
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

# Compiled code at first use, in this process (no numpy fallback, no background warm-up): the
# suite's numbers do not depend on when a warm-up finishes. tests/test_jit.py covers the fallback.
os.environ["H4PIN_WARMUP"] = "inline"

import h4pin  # noqa: E402
from h4pin.kinematics.closed_form import centre_pose  # noqa: E402

_WARMUP: list = []


def pytest_sessionstart(session):
    """With numba's cache not yet full (a fresh clone), compile it on the second core: one
    ``h4pin warmup`` process beside the suite (the machines here have two cores; the suite runs on
    one). A test still compiles what it needs when the warm-up has not got there yet, so the
    numbers never depend on it; the warm-up only saves the suite about a third of its compile.
    ``H4PIN_TEST_WARMUP=0`` turns it off."""
    import subprocess
    import sys

    from h4pin import _jit, warmup

    if os.environ.get("H4PIN_TEST_WARMUP") == "0" or all(g.cached() for g in warmup.gates()) or _jit.running():
        return
    _WARMUP.append(subprocess.Popen([sys.executable, "-m", "h4pin.warmup", "--lock", _jit.lock_path(), "--quiet"],
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))


def pytest_sessionfinish(session, exitstatus):
    """The suite's warm-up ends with it (a SIGTERM ends its child too and releases the lock)."""
    for proc in _WARMUP:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except Exception:  # noqa: BLE001 - last resort
                proc.kill()


@pytest.fixture(scope="session")
def proto() -> h4pin.H4:
    return h4pin.load("prototype")


@pytest.fixture(scope="session")
def sym() -> h4pin.H4:
    return h4pin.load("symmetric")


@pytest.fixture(scope="session")
def centre(proto) -> np.ndarray:
    return centre_pose(proto)


def sample_poses(h4: h4pin.H4, n: int, seed: int = 0) -> np.ndarray:
    """n reachable poses around the workspace centre (x, y within 12 cm, theta within 0.5 rad)."""
    rng = np.random.default_rng(seed)
    c = centre_pose(h4)
    out = []
    while len(out) < n:
        x = c + rng.uniform(-1, 1, 4) * [0.12, 0.12, 0.08, 0.5]
        if np.all(np.isfinite(h4.inverse_geometry(x, on_error="nan"))):
            out.append(x)
    return np.array(out)


@pytest.fixture(scope="session")
def poses(proto) -> np.ndarray:
    return sample_poses(proto, 12)


PROCESS_TAG = "H4PIN_TEST_PROCESS_TAG"


def tagged_processes(tag: str) -> dict[int, str]:
    """Live processes (pid -> command line) whose environment holds ``PROCESS_TAG=tag``.

    Every process a test starts inherits the tag, even after its parent died and it was
    re-parented, so this finds exactly the test's own processes, not the machine's."""
    needle = f"{PROCESS_TAG}={tag}".encode()
    out = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            if needle not in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0"):
                continue
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
                continue  # exited, not yet reaped by its parent
            out[int(pid)] = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # gone meanwhile, or not ours to read
            continue
    return out


@pytest.fixture
def no_process_left(monkeypatch):
    """Tag the processes this test starts; afterwards none of them may still run (10 s grace).

    Yields the tag. Leftovers are killed (they are this test's own) and the test fails."""
    tag = uuid.uuid4().hex
    monkeypatch.setenv(PROCESS_TAG, tag)
    yield tag
    deadline = time.monotonic() + 10
    while (left := tagged_processes(tag)) and time.monotonic() < deadline:
        time.sleep(0.1)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    assert not left, f"processes left running: {left}"


def assert_solve_close(actual, desired, cond: float, n: int, scale: float | None = None) -> None:
    """``actual`` equals ``desired`` within the forward-error bound of an n x n linear solve.

    Two routes through a solve with a matrix of condition number ``cond`` may differ by about
    ``n eps cond`` relative to the size of the result, and how much of that a run shows depends on
    the CPU's instruction set (FMA, SIMD width) and the BLAS kernels it picks. A fixed absolute
    tolerance passes on one CPU and fails on another; this one holds on any IEEE double machine
    and still fails on an error of a frame, a sign or a missed closure (orders of magnitude more).
    ``scale``: the size of the compared quantity where ``desired`` does not show it (a residual
    that should be zero); by default the largest entry of ``desired``."""
    desired = np.asarray(desired)
    if scale is None:
        scale = np.max(np.abs(desired))
    tol = n * np.finfo(float).eps * cond * scale
    np.testing.assert_allclose(actual, desired, rtol=0, atol=tol)


def run_cli_in_process(argv: list[str], monkeypatch, capsys) -> tuple[int, str, str]:
    """``h4pin <argv>`` in this process (``h4pin.cli.main``): exit code, stdout, stderr."""
    import sys

    from h4pin import cli

    monkeypatch.setattr(sys, "argv", ["h4pin", *argv])
    with pytest.raises(SystemExit) as info:
        cli.main()
    out = capsys.readouterr()
    return info.value.code, out.out, out.err

#: Cases of 2 s or more each on the project's 2-core VM (pytest --durations, this release): they
#: run with the slow cases (``pytest -m slow``, once in CI) so that the README's test command stays
#: within a few minutes there, compile included. Each is a whole command, a browser page, a server
#: or a sweep over every variant; a cheaper case of the same code stays in the default run.
SLOW_IDS = frozenset({
    'tests/test_atlas.py::test_a_killed_stream_resumes_from_its_blocks',
    'tests/test_atlas.py::test_cli_writes_the_atlas',
    'tests/test_atlas.py::test_maps_have_one_figure_per_quantity',
    'tests/test_atlas.py::test_streamed_atlas_equals_the_one_in_memory',
    'tests/test_cli.py::test_a_user_file_is_kept_unless_overwrite[export]',
    'tests/test_cli.py::test_cli_errors_are_one_line[args1-singular]',
    'tests/test_cli.py::test_table2_prints_the_computed_block',
    'tests/test_core.py::test_elements_against_the_independent_routes[measured_match]',
    'tests/test_core.py::test_elements_against_the_independent_routes[prototype]',
    'tests/test_core.py::test_elements_against_the_independent_routes[symmetric]',
    'tests/test_core.py::test_elements_against_the_independent_routes[toleranced]',
    'tests/test_core.py::test_one_robot_shared_by_eight_threads',
    'tests/test_cycle.py::test_dynamic_deflection_of_a_harmonic_load_is_the_textbook_response',
    'tests/test_elastic_cycle.py::test_a_slow_cycle_is_quasi_static_and_a_fast_one_is_not',
    'tests/test_elastic_cycle.py::test_cli_prints_the_elastic_cycle',
    'tests/test_elements.py::test_element_terms_equal_finite_differences[2]',
    'tests/test_elements.py::test_element_terms_equal_finite_differences[7]',
    'tests/test_elements.py::test_forearm_out_of_plane_on_every_route',
    'tests/test_elements.py::test_on_stays_symmetric_and_equals_the_deformed_route',
    'tests/test_elements.py::test_per_element_values_on_a_toleranced_robot_with_tilted_joint_axes',
    'tests/test_erd.py::test_import_time_registration_in_a_fresh_interpreter',
    'tests/test_frequencies.py::test_every_frequency_equals_the_pinocchio_route[measured_match-bare-elements]',
    'tests/test_frequencies.py::test_every_frequency_equals_the_pinocchio_route[prototype-bare-elements]',
    'tests/test_frequencies.py::test_every_frequency_equals_the_pinocchio_route[symmetric-bare-elements]',
    'tests/test_frequencies.py::test_every_frequency_equals_the_pinocchio_route[symmetric-payload-elements]',
    'tests/test_identify.py::test_computed_table_is_met_within_rounding_by_the_robot_quantities',
    'tests/test_identify.py::test_measured_match_is_current_and_saturated',
    'tests/test_limits.py::test_a_scheduler_that_is_not_dask_is_refused_in_seconds[http_server]',
    'tests/test_mechanism.py::test_the_viewer_draws_any_mechanism_and_its_ellipsoid',
    'tests/test_mjcf.py::test_export_cli_writes_a_loadable_file',
    'tests/test_mjcf_elastic.py::test_first_frequency_equals_modes',
    'tests/test_mjcf_elastic.py::test_soft_closures_spoil_the_springs',
    'tests/test_mjcf_elastic.py::test_static_deflection_with_every_element_equals_the_compliance[centre]',
    'tests/test_mjcf_elastic.py::test_static_deflection_with_every_element_equals_the_compliance[off-centre]',
    'tests/test_mjcf_elastic.py::test_text_round_trip_and_cli',
    'tests/test_mjcf_writer.py::test_static_displacement_equals_the_compliance[5bar_linkage_iso3d]',
    'tests/test_mjcf_writer.py::test_static_displacement_equals_the_compliance[5bar_with_beams]',
    'tests/test_packaging.py::test_scripts_write_world_readable_files',
    'tests/test_pipeline.py::test_bar_interpenetration_status',
    'tests/test_pipeline.py::test_compiled_code_is_cached',
    'tests/test_readme.py::test_printed_samples_match_the_commands[README.md:* .venv/bin/h4pin table2]',
    ('tests/test_readme.py::test_shell_lines_run[docs/studies.md:* .venv/bin/h4pin atlas --x -0.2 0.2 '
     '21 --y -0.2 0.2 21 --out atlas.nc --quiet]'),
    ('tests/test_readme.py::test_shell_lines_run[docs/motion.md:* .venv/bin/h4pin cycle --time 0.5 --'
     'payload 0 --payload 0.5]'),
    'tests/test_readme.py::test_shell_lines_run[docs/motion.md:* .venv/bin/h4pin modes --payload 0.5]',
    ('tests/test_readme.py::test_shell_lines_run[docs/studies.md:* .venv/bin/h4pin sweep --designs 16 '
     '--chunk 8 --out sweep.zarr --quiet]'),
    ('tests/test_readme.py::test_shell_lines_run[docs/studies.md:* .venv/bin/h4pin tolerance --robots 200 '
     '--no-sensitivity]'),
    ('tests/test_readme.py::test_shell_lines_run[docs/viewer.md:* .venv/bin/h4pin view --load 0 0 -10'
     ' --field --out h4.html]'),
    'tests/test_readme.py::test_shell_lines_run[docs/motion.md:* .venv/bin/h4pin view --mode 1 --out mode1.html]',
    'tests/test_readme.py::test_shell_lines_run[docs/viewer.md:* .venv/bin/h4pin view --variant symmetric]',
    ('tests/test_readme.py::test_shell_lines_run[README.md:* python3 -m venv .venv && .venv/bin/'
     'pip install . && .venv/bin/h4pin table2]'),
    ('tests/test_readme.py::test_shell_lines_run[docs/first_use.md:* python3 -m venv .venv && .venv/bin/'
     'pip install . && .venv/bin/h4pin table2]'),
    'tests/test_robot.py::test_a_robot_goes_to_a_process_pool',
    'tests/test_sweep.py::test_cli_sweep',
    'tests/test_sweep.py::test_packed_kernels_equal_the_canonical_route',
    'tests/test_sweep.py::test_two_dask_workers_give_the_same_numbers',
    'tests/test_tolerance.py::test_report_and_sensitivity',
    'tests/test_toolbox.py::test_inverse_kinematics_accuracy_depends_on_the_seed',
    'tests/test_urdf.py::test_every_variant_is_shipped_and_current',
    'tests/test_verdicts.py::test_sweep_of_random_poses[toleranced]',
    'tests/test_viewer_mechanism.py::test_browser_draws_the_mechanism_and_its_field',
    'tests/test_viewer.py::test_cli_bad_input_is_one_line_and_writes_nothing[args0-cannot reach]',
    'tests/test_viewer.py::test_cli_bad_input_is_one_line_and_writes_nothing[args1-singular]',
    ('tests/test_viewer.py::test_cli_bad_input_is_one_line_and_writes_nothing[args13-mode index '
     'must be an integer in 0..15]'),
    'tests/test_viewer.py::test_cli_html_must_name_a_file_in_an_existing_folder[folder]',
    'tests/test_viewer.py::test_cli_html_must_name_a_file_in_an_existing_folder[missing folder]',
    'tests/test_viewer.py::test_cli_server_stops_on_signals[2-130-None]',
    'tests/test_viewer.py::test_cli_writes_a_self_contained_page',
    'tests/test_viewer.py::test_mode_animation_moves_the_plate_by_the_mode_shape',
    'tests/test_viewer.py::test_server_stops_when_the_viewer_is_killed',
    'tests/test_viewer.py::test_view_in_process_leaves_the_callers_signal_handlers',
})


@pytest.hookimpl(tryfirst=True)  # before the mark plugin deselects by -m
def pytest_collection_modifyitems(config, items):
    for item in items:
        if re.sub(r"(README\.md|docs/\w+\.md):\d+ ", r"\1:* ", item.nodeid) in SLOW_IDS:  # page lines move
            item.add_marker(pytest.mark.slow)
