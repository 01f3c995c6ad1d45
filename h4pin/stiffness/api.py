# SPDX-License-Identifier: Apache-2.0
"""The compliance of an H4: :func:`compliance` and :class:`Compliance`.

:func:`compliance` gives the 8x8 compliance matrix ``K``, ``dtp = K Gamma_ext``, with

* ``dtp = [dD, dOmega, domega_1, domega_2]`` (eq. 3): small translation and rotation of the
  central bar (world-aligned, at D) and the relative rotations of the lateral bars on their
  revolute joints (m, rad);
* ``Gamma_ext = [F, T, t_1, t_2]`` (eq. 16): force and torque on the central bar at D and the
  torques on the two revolute joints (N, N.m).

``K`` is the robot's: the four terms of eq. 30 (``control``, ``bending``, ``torsion``,
``tension``; :mod:`h4pin.stiffness.eq30`) plus one named term per kind of optional compliant
element the robot carries (:attr:`H4.elements <h4pin.H4>`, from its URDF;
:mod:`h4pin.stiffness.elements`). ``elements=False`` gives eq. 30 alone.

Two models of eq. 30 (``docs/errata.md``): ``"paper"`` (as printed, errata 1-3 fixed) and
``"consistent"`` (erratum 4 fixed too: K symmetric, equal to the statics route). The elements'
terms are the same in both.

Backends (``method``), one verdict per pose on all of them (:mod:`h4pin.verdicts`): ``"kernel"``
(the compiled pipeline, :mod:`h4pin.stiffness.kernel` and :mod:`h4pin.stiffness.pipeline`: one
pose or a batch, eq. 30 and the elements' terms in one compiled call), ``"closed_form"`` (the
numpy reference, any robot), ``"pinocchio"`` (Pinocchio's Jacobians and the numpy eq. 30,
:mod:`h4pin.stiffness.pinocchio`); ``"auto"`` takes the kernel when it applies (exact
parallelograms) and is compiled, else the numpy reference (the first calls after an install
do not wait for the compiler: :mod:`h4pin._jit`). The numpy and Pinocchio paths take the
elements' terms from the statics route of :mod:`h4pin.stiffness.elements`, pose by pose. Each
is a module with a ``backend(h4, x, model, terms, elements)`` function listed in :data:`BACKENDS`.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import weakref
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np

from h4pin import limits
from h4pin.description.elements import Elements
from h4pin.errors import LoadError, ParameterError
from h4pin.inputs import check_choice, check_flag, check_instance, describe, is_mechanism, real_array
from h4pin.kinematics import closed_form as cf
from h4pin.kinematics import pinocchio as kin
from h4pin.robot import H4
from h4pin.stiffness import kernel
from h4pin.stiffness.eq30 import MODELS, TERMS, Raw
from h4pin.stiffness.matrices import R_CONSISTENT, R_PAPER, Matrices, from_kinematics, n_matrix
from h4pin.verdicts import INVALID, OK, SINGULAR, SINGULAR_COND, raise_for_status, singular_message

#: The backends of :func:`compliance`: method name -> module with a ``backend`` function
#: (:class:`Raw` from poses). A new backend is one module, one line here and one test parameter.
BACKENDS = {"kernel": "h4pin.stiffness.kernel", "closed_form": "h4pin.stiffness.numpy_backend",
            "pinocchio": "h4pin.stiffness.pinocchio"}
METHODS = ("auto", *BACKENDS)
ON_ERRORS = ("raise", "nan")
_BATCH_CHUNK = 8192
_F64 = np.dtype(np.float64)

__all__ = ["BACKENDS", "METHODS", "MODELS", "ON_ERRORS", "R_CONSISTENT", "R_PAPER", "SINGULAR_COND", "TERMS",
           "Compliance", "Matrices", "Raw", "as_load", "check_options", "compliance", "matrices_at", "n_matrix"]


class LazyTerms(Mapping):
    """The four terms of eq. 30, computed on first access (a read-only mapping of name -> array).

    A compliance result carries one, so that a user who does not look at the terms does not pay
    for them (time, and 2 KB a pose)."""

    __slots__ = ("_compute", "_args", "_data")  # no __dict__: one object less for the collector a result

    def __init__(self, compute: Callable[..., Mapping[str, np.ndarray]], *args: Any):
        self._compute: Callable[..., Mapping[str, np.ndarray]] | None = compute
        self._args = args
        self._data: dict[str, np.ndarray] | None = None

    def _get(self) -> dict[str, np.ndarray]:
        if self._data is None:
            self._data = dict(self._compute(*self._args))  # type: ignore[misc]
            self._compute, self._args = None, ()
        return self._data

    @property
    def computed(self) -> bool:
        """Whether the terms have been computed yet."""
        return self._data is not None

    def __getitem__(self, key: str) -> np.ndarray:
        return self._get()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())

    def __repr__(self) -> str:
        return f"LazyTerms({'computed: ' + ', '.join(self._get()) if self.computed else 'not computed yet'})"


@dataclasses.dataclass(frozen=True)
class Compliance:
    """Compliance of an H4 at one pose (shapes as below) or a batch (a leading N axis).

    Attributes:
        matrix: (8, 8) K of eq. 30, dtp = K Gamma_ext, SI (m/N, rad/N, m/(N.m), rad/(N.m)).
        terms: "control", "bending", "torsion", "tension" (eq. 30) and one per kind of optional
            element that is on (``"revolute_radial"``, ..., :data:`h4pin.description.elements.ELEMENTS`):
            (8, 8) each, summing to ``matrix``; computed on first access (:class:`LazyTerms`)
            unless ``compliance(..., terms=True)``.
        pose: (4,) [x, y, z, theta] in m, rad.
        q: (4,) actuator angles in rad.
        model: "paper" or "consistent".
        condition: condition number of the scaled M1 (how close to a singularity the pose is;
            poses at or above :data:`SINGULAR_COND` are refused).
        status: verdict code per pose (0 ok; 1 unreachable, 2 joint limits, 3 interfering bars,
            4 singular, 5 not a finite pose; :data:`h4pin.verdicts.STATUS_NAMES`).
        valid: (N,) bool for a batch computed with ``on_error="nan"`` (False rows are NaN);
            ``None`` otherwise.
        elements: the optional elements included (``None``: eq. 30 alone).
    """

    matrix: np.ndarray
    terms: Mapping[str, np.ndarray]
    pose: np.ndarray
    q: np.ndarray
    model: str
    condition: np.ndarray | float
    status: np.ndarray | int = 0
    valid: np.ndarray | None = None
    elements: Elements | None = None

    @classmethod
    def _of(cls, *values: Any) -> Compliance:
        """The result of the one-pose fast path, made without the dataclass' field-by-field
        ``__init__`` (the same fields, in order)."""
        obj = object.__new__(cls)
        obj.__dict__.update(zip(_FIELDS, values, strict=True))
        return obj

    @classmethod
    def _one(cls, matrix: np.ndarray, terms: Mapping[str, np.ndarray], pose: np.ndarray, q: np.ndarray, model: str,
             condition: float, elements: Elements | None) -> Compliance:
        """:meth:`_of` for one regular pose (status 0, valid None), field by field (a third of
        the time of ``dict.update``; :data:`_FIELDS` is checked against it in the tests)."""
        obj = object.__new__(cls)
        d = obj.__dict__
        d["matrix"] = matrix
        d["terms"] = terms
        d["pose"] = pose
        d["q"] = q
        d["model"] = model
        d["condition"] = condition
        d["status"] = 0
        d["valid"] = None
        d["elements"] = elements
        return obj

    @property
    def translational(self) -> np.ndarray:
        """The 3x3 block dD = K_tt F, in m/N (Table II of the paper, in um/N, is 1e6 times it)."""
        return self.matrix[..., :3, :3]

    def deflection(self, load: np.ndarray) -> np.ndarray:
        """dtp (8,) (or (N, 8)) for a load Gamma_ext (8,) or a force F (3,) at D, SI."""
        return self.matrix @ as_load(load)

    def at(self, offset: np.ndarray, load_at: np.ndarray | None = None) -> np.ndarray:
        """Translational compliance (3, 3) (or (N, 3, 3)) at a point p fixed to the central bar,
        for a force applied at p' (default p' = p), SI (m/N).

        ``offset`` o and ``load_at`` o' (3,) (or (N, 3)) are the points in the central-bar frame,
        in m: p - D = Rz(theta) o, with theta the pose's (the frame is world-aligned at theta = 0).
        A small plate motion moves p by ``dp = dD + dOmega x (p - D) = T_p [dD; dOmega]`` with
        ``T_p = [I, -[p - D]x]`` (3x6); a force F at p' is ``[F, (p' - D) x F] = T_p'^T F`` at D.
        Hence ``C_pp' = T_p K6 T_p'^T``, K6 the F, T block of :attr:`matrix` (the same in both
        models). With ``offset = load_at = 0`` it is :attr:`translational`; for p != p' it is not
        symmetric (``C_p'p = C_pp'^T``).
        """
        theta = np.asarray(self.pose)[..., 3]
        rot = cf.rot_z(theta)

        def transform(o: np.ndarray, name: str) -> np.ndarray:
            o = real_array(o, name, ParameterError, "real numbers (m)")
            if o.shape[-1:] != (3,) or o.ndim > 2:
                raise ParameterError(f"a point offset must have shape (3,) or (N, 3), got shape {o.shape}")
            if not np.all(np.isfinite(o)):
                raise ParameterError(f"a point offset must be finite (m), got {o.tolist()}")
            r = np.einsum("...ab,...b->...a", rot, o)
            t = np.zeros((*r.shape[:-1], 3, 6))
            t[..., :, :3] = np.eye(3)
            t[..., :, 3:] = -np.swapaxes(cf.cross(r[..., None, :], np.eye(3)), -1, -2)  # -[r]x
            return t

        tp = transform(offset, "offset")
        tq = tp if load_at is None else transform(load_at, "load_at")
        return tp @ self.matrix[..., :6, :6] @ np.swapaxes(tq, -1, -2)


_FIELDS = tuple(f.name for f in dataclasses.fields(Compliance))


def as_load(load: Any) -> np.ndarray:
    """A force F (3,) or a full Gamma_ext = [F, T, t1, t2] (8,) as Gamma_ext (8,), SI."""
    g = real_array(load, "load", LoadError, "real numbers: a force F (3,) in N or Gamma_ext (8,)")
    if g.shape == (3,):
        g = np.r_[g, np.zeros(5)]
    if g.shape != (8,) or not np.all(np.isfinite(g)):
        raise LoadError(f"load must be a finite force F (3,) in N or Gamma_ext = [F, T, t1, t2] (8,), "
                        f"got {load!r}")
    limits.check_range("load: force F", g[:3], "load")  # h4pin.limits.RANGES (1e300 N is a typo, not a load)
    limits.check_range("load: torque T, t1, t2", g[3:], "torque")
    return g


def matrices_at(h4, pose: np.ndarray) -> Matrices:
    """All the paper's matrices at one pose, through Pinocchio (:func:`h4pin.stiffness.matrices.from_kinematics`).

    Raises:
        UnreachablePoseError (and subclasses): as :func:`compliance`.
    """
    return from_kinematics(kin.kinematics(h4, pose))


def check_options(model: str, on_error: str, method: str) -> None:
    """The options of :func:`compliance`: each a ``str`` among its names, else a :class:`ParameterError`."""
    check_choice(model, MODELS, "model")
    check_choice(on_error, ON_ERRORS, "on_error")
    check_choice(method, METHODS, "method")


def _check_call(h4: Any, model: Any, on_error: Any, method: Any, terms: Any) -> tuple[str, str, str, bool | None]:
    """The arguments of :func:`compliance` other than the pose and ``elements`` (the slow side of its
    door: a subclass, a ``numpy.str_`` or a ``numpy.bool_`` passes, as plain values; anything
    else is a :class:`ParameterError` naming the argument)."""
    if is_mechanism(h4):
        raise ParameterError("h4pin.compliance computes the H4's compliance (eq. 30) and takes an h4pin.H4 "
                             "(from h4pin.load), got a Mechanism: for any closed-loop robot call its own method, "
                             "Mechanism.compliance(q, springs, outputs) (docs/mechanisms.md)")
    check_instance(h4, H4, "h4", "an h4pin.H4 (from h4pin.load)")
    return (check_choice(model, MODELS, "model"), check_choice(on_error, ON_ERRORS, "on_error"),
            check_choice(method, METHODS, "method"), check_flag(terms, "terms", none=True))


def _elements_of(h4, elements: Elements | bool | None) -> Elements | None:
    """The elements a call includes: the robot's (None/True), none (False), or those given."""
    if elements is None or elements is True:
        active = h4.elements
    elif elements is False:
        return None
    elif isinstance(elements, Elements):
        active = elements
    elif isinstance(elements, np.bool_):
        return _elements_of(h4, bool(elements))
    else:
        raise ParameterError(f"elements must be None (the robot's own), False (eq. 30 alone) or an h4pin.Elements, "
                             f"got {describe(elements)}")
    return None if active.off else active


