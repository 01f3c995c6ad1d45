# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures: the shipped robots, the centre pose and a deterministic set of poses."""

from __future__ import annotations

import numpy as np
import pytest

import h4pin
from h4pin.table2 import centre_pose


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
