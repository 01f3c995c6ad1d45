# SPDX-License-Identifier: Apache-2.0
"""Compile h4pin's numba functions into numba's on-disk cache now, instead of at first use.

``h4pin warmup`` (or ``python -m h4pin.warmup``, or :func:`compile_all`) compiles, in order of
first need: the Pinocchio configuration (``h4pin.load``), the compiled pipeline's one-pose and
batch entries, the natural frequencies, the atlas and sweep reductions, a tiny atlas and
sweep run as their commands run them (every signature the commands compile: a test lists them),
and the compiled path of any closed-loop mechanism (:mod:`h4pin.mechanism.compiled`).
After it, every call starts compiled. ``h4pin warmup`` and ``python -m h4pin.warmup`` run the
steps in three child processes, one after the other (:func:`compile_all` with ``isolate``),
which bounds the peak memory to the largest group's.
h4pin starts this module by itself in the background the first time a call needs code that is
not compiled yet (:mod:`h4pin._jit`), the step that call needs first; run it yourself where a
first call must be fast, e.g. after ``pip install`` in a Dockerfile.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np

#: The steps' keys, in the default order (order of first need of the H4's commands).
KEYS = ("configuration", "one", "batch", "frequencies", "fields", "studies", "mechanism")
#: What each step compiles.
NAMES = {"configuration": "configuration (h4pin.load)", "one": "compiled pipeline, one pose",
         "batch": "compiled pipeline, batch", "frequencies": "natural frequencies",
         "fields": "atlas and sweep fields", "studies": "atlas and sweep, as their commands run",
         "mechanism": "any mechanism's compiled path (h4pin.mechanism.Mechanism)"}
#: The steps a step's call runs first (it needs a loaded robot).
_NEEDS = {"one": ("configuration",), "batch": ("configuration",), "frequencies": ("configuration",),
          "studies": ("configuration",)}
#: The steps that share a process in an isolated warm-up (:func:`compile_all`), when they come one
#: after the other: numba compiles its own helpers (``np.empty``, ``reshape``, their errors...)
#: again in every process, so a process per step costs about 8 s a step more.
GROUPS = {"configuration": "compliance", "one": "compliance", "batch": "compliance", "frequencies": "studies",
          "fields": "studies", "studies": "studies", "mechanism": "mechanism"}


def order(first: str | None = None) -> list[str]:
    """The steps' keys in compile order: step ``first`` (and what it needs) before the others,
    so that the call that started a background warm-up waits for its own code only (a
    :class:`h4pin.mechanism.Mechanism` user waits 20 s for the generic path, not for the H4's
    two minutes before it); then the rest in :data:`KEYS` order. ``first`` None or unknown:
    :data:`KEYS` order."""
    return with_needs([first, *KEYS] if first in KEYS else list(KEYS))


def chunks(first: str | None = None) -> list[list[str]]:
    """:func:`order` cut into the runs of steps of one :data:`GROUPS` group (a process each in
    an isolated warm-up)."""
    out: list[list[str]] = []
    for key in order(first):
        if out and GROUPS[out[-1][-1]] == GROUPS[key]:
            out[-1].append(key)
        else:
            out.append([key])
    return out


def with_needs(keys: list[str]) -> list[str]:
    """Steps ``keys`` in their order, each after the steps it needs (:data:`_NEEDS`), each once."""
    out: list[str] = []
    for key in keys:
        out += [k for k in (*_NEEDS.get(key, ()), key) if k not in out]
    return out


def calls() -> dict[str, Callable[[], object]]:
    """The compile steps' calls by key (sharing the robot the configuration step loads)."""
    from h4pin.kinematics import closed_form as cf
    from h4pin.robot import load
    from h4pin.stiffness.api import compliance
    from h4pin.vibration import modes

    state: dict[str, object] = {}

    def configuration() -> object:
        state["h4"] = load()
        return state["h4"]

    def pose() -> np.ndarray:
        return cf.centre_pose(state["h4"])

    return {"configuration": configuration,
            "one": lambda: compliance(state["h4"], pose(), method="kernel"),
            "batch": lambda: compliance(state["h4"], np.tile(pose(), (2, 1)), method="kernel"),
            "frequencies": lambda: modes(state["h4"], np.tile(pose(), (2, 1)), method="compiled"),
            "fields": _study_fields,
            "studies": lambda: _studies(state["h4"]),
            "mechanism": _mechanism}


