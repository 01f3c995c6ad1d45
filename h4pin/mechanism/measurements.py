# SPDX-License-Identifier: Apache-2.0
"""Measured tool positions of a robot (:class:`Measurements`): per sample, what was commanded
(the configuration of a tree, or the motor positions of a closed loop), where an external tracker
saw markers on the robot, and the known loads; read from and written to CSV and NumPy files.

The CSV layout (one row a sample, a header of column names; lines starting with ``#`` are
comments): ``q.<joint>`` (one per coordinate of a configuration, ``q.<joint>.<k>`` for a multi-
coordinate joint) or ``m.<motor>`` (motor positions), ``p.<frame>.x``, ``.y``, ``.z`` (a marker's
measured position, m; empty or ``nan`` where it was not seen), and optionally ``f.<frame>.fx``,
``fy``, ``fz``, ``tx``, ``ty``, ``tz`` (a known load at the frame's origin, N and N.m, world
axes). ``.npz``: the arrays ``configurations`` or ``motors``, ``points/<frame>`` and
``loads/<frame>``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from h4pin.errors import ParameterError

#: The largest number of samples (a tracker session is hundreds to thousands).
MAX_SAMPLES = 1_000_000


def _array(value: Any, what: str, tail: tuple[int, ...] | None, nan: bool) -> np.ndarray:
    raw = np.asarray(value, dtype=object)
    if raw.size and any(isinstance(v, (bool, np.bool_, complex, np.complexfloating, str, bytes)) for v in raw.flat):
        raise ParameterError(f"{what}: real numbers, got {value!r:.80}")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: an array of numbers, got {value!r:.80}") from None
    if a.ndim != (1 if tail is None else 1 + len(tail)) or (tail is not None and a.shape[1:] != tail):
        want = "(N,)" if tail is None else f"(N, {', '.join(map(str, tail))})"
        raise ParameterError(f"{what}: shape {want}, got {a.shape}")
    bad = ~np.isfinite(a) if not nan else np.isinf(a)
    if bad.any():
        raise ParameterError(f"{what}: not finite at row {int(np.argwhere(bad)[0][0])}")
    a.setflags(write=False)
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class Measurements:
    """What a tracker measured on a robot, sample by sample.

    Attributes:
        configurations: (N, nq) the commanded configurations (a tree: every joint commanded), or
            None.
        motors: (N, n_act) the commanded motor positions of a closed loop (rad, m), in the
            mechanism's ``actuated`` order, or None. Exactly one of the two is given.
        points: ``{frame: (N, 3)}`` the markers' measured positions in the tracker's frame (m);
            NaN where a marker was not seen.
        loads: ``{frame: (N, 6)}`` known loads ``[force; torque]`` at the frames' origins (N, N.m,
            world axes), or None.
    """

    configurations: Any = None
    motors: Any = None
    points: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    loads: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        if (self.configurations is None) == (self.motors is None):
            raise ParameterError("measurements: give configurations (a tree) or motors (a closed loop), one of them")
        key = "configurations" if self.motors is None else "motors"
        cmd = np.asarray(getattr(self, key), dtype=object)
        width = cmd.shape[1] if cmd.ndim == 2 else -1
        commands = _array(getattr(self, key), f"measurements: {key}", (width,) if width > 0 else (0,), False)
        n = len(commands)
        if not 0 < n <= MAX_SAMPLES:
            raise ParameterError(f"measurements: 1 to {MAX_SAMPLES:,} samples, got {n:,}")
        object.__setattr__(self, key, commands)
        if not isinstance(self.points, Mapping) or not self.points:
            raise ParameterError("measurements: points, a mapping {marker frame: (N, 3) positions} with a marker")
        points = {}
        for frame, value in self.points.items():
            if not isinstance(frame, str):
                raise ParameterError(f"measurements: a marker is a frame name, got {frame!r}")
            p = _array(value, f"measurements: points[{frame!r}]", (3,), True)
            if len(p) != n:
                raise ParameterError(f"measurements: points[{frame!r}] has {len(p)} rows, the commands {n}")
            if np.isnan(p).all():
                raise ParameterError(f"measurements: marker {frame!r} was never seen (every row is NaN)")
            points[frame] = p
        object.__setattr__(self, "points", points)
        if self.loads is not None:
            if not isinstance(self.loads, Mapping):
                raise ParameterError("measurements: loads, a mapping {frame: (N, 6) wrenches}")
            loads = {}
            for frame, value in self.loads.items():
                w = _array(value, f"measurements: loads[{frame!r}]", (6,), False)
                if len(w) != n or not isinstance(frame, str):
                    raise ParameterError(f"measurements: loads[{frame!r}] has {len(w)} rows, the commands {n}")
                loads[frame] = w
            object.__setattr__(self, "loads", loads)

    @property
    def n(self) -> int:
        """The number of samples."""
        return len(self.commands)

    @property
    def commands(self) -> np.ndarray:
        """(N, k): the configurations or the motor positions."""
        return self.motors if self.configurations is None else self.configurations

    @property
    def markers(self) -> tuple[str, ...]:
        return tuple(self.points)

    def observed(self) -> np.ndarray:
        """(N, m, 3) the measured points, markers in :attr:`markers` order (NaN: not seen)."""
        return np.stack([self.points[f] for f in self.markers], axis=1)

    def subset(self, rows: Any) -> Measurements:
        """The samples ``rows`` (indices or a boolean mask)."""
        rows = np.arange(self.n)[rows]
        cmd = {"configurations": self.configurations[rows]} if self.motors is None else {"motors": self.motors[rows]}
        return Measurements(**cmd, points={f: p[rows] for f, p in self.points.items()},
                            loads=None if self.loads is None else {f: w[rows] for f, w in self.loads.items()})

    # ------------------------------------------------------------------ files
    def columns(self, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The CSV columns (module docstring); ``names``: a column name per command coordinate."""
        out = {f"{'q' if self.motors is None else 'm'}.{n}": self.commands[:, i] for i, n in enumerate(names)}
        for f, p in self.points.items():
            out.update({f"p.{f}.{a}": p[:, k] for k, a in enumerate("xyz")})
        for f, w in (self.loads or {}).items():
            out.update({f"f.{f}.{a}": w[:, k] for k, a in enumerate(("fx", "fy", "fz", "tx", "ty", "tz"))})
        return out

    def to_csv(self, path: str | Path, names: tuple[str, ...]) -> Path:
        """Write the samples as CSV (module docstring), atomically."""
        from h4pin.files import check_output, write_text

        path = check_output(path, "path", suffixes=(".csv",))
        cols = self.columns(tuple(names))
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(cols)
        for row in zip(*cols.values(), strict=True):
            w.writerow(["" if np.isnan(v) else repr(float(v)) for v in row])
        return write_text(path, buf.getvalue(), comment="#")

    @classmethod
    def from_csv(cls, path: str | Path) -> Measurements:
        """Read a CSV of the layout of the module docstring.

        Raises:
            ParameterError: no such file, a column of another kind, a value that is not a number,
                rows of different lengths.
        """
        path = Path(path)
        if not path.is_file():
            raise ParameterError(f"measurements: no file {path}")
        try:
            with open(path, newline="", encoding="utf-8") as fh:
                rows = [r for r in csv.reader(line for line in fh if not line.startswith("#"))]
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise ParameterError(f"measurements: cannot read {path}: {exc}") from None
        if len(rows) < 2:
            raise ParameterError(f"measurements: {path} has no sample (a header and a row at least)")
        header, body = rows[0], rows[1:]
        if any(len(r) != len(header) for r in body):
            raise ParameterError(f"measurements: {path}: a row has not {len(header)} values")
        try:
            data = np.array([[float(v) if v.strip() else np.nan for v in r] for r in body])
        except ValueError as exc:
            raise ParameterError(f"measurements: {path}: {exc}") from None
        return cls.from_columns(dict(zip(header, data.T, strict=True)), str(path))

    @classmethod
    def from_columns(cls, cols: Mapping[str, np.ndarray], where: str = "columns") -> Measurements:
        """From named columns (module docstring)."""
        kinds = {name.split(".", 1)[0] for name in cols}
        unknown = kinds - {"q", "m", "p", "f"}
        if unknown:
            raise ParameterError(f"measurements: {where}: columns start with q., m., p. or f., got {sorted(unknown)}")
        cmd = [c for c in cols if c.startswith(("q.", "m."))]
        if {c[0] for c in cmd} not in ({"q"}, {"m"}):
            raise ParameterError(f"measurements: {where}: q.<joint> columns or m.<motor> columns, one kind")
        points, loads = {}, {}
        for name in cols:
            kind, _, rest = name.partition(".")
            frame, _, axis = rest.rpartition(".")
            if kind == "p":
                points.setdefault(frame, {})[axis] = cols[name]
            elif kind == "f":
                loads.setdefault(frame, {})[axis] = cols[name]
        try:
            pts = {f: np.column_stack([v[a] for a in "xyz"]) for f, v in points.items()}
            lds = {f: np.column_stack([v[a] for a in ("fx", "fy", "fz", "tx", "ty", "tz")]) for f, v in loads.items()}
        except KeyError as exc:
            raise ParameterError(f"measurements: {where}: missing column {exc}") from None
        arr = np.column_stack([cols[c] for c in cmd])
        return cls(**({"configurations": arr} if cmd[0][0] == "q" else {"motors": arr}), points=pts,
                   loads=lds or None)

    def to_npz(self, path: str | Path) -> Path:
        """Write the arrays as ``.npz`` (module docstring), atomically."""
        from h4pin.files import check_output, write_atomic

        path = check_output(path, "path", suffixes=(".npz",))
        arrays = {"configurations" if self.motors is None else "motors": self.commands}
        arrays.update({f"points/{f}": p for f, p in self.points.items()})
        arrays.update({f"loads/{f}": w for f, w in (self.loads or {}).items()})
        return write_atomic(path, lambda tmp: np.savez(tmp, **arrays), suffix=".npz")

    @classmethod
    def from_npz(cls, path: str | Path) -> Measurements:
        """Read a ``.npz`` of :meth:`to_npz`'s layout."""
        path = Path(path)
        if not path.is_file():
            raise ParameterError(f"measurements: no file {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise ParameterError(f"measurements: cannot read {path}: {exc}") from None
        cmd = {k: arrays[k] for k in ("configurations", "motors") if k in arrays}
        return cls(**cmd, points={k[7:]: v for k, v in arrays.items() if k.startswith("points/")},
                   loads={k[6:]: v for k, v in arrays.items() if k.startswith("loads/")} or None)

    @classmethod
    def read(cls, path: str | Path) -> Measurements:
        """:meth:`from_csv` or :meth:`from_npz` by the file's suffix."""
        suffix = Path(path).suffix.lower()
        if suffix not in (".csv", ".npz"):
            raise ParameterError(f"measurements: a .csv or .npz file, got {path}")
        return cls.from_csv(path) if suffix == ".csv" else cls.from_npz(path)


__all__ = ["MAX_SAMPLES", "Measurements"]
