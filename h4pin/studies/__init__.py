# SPDX-License-Identifier: Apache-2.0
"""Studies built on :func:`h4pin.compliance`: Table II, gap analysis, identification, atlases,
design sweeps, tolerances and the serial-arm comparison (``docs/architecture.md``).
"""
