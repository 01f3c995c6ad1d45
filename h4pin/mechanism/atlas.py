# SPDX-License-Identifier: Apache-2.0
"""Motor-space atlas of any closed-loop robot (:class:`h4pin.mechanism.Mechanism`).

The H4's atlas (:mod:`h4pin.studies.atlas`) maps its workspace; a robot read from its own files
has no closed forms, so its atlas is a grid over its motor positions (one axis per motor of
``Mechanism.actuated``, rad or m). At each grid point the loops are closed by
continuation (:meth:`~h4pin.mechanism.Mechanism.assemble`, from an assembled neighbour, else from the
reference assembly), then the compliance of the output frame
(:meth:`~h4pin.mechanism.Mechanism.compliance`, the compiled generic path over each block) gives:

* ``compliance_max`` (m/N): the worst-direction translational compliance, the largest eigenvalue
  of the symmetric part of the 3x3 translational block C_tt (a unit force along its axis moves
  the frame's origin by this much);
* ``compliance_axes`` (m/N, dim ``axis``): the three eigenvalues of C_tt, ascending (the
  ellipsoid's radii), and ``compliance_vectors`` (1, dims ``xyz``, ``axis``): the unit axes,
  world coordinates, column ``axis`` for radius ``axis`` (a right-handed frame);
* ``position`` (m, dim ``xyz``): the output frame's origin, and ``configuration`` (dim
  ``coordinate``): the assembled configuration (nq,), Pinocchio's order;
* with ``frequency=True``, ``first_frequency`` (Hz): the lowest natural frequency with the
  model's inertias and the same springs (:meth:`~h4pin.mechanism.Mechanism.modes`);
* ``status`` (int8, :data:`STATUS_NAMES`): 0 where all the above hold; 1 where the loops do not
  close (or a joint leaves its range), 2 where a motion strains no spring (a singular
  configuration, or too few springs), 3 where the compliance holds but the frequency does not
  (nothing with mass), 4 where the load of ``gravity=True`` cannot be carried (past a critical
  load). The quantities are NaN where they do not hold; a grid point that fails never stops the
  atlas;
* with ``gravity=True``, ``sag`` (m, dim ``xyz``): the output's displacement under the robot's
  weight and a ``payload`` (kg at the output), the loaded equilibrium
  (:meth:`~h4pin.mechanism.Mechanism.equilibrium`, ``docs/loaded.md``).

Springs (:func:`default_springs`): the file's own joint springs when it has them (an MJCF's
``stiffness``), else every motor at ``motor_stiffness`` and every other joint at
``joint_stiffness`` (both 100 N.m/rad or N/m by default, the corpus tests' convention; a
joint stiffness of 0 leaves the passive joints free, which suits a parallel robot whose passive
joints all close loops, and leaves most others unrestrained: status 2).

The result is an :class:`xarray.Dataset` (one dim per motor, named by its joint) in the store
every atlas shares (:mod:`h4pin.mechanism.store`): saved to ``.nc`` or ``.zarr``; a ``.zarr``
output streams block by block into a partial store (a lock, a fingerprint) and a killed run
resumes from the blocks it finished (:func:`stream`). As the H4's workspace atlas,
it runs in one process (``threads`` for the compliance of a block): the continuation makes each
block start from its neighbours', so the blocks are not independent tasks for Dask workers.
:func:`h4pin.plots.atlas_maps` draws the maps. See ``docs/mechanisms.md``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from h4pin.extras import require

require("xarray", extra="studies", what="the motor-space atlas (h4pin.mechanism.atlas)")
import xarray as xr  # noqa: E402

from h4pin import limits  # noqa: E402
from h4pin.errors import H4Error, ParameterError  # noqa: E402
from h4pin.mechanism import store  # noqa: E402
from h4pin.mechanism.arguments import checked_springs  # noqa: E402
from h4pin.mechanism.core import Mechanism  # noqa: E402
from h4pin.mechanism.engine import UnassembledError  # noqa: E402

#: The verdict of a grid point (``status``), by code.
STATUS_NAMES = ("ok", "unassembled", "unrestrained", "no frequency", "over the critical load")
OK, UNASSEMBLED, UNRESTRAINED, NO_FREQUENCY, CRITICAL = range(5)
#: The quantities of a motor-space atlas: (units, description).
QUANTITIES = dict(
    compliance_max=("m/N", "largest eigenvalue of the symmetric part of C_tt (worst-direction compliance)"),
    compliance_axes=("m/N", "eigenvalues of the symmetric part of C_tt, ascending (ellipsoid radii)"),
    compliance_vectors=("1", "unit eigenvectors of C_tt, world axes: [xyz, axis] is axis's component xyz"),
    position=("m", "origin of the output frame, world axes"),
    configuration=("rad, m", "assembled configuration (Pinocchio's q)"),
)
FREQUENCY = dict(first_frequency=("Hz", "lowest natural frequency (model inertias, the atlas's springs)"))
#: The quantity an atlas adds with ``gravity=True``.
LOADED = dict(sag=("m", "output's displacement under the robot's weight and payload (loaded equilibrium)"))
#: Extra dims of the quantities that have them.
_EXTRA = {"compliance_axes": ("axis",), "compliance_vectors": ("xyz", "axis"), "position": ("xyz",), "sag": ("xyz",),
          "configuration": ("coordinate",)}
#: Default grid: a motor's range from its file where finite, else the reference assembly's motor
#: position +- these (rad for a revolute motor, m for a prismatic one).
REVOLUTE_SPAN, PRISMATIC_SPAN = 0.25, 0.025
#: Default spring stiffness of a motor and of every other joint (N.m/rad or N/m).
MOTOR_STIFFNESS = JOINT_STIFFNESS = 100.0
#: Grid points per motor by default: 21 for one or two motors, 7 for three, 3 beyond.
DEFAULT_COUNTS = {1: 21, 2: 21, 3: 7}
#: Grid points per block (one zarr chunk, one batch of compliance): whole rows of the last motor.
CHUNK = 256
#: Seconds a grid point (assembly by continuation, compliance; measured about 10 ms on the
#: corpus's 14-DoF delta on this 2-core machine, rounded up) and bytes it holds besides its
#: configuration (the quantities, twice while a file engine writes).
SECONDS_PER_POINT, BYTES_PER_POINT = 2e-2, 2 * (1 + 3 + 9 + 3 + 1) * 8


@dataclasses.dataclass(frozen=True)
class Setup:
    """What fixes the numbers of an atlas besides the robot and the grid: the output frame, the
    springs ``{joint: stiffness}``, the locked joints, whether the frequency is computed, and
    whether the sag under gravity is (with ``payload`` kg at the output)."""

    output: str
    springs: dict[str, Any]
    locked: tuple[str, ...] = ()
    frequency: bool = False
    gravity: bool = False
    payload: float = 0.0

    def extras(self) -> tuple[str, ...]:
        """The optional quantities this setup computes."""
        return (*(FREQUENCY if self.frequency else ()), *(LOADED if self.gravity else ()))


def default_springs(mech: Mechanism, motor_stiffness: float = MOTOR_STIFFNESS,
                    joint_stiffness: float = JOINT_STIFFNESS, locked: Iterable[str] = ()) -> dict[str, float]:
    """The springs of an atlas when none are given: the file's (:attr:`Mechanism.springs`) when
    it has any; else each motor at ``motor_stiffness`` and every other joint (but the locked ones
    and a free-flyer root) at ``joint_stiffness`` (0: free). N.m/rad for a revolute joint, N/m for
    a prismatic one, the value per coordinate for a multi-coordinate joint.

    Raises:
        ParameterError: a stiffness that is not finite > 0 (or >= 0 for ``joint_stiffness``).
    """
    for name, k, zero in (("motor_stiffness", motor_stiffness, False), ("joint_stiffness", joint_stiffness, True)):
        if (isinstance(k, bool) or not isinstance(k, (int, float, np.floating)) or not (0 <= k < math.inf)
                or (k == 0 and not zero)):
            raise ParameterError(f"{name}: a finite stiffness {'>= 0' if zero else '> 0'} (N.m/rad, N/m), got {k!r}")
    if mech.springs:
        return dict(mech.springs)
    skip = set(locked) | set(mech.free_flyers)
    out = {n: float(motor_stiffness) for n in mech.actuated}
    if joint_stiffness > 0:
        out.update({n: float(joint_stiffness) for n in list(mech.model.names)[1:] if n not in out and n not in skip})
    return out


def _motor_index(mech: Mechanism) -> list[int]:
    """The q index of each motor (one-coordinate joints only: a grid sets them by value)."""
    out = []
    for name in mech.actuated:
        j = mech.model.joints[mech.model.getJointId(name)]
        if j.nq != 1:
            raise ParameterError(f"{mech.name}: motor {name!r} has {j.nq} coordinates; a motor-space atlas needs "
                                 "one-coordinate motors")
        out.append(j.idx_q)
    if not out:
        raise ParameterError(f"{mech.name}: no motor (actuated joints) to make a grid of")
    return out


def motor_axes(mech: Mechanism, grid: Mapping[str, Any] | None = None, reference: Any = None,
               count: int | None = None) -> dict[str, np.ndarray]:
    """The grid's axis of each motor, in :attr:`Mechanism.actuated` order: ``grid[motor]`` as
    ``(lower, upper, count)`` or the values (1-D, rad or m); a motor not in ``grid`` spans its
    file range where finite, else the ``reference`` configuration's motor position (default: the
    reference assembly) +- :data:`REVOLUTE_SPAN` rad or :data:`PRISMATIC_SPAN` m, ``count``
    points (default :data:`DEFAULT_COUNTS`).

    Raises:
        ParameterError: an unknown motor, a bad axis (not finite, empty, count < 1).
    """
    idx = _motor_index(mech)
    grid = dict(grid or {})
    unknown = sorted(set(grid) - set(mech.actuated))
    if unknown:
        raise ParameterError(f"grid: {unknown[0]!r} is not a motor of {mech.name} (motors: {', '.join(mech.actuated)})")
    n = DEFAULT_COUNTS.get(len(idx), 3) if count is None else count
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"count: grid points per motor, an integer >= 1, got {count!r}")
    lo, hi = mech.ranges
    out = {}
    for name, i in zip(mech.actuated, idx, strict=True):
        spec = grid.get(name)
        if spec is None:
            if np.isfinite(lo[i]) and np.isfinite(hi[i]):
                spec = (lo[i], hi[i], n)
            else:
                if reference is None:
                    reference = mech.assemble()
                kind = mech.model.joints[mech.model.getJointId(name)].shortname()
                span = PRISMATIC_SPAN if "Prismatic" in kind or kind.startswith("JointModelP") else REVOLUTE_SPAN
                spec = (reference[i] - span, reference[i] + span, n)
        out[name] = _axis(name, spec)
    return out


def _axis(name: str, spec: Any) -> np.ndarray:
    if isinstance(spec, tuple) and len(spec) == 3:
        lo, hi, n = spec
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ParameterError(f"grid {name!r}: (lower, upper, count) with an integer count >= 1, got {spec!r}")
        if not (np.isfinite(lo) and np.isfinite(hi)) or (n > 1 and not lo < hi):
            raise ParameterError(f"grid {name!r}: finite lower < upper, got {spec!r}")
        return np.linspace(float(lo), float(hi), int(n))
    try:
        a = np.atleast_1d(np.asarray(spec, dtype=float))
    except (TypeError, ValueError):
        a = np.empty((0, 0))
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ParameterError(f"grid {name!r}: (lower, upper, count) or a non-empty 1-D array of finite values, "
                             f"got {spec!r}")
    return a


def _dim(name: str) -> str:
    """A motor's dim name: its joint name, characters a zarr path cannot hold replaced by ``_``."""
    dim = re.sub(r"[^A-Za-z0-9_.-]", "_", name)
    if dim in ("axis", "xyz", "coordinate"):
        dim = f"motor_{dim}"
    return dim


