# SPDX-License-Identifier: Apache-2.0
"""First use without waiting for the compiler: which compiled functions are ready, their
interpreted twins, and the background warm-up.

h4pin's compiled code (numba, cached on disk) takes about two minutes to compile the first time, once per
install. Until it is in numba's cache, the calls that need it do not wait:

* :func:`h4pin.compliance` (``method="auto"``) takes the numpy reference backend, vectorised
  over the poses (the same numbers to round-off, the same verdicts: a test keeps them equal);
* :func:`h4pin.load` and the Pinocchio path run the *interpreted twin* of the compiled function
  (:func:`interpreted`): the very same Python source, run by the interpreter, its compiled
  callees replaced by their own twins (no second copy of the math);
* and one background process (``python -m h4pin.warmup``) compiles everything into the cache.
  A process checks at most once a second whether the cache is ready and then switches to the
  compiled code (results may then differ in the last bits, never more than the tested 1e-12).

``H4PIN_WARMUP`` chooses: ``background`` (default, as above), ``inline`` (compile in the calling
process at first use, as plain numba does: no fallback, no extra process), ``off`` (fall back
but start no background process). ``h4pin warmup`` (or :func:`h4pin.warmup.compile_all`)
compiles everything in the foreground, e.g. in a Dockerfile after ``pip install``.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import threading
import time
import types
from collections.abc import Callable
from typing import Any

from h4pin import _numba_cache
from h4pin.files import alive

MODES = ("background", "inline", "off")
_RECHECK_S = 1.0


def mode() -> str:
    """``H4PIN_WARMUP`` (default ``background``); an unknown value means ``background``."""
    value = os.environ.get("H4PIN_WARMUP", "background").strip().lower()
    return value if value in MODES else "background"


def _ready_one(f: Any) -> bool:
    """Whether dispatcher ``f`` is compiled in this process or loadable from numba's cache."""
    if not hasattr(f, "signatures"):  # NUMBA_DISABLE_JIT: a plain function
        return True
    if f.signatures:
        return True
    try:
        return bool(f._cache._cache_file._load_index())  # overloads whose source stamp is current
    except Exception:  # another numba's cache layout: do not guess, compile as numba would
        return True


class Gate:
    """Readiness of a group of compiled functions that one call needs (checked on disk at most
    once a second while not ready; once ready, ready for good)."""

    def __init__(self, name: str, *functions: Any, step: str | None = None):
        self.name = name
        self.functions = functions
        #: The warm-up step (:data:`h4pin.warmup.KEYS`) that compiles them: a background
        #: warm-up started here compiles it first.
        self.step = step
        self._ok = False
        self._next = 0.0

    def cached(self) -> bool:
        """Whether the functions are compiled here or current in numba's cache (no side effect)."""
        return self._ok or all(_ready_one(f) for f in self.functions)

    @property
    def ready(self) -> bool:
        """True when the call may use the compiled functions without compiling (or when
        ``H4PIN_WARMUP=inline``); else starts the background warm-up (once) and says False."""
        if self._ok:
            return True
        if all(getattr(f, "signatures", True) for f in self.functions):  # compiled in this process
            self._ok = True
            return True
        if _forced or mode() == "inline":
            return True
        now = time.monotonic()
        if now < self._next:
            return False
        if all(_ready_one(f) for f in self.functions):
            self._ok = True
            return True
        self._next = now + _RECHECK_S
        start_background(self.step)
        return False


_forced = 0


class compiling:  # noqa: N801  (a context manager, used like a function)
    """Within it, every gate says ready: calls compile what they need (:mod:`h4pin.warmup`)."""

    def __enter__(self) -> None:
        global _forced
        _forced += 1

    def __exit__(self, *exc: object) -> None:
        global _forced
        _forced -= 1


# ----------------------------------------------------------------------------------------------
# Entry points linked without a second optimisation


#: The mangled-name prefixes of the functions :func:`link_as_compiled` marked, by numba's library
#: name (the function's qualified name).
_LINKED_AS_COMPILED: dict[str, tuple[str, ...]] = {}


def link_as_compiled(f: Any) -> Any:
    """Mark compiled function ``f`` (a numba dispatcher, returned) so that, when numba builds its
    machine code, the compiled functions it calls are linked in as they were optimised when they
    were compiled, not optimised a second time together with ``f``.

    Numba links the optimised module of every callee into its caller's and runs LLVM's whole
    module pipeline over the result again, at every level of calls. For an entry point whose
    callees are a few large stages, called once per block of poses, that second pass is pure
    compile time: on the pipeline's batch entry, LLVM's module passes took 15.5 of the 45 s it
    took to compile alone, optimising the 64-lane stages again. Marked, ``f``'s own code still
    gets numba's function passes and its callees keep their own full optimisation; the results
    are bit-identical and the speed the same (measured on the three entry points marked,
    docs/architecture.md "First use").

    This hooks a private method of numba (``CPUCodeLibrary._optimize_final_module``), once per
    process, for the marked functions only; a numba without it, or whose pass managers differ,
    compiles them as usual (optimising twice changes nothing but the time).
    """
    py = getattr(f, "py_func", None)
    if py is None:  # NUMBA_DISABLE_JIT: a plain function
        return f
    try:
        from numba.core.itanium_mangler import mangle_identifier
    except ImportError:  # pragma: no cover - another numba: compiled as usual
        return f
    parts = [*py.__module__.split("."), *py.__qualname__.split(".")]
    prefix = "_ZN" + "".join(mangle_identifier(part) for part in parts)
    _LINKED_AS_COMPILED[py.__qualname__] = (*_LINKED_AS_COMPILED.get(py.__qualname__, ()), prefix)
    _hook_codegen()
    return f


