# SPDX-License-Identifier: Apache-2.0
"""h4pin's version, the one place it is written (``pyproject.toml`` reads it; ``CHANGELOG.md``)."""

__version__ = "0.2.0"
