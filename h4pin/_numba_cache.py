# SPDX-License-Identifier: Apache-2.0
"""Where numba caches h4pin's compiled functions, and when a cached one is stale.

Where: in a per-user folder keyed by the source, not by the install location:
``$XDG_CACHE_HOME/h4pin/numba`` (``~/.cache/h4pin/numba`` when ``XDG_CACHE_HOME`` is not set),
or ``$NUMBA_CACHE_DIR/h4pin`` when ``NUMBA_CACHE_DIR`` is set, or, when neither can be written (a
read-only home), ``h4pin-numba-cache-<uid>`` under the temporary directory. Inside it, each source
file's functions live in ``numba-<version>-numpy-<major.minor>/<module>/<stamp>``, where the stamp is a content
hash (below): reinstalling the same source (``pip install .`` twice, a second venv, a copy of the
checkout) finds the kernels the first install compiled, instead of compiling them again for two
minutes, and two different sources (a branch, a release) keep their own folders side by side.
numba's own locators put the cache beside the code (thrown away with it by a reinstall) and key
it by the file's absolute path. The folder may be deleted at any time: h4pin compiles again.

When: numba stamps a cached function with its own source file alone (its modification time and
size up to numba 0.67, its content since 0.68), but h4pin's compiled pipeline freezes constants of
other modules (the packed layouts of ``stiffness/packed.py``, the element codes of
``description/elements.py``, ``SINGULAR_COND`` of ``verdicts.py``): a checkout that changed one
of them but not ``pipeline.py`` would run the old code from the cache, silently. :class:`_Locator`
stamps every h4pin function with the content of its file and of every h4pin module that file
imports, following imports through the modules that define compiled functions (:func:`sources`).

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
    """A content hash of :func:`sources` of ``path`` (the source stamp of :class:`_Locator`, and its folder)."""
    files = sources(path)
    return _hash(tuple((f, f.stat().st_mtime_ns, f.stat().st_size) for f in files), _ROOT)


@functools.cache
def _hash(files: tuple[tuple[Path, int, int], ...], root: Path) -> str:
    """sha256 of the files' names and contents (memoised on their mtimes and sizes, as numba's)."""
    digest = hashlib.sha256()
    for source, _, _ in files:
        digest.update(str(source.relative_to(root)).encode() + b"\0" + source.read_bytes() + b"\0")
    return digest.hexdigest()


_folder: Path | None = None


def _usable(folder: Path) -> bool:
    """Whether ``folder`` exists or can be made, and takes a file."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def candidates() -> list[Path]:
    """The folders h4pin's compiled code may go to, first choice first (see the module's text)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return [Path(os.environ["NUMBA_CACHE_DIR"]) / "h4pin"]
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    user = Path(xdg) if os.path.isabs(xdg) else Path(os.path.expanduser("~")) / ".cache"
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return [user / "h4pin" / "numba", Path(tempfile.gettempdir()) / f"h4pin-numba-cache-{uid}"]


def folder() -> Path | None:
    """The folder h4pin's compiled code is cached in (None until :func:`configure` found one)."""
    return _folder


def cache_path(path: Path) -> Path:
    """Where the compiled functions of h4pin source file ``path`` are cached: under
    :func:`folder`, by numba's and numpy's versions, module and :func:`stamp` (not by the install
    location)."""
    import numba
    import numpy

    module = ".".join(path.relative_to(_ROOT).with_suffix("").parts)
    versions = f"numba-{numba.__version__}-numpy-{'.'.join(numpy.__version__.split('.')[:2])}"  # venvs apart
    return _folder / versions / module / stamp(path)[:20]


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
        """An h4pin file's functions cached under :func:`cache_path`, stamped by content (:func:`stamp`)."""

        _h4pin = True

        def __init__(self, path: Path, lineno: int):
            self._path = path
            self._lineno = lineno
            self._cache_path = str(cache_path(path))

        def get_cache_path(self) -> str:
            return self._cache_path

        def get_source_stamp(self) -> object:
            return stamp(self._path)

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: object, py_file: str) -> object:
            path = Path(py_file).resolve()
            if _folder is None or _ROOT not in path.parents or not path.is_file():
                return None
            try:
                self = cls(path, py_func.__code__.co_firstlineno)
                self.ensure_cache_path()
            except OSError:  # numba's own locators then
                return None
            return self

    impl._locator_classes.insert(0, _Locator)
    return True


def configure() -> str | None:
    """Choose the cache folder (:func:`candidates`: the first that can be written) and install
    the locator that puts h4pin's compiled code there; returns the folder. With a numba whose
    caching internals differ (no locator), numba's own places are used, moved to a per-user
    temporary folder when h4pin's own folders cannot be written; returns that folder then, or
    None when nothing had to change."""
    global _folder
    _folder = next((f for f in candidates() if _usable(f)), None)
    if _folder is not None and _install_locator():
        return str(_folder)
    _folder = None
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    root = _ROOT
    if all(_writable(root / sub) for sub in _COMPILED):
        return None
    import numba

    folder = os.path.join(tempfile.gettempdir(), f"h4pin-numba-cache-{os.getuid() if hasattr(os, 'getuid') else 0}")
    numba.config.CACHE_DIR = folder
    return folder
