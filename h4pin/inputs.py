# SPDX-License-Identifier: Apache-2.0
"""The checks at the door of h4pin's public functions (project issue 30, "Wrong types reach the inside").

A public function checks what it is given before anything else touches it, so that a wrong type
gives a typed h4pin error (:class:`h4pin.ParameterError`, or :class:`h4pin.PoseError` for a pose)
naming the argument and what it got, never an ``AttributeError`` or ``TypeError`` from inside
numpy or Pinocchio. The hot paths check with ``type(x) is`` first and call these helpers only when
that fails (to refuse, or to accept a subclass, a numpy bool, ...).

* :func:`describe`: what a value is, for a message: its type name and a short repr (:func:`short`).
* :func:`check_instance`: an object of the documented class(es).
* :func:`check_choice`: a ``str`` among the documented names.
* :func:`check_flag`: a real bool (``numpy.bool_`` too), optionally ``None``.
* :func:`check_real`: a real number (not a bool), optionally finite and >= 0.
* :func:`real_array`: a real numeric array (not bool, object, complex, text, nor masked) as float64.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from typing import Any

import numpy as np

from h4pin.errors import ParameterError, PoseError

_REPR = reprlib.Repr()
_REPR.maxstring = 48
_REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 4
_REPR.maxlevel = 2
#: dtype kinds of a real numeric array: signed and unsigned integers, floats.
REAL_KINDS = frozenset("iuf")


def short(value: Any) -> str:
    """A short one-line repr of ``value`` (long strings and containers cut in the middle)."""
    try:
        text = _REPR.repr(value)
    except Exception:  # noqa: BLE001 - a repr that fails still gets a message
        text = "<no repr>"
    return " ".join(text.split())


def describe(value: Any) -> str:
    """``"<type name> <short repr>"`` of ``value`` (for an array, its dtype and shape too)."""
    text = short(value)
    if isinstance(value, np.ndarray):
        return f"{type(value).__name__} of dtype {value.dtype}, shape {value.shape}: {text}"
    return f"{type(value).__name__} {text}"


def is_mechanism(value: Any) -> bool:
    """Whether ``value`` is an :class:`h4pin.mechanism.Mechanism` (by its class, without importing
    the generic engine: the H4's doors name its own method when one is passed to them)."""
    return any(c.__name__ == "Mechanism" and c.__module__.startswith("h4pin.mechanism") for c in type(value).__mro__)


def check_instance(value: Any, types: type | tuple[type, ...], name: str, what: str,
                   error: type[Exception] = ParameterError) -> Any:
    """``value`` if it is an instance of ``types``; else ``error`` "``name`` must be ``what``, got ..."."""
    if isinstance(value, types):
        return value
    raise error(f"{name} must be {what}, got {describe(value)}")


def check_choice(value: Any, choices: tuple[str, ...], name: str) -> str:
    """``value`` as a plain ``str`` if it is one of ``choices`` (a ``str``, ``numpy.str_`` too);
    else a :class:`ParameterError` naming ``name``, the choices and what it got."""
    if isinstance(value, str) and value in choices:
        return str(value)
    raise ParameterError(f"{name} must be one of {choices} (a str), got {describe(value)}")


def check_flag(value: Any, name: str, none: bool = False) -> bool | None:
    """``value`` as a ``bool`` if it is a real bool (Python's or numpy's), or ``None`` when ``none``;
    else a :class:`ParameterError` (``"no"``, ``[]``, 0 and 1 are not flags)."""
    if value is None and none:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ParameterError(f"{name} must be True or False{' (or None)' if none else ''}, got {describe(value)}")


def check_real(value: Any, name: str, *, finite: bool = True, minimum: float | None = None,
               unit: str = "") -> float:
    """``value`` as a float if it is a real number (not a bool), finite (``finite``) and
    ``>= minimum``; else a :class:`ParameterError` naming ``name``."""
    unit = f" ({unit})" if unit else ""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number{unit}, got {describe(value)}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the floats (10**400): infinite as a float
        x = math.inf if value > 0 else -math.inf
    if (finite and not np.isfinite(x)) or (minimum is not None and not x >= minimum):
        rule = " and ".join([*(["finite"] if finite else []), *([f">= {minimum:g}"] if minimum is not None else [])])
        raise ParameterError(f"{name} must be {rule}{unit}, got {describe(value)}")
    return x


def _holds_bool(value: list | tuple) -> bool:
    """Whether a (nested) list or tuple holds a bool (Python's or numpy's)."""
    stack = [value]
    while stack:
        for x in stack.pop():
            if isinstance(x, (bool, np.bool_)):
                return True
            if isinstance(x, (list, tuple)):
                stack.append(x)
    return False


def real_array(value: Any, name: str, error: type[Exception] = PoseError, what: str = "real numbers") -> np.ndarray:
    """``value`` as a float64 array if it holds real numbers: integers or floats, in an array (not a
    masked one: its mask would be silently dropped), a list or a scalar; else ``error`` naming
    ``name`` and what it got. Bools (a ``True`` among numbers in a list too), text, ``None``
    (object arrays) and complex numbers are refused.
    The shape is the caller's to check; no copy when ``value`` already is a float64 ndarray."""
    if isinstance(value, np.ma.MaskedArray):
        raise error(f"{name} must be {what} in a plain array, not a masked array (its mask would be "
                    f"ignored), got {describe(value)}")
    if type(value) is np.ndarray:
        arr = value
    elif isinstance(value, (str, bytes, bytearray, dict, set, frozenset)) or value is None:
        raise error(f"{name} must be {what}, got {describe(value)}")
    else:
        try:
            arr = np.asarray(value)
        except Exception:  # noqa: BLE001 - ragged lists (ValueError), objects whose __array__ fails, ...
            raise error(f"{name} must be {what}, got {describe(value)}") from None
    kind = arr.dtype.kind
    if kind in REAL_KINDS and isinstance(value, (list, tuple)) and _holds_bool(value):
        kind = "b"  # numpy reads [True, 0.5] as floats: a bool among numbers is refused all the same
    if kind not in REAL_KINDS:
        if kind == "c":
            what = f"{what} (not complex)"
        elif kind == "b":
            what = f"{what} (not bools)"
        raise error(f"{name} must be {what}, got {describe(value)}")
    return arr if arr.dtype == np.float64 else arr.astype(np.float64)


__all__ = ["REAL_KINDS", "check_choice", "check_flag", "check_instance", "check_real", "describe", "real_array",
           "short"]