def gates() -> list:
    """The gates (:class:`h4pin._jit.Gate`) of the compiled entry points the steps compile."""
    from h4pin.kinematics import pinocchio as kin
    from h4pin.mechanism import batch
    from h4pin.stiffness import frequencies, kernel

    return [kin.CONFIGURATION, kernel.ONE, kernel.BATCH, frequencies.FREQUENCIES, batch.GATE]


def _mechanism() -> None:
    """The generic compiled path (:mod:`h4pin.mechanism.compiled`): a batch compliance and a batch of
    natural frequencies of a three-joint closed loop built here, through :class:`Mechanism`."""
    import pinocchio as pin

    from h4pin.mechanism import Mechanism

    model = pin.Model()
    placed = [(0, (0.0, 0.0, 0.0), "a"), (1, (1.0, 0.0, 0.0), "b"), (0, (2.0, 0.0, 0.0), "c")]
    for parent, at, name in placed:
        j = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array(at)), name)
        model.appendBodyToJoint(j, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    tip = pin.SE3(np.eye(3), np.array([0.0, 1.0, 0.0]))
    model.addFrame(pin.Frame("tip", 2, 0, tip, pin.FrameType.OP_FRAME))
    loop = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, 2, tip, 3,
                                    pin.SE3(np.eye(3), np.array([-1.0, 1.0, 0.0])))
    mech = Mechanism(model, [loop], ["a"])
    q = np.tile(mech.assemble(), (2, 1))
    springs = {"a": 10.0, "b": 1.0, "c": 1.0}
    mech.compliance(q, springs, ["tip"], method="compiled", threads=1)
    mech.modes(q, springs, method="compiled", threads=1)


def _study_fields() -> None:
    """The compiled reductions of the atlas and the sweep (:mod:`h4pin.studies._derived`)."""
    from h4pin.studies import _derived

    K, J, status = np.tile(np.eye(8), (2, 1, 1)), np.tile(np.eye(4), (2, 1, 1)), np.zeros(2, dtype=np.int8)
    _derived.atlas_fields(K, J, status, *(np.empty(2) for _ in range(4)))
    _derived.design_reduce(K, status, 1)


def _studies(h4) -> None:
    """A one-pose atlas and a one-design sweep, natural frequencies included, through the code
    their commands run: every signature they compile is compiled here too. Numba compiles one
    version per signature, and a signature includes each array's layout and read-only flag: the
    studies pass the same kinds of arrays as ``h4pin.modes`` (the sweep's configuration constants
    read-only, as a loaded robot's), so that this step compiles little of its own
    (``tests/test_warmup_coverage.py`` checks that the commands compile nothing after it)."""
    from h4pin.extras import MissingExtraError
    from h4pin.kinematics import closed_form as cf

    try:
        from h4pin.studies import atlas, sweep
    except MissingExtraError:  # without the 'studies' extra no command runs them
        return
    c = cf.centre_pose(h4)
    atlas.atlas(h4, [c[0]], [c[1]], [c[2]], [c[3]], frequency=True, progress=False)
    spec = sweep.Spec(n_designs=1, chunk=1, frequency=True)
    sweep.evaluate(sweep.designs(spec), spec)


def compile_all(progress: Callable[[str, float], None] | None = None, first: str | None = None, *,
                isolate: bool = False) -> float:
    """Compile every function into numba's cache (loaded instead if it is there); returns the
    seconds taken. ``progress(step, seconds)`` is called after each step; ``first``: the step
    (:data:`KEYS`) to compile before the others (:func:`order`).

    ``isolate``: the steps in child processes, one after the other, a process for each run of
    steps of one :data:`GROUPS` group (:func:`chunks`; what ``h4pin warmup`` and the background
    warm-up do). numba keeps every module it compiled in memory, so that one process compiling
    all the steps ends at the sum of their memory (about 690 MB); a process per group ends at the
    largest group's (about 420 MB). Else in this process (its functions are then compiled here
    too, not only cached)."""
    t0 = time.perf_counter()
    if isolate:
        for chunk in chunks(first):
            run_child(chunk, progress)
        return time.perf_counter() - t0
    compile_steps(order(first), None if progress is None else lambda key, seconds: progress(NAMES[key], seconds))
    return time.perf_counter() - t0


