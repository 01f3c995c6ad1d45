# SPDX-License-Identifier: Apache-2.0
"""Where numba caches h4pin's compiled functions: beside the code when that folder is writable
(the usual case: a venv or a checkout), else in a per-user folder under the temporary directory
(a read-only system or container install, where numba would otherwise refuse to import the
package: "cannot cache function ...: no locator available"). ``NUMBA_CACHE_DIR``, when set,
always wins. Called once, by ``h4pin/__init__.py``, before any compiled function is defined."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

#: The packages whose modules define cached numba functions.
_COMPILED = ("kinematics", "stiffness")


def _writable(folder: Path) -> bool:
    target = folder / "__pycache__"
    return os.access(target if target.is_dir() else folder, os.W_OK)


def configure() -> str | None:
    """Redirect numba's cache if h4pin's own folders cannot hold it; returns the folder used
    instead, or None when nothing had to change."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    root = Path(__file__).resolve().parent
    if all(_writable(root / sub) for sub in _COMPILED):
        return None
    import numba

    folder = os.path.join(tempfile.gettempdir(), f"h4pin-numba-cache-{os.getuid() if hasattr(os, 'getuid') else 0}")
    numba.config.CACHE_DIR = folder
    return folder
