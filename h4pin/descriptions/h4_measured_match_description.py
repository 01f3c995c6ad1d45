# SPDX-License-Identifier: Apache-2.0
"""The H4 'measured_match' variant, robot_descriptions-style: PACKAGE_PATH, REPOSITORY_PATH, URDF_PATH,
SRDF_PATH, MJCF_PATH (see :mod:`h4pin.descriptions`)."""

from h4pin.descriptions import paths

PACKAGE_PATH, REPOSITORY_PATH, URDF_PATH, SRDF_PATH, MJCF_PATH = paths("measured_match")

__all__ = ["MJCF_PATH", "PACKAGE_PATH", "REPOSITORY_PATH", "SRDF_PATH", "URDF_PATH"]