def _backend(h4, method: str) -> Callable[..., Raw]:
    if method == "auto":  # the kernel once compiled (h4pin._jit), for exact parallelograms
        method = "kernel" if h4.geometry.ideal and kernel.BATCH.ready else "closed_form"
    return importlib.import_module(BACKENDS[method]).backend


def _names(active: Elements | None) -> tuple[str, ...]:
    """The terms of a result: eq. 30's four, then one per element kind on."""
    return TERMS + (() if active is None else tuple(k.name for k in active.kinds_on()))


def compliance(h4, pose: np.ndarray, model: str = "paper", *, elements: Elements | bool | None = None,
               on_error: str = "raise", method: str = "auto", terms: bool | None = None) -> Compliance:
    """Compliance matrix K of the robot at a pose or a batch of poses: eq. 30 plus its elements.

    Args:
        h4: The robot (:func:`h4pin.load`).
        pose: (4,) or (N, 4) poses [x, y, z, theta] in m, rad (copied: the result owns it).
        model: ``"paper"`` (eq. 30 as printed, errata 1-3 fixed) or ``"consistent"``
            (erratum 4 fixed too, K symmetric).
        elements: ``None`` (default): the robot's own optional elements (:attr:`H4.elements <h4pin.H4>`,
            from its URDF), each a named term; ``False``: eq. 30 alone; an :class:`h4pin.Elements`:
            those instead.
        on_error: ``"raise"``: the first pose the robot cannot take, or a singular one, raises
            its typed error (:class:`h4pin.UnreachablePoseError` and subclasses,
            :class:`h4pin.SingularPoseError`) naming its index. ``"nan"``: such poses (and NaN
            poses) give NaN matrices, ``valid`` False and their ``status``.
        method: ``"auto"``, ``"kernel"``, ``"closed_form"`` or ``"pinocchio"`` (module docstring).
            Every method gives the same verdicts and numbers (to round-off).
        terms: Compute the terms now (``True``); by default they are computed when first
            accessed (:attr:`Compliance.terms`).

    Returns:
        A :class:`Compliance`.

    Raises:
        ParameterError: ``h4`` is not an :class:`h4pin.H4`, an option is not one of its names (a
            ``str``), ``terms`` is not a bool or None, ``elements`` is none of the above.
        PoseError: ``pose`` is not real numbers of shape (4,) or (N, 4) (bools, text, ``None``,
            complex numbers and masked arrays are refused), or not finite with ``on_error="raise"``.
        UnreachablePoseError, SingularPoseError: as ``on_error`` says.
    """
    if elements is None and terms is None and type(model) is str and type(method) is str and type(on_error) is str \
            and on_error == "raise" and type(pose) is np.ndarray and pose.shape == (4,) and pose.dtype is _F64:
        # The usual call: one pose of the robot's own elements, through the one-pose entry of the
        # compiled pipeline; its robot-dependent part looked up once per (robot, model, method).
        fast = _FAST.get((id(h4), model, method))
        if fast is None:
            fast = _fast(h4, model, method)
        if fast:
            x = pose.copy()
            x.setflags(write=False)
            K, q, cond, status, _ = kernel.one(fast[0], x, fast[1])
            if status == OK:
                return Compliance._one(K, LazyTerms(_terms_of, h4, x, model, method, fast[2]), x, q, model, cond,
                                       fast[2])
    # The door (issue 30): the usual call passes on identity tests alone (a few tens of ns);
    # anything else goes through _check_call, which accepts subclasses and numpy's str and bool.
    if not (type(h4) is H4 and type(model) is str and model in MODELS and type(on_error) is str
            and on_error in ON_ERRORS and type(method) is str and method in METHODS
            and (terms is None or terms is True or terms is False)):
        model, on_error, method, terms = _check_call(h4, model, on_error, method, terms)
    active = _elements_of(h4, elements)
    if on_error == "raise" and type(pose) is np.ndarray and pose.shape == (4,) and pose.dtype is _F64:
        # One pose: straight to its backend (a pose it refuses goes the long way for its error).
        x = pose.copy()
        x.setflags(write=False)
        want = bool(terms)
        g = h4.geometry
        if g.ideal and (method == "kernel" or (method == "auto" and kernel.ONE.ready)):  # the one-pose entry
            K, q, cond, status, T = kernel.one(kernel.for_geometry(g, active), x, MODELS.index(model), want)
        elif math.isfinite(sum(pose.tolist())):
            r = _backend(h4, method)(h4, x[None], model, want, active)
            K, q, cond, status = r.matrix[0], r.q[0], float(r.condition[0]), int(r.status[0])
            T = None if r.terms is None else r.terms[0]
        else:
            status = INVALID
        if status == OK:
            parts: Mapping[str, np.ndarray] = (LazyTerms(_terms_of, h4, x, model, method, active) if not want
                                               else dict(zip(_names(active), T, strict=True)))
            return Compliance._one(K, parts, x, q, model, cond, active)
    return _compliance(h4, pose, model, on_error, method, bool(terms), active)


