# SPDX-License-Identifier: Apache-2.0
"""Files h4pin writes: atomically (a temporary file in the same folder, then a rename, so a
failure never leaves a half-written file) and world-readable (mode 0644).

Every temporary file or folder is named ``.<name>.h4pin-tmp-<pid>-<random>`` beside its target;
one left by a process that was killed (its pid is gone) is removed the next time anything is
written to that target (:func:`clean_stale`). :func:`check_output` refuses an output path that
cannot be written, before any work is done.

The rule for existing outputs: a file is replaced (atomically); a folder is never replaced or
written into unless it is a store h4pin made for the same job (a sweep resumes its own store).
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from h4pin.errors import ParameterError

TMP_TAG = "h4pin-tmp"


def tmp_prefix(path: Path) -> str:
    """The prefix of this process's temporary files for ``path``."""
    return f".{path.name}.{TMP_TAG}-{os.getpid()}-"


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (or exists under another user)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale(path: str | Path) -> list[Path]:
    """Remove the temporary files and folders that killed processes left for ``path``; returns them."""
    path = Path(path)
    pattern = re.compile(re.escape(f".{path.name}.{TMP_TAG}-") + r"(\d+)-")
    removed = []
    if not path.parent.is_dir():
        return removed
    for entry in path.parent.iterdir():
        m = pattern.match(entry.name)
        if m and not alive(int(m.group(1))):
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)
            removed.append(entry)
    return removed


def check_output(path: str | Path, what: str, *, folder: bool = False, suffixes: tuple[str, ...] = ()) -> Path:
    """Refuse, before any work, an output that cannot be written: a wrong suffix, a missing or
    unwritable folder (tried by writing a probe file there), a folder where a file is wanted
    (``folder=False``) or a file where a folder is wanted. ``what`` names the option or argument
    in the message (:class:`h4pin.ParameterError`)."""
    path = Path(path)
    if suffixes and path.suffix not in suffixes:
        raise ParameterError(f"{what} {path}: the name must end in {' or '.join(suffixes)}")
    if not folder and path.is_dir():
        raise ParameterError(f"{what} {path} is a folder: give the path of the file to write")
    if folder and path.exists() and not path.is_dir():
        raise ParameterError(f"{what} {path} is a file: give the path of a folder")
    parent = path.parent
    if not parent.is_dir():
        raise ParameterError(f"{what} {path}: folder {parent} does not exist")
    try:
        fd, probe = tempfile.mkstemp(prefix=tmp_prefix(path), dir=parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        reason = os.strerror(exc.errno) if exc.errno else str(exc)
        if exc.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
            reason += " (read-only?)"
        raise ParameterError(f"{what} {path}: cannot write in {parent}: {reason}") from None
    return path


def write_atomic(path: str | Path, write: Callable[[str], Any], suffix: str = "") -> Path:
    """Call ``write(tmp)`` on a temporary path beside ``path``, then move it into place (0644).

    Raises:
        IsADirectoryError: ``path`` is a folder.
        FileNotFoundError: its folder does not exist.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{path} is a folder")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"no folder {path.parent} to write {path.name} in")
    clean_stale(path)
    fd, tmp = tempfile.mkstemp(prefix=tmp_prefix(path), suffix=suffix or path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, mode 0644."""
    return write_atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def make_readable(path: str | Path) -> Path:
    """Make a folder written by a library (a zarr store) world-readable: folders 0755, files 0644."""
    for root, dirs, files in os.walk(path):
        os.chmod(root, 0o755)
        for d in dirs:
            os.chmod(os.path.join(root, d), 0o755)
        for f in files:
            os.chmod(os.path.join(root, f), 0o644)
    return Path(path)


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def same_generated_text(a: str, b: str, rtol: float = 1e-12, atol: float = 1e-12) -> bool:
    """Whether two generated files (URDF, MJCF, SRDF, YAML) say the same thing: the same text
    between their numbers, and each pair of numbers within ``rtol`` (relative) or ``atol``.

    A generator that computes its numbers (assembled configurations, inertias turned into
    principal axes, a camera looking at the robot) writes them to 17 digits, whose last ones
    follow the CPU's rounding (the BLAS kernels it picks, FMA or not): the same generator gives
    ``0`` on one machine and ``-1.4e-17`` on another. The defaults are far above that and far
    below any change of the model (a length or an angle that a design change moves)."""
    if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    for x, y in zip(_NUMBER.findall(a), _NUMBER.findall(b), strict=True):
        if x != y and not abs(float(x) - float(y)) <= atol + rtol * max(abs(float(x)), abs(float(y))):
            return False
    return True


def save_figure(fig: Any, path: str | Path, dpi: int = 100) -> Path:
    """Save a matplotlib figure to ``path`` atomically, mode 0644, and close it if pyplot made it."""
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi))
    finally:
        import matplotlib.pyplot as plt

        if plt.fignum_exists(getattr(fig, "number", -1)):
            plt.close(fig)
