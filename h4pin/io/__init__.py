# SPDX-License-Identifier: Apache-2.0
"""Outputs and interop: the meshcat viewer, MJCF, example-robot-data, Gepetto's toolbox
(``docs/architecture.md``).
"""
