# SPDX-License-Identifier: Apache-2.0
"""Files h4pin writes: atomically (a temporary file in the same folder, then a rename, so a
failure never leaves a half-written file) and world-readable (mode 0644).

Every temporary file or folder is named ``.<name>.h4pin-tmp-<pid>-<random>`` beside its target;
one left by a process that was killed (its pid is gone) is removed the next time anything is
written to that target (:func:`clean_stale`). :func:`check_output` refuses an output path that
cannot be written, before any work is done.

The rule for existing outputs: a file is replaced (atomically) only if h4pin wrote it and it is
unchanged since (:func:`written_by_h4pin`: a text file carries a comment with the SHA-256 of the
rest of its content, a PNG or NetCDF file a marker, see :data:`MARKER`) or the user says so
(``--overwrite``, :func:`check_replace`); a folder is never replaced or written into unless it
is a store h4pin made for the same job (a sweep resumes its own store). Files the project ships
(``urdf/``, ``mjcf/``) carry no marker: a copy a user edits is the user's. Something at an output
path that is neither a file nor a folder (a FIFO, a device) is refused at once.

A zarr store is h4pin's only if its attributes hold :data:`STORE_ATTR` with a format and version
h4pin knows (:data:`STORE_FORMATS`, :func:`store_format`), written when the store is made; no
other attribute counts (a user's store whose attributes say ``kind: atlas`` is the user's). Only
``--overwrite`` replaces another zarr store, and no other folder is ever replaced. One process at
a time writes a store (:func:`store_lock`, a lock file beside it: :func:`take_lock`).

Files h4pin reads (a robot's URDF, MJCF or sidecar, the files an MJCF names, a stored atlas) are
regular files of a bounded size (:func:`check_input`, :func:`read_input`): a FIFO (which blocks
its reader until a writer comes), a device (``/dev/zero`` never ends), a socket, a folder where a
file is wanted or a file over :data:`INPUT_BYTES` is refused in one line naming the path and what
it is, before anything opens it.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from h4pin.errors import InputFileError, ParameterError

TMP_TAG = "h4pin-tmp"
#: What marks a binary file as h4pin's: a ``Comment`` text chunk of a PNG (:func:`save_figure`);
#: a NetCDF (HDF5) file carries an ``h4pin`` global attribute instead, a zarr store
#: :data:`STORE_ATTR`. A text file carries the digest comment of :func:`write_text`.
MARKER = "written by h4pin"
#: The attribute that makes a zarr store h4pin's: ``{"format": "atlas", "version": 1}``
#: (:func:`store_tag`), written when the store is made and checked by :func:`store_format`.
STORE_ATTR = "h4pin_store"
#: The store formats h4pin writes and reads, with their version. A store of another version
#: (an older or newer layout) is not read as h4pin's: it is refused, naming its version.
STORE_FORMATS = {"atlas": 1, "sweep": 1}
#: Tag of the lock file beside a store being written: ``.NAME.h4pin-lock`` (:func:`store_lock`).
LOCK_TAG = "h4pin-lock"
#: A text output's marker: a comment holding the SHA-256 (hex) of the text without this comment;
#: an edited file no longer matches and is the user's (:func:`written_by_h4pin`).
_DIGEST = re.compile(r"<!-- written by h4pin, unchanged if sha256 ([0-9a-f]{64}) -->")
_PNG = b"\x89PNG\r\n\x1a\n"
_HDF5 = b"\x89HDF\r\n\x1a\n"


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
    try:
        return _check_output(Path(path), what, folder, suffixes)
    except ParameterError:
        raise
    except OSError as exc:  # a name too long, a name the file system cannot encode, ...
        raise ParameterError(f"{what} {path!s:.200}: {_reason(exc)}") from None
    except (UnicodeError, ValueError) as exc:
        raise ParameterError(f"{what} {path!r:.200}: not a usable file name ({exc})") from None
    except TypeError:  # not a path: None, a number, bytes (give os.fsdecode(path))
        raise ParameterError(f"{what}: a path (a str or a pathlib.Path), got {type(path).__name__} "
                             f"{path!r:.100}") from None


def _check_output(path: Path, what: str, folder: bool, suffixes: tuple[str, ...]) -> Path:
    if not str(path) or str(path) in (".", ""):
        raise ParameterError(f"{what}: give a file name (got an empty one)")
    if suffixes and path.suffix not in suffixes:
        raise ParameterError(f"{what} {path}: the name must end in {' or '.join(suffixes)}")
    if path.exists() and not (path.is_file() or path.is_dir()):
        raise ParameterError(f"{what} {path} is neither a file nor a folder (a FIFO, a device or a socket): "
                             "give the path of a file to write")
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


#: The largest robot description (URDF, MJCF, sidecar YAML) h4pin reads, in bytes (the largest of
#: the corpus is under 1 MiB).
INPUT_BYTES = 64 * 2**20
#: The largest file an MJCF names (a mesh, a texture, a height field) h4pin lets MuJoCo read.
ASSET_BYTES = 2**30


def input_path(path: Any, what: str) -> Path:
    """``path`` (a ``str`` or an ``os.PathLike``; a non-UTF-8 name as Python decodes it) as a
    :class:`Path`; else a :class:`~h4pin.errors.ParameterError` naming ``what`` (a bytes path too:
    give it as ``os.fsdecode(path)``)."""
    if isinstance(path, (bytes, bytearray)):
        raise ParameterError(f"{what}: a path as a str or a pathlib.Path, got bytes {path!r:.200} (give "
                             "os.fsdecode(path))")
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterError(f"{what}: a path (a str or a pathlib.Path), got {type(path).__name__} {path!r:.100}")
    try:
        text = os.fspath(path)
    except TypeError:  # a PathLike whose __fspath__ gives no path
        raise ParameterError(f"{what}: a path-like object without a path, got {type(path).__name__}") from None
    if not isinstance(text, str) or not text:
        raise ParameterError(f"{what}: a path (a str), got {text!r:.100}")
    return Path(text)


def _reason(exc: OSError) -> str:
    """The system's words for an OS error (its errno's message, else the error's own text)."""
    return os.strerror(exc.errno) if exc.errno else str(exc)


