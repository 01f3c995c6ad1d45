# SPDX-License-Identifier: Apache-2.0
"""The H4 variants as robot_descriptions-style description modules.

One module per shipped variant, ``h4_<variant>_description`` in :mod:`h4pin.descriptions` (see
:data:`MODULES`), with the attributes robot_descriptions' modules have: ``PACKAGE_PATH``,
``REPOSITORY_PATH``, ``URDF_PATH``, ``SRDF_PATH`` and ``MJCF_PATH`` (strings). They point at the
files shipped with the running h4pin: inside the installed package (``h4pin/urdf``,
``h4pin/srdf``, ``h4pin/mjcf``) or, in a source tree, the repository's ``urdf/``, ``srdf/`` and
``mjcf/``. Importing one reads no file; ``MJCF_PATH`` may name a file that is not there
(:func:`paths` says so with ``exists``).

robot_descriptions' loaders (``robot_descriptions.loaders.pinocchio``, ``.yourdfpy``, ``.mujoco``)
take a *name* and import ``robot_descriptions.<name>``; they have no registry for descriptions of
other packages. :func:`register_robot_descriptions` makes h4pin's modules importable under those
names (entries of ``sys.modules``, which ``importlib.import_module`` returns as they are), so that
``load_robot_description("h4_prototype_description")`` works. It is not a documented plug-in point
of robot_descriptions, but the loaders need nothing else (tested with robot_descriptions 3.3).
See ``docs/descriptions.md``.
"""

from __future__ import annotations

import importlib
import sys
from importlib import resources
from pathlib import Path
from typing import NamedTuple

from h4pin.description.params import VARIANTS
from h4pin.errors import ParameterError

#: The module name of each variant's description (robot_descriptions' ``<robot>_description``).
MODULES: dict[str, str] = {variant: f"h4_{variant}_description" for variant in VARIANTS}


class DescriptionPaths(NamedTuple):
    """The paths of one variant's files (strings, as robot_descriptions' modules have them)."""

    PACKAGE_PATH: str
    REPOSITORY_PATH: str
    URDF_PATH: str
    SRDF_PATH: str
    MJCF_PATH: str


def data_dir(kind: str) -> Path:
    """Folder of the shipped ``kind`` files (``urdf``, ``srdf`` or ``mjcf``): inside the installed
    package, else the repository's top-level folder (a source tree)."""
    if kind not in ("urdf", "srdf", "mjcf"):
        raise ParameterError(f"kind: expected 'urdf', 'srdf' or 'mjcf', got {kind!r}")
    packaged = Path(str(resources.files("h4pin"))) / kind
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent.parent / kind


def paths(variant: str) -> DescriptionPaths:
    """The description paths of ``variant``. ``REPOSITORY_PATH`` and ``PACKAGE_PATH`` are the folder
    holding ``urdf/`` (the package, or the repository); the H4's geometry is primitives, so no mesh
    is looked up there.

    Raises:
        ParameterError: unknown variant (the message lists them).
    """
    if variant not in VARIANTS:
        raise ParameterError(f"variant: unknown H4 variant {variant!r}; available: {', '.join(sorted(VARIANTS))}")
    urdf = data_dir("urdf")
    stem = f"h4_{variant}"
    return DescriptionPaths(PACKAGE_PATH=str(urdf.parent), REPOSITORY_PATH=str(urdf.parent),
                            URDF_PATH=str(urdf / f"{stem}.urdf"), SRDF_PATH=str(data_dir("srdf") / f"{stem}.srdf"),
                            MJCF_PATH=str(data_dir("mjcf") / f"{stem}.xml"))


def register_robot_descriptions() -> tuple[str, ...]:
    """Make each description module importable as ``robot_descriptions.<name>`` (the names of
    :data:`MODULES`), for robot_descriptions' loaders; returns the names. Idempotent; an existing
    ``robot_descriptions`` module of the same name is never replaced.

    Raises:
        MissingExtraError: robot_descriptions is not installed.
    """
    from h4pin.extras import require

    require("robot_descriptions", extra="descriptions", what="loading the H4 through robot_descriptions")
    package = importlib.import_module("robot_descriptions")
    names = []
    for name in MODULES.values():
        key = f"robot_descriptions.{name}"
        if key not in sys.modules:
            sys.modules[key] = importlib.import_module(f"{__name__}.{name}")
            setattr(package, name, sys.modules[key])
        names.append(name)
    return tuple(names)


__all__ = ["MODULES", "DescriptionPaths", "data_dir", "paths", "register_robot_descriptions"]
