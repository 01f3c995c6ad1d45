# SPDX-License-Identifier: Apache-2.0
"""Where numba caches h4pin's compiled functions, and when a cached one is stale.

Where: beside the code when that folder is writable (the usual case: a venv or a checkout), else
in a per-user folder under the temporary directory (a read-only system or container install,
where numba would otherwise refuse to import the package: "cannot cache function ...: no locator
available"). ``NUMBA_CACHE_DIR``, when set, always wins.

When: numba stamps a cached function with its own source file alone, but h4pin's compiled
pipeline freezes constants of other modules (the packed layouts of ``stiffness/packed.py``, the
element codes of ``description/elements.py``, ``SINGULAR_COND`` of ``verdicts.py``): a checkout
that changed one of them but not ``pipeline.py`` would run the old code from the cache, silently.
:class:`_Locator` stamps every h4pin function with its file and every h4pin module that file
imports, following imports through the modules that define compiled
functions (:func:`sources`).

:func:`configure` is called once, by ``h4pin/__init__.py``, before any compiled function is
defined."""

from __future__ import annotations

import ast
import functools
import hashlib
import os
import tempfile
from pathlib import Path

#: The packages whose modules define cached numba functions.
_COMPILED = ("kinematics", "stiffness")


def _writable(folder: Path) -> bool:
    target = folder / "__pycache__"
    return os.access(target if target.is_dir() else folder, os.W_OK)


_ROOT = Path(__file__).resolve().parent


def _module_file(name: str) -> Path | None:
    """The source file of h4pin module ``name`` (dotted), or None if it is not one."""
    parts = name.split(".")
    if parts[0] != "h4pin":
        return None
    base = _ROOT.joinpath(*parts[1:])
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


@functools.cache
def _imports(path: Path) -> tuple[Path, ...]:
    """The h4pin modules a source file imports, anywhere in it: ``import`` of a dotted h4pin
    module, ``from`` one of its names, or ``from`` a package of its submodules."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [_module_file(alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            submodules = [_module_file(f"{node.module}.{alias.name}") for alias in node.names]
            found += submodules
            if None in submodules:  # a name defined in the module itself
                found.append(_module_file(node.module))
    return tuple(sorted({f for f in found if f is not None and f != path}))


def _compiles(path: Path) -> bool:
    return "njit" in path.read_text()


def sources(path: Path) -> tuple[Path, ...]:
    """The files whose content a compiled function of ``path`` may depend on: ``path``, the h4pin
    modules it imports, and, through every module that defines compiled functions, theirs."""
    seen, todo = {path}, [path]
    while todo:
        current = todo.pop()
        for dep in _imports(current):
            if dep not in seen:
                seen.add(dep)
                if _compiles(dep):
                    todo.append(dep)
    return tuple(sorted(seen))


def stamp(path: Path) -> str:
    """A content hash of :func:`sources` of ``path`` (what :class:`_Locator` adds to numba's)."""
    files = sources(path)
    return _hash(tuple((f, f.stat().st_mtime_ns, f.stat().st_size) for f in files), _ROOT)


@functools.cache
def _hash(files: tuple[tuple[Path, int, int], ...], root: Path) -> str:
    """sha256 of the files' names and contents (memoised on their mtimes and sizes, as numba's)."""
    digest = hashlib.sha256()
    for source, _, _ in files:
        digest.update(str(source.relative_to(root)).encode() + b"\0" + source.read_bytes() + b"\0")
    return digest.hexdigest()


def _install_locator() -> bool:
    """Put :class:`_Locator` first in numba's locators (for h4pin's files only); False when this
    numba's caching internals are not the ones it was written against."""
    try:
        from numba.core import caching
    except ImportError:
        return False
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)  # numba >= 0.59 / older
    base = getattr(caching, "_CacheLocator", None)
    if impl is None or base is None or not isinstance(getattr(impl, "_locator_classes", None), list):
        return False
    if any(getattr(c, "_h4pin", False) for c in impl._locator_classes):
        return True

    class _Locator(base):
        """numba's own locator for an h4pin file, with :func:`stamp` added to its source stamp."""

        _h4pin = True

        def __init__(self, inner: object, path: Path):
            self._inner = inner
            self._path = path

        def ensure_cache_path(self) -> None:
            self._inner.ensure_cache_path()

        def get_cache_path(self) -> str:
            return self._inner.get_cache_path()

        def get_source_stamp(self) -> object:
            return (self._inner.get_source_stamp(), stamp(self._path))

        def get_disambiguator(self) -> str:
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func: object, py_file: str) -> object:
            path = Path(py_file).resolve()
            if _ROOT not in path.parents:
                return None
            for other in impl._locator_classes:
                if other is not cls:
                    inner = other.from_function(py_func, py_file)
                    if inner is not None:
                        return cls(inner, path)
            return None

    impl._locator_classes.insert(0, _Locator)
    return True


def configure() -> str | None:
    """Install the stamping locator, and redirect numba's cache if h4pin's own folders cannot
    hold it; returns the folder used instead, or None when nothing had to change."""
    _install_locator()
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    root = _ROOT
    if all(_writable(root / sub) for sub in _COMPILED):
        return None
    import numba

    folder = os.path.join(tempfile.gettempdir(), f"h4pin-numba-cache-{os.getuid() if hasattr(os, 'getuid') else 0}")
    numba.config.CACHE_DIR = folder
    return folder
