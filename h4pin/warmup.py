# SPDX-License-Identifier: Apache-2.0
"""Compile h4pin's numba functions into numba's on-disk cache now, instead of at first use.

``h4pin warmup`` (or ``python -m h4pin.warmup``, or :func:`compile_all`) compiles, in order of
first need: the Pinocchio configuration (``h4pin.load``), the compiled pipeline's one-pose and
batch entries, the natural frequencies, the atlas and sweep reductions, a tiny atlas and
sweep run as their commands run them (every signature the commands compile: a test lists them),
and the compiled path of any closed-loop mechanism (:mod:`h4pin.elastic.compiled`).
After it, every call starts compiled.
h4pin starts this module by itself in the background the first time a call needs code that is
not compiled yet (:mod:`h4pin._jit`); run it yourself where a first call must be fast, e.g. after
``pip install`` in a Dockerfile.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import numpy as np


def steps() -> list[tuple[str, Callable[[], object]]]:
    """The compile steps (name, call), in order of first need."""
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

    return [("configuration (h4pin.load)", configuration),
            ("compiled pipeline, one pose", lambda: compliance(state["h4"], pose(), method="kernel")),
            ("compiled pipeline, batch", lambda: compliance(state["h4"], np.tile(pose(), (2, 1)), method="kernel")),
            ("natural frequencies", lambda: modes(state["h4"], np.tile(pose(), (2, 1)), method="compiled")),
            ("atlas and sweep fields", _study_fields),
            ("atlas and sweep, as their commands run", lambda: _studies(state["h4"])),
            ("any mechanism's compiled path (h4pin.elastic.Mechanism)", _mechanism)]


def _mechanism() -> None:
    """The generic compiled path (:mod:`h4pin.elastic.compiled`): a batch compliance and a batch of
    natural frequencies of a three-joint closed loop built here, through :class:`Mechanism`."""
    import pinocchio as pin

    from h4pin.elastic import Mechanism

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


def compile_all(progress: Callable[[str, float], None] | None = None) -> float:
    """Compile every function into numba's cache (loaded instead if it is there); returns the
    seconds taken. ``progress(step, seconds)`` is called after each step."""
    from h4pin import _jit

    t0 = time.perf_counter()
    with _jit.compiling():
        for name, call in steps():
            t = time.perf_counter()
            call()
            if progress is not None:
                progress(name, time.perf_counter() - t)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    """``python -m h4pin.warmup [--lock PATH] [--quiet]``: the background warm-up holds ``--lock``
    while it compiles, so that no second process compiles the same cache at once."""
    parser = argparse.ArgumentParser(prog="python -m h4pin.warmup", description=__doc__.splitlines()[0])
    parser.add_argument("--lock", help="lock file to hold while compiling (background warm-up)")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    from h4pin.files import release_lock, take_lock

    if args.lock and not take_lock(args.lock):
        return 0  # another process compiles this cache now
    try:
        def say(name: str, seconds: float) -> None:
            if not args.quiet:
                print(f"compiled {name} in {seconds:.1f} s", flush=True)

        total = compile_all(say)
        if not args.quiet:
            print(f"h4pin: compiled code cached ({total:.1f} s)", flush=True)
    finally:
        if args.lock:
            release_lock(args.lock)
    return 0


if __name__ == "__main__":
    sys.exit(main())
