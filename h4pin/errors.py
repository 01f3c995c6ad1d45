# SPDX-License-Identifier: Apache-2.0
"""Typed errors of h4pin: every failure a user can act on has its own class.

All derive from :class:`H4Error`, so ``except h4pin.H4Error`` catches any of them.
Errors about a value the caller passed also derive from :class:`ValueError`.
"""

from __future__ import annotations


class H4Error(Exception):
    """Base class of every error raised by h4pin. Its message is one line: the line breaks a
    value's repr brings (a 2-D array's) are made spaces."""

    def __init__(self, *args: object):
        if args and isinstance(args[0], str) and ("\n" in args[0] or "\r" in args[0]):
            args = (" ".join(args[0].split()), *args[1:])
        super().__init__(*args)


class ParameterError(H4Error, ValueError):
    """A parameter of :class:`h4pin.H4Params` (or of a function) is invalid; the message names it."""


class MalformedURDFError(H4Error, ValueError):
    """A URDF cannot describe an H4: a closure, frame or spring datum is missing or inconsistent."""


class InputFileError(ParameterError):
    """An input file h4pin cannot read as one: missing, not a regular file (a FIFO, a device, a
    folder, a socket: reading one could block forever or never end), larger than h4pin reads, or
    unreadable; the message names the path and what it is (:func:`h4pin.files.read_input`)."""


class LoadError(H4Error, ValueError):
    """A load (force F or Gamma_ext) is malformed or not finite; the message names the argument."""


class PoseError(H4Error, ValueError):
    """Base class of the errors about one pose (or one index of a batch of poses).

    Attributes:
        index: Index of the first bad pose in a batch, or ``None`` for a single pose.
    """

    def __init__(self, message: str, index: int | None = None):
        super().__init__(message if index is None else f"pose #{index}: {message}")
        self.index = index


class UnreachablePoseError(PoseError):
    """The robot cannot take this pose: a leg cannot reach its plate point (the closure has no
    real solution), or (subclasses) a joint limit or an interference forbids it."""


class SingularPoseError(PoseError):
    """The pose is (numerically) singular: a matrix the model inverts has lost rank."""


class ConvergenceError(H4Error, RuntimeError):
    """An iterative solve (forward geometry, loaded equilibrium) did not converge."""


class JointLimitError(UnreachablePoseError):
    """The pose needs an actuator or a lateral bar beyond its URDF joint limits."""


class InterferenceError(UnreachablePoseError):
    """At this pose two bars of different legs would pass through each other."""


class URDFNotFoundError(H4Error, FileNotFoundError):
    """No URDF file at the given path."""


class MechanismWarning(UserWarning):
    """A closed-loop robot was read or assembled with a repair the user should know of: a sidecar
    entry the model lacks (ignored, as Gepetto's loader does), motors that had to move for the
    loops to close."""


class UnsupportedFeatureError(H4Error, ValueError):
    """A robot file uses a feature h4pin cannot represent (an MJCF joint coupling, a tendon
    motor): refused by name rather than dropped."""


def located(exc: H4Error, where: str | None) -> H4Error:
    """``exc`` with ``where`` (which configuration of a batch, say) in front of its message."""
    if where is not None and exc.args:
        exc.args = (f"{where}: {exc.args[0]}",) + exc.args[1:]
    return exc