def _block_points(b: int, shape: tuple[int, ...], block: tuple[int, ...], grid: tuple[int, ...]) -> list[tuple]:
    """Grid indices of block ``b`` in continuation order (serpentine: every other row reversed)."""
    corner = [i * s for i, s in zip(np.unravel_index(b, grid), block, strict=True)]
    ranges = [range(c, min(c + s, n)) for c, s, n in zip(corner, block, shape, strict=True)]
    rows = [tuple(r) for r in np.ndindex(*(len(r) for r in ranges[:-1]))] if len(shape) > 1 else [()]
    out = []
    for k, row in enumerate(rows):
        head = tuple(ranges[a][i] for a, i in enumerate(row))
        cols = ranges[-1] if k % 2 == 0 else reversed(ranges[-1])
        out += [(*head, c) for c in cols]
    return out


def _slices(b: int, shape: tuple[int, ...], block: tuple[int, ...], grid: tuple[int, ...]) -> tuple[slice, ...]:
    corner = [i * s for i, s in zip(np.unravel_index(b, grid), block, strict=True)]
    return tuple(slice(c, min(c + s, n)) for c, s, n in zip(corner, block, shape, strict=True))


def _fingerprint(mech: Mechanism, axes: dict[str, np.ndarray], setup: Setup, block: tuple[int, ...]) -> str:
    """What fixes the numbers of a streamed atlas: the robot (model, closures, motors, reference,
    ranges), the grid, the setup and the blocks."""
    h = hashlib.sha256(mech.model.saveToString().encode())
    for cm in mech.constraint_models:
        h.update(f"{cm.name} {cm.type} {cm.joint1_id} {cm.joint2_id}".encode())
        h.update(np.ascontiguousarray(cm.joint1_placement.homogeneous).tobytes())
        h.update(np.ascontiguousarray(cm.joint2_placement.homogeneous).tobytes())
    for a in (mech.reference, *mech.ranges, *axes.values()):
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    h.update(json.dumps([list(mech.actuated), list(axes), sorted(setup.springs.items(), key=str), list(setup.locked),
                         setup.output, setup.frequency, list(block), setup.gravity, setup.payload],
                        default=repr).encode())
    return h.hexdigest()


