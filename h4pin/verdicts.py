# SPDX-License-Identifier: Apache-2.0
"""One verdict per pose, on every path: the codes, their names, the thresholds and the errors.

Every path that computes a pose (the numpy reference, the compiled core, Pinocchio; one pose or a
batch) gives the same code, and :func:`raise_for_status` turns the first bad one into its typed
error. The order in which they are checked: unreachable, joint limits, interfering bars, singular.

Codes (``int8``): :data:`OK` 0; :data:`UNREACHABLE` 1 (a leg cannot reach its plate point);
:data:`LIMITS` 2 (an actuator or a lateral revolute outside its URDF limits); :data:`INTERFERENCE`
3 (the axes of two bars of different legs closer than the robot's ``bar_clearance``);
:data:`SINGULAR` 4 (the scaled condition number of M1 is not below :data:`SINGULAR_COND`);
:data:`INVALID` 5 (the pose itself is not finite; only with ``on_error="nan"``).
"""

from __future__ import annotations

import numpy as np

from h4pin.errors import InterferenceError, JointLimitError, PoseError, SingularPoseError, UnreachablePoseError

OK, UNREACHABLE, LIMITS, INTERFERENCE, SINGULAR, INVALID = 0, 1, 2, 3, 4, 5
#: Names of the codes, indexed by code.
STATUS_NAMES = ("ok", "unreachable", "outside joint limits", "bars interpenetrate", "singular", "not a finite pose")
#: A pose is singular unless the 1-norm condition number of the scaled M1 (rows over the bar
#: lengths, rotation columns over the mean bar length) is below this. K's relative error is about
#: cond x 1e-16, so an accepted pose's K is accurate to ~1e-7 (tests/test_verdicts.py checks it
#: against the independent statics route at the worst accepted poses).
#: Not 1e10: at 1e10 the symmetric variant's accepted poses near its singular centre are no longer
#: positive definite to round-off in 1 % of them, and the pose 10 nm from it is accepted
#: (tests/test_verdicts.py, measured in issue 37). This is the 1-norm condition of the H4's 8 x 8
#: M1; the generic engine's frozen-mechanism check (h4pin.mechanism.engine) is a 2-norm condition of
#: a stacked closure-Jacobian matrix, the kind of number :data:`CLOSURE_SINGULAR_COND` bounds.
SINGULAR_COND = 1e9
#: Condition number of a closed-loop system (the 24x24 passive block of the H4, a Gepetto toolbox
#: constraint Jacobian, or the generic engine's frozen mechanism ``[Jc; S_locked; S_elastic]`` in
#: scaled units) from which the motion it leaves is taken as uncontrolled: the configuration is
#: refused as singular. (:data:`SINGULAR_COND` is the H4's M1 threshold, another matrix.)
CLOSURE_SINGULAR_COND = 1e10

ERRORS: dict[int, type[PoseError]] = {UNREACHABLE: UnreachablePoseError, LIMITS: JointLimitError,
                                      INTERFERENCE: InterferenceError, SINGULAR: SingularPoseError,
                                      INVALID: PoseError}


def singular_message(cond: float) -> str:
    """The message of a pose refused as singular (:data:`SINGULAR_COND`)."""
    return (f"M1 is singular (cond = {cond:.2e} >= {SINGULAR_COND:.0e}): the plate has a motion that no spring "
            "resists")


def describe_status(status: int) -> str:
    """Human name of a verdict code."""
    code = int(status)
    return STATUS_NAMES[code] if 0 <= code < len(STATUS_NAMES) else "unknown"


def raise_for_status(status: np.ndarray | int, detail: list[str | None], batch: bool) -> None:
    """Raise the typed error of the first pose whose status is not :data:`OK` (with its index for
    a batch); ``detail[k]`` is its message (the code's name when None)."""
    flat = np.atleast_1d(status)
    bad = np.flatnonzero(flat != OK)
    if bad.size:
        k = int(bad[0])
        raise ERRORS[int(flat[k])](detail[k] or STATUS_NAMES[int(flat[k])], k if batch else None)


__all__ = ["CLOSURE_SINGULAR_COND", "ERRORS", "INTERFERENCE", "INVALID", "LIMITS", "OK", "SINGULAR", "SINGULAR_COND",
           "STATUS_NAMES", "UNREACHABLE", "describe_status", "raise_for_status", "singular_message"]