def _hook_codegen() -> None:
    """Install :func:`link_as_compiled`'s hook on numba's code library class (once)."""
    try:
        from numba.core import codegen
    except ImportError:  # pragma: no cover - numba is a dependency
        return
    cls = getattr(codegen, "CPUCodeLibrary", None)
    full = getattr(cls, "_optimize_final_module", None)
    if full is None or getattr(full, "_h4pin_hook", False):
        return

    def optimize_final_module(self: Any) -> None:
        prefixes = _LINKED_AS_COMPILED.get(getattr(self, "name", None), ())
        module = getattr(self, "_final_module", None)
        if not prefixes or module is None or not any(fn.name.startswith(prefixes) for fn in module.functions):
            full(self)
            return
        try:  # numba's cheap module passes alone (its reference-count pruning needs them)
            cheap, builder = self._codegen._module_pass_manager(loop_vectorize=self._codegen._loopvect,
                                                                slp_vectorize=False, opt=self._codegen._opt_level,
                                                                cost="cheap")
            cheap.run(module, builder)
            if not codegen.config.LLVM_REFPRUNE_PASS:
                self._final_module = codegen.remove_redundant_nrt_refct(module)
        except Exception:  # another numba's pass managers: optimise as numba does
            full(self)

    optimize_final_module._h4pin_hook = True  # type: ignore[attr-defined]
    cls._optimize_final_module = optimize_final_module


# ----------------------------------------------------------------------------------------------
# Interpreted twins


_TWINS: dict[int, Callable] = {}
_TWIN_LOCK = threading.RLock()


class _ModuleTwin:
    """A module seen from an interpreted twin: its compiled functions are twins too."""

    def __init__(self, module: types.ModuleType):
        self._module = module

    def __getattr__(self, name: str) -> Any:
        return _twin_of(getattr(self._module, name))


def _is_dispatcher(value: Any) -> bool:
    return hasattr(value, "py_func") and hasattr(value, "signatures")


def _twin_of(value: Any) -> Any:
    if _is_dispatcher(value):
        return interpreted(value)
    if isinstance(value, types.ModuleType) and value.__name__.startswith("h4pin."):
        return _ModuleTwin(value)
    return value


def interpreted(f: Any) -> Callable:
    """The interpreted twin of compiled function ``f``: its Python source, run by the interpreter,
    with every compiled function it calls (directly or through an h4pin module) replaced by
    that one's twin, so that calling it never compiles anything. Same results as ``f`` up to
    floating-point round-off (tests compare them); much slower (it is for first use only)."""
    if not _is_dispatcher(f):
        return f
    key = id(f)
    twin = _TWINS.get(key)
    if twin is not None:
        return twin
    with _TWIN_LOCK:
        py = f.py_func
        names = py.__code__.co_names
        glob = dict(py.__globals__)
        twin = types.FunctionType(py.__code__, glob, py.__name__, py.__defaults__, py.__closure__)
        _TWINS[key] = twin  # before the callees: a recursive call finds it
        for name in names:
            if name in glob:
                glob[name] = _twin_of(glob[name])
    return twin


# ----------------------------------------------------------------------------------------------
# The background warm-up


_started = False
_start_lock = threading.Lock()


def lock_path() -> str:
    """One lock per cache location and user: two processes never compile the same cache at once."""
    import numba

    where = str(_numba_cache.folder() or os.environ.get("NUMBA_CACHE_DIR") or numba.config.CACHE_DIR
                or os.path.dirname(__file__))
    tag = hashlib.sha1(os.path.abspath(where).encode()).hexdigest()[:12]
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return os.path.join(tempfile.gettempdir(), f"h4pin-warmup-{uid}-{tag}.lock")


def running() -> bool:
    """Whether a warm-up process is compiling into this process's cache now."""
    try:
        with open(lock_path()) as fh:
            return alive(int(fh.read().strip() or 0))
    except (OSError, ValueError):
        return False


def start_background(first: str | None = None) -> bool:
    """Start the warm-up process unless one runs, one was started here, or ``H4PIN_WARMUP`` is
    not ``background``; it compiles step ``first`` (:data:`h4pin.warmup.KEYS`) before the others.
    Returns whether this call started it."""
    global _started
    if _started or mode() != "background":
        return False
    with _start_lock:
        if _started or running():
            return False
        _started = True
        env = dict(os.environ, H4PIN_WARMUP="inline")
        try:
            first_args = ["--first", first] if first else []
            subprocess.Popen([sys.executable, "-m", "h4pin.warmup", "--lock", lock_path(), *first_args], env=env,
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True, close_fds=True)
        except OSError:
            return False
        return True