def _setup(mech: Mechanism, output: str, springs: Mapping[str, Any] | None, locked: Iterable[str],
           frequency: bool, loaded: tuple[bool, float] = (False, 0.0)) -> Setup:
    if not isinstance(mech, Mechanism):
        raise ParameterError(f"mechanism: an h4pin.mechanism.Mechanism, got {type(mech).__name__}")
    if not isinstance(output, str) or not mech.model.existFrame(output):
        raise ParameterError(f"output: no frame {output!r} in {mech.name}")
    if not isinstance(frequency, bool):
        raise ParameterError(f"frequency: True or False, got {frequency!r}")
    locked = tuple(locked)
    springs = default_springs(mech, locked=locked) if springs is None else dict(springs)
    checked_springs(mech, springs, locked)  # checked now: names, values, both locked and sprung
    gravity, payload = loaded
    if not isinstance(gravity, bool):
        raise ParameterError(f"gravity: True or False, got {gravity!r}")
    payload = float(limits.check_range("payload", payload, "payload"))
    if payload > 0 and not gravity:
        raise ParameterError("payload: its weight acts only with gravity=True")
    return Setup(output, springs, locked, frequency, gravity, payload)


def _plan(mech: Mechanism, output: str, axes: Any, springs: Any, locked: Iterable[str], frequency: bool, chunk: int,
          streamed: bool, loaded: tuple[bool, float]) -> tuple[Any, np.ndarray, dict[str, np.ndarray], tuple[int, ...],
                                                              tuple[int, ...], tuple[int, ...]]:
    """An atlas's setup, reference assembly, motor axes, grid shape, block and block grid, its
    size checked (:func:`atlas` and :func:`stream`)."""
    setup = _setup(mech, output, springs, locked, frequency, loaded)
    reference = mech.assemble()
    grid_axes = motor_axes(mech, axes, reference)
    shape = tuple(len(v) for v in grid_axes.values())
    block, grid = store.block_layout(shape, chunk)
    _check_memory(mech, shape, chunk, frequency, streamed, setup.gravity)
    return setup, reference, grid_axes, shape, block, grid