#: The one-pose compiled path per (id of a robot, model, method): (kernel, model code, elements),
#: or () where it does not apply (a toleranced robot, method="closed_form"...). Filled at first use
#: once the compiled pipeline is ready (before, "auto" takes the numpy reference); an entry goes
#: with its robot (the robot is immutable: nothing else can make it stale).
_FAST: dict[tuple[int, Any, Any], tuple] = {}


def _fast(h4: Any, model: Any, method: Any) -> tuple:
    """The entry of :data:`_FAST` for the arguments of :func:`compliance` (``()``: the general path)."""
    if type(h4) is not H4:
        return ()  # the door's (a robot of another type is not cached)
    ideal = h4.geometry.ideal
    if method == "auto" and ideal and not kernel.ONE.ready:
        return ()  # not cached: the pipeline may be ready at the next call
    entry: tuple = ()
    if model in MODELS and method in ("auto", "kernel") and ideal:
        active = _elements_of(h4, None)
        entry = (kernel.for_geometry(h4.geometry, active), MODELS.index(model), active)
    key = (id(h4), model, method)
    if _FAST.setdefault(key, entry) is entry:
        weakref.finalize(h4, _FAST.pop, key, None)
    return _FAST[key]


def _terms_of(h4, x: np.ndarray, model: str, method: str, active: Elements | None) -> Mapping[str, np.ndarray]:
    """The terms of a result (:class:`LazyTerms`), computed on first access by the same backend
    (``x`` is the result's own read-only pose)."""
    return _compliance(h4, x, model, "nan", method, True, active).terms