def _kind(mode: int) -> str:
    """What a file that is not a regular one is, for a message."""
    if stat.S_ISFIFO(mode):
        return "a FIFO (a named pipe: reading it would wait for a writer)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device (reading it may never end)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISDIR(mode):
        return "a folder"
    return "a special file"


def check_input(path: Any, what: str, *, max_bytes: int = INPUT_BYTES, folder: bool = False) -> Path:
    """``path`` as a :class:`Path` if it is a regular file of at most ``max_bytes`` (or, with
    ``folder``, a folder), checked without opening it; else an
    :class:`~h4pin.errors.InputFileError` naming ``what``, the path and what it is (missing, a
    FIFO, a device, a socket, a folder, too large)."""
    path = input_path(path, what)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputFileError(f"{what} {path}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{what} {path}: {_reason(exc)}") from None
    except ValueError as exc:  # a NUL byte in the name
        raise InputFileError(f"{what} {path!r:.200}: not a usable file name ({exc})") from None
    if folder and stat.S_ISDIR(st.st_mode):
        return path
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(f"{what} {path} is {_kind(st.st_mode)}, not {'a folder' if folder else 'a regular file'}")
    if folder:
        raise InputFileError(f"{what} {path} is a file, not a folder")
    if st.st_size > max_bytes:
        raise InputFileError(f"{what} {path} is {st.st_size / 2**20:.1f} MiB, over the {max_bytes / 2**20:.0f} MiB "
                             "h4pin reads as one")
    return path


