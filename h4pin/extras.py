# SPDX-License-Identifier: Apache-2.0
"""Optional dependencies: which extra brings what, and one clear error when one is missing.

The core install (loading, compliance, Table II, the viewer) needs none of them. The extras:

* ``studies``: atlases and design sweeps (xarray, zarr, Dask, h5netcdf/h5py for ``.nc`` files);
* ``interop``: Gepetto's toolbox-parallel-robots; ``erd``: example-robot-data; ``mujoco``: MuJoCo;
* ``test``: the test suite (it includes ``studies``).
"""

from __future__ import annotations

import importlib

from h4pin.errors import H4Error


class MissingExtraError(H4Error, ImportError):
    """An optional dependency is not installed; the message names the extra that brings it."""


def require(*modules: str, extra: str, what: str) -> None:
    """Import ``modules`` or raise :class:`MissingExtraError` naming ``extra`` (one line)."""
    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError:
            raise MissingExtraError(f"{what} needs the optional '{extra}' dependencies ({name} is not installed): "
                                    f"pip install 'h4pin[{extra}]'") from None


__all__ = ["MissingExtraError", "require"]