def _check_memory(mech: Mechanism, shape: tuple[int, ...], chunk: int, frequency: bool, streamed: bool,
                  gravity: bool = False) -> None:
    n = math.prod(shape)
    per = BYTES_PER_POINT + 16 * mech.model.nq  # the quantities; the configurations (kept for continuation)
    need = n * (per if not streamed else 8 * mech.model.nq + 2) + min(n, chunk) * 4096
    seconds = n * SECONDS_PER_POINT * (1.5 if frequency else 1.0) + (n * 1e-4 * mech.model.nv ** 2 if gravity else 0)
    limits.check_size(f"{mech.name}: a motor-space atlas of {n:,} points", need, seconds,
                      "use fewer points per motor")


def _template(mech: Mechanism, axes: dict[str, np.ndarray], setup: Setup, data: dict[str, Any]) -> xr.Dataset:
    """The atlas Dataset of the arrays ``data`` (numpy, or dask for a store's template)."""
    dims = tuple(_dim(m) for m in axes)
    known = {**QUANTITIES, **FREQUENCY, **LOADED}
    out = {q: ((*dims, *_EXTRA.get(q, ())), data[q], {"units": known[q][0], "long_name": known[q][1]})
           for q in known if q in data}
    out["status"] = (dims, data["status"], {
        "units": "1", "long_name": "verdict (h4pin.mechanism.atlas.STATUS_NAMES)",
        "flag_values": np.arange(len(STATUS_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(s.replace(" ", "_") for s in STATUS_NAMES)})
    coords = {d: (d, v, {"units": "rad or m", "joint": m}) for d, (m, v) in zip(dims, axes.items(), strict=True)}
    # "h4pin": "atlas" is what h4pin.mechanism.store.check_out recognises (an atlas may be replaced).
    return xr.Dataset(out, coords=coords, attrs={
        "title": f"motor-space atlas of {mech.name}", "h4pin": "atlas", "kind": "mechanism",
        "mechanism": mech.name, "output": setup.output, "motors": json.dumps(list(axes)),
        "springs": json.dumps(setup.springs, default=lambda v: np.asarray(v, float).tolist()),
        "locked": json.dumps(list(setup.locked)), "gravity": int(setup.gravity), "payload_kg": setup.payload,
        "reference": "h4pin.mechanism.Mechanism.compliance (world axes), .assemble, .modes"})


def _empty(mech: Mechanism, shape: tuple[int, ...], setup: Setup, full: Any = np.full) -> dict[str, Any]:
    sizes = {"axis": 3, "xyz": 3, "coordinate": mech.model.nq}
    q = [*QUANTITIES, *setup.extras()]
    return {k: full((*shape, *(sizes[d] for d in _EXTRA.get(k, ()))), np.nan) for k in q}


class _Run:
    """One atlas computation: the blocks in order, each point closed from an assembled neighbour
    (continuation), else from the reference assembly; then the block's compliance in one batch."""

    def __init__(self, mech: Mechanism, axes: dict[str, np.ndarray], setup: Setup, threads: int | None,
                 Q: np.ndarray, known: np.ndarray, ok: np.ndarray, reference: np.ndarray):
        self.mech, self.axes, self.setup, self.threads = mech, list(axes.values()), setup, threads
        self.idx = _motor_index(mech)
        self.Q, self.known, self.ok = Q, known, ok  # full-grid configurations, computed, assembled
        self.reference = reference

    def _close(self, point: tuple, before: tuple | None) -> np.ndarray | None:
        m = np.array([a[i] for a, i in zip(self.axes, point, strict=True)])
        seeds = [before] if before is not None else []
        seeds += [(*point[:a], point[a] - 1, *point[a + 1:]) for a in reversed(range(len(point))) if point[a] > 0]
        tried = 0
        for s in dict.fromkeys(seeds):
            if tried == 2:
                break
            if self.known[s] and self.ok[s]:
                tried += 1
                try:
                    return self.mech.assemble(self.Q[s], motors=m)
                except UnassembledError:
                    pass
        try:
            return self.mech.assemble(self.reference, motors=m)
        except UnassembledError:
            return None

    def block(self, points: list[tuple]) -> dict[str, np.ndarray]:
        """The fields (flat, in the order of ``points``) and the status of one block."""
        mech, s = self.mech, self.setup
        n = len(points)
        f = _empty(mech, (n,), s)
        status = np.full(n, UNASSEMBLED, dtype=np.int8)
        before = None
        for k, p in enumerate(points):
            q = self._close(p, before)
            self.known[p] = True
            if q is not None:
                self.Q[p], self.ok[p] = q, True
                f["configuration"][k], status[k] = q, OK
                before = p
        good = np.flatnonzero(status == OK)
        C = self._batch(lambda Q: mech.compliance(Q, s.springs, [s.output], s.locked, threads=self.threads),
                        f["configuration"][good], (6, 6))
        status[good[~np.isfinite(C[:, 0, 0])]] = UNRESTRAINED
        for j, k in enumerate(good):
            if status[k] == OK:
                block = C[j, :3, :3]
                vals, vecs = np.linalg.eigh((block + block.T) / 2)
                if np.linalg.det(vecs) < 0:
                    vecs[:, 0] = -vecs[:, 0]
                f["compliance_axes"][k], f["compliance_vectors"][k], f["compliance_max"][k] = vals, vecs, vals[2]
        d = mech.model.createData()
        fid = mech.model.getFrameId(s.output)
        for k in good:
            pin.framesForwardKinematics(mech.model, d, f["configuration"][k])
            f["position"][k] = d.oMf[fid].translation
        if s.frequency:
            good = np.flatnonzero(status == OK)
            first = self._batch(lambda Q: np.asarray(mech.modes(Q, s.springs, s.locked, threads=self.threads).first),
                                f["configuration"][good], ())
            f["first_frequency"][good] = first
            status[good[~(np.isfinite(first) & (first > 0))]] = NO_FREQUENCY
        if s.gravity:
            self._sag(f, status)
        f["status"] = status
        return f

    def _sag(self, f: dict[str, np.ndarray], status: np.ndarray) -> None:
        """The output's displacement under gravity (and the payload) at each point of status 0:
        :meth:`Mechanism.equilibrium`; status :data:`CRITICAL` where the load cannot be carried."""
        from h4pin.mechanism.loaded import LimitLoadError
        from h4pin.mechanism.payload import Payload

        s = self.setup
        payload = (s.output, Payload(s.payload)) if s.payload > 0 else None
        for k in np.flatnonzero(status == OK):
            try:
                eq = self.mech.equilibrium(f["configuration"][k], s.springs, gravity=True, payload=payload,
                                           locked=s.locked)
            except (LimitLoadError, H4Error):
                status[k] = CRITICAL
                continue
            f["sag"][k] = eq.displacement(s.output)[:3]

    @staticmethod
    def _batch(call: Any, Q: np.ndarray, tail: tuple[int, ...]) -> np.ndarray:
        """``call(Q)`` over a batch; where it refuses one configuration, each alone (NaN where
        it refuses: a motion no spring strains, nothing with mass)."""
        if len(Q) == 0:
            return np.empty((0, *tail))
        try:
            return np.asarray(call(Q))
        except H4Error:  # e.g. UnrestrainedMotionError at one configuration
            out = np.full((len(Q), *tail), np.nan)
            for i, q in enumerate(Q):
                try:
                    out[i] = call(q[None])[0]
                except H4Error:
                    pass
            return out


def atlas(mech: Mechanism, output: str, axes: Mapping[str, Any] | None = None,
          springs: Mapping[str, Any] | None = None, locked: Iterable[str] = (), *, frequency: bool = False,
          chunk: int = CHUNK, threads: int | None = None, progress: bool = True,
          out: str | Path | None = None, gravity: bool = False, payload: float = 0.0) -> xr.Dataset:
    """The motor-space atlas of ``mech`` at the frame ``output`` (module docstring).

    Args:
        mech: the robot (:meth:`Mechanism.from_urdf`, :meth:`Mechanism.from_mjcf`).
        output: the frame whose compliance is mapped (its origin, world axes).
        axes: ``{motor: (lower, upper, count) or values}`` (:func:`motor_axes`; motors left out
            take the default range).
        springs, locked: as :meth:`Mechanism.compliance` (default :func:`default_springs`).
        frequency: also the first natural frequency (Hz).
        gravity: also ``sag`` (m, ``xyz``): the output's displacement under the robot's weight and
            ``payload`` kg at the output, the loaded equilibrium (:meth:`Mechanism.equilibrium`);
            status 4 where the load cannot be carried.
        chunk: grid points per block (whole rows of the last motor; a zarr chunk).
        threads: threads of each block's compliance (default one per core).
        progress: a tqdm progress bar.
        out: also write it there: ``.nc`` (computed in memory, saved atomically) or ``.zarr``
            (streamed, resumed after a kill: :func:`stream`; returned opened lazily).

    Raises:
        ParameterError: an unknown frame, motor or joint, a bad grid or spring.
        TooLargeError: over the memory or time limit (before any work).
        UnassembledError: the reference configuration does not close.
    """
    if out is not None and Path(out).suffix == ".zarr":
        return stream(mech, output, axes, springs, locked, out=out, frequency=frequency, chunk=chunk,
                      threads=threads, progress=progress, gravity=gravity, payload=payload)
    if out is not None:
        store.check_out(out)
    setup, reference, grid_axes, shape, block, grid = _plan(mech, output, axes, springs, locked, frequency, chunk,
                                                            False, (gravity, payload))
    data = _empty(mech, shape, setup)
    data["status"] = np.zeros(shape, dtype=np.int8)
    run = _Run(mech, grid_axes, setup, threads, data["configuration"], np.zeros(shape, bool), np.zeros(shape, bool),
               reference)
    with tqdm(total=math.prod(shape), desc="atlas", unit="point", disable=not progress) as bar:
        for b in range(math.prod(grid)):
            points = _block_points(b, shape, block, grid)
            fields = run.block(points)
            where = tuple(np.array(points).T)
            for q, v in data.items():
                v[where] = fields[q]
            bar.update(len(points))
    ds = _template(mech, grid_axes, setup, data)
    if out is not None:
        store.save(ds, out)
    return ds


def stream(mech: Mechanism, output: str, axes: Mapping[str, Any] | None = None,
           springs: Mapping[str, Any] | None = None, locked: Iterable[str] = (), *, out: str | Path,
           frequency: bool = False, chunk: int = CHUNK, threads: int | None = None, progress: bool = True,
           stop_after: int | None = None, gravity: bool = False, payload: float = 0.0) -> xr.Dataset | None:
    """:func:`atlas` streamed into the zarr store ``out`` (:func:`h4pin.mechanism.store.partial`):
    the arrays made first in the partial store beside ``out`` (its lock and fingerprint: the robot,
    grid, setup and blocks), each block written and flagged done as it is computed, the store
    renamed to ``out`` when whole; a killed run resumes from the blocks done (their assembled
    configurations seed the next blocks, so the result is the uninterrupted run's).
    ``stop_after``: stop after that many blocks of this run, leaving the partial store (returns
    None), as a kill would.

    Returns:
        The store at ``out``, opened lazily.
    """
    import dask.array as da

    path = store.check_stream(out, "out")
    setup, reference, grid_axes, shape, block, grid = _plan(mech, output, axes, springs, locked, frequency, chunk,
                                                            True, (gravity, payload))
    lazy = _empty(mech, shape, setup, lambda s, v: da.full(s, v, chunks=(*block, *s[len(shape):])))
    lazy["status"] = da.zeros(shape, dtype=np.int8, chunks=block)
    with store.partial(path, _template(mech, grid_axes, setup, lazy), _fingerprint(mech, grid_axes, setup, block),
                       math.prod(grid)) as group:
        return _fill(mech, path, group, grid_axes, setup, shape, block, grid, reference, threads, progress, stop_after)


def _fill(mech: Mechanism, path: Path, group: Any, grid_axes: dict[str, np.ndarray], setup: Any,
          shape: tuple[int, ...], block: tuple[int, ...], grid: tuple[int, ...], reference: np.ndarray,
          threads: int | None, progress: bool, stop_after: int | None) -> xr.Dataset | None:
    """The blocks :func:`stream` has not done yet, into its partial store, then the store moved
    into place (the caller holds the store's lock)."""
    done = group[store.DONE]
    flags = done[:]
    known = np.zeros(shape, bool)
    for b in np.flatnonzero(flags):
        known[_slices(b, shape, block, grid)] = True
    status = group["status"][:]
    Q = np.where(known[..., None], group["configuration"][:], np.nan)
    run = _Run(mech, grid_axes, setup, threads, Q, known, known & (status != UNASSEMBLED), reference)
    arrays = {q: group[q] for q in (*QUANTITIES, *setup.extras(), "status")}
    todo = np.flatnonzero(~flags)
    with tqdm(total=math.prod(shape), desc="atlas", unit="point", disable=not progress,
              initial=int(known.sum())) as bar:
        for count, b in enumerate(todo):
            if stop_after is not None and count >= stop_after:
                return None
            points = _block_points(b, shape, block, grid)
            fields = run.block(points)
            sl = _slices(b, shape, block, grid)
            local = tuple(np.array(points).T - np.array([s.start for s in sl])[:, None])
            for q, arr in arrays.items():
                v = np.empty((*(s.stop - s.start for s in sl), *fields[q].shape[1:]), fields[q].dtype)
                v[local] = fields[q]
                arr[sl] = v
            flags[b] = True
            done[:] = flags  # after the block's values: a block killed half-way is computed again
            bar.update(len(points))
    store.finish(path)
    return store.opened(path)


def motors(ds: xr.Dataset) -> list[str]:
    """The motor joints of a motor-space atlas, in the order of its dims."""
    if ds.attrs.get("kind") != "mechanism" or "motors" not in ds.attrs:
        raise ParameterError("not a motor-space atlas (h4pin.mechanism.atlas): no 'motors' attribute")
    return json.loads(ds.attrs["motors"])