def read_input(path: Any, what: str, max_bytes: int = INPUT_BYTES) -> bytes:
    """The bytes of the regular file ``path`` (:func:`check_input`), at most ``max_bytes``: opened
    without blocking and checked again once open (a file swapped for a FIFO meanwhile is refused
    too), read to its end or to ``max_bytes + 1`` bytes (a file that grew past it is refused).

    Raises:
        InputFileError: as :func:`check_input`; it cannot be read (permissions, an I/O error).
    """
    path = check_input(path, what, max_bytes=max_bytes)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputFileError(f"{what} {path}: {_reason(exc)}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise InputFileError(f"{what} {path} is {_kind(mode)}, not a regular file")
        chunks, size = [], 0
        while size <= max_bytes:
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise InputFileError(f"{what} {path}: {_reason(exc)}") from None
    finally:
        os.close(fd)
    if size > max_bytes:
        raise InputFileError(f"{what} {path} is over the {max_bytes / 2**20:.0f} MiB h4pin reads as one")
    return b"".join(chunks)


@contextlib.contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Hold what C code (a C++ parser's console messages) writes on the process's standard error
    (file descriptor 2) while the block runs; the list it gives receives that text, stripped,
    when the block ends. Python's own ``sys.stderr`` is untouched. Meant for short calls: another
    thread's C output meanwhile is held too."""
    out: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no fd 2 (an embedded interpreter): nothing to hold
        yield out
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            out.append(tmp.read(1 << 16).decode("utf-8", "replace").strip())


def _png_marked(f: Any) -> bool:
    """Whether the PNG open in ``f`` (after its signature) has a text chunk holding :data:`MARKER`."""
    import struct

    while True:
        head = f.read(8)
        if len(head) < 8:
            return False
        length, kind = struct.unpack(">I4s", head)
        if kind in (b"tEXt", b"iTXt", b"zTXt") and length <= 1 << 16:
            if MARKER.encode() in f.read(length):
                return True
            f.seek(4, os.SEEK_CUR)  # CRC
        elif kind == b"IEND":
            return False
        else:
            f.seek(length + 4, os.SEEK_CUR)


def _hdf5_marked(path: Path) -> bool:
    """Whether the HDF5 (NetCDF4) file ``path`` has an ``h4pin`` global attribute."""
    try:
        import h5py
    except ImportError:  # without the studies extra h4pin writes no NetCDF
        return False
    try:
        with h5py.File(path, "r") as f:
            return "h4pin" in f.attrs
    except (OSError, ValueError):
        return False


def written_by_h4pin(path: str | Path) -> bool:
    """Whether h4pin wrote ``path`` and it is unchanged since, told from the file itself (its
    suffix does not matter): a text file (MJCF, URDF, HTML) whose first 4 KiB hold the digest
    comment of :func:`write_text` matching the rest of its content; a PNG with :data:`MARKER` in
    a text chunk; a NetCDF4 (HDF5) file with an ``h4pin`` attribute; a zarr store tagged as
    :func:`store_format` reads it. A symbolic link, or anything that is not a regular file or
    folder, is never h4pin's."""
    path = Path(path)
    try:
        if path.is_symlink() or not path.exists():
            return False
        if path.is_dir():
            return store_format(path) is not None
        if not path.is_file():
            return False
        with open(path, "rb") as f:
            head = f.read(4096)
            if head.startswith(_PNG):
                f.seek(len(_PNG))
                return _png_marked(f)
            if head.startswith(_HDF5):
                return _hdf5_marked(path)
            m = _DIGEST.search(head.decode("utf-8", errors="replace"))
            if m is None:
                return False
            f.seek(0)
            body = f.read()
    except OSError:
        return False
    token = m.group(0).encode()
    return _sha256(body.replace(token, b"", 1)) == m.group(1)


def store_tag(fmt: str) -> dict[str, Any]:
    """The value of :data:`STORE_ATTR` for a new store of format ``fmt`` (``"atlas"``, ``"sweep"``)."""
    return {"format": fmt, "version": STORE_FORMATS[fmt]}


def store_attributes(path: str | Path) -> dict[str, Any] | None:
    """The attributes of the zarr group at ``path`` (zarr 3's ``zarr.json``, zarr 2's ``.zattrs``
    beside ``.zgroup``); ``{}`` for a zarr store whose metadata cannot be read; None where there is
    no zarr group metadata at all (not a zarr store)."""
    path = Path(path)
    v3, v2 = path / "zarr.json", path / ".zattrs"
    try:
        if v3.is_file():
            meta = json.loads(v3.read_text(encoding="utf-8"))
            attrs = meta.get("attributes", {}) if isinstance(meta, dict) else {}
        elif v2.is_file():
            attrs = json.loads(v2.read_text(encoding="utf-8"))
        else:
            return {} if (path / ".zgroup").is_file() else None
    except (OSError, ValueError):  # unreadable, not UTF-8, not JSON
        return {}
    return attrs if isinstance(attrs, dict) else {}


def store_format(path: str | Path) -> str | None:
    """The format of the h4pin store at ``path`` (``"atlas"``, ``"sweep"``): its attributes hold
    :data:`STORE_ATTR` with a format and the version of it that this h4pin writes
    (:data:`STORE_FORMATS`); else None (a user's store, or one of another h4pin version)."""
    tag = (store_attributes(path) or {}).get(STORE_ATTR)
    if not isinstance(tag, dict):
        return None
    fmt, version = tag.get("format"), tag.get("version")
    if isinstance(fmt, str) and type(version) is int and STORE_FORMATS.get(fmt) == version:
        return fmt
    return None


def not_ours(attrs: dict[str, Any], fmt: str) -> str:
    """Why a zarr store with attributes ``attrs`` is not an h4pin store of format ``fmt``, for a message."""
    tag = attrs.get(STORE_ATTR)
    if isinstance(tag, dict) and tag.get("format") in STORE_FORMATS:
        if tag.get("format") != fmt:
            return f"is an h4pin {tag.get('format')} store, not {'an' if fmt[0] in 'aeiou' else 'a'} {fmt}"
        return (f"is an h4pin {fmt} store of format version {tag.get('version')!r:.20}, which this h4pin (version "
                f"{STORE_FORMATS[fmt]}) does not read")
    if tag is None and attrs.get("h4pin") in STORE_FORMATS:
        return f"was written by an older h4pin (its attributes hold no {STORE_ATTR})"
    return "exists and h4pin did not write it"


def check_store_folder(path: Path, fmt: str, what: str, overwrite: bool = False) -> str:
    """What is at the store path ``path`` (after :func:`check_output`): ``"new"`` (nothing, or an
    empty folder), ``"ours"`` (an h4pin store of format ``fmt``: :func:`store_format`) or
    ``"foreign"`` (another zarr store, to be replaced: only with ``overwrite``).

    Raises:
        ParameterError: another zarr store without ``overwrite``, naming why it is not h4pin's
            (no :data:`STORE_ATTR`, another format or version); a folder that is not a zarr store,
            even with ``overwrite`` (h4pin never replaces one).
    """
    if not path.is_dir() or not any(path.iterdir()):
        return "new"
    if store_format(path) == fmt:
        return "ours"
    attrs = store_attributes(path)
    if attrs is None:
        raise ParameterError(f"{what} {path} exists and is not a zarr store: give a new path (h4pin never replaces "
                             "or writes into another folder)")
    if overwrite:
        return "foreign"
    raise ParameterError(f"{what} {path} {not_ours(attrs, fmt)}: give another path, or --overwrite to replace it")


def take_lock(path: str | Path) -> bool:
    """Take the lock file ``path`` for this process (an exclusive ``flock``, released however the
    process ends; the file holds the holder's pid) unless another process, or another caller in
    this one, holds it. The file stays until :func:`release_lock`; one left by a killed process is
    taken over."""
    import fcntl

    path = os.fspath(path)
    for _ in range(8):
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            return False
        try:  # the file may have been released (unlinked) between our open and flock: lock the one there now
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, str(os.getpid()).encode())
            _held[path] = fd
            return True
        os.close(fd)
    return False


_held: dict[str, int] = {}


def release_lock(path: str | Path) -> None:
    """Release (and remove) a lock file :func:`take_lock` took in this process; nothing otherwise."""
    path = os.fspath(path)
    fd = _held.pop(path, None)
    if fd is None:
        return
    try:
        os.unlink(path)  # before the close: whoever opens the name next makes a new file
    except OSError:
        pass
    os.close(fd)


def lock_holder(path: str | Path) -> int | None:
    """The pid written in the lock file ``path``, or None."""
    try:
        with open(path) as fh:
            return int(fh.read().strip() or 0) or None
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def store_lock(path: str | Path, job: str) -> Iterator[None]:
    """Hold the lock of the store ``path`` (``.NAME.h4pin-lock`` beside it) while writing it: a
    second writer of the same store (another process, or another thread) is refused at once.

    Raises:
        ParameterError: another h4pin ``job`` holds it, naming the process.
    """
    path = Path(path)
    lock = path.parent / f".{path.name}.{LOCK_TAG}"
    if not take_lock(lock):
        pid = lock_holder(lock)
        by = f" (process {pid})" if pid else ""
        raise ParameterError(f"another h4pin {job}{by} is writing {path} now: wait for it to finish, or give "
                             "another path")
    try:
        yield
    finally:
        release_lock(lock)


def unmarked(text: str) -> str:
    """``text`` without the digest comment :func:`write_text` put in it (what was given to write)."""
    return _DIGEST.sub("", text, count=1)


def _sha256(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


def check_replace(path: str | Path, what: str, overwrite: bool = False) -> Path:
    """Refuse, before any work, to replace an existing file that h4pin did not write
    (:func:`written_by_h4pin`) unless ``overwrite``: :class:`h4pin.ParameterError` naming ``what``
    (the option) and the file, which is left as it is. A folder is left to the store checks
    (:func:`h4pin.mechanism.store.check_out`, :func:`h4pin.studies.sweep.check_store`)."""
    path = Path(path)
    if overwrite or not (path.exists() or path.is_symlink()) or (path.is_dir() and not path.is_symlink()):
        return path
    if not written_by_h4pin(path):
        raise ParameterError(f"{what} {path} exists and h4pin did not write it: give another path, or --overwrite "
                             "to replace it")
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


_DOCTYPE = re.compile(r"\s*<!doctype html[^>]*>", re.IGNORECASE)
_XML_DECL = re.compile(r"\s*<\?xml[^>]*\?>")


def write_text(path: str | Path, text: str, *, mark: bool = True, comment: str | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, mode 0644, with (``mark``) a comment holding
    the SHA-256 of the rest (:func:`written_by_h4pin`): after an XML declaration or an HTML
    doctype, else first; ``comment``: a line comment's prefix (``"#"`` for YAML) to hold it on a
    first line of its own. ``mark=False``: as given (the files the project ships)."""
    if mark and comment is not None:
        text = f"{comment} \n{text}"
        digest = _sha256(text.encode("utf-8"))
        text = f"{comment} <!-- written by h4pin, unchanged if sha256 {digest} -->\n{text[len(comment) + 2:]}"
    elif mark:
        m = _DOCTYPE.match(text) or _XML_DECL.match(text)
        at = m.end() if m else 0
        digest = _sha256(text.encode("utf-8"))
        text = f"{text[:at]}<!-- written by h4pin, unchanged if sha256 {digest} -->{text[at:]}"
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
    """Save a matplotlib figure to ``path`` atomically, mode 0644, and close it if pyplot made it.
    A PNG carries :data:`MARKER` in a ``Comment`` text chunk."""
    metadata = {"Comment": MARKER} if Path(path).suffix.lower() == ".png" else None
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, metadata=metadata))
    finally:
        import matplotlib.pyplot as plt

        if plt.fignum_exists(getattr(fig, "number", -1)):
            plt.close(fig)