_MARK = "h4pin-warmup-step"


def run_child(keys: list[str], progress: Callable[[str, float], None] | None) -> None:
    """Steps ``keys`` in a child process (``--steps``), its progress passed on as it comes; a
    failure raises, naming the step that failed and the end of the child's output."""
    env = dict(os.environ, H4PIN_WARMUP="inline")
    # Not ``-m h4pin.warmup``: run as ``__main__``, the same steps compiled 8-10 s slower (measured,
    # one pose: 49.7 s against 40.0 s through main() in the same hour).
    args = [sys.executable, "-c", "import sys; from h4pin.warmup import main; sys.exit(main(sys.argv[1:]))",
            "--steps", ",".join(keys)]
    other: list[str] = []
    done: list[str] = []
    with subprocess.Popen(args, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True) as child:
        assert child.stdout is not None
        try:
            for line in child.stdout:
                mark, _, rest = line.partition(" ")
                key, _, secs = rest.strip().partition(" ")
                if mark == _MARK and key in NAMES:
                    done.append(key)
                    if progress is not None:
                        progress(NAMES[key], float(secs))
                else:
                    other.append(line)
        except BaseException:  # a SIGTERM (main's SystemExit), Ctrl-C, a failing progress: end the child too
            child.kill()
            raise
    if child.returncode != 0:
        failed = next((k for k in keys if k not in done), keys[-1])
        tail = "".join(other).strip()[-2000:]
        raise RuntimeError(f"h4pin warm-up step {NAMES.get(failed, failed)!r} failed:\n{tail}")


def compile_steps(keys: list[str], report: Callable[[str, float], None] | None = None) -> None:
    """Compile steps ``keys`` (:data:`KEYS`) in this process, in their order, each after the steps
    it needs (loaded from the cache when compiled before); ``report(key, seconds)`` after each of
    ``keys``."""
    from h4pin import _jit

    table = calls()
    with _jit.compiling():
        for key in with_needs(keys):
            t = time.perf_counter()
            table[key]()
            if report is not None and key in keys:
                report(key, time.perf_counter() - t)


def main(argv: list[str] | None = None) -> int:
    """``python -m h4pin.warmup [--lock PATH] [--quiet] [--first STEP]``: the background warm-up
    holds ``--lock`` while it compiles, so that no second process compiles the same cache at once,
    and compiles first the step of the call that started it."""
    parser = argparse.ArgumentParser(prog="python -m h4pin.warmup", description=__doc__.splitlines()[0])
    parser.add_argument("--lock", help="lock file to hold while compiling (background warm-up)")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--first", choices=KEYS, help="compile this step (and what it needs) before the others")
    parser.add_argument("--steps", help="compile these steps (comma-separated keys, and what they need) in this "
                                         "process, printing a line per step (an isolated warm-up's child)")
    args = parser.parse_args(argv)
    if args.steps:
        keys = args.steps.split(",")
        if not set(keys) <= set(KEYS):
            parser.error(f"--steps: unknown step in {args.steps!r}; the steps are {', '.join(KEYS)}")
        compile_steps(keys, lambda key, secs: print(f"{_MARK} {key} {secs:.3f}", flush=True))
        return 0
    from h4pin.files import release_lock, take_lock

    if args.lock and not take_lock(args.lock):
        return 0  # another process compiles this cache now
    # A SIGTERM ends the running child too (run_child kills it on the SystemExit).
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    try:
        def say(name: str, seconds: float) -> None:
            if not args.quiet:
                print(f"compiled {name} in {seconds:.1f} s", flush=True)

        total = compile_all(say, args.first, isolate=True)
        if not args.quiet:
            print(f"h4pin: compiled code cached ({total:.1f} s)", flush=True)
    finally:
        if args.lock:
            release_lock(args.lock)
    return 0


if __name__ == "__main__":
    sys.exit(main())
