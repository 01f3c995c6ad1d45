# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures: the shipped robots, the centre pose, a deterministic set of poses, and a
check that a test leaves none of the processes it started running."""

from __future__ import annotations

import os
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