def _check_size(pose: Any, keep: bool, active: Elements | None) -> None:
    """Refuse, before any copy, a batch whose results do not fit in memory (:mod:`h4pin.limits`:
    ``H4PIN_MEMORY_LIMIT``): e.g. a broadcast view of 1e9 poses takes no memory, its results 700 GB."""
    shape = getattr(pose, "shape", None)
    if not isinstance(shape, tuple) or len(shape) != 2 or shape[0] < 100_000:
        return
    n = int(shape[0])
    per = limits.COMPLIANCE_BYTES_PER_POSE + (limits.COMPLIANCE_BYTES_PER_TERM * len(_names(active)) if keep else 0)
    limits.check_size(f"h4pin.compliance: {n:,} poses", n * per, n / limits.COMPLIANCE_POSES_PER_S,
                      "give fewer poses a call, or stream them (h4pin.stiffness.kernel.iter_compliance)")


def _compliance(h4, pose: Any, model: str, on_error: str, method: str, keep: bool,
                active: Elements | None) -> Compliance:
    _check_size(pose, keep, active)
    pose = real_array(pose, "pose")  # no bools, text, None, complex or masked arrays (PoseError)
    raw = pose.copy() if on_error == "nan" else None
    if raw is not None and raw.ndim in (1, 2) and raw.shape[-1] == 4:
        x = raw
        finite = np.atleast_1d(np.all(np.isfinite(np.atleast_2d(x)), axis=1))
    else:
        x = cf.as_poses(pose).copy()
        finite = None  # every pose (as_poses refuses the others)
    x.setflags(write=False)
    single = x.ndim == 1
    xb = x[None] if single else x
    n = len(xb)
    names = _names(active)
    backend = _backend(h4, method)
    idx_all = slice(None) if finite is None else np.flatnonzero(finite)  # the finite poses
    if ((finite is None or len(idx_all) == n)
            and (backend.__module__ == kernel.__name__ or n <= _BATCH_CHUNK)):
        # Every pose finite, one call: the backend's arrays are the result's (no copy; the kernel
        # is never cut in chunks: its memory is its output's).
        r = backend(h4, np.ascontiguousarray(xb), model, keep, active)
        matrix, q, cond, status = r.matrix, r.q, r.condition, r.status.astype(np.int8, copy=False)
        out_terms = {name: r.terms[:, t] for t, name in enumerate(names)} if keep else None
    else:
        idx_all = np.arange(n) if finite is None else idx_all
        matrix, q = np.full((n, 8, 8), np.nan), np.full((n, 4), np.nan)
        cond, status = np.full(n, np.nan), np.full(n, INVALID, dtype=np.int8)
        out_terms = {t: np.full((n, 8, 8), np.nan) for t in names} if keep else None
        for start in range(0, len(idx_all), _BATCH_CHUNK):
            idx = idx_all[start:start + _BATCH_CHUNK]
            r = backend(h4, np.ascontiguousarray(xb[idx]), model, keep, active)
            matrix[idx], q[idx], cond[idx], status[idx] = r.matrix, r.q, r.condition, r.status
            if keep:
                for t, name in enumerate(names):
                    out_terms[name][idx] = r.terms[:, t]
    if on_error == "raise" and np.any(status != OK):
        k = int(np.argmax(status != OK))
        raise_for_status(status, [None] * k + [_detail(h4, xb[k], int(status[k]), cond[k], k)], batch=not single)
    valid = None if on_error == "raise" else status == OK
    parts: Mapping[str, np.ndarray] = (LazyTerms(_terms_of, h4, x, model, method, active) if out_terms is None
                                       else {t: v[0] for t, v in out_terms.items()} if single else out_terms)
    if single:
        return Compliance._of(matrix[0], parts, x, q[0], model, float(cond[0]), int(status[0]),
                              None if valid is None else np.array(valid[0]), active)
    return Compliance._of(matrix, parts, x, q, model, cond, status, valid, active)


def _detail(h4, x: np.ndarray, status: int, cond: float, k: int) -> str:
    """The message of a refused pose (built only for the pose that raises)."""
    if status == SINGULAR:
        return singular_message(cond)
    if status == INVALID:
        return f"pose #{k} is not finite: {x}"
    return cf.solve(h4.geometry, x).detail[0]
