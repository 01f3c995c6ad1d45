# SPDX-License-Identifier: Apache-2.0
"""The checks of the arguments a :class:`~h4pin.mechanism.Mechanism` call takes: joints given by
name or Pinocchio id, one item or several, each refused by name when it is not the model's."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError


def items(value: Any, single: tuple[type, ...], what: str) -> list[Any]:
    """``value`` as a list: one item of a ``single`` type, or the items of an iterable; else a
    :class:`ParameterError` "``what``, got ..."."""
    if isinstance(value, single):
        return [value]
    try:
        return list(value)
    except TypeError:
        raise ParameterError(f"{what}, got {value!r}") from None


def joint_names(model: pin.Model, joints: Iterable[Any], what: str) -> tuple[str, ...]:
    """Joint names from names or Pinocchio ids (one, or several), each checked (a typed error
    naming it)."""
    if isinstance(joints, bytes):  # list(b"ab") would read as joint ids 97, 98
        raise ParameterError(f"{what}: joint names (text) or Pinocchio joint ids, got {joints!r}")
    joints = items(joints, (str, int, np.integer), f"{what}: joint names or Pinocchio joint ids")
    out = []
    for j in joints:
        if isinstance(j, (int, np.integer)) and not isinstance(j, bool):
            if not 0 < int(j) < model.njoints:
                raise ParameterError(f"{what}: joint id {int(j)} is not a joint of the model (1..{model.njoints - 1})")
            out.append(model.names[int(j)])
        elif isinstance(j, str):
            if not model.existJointName(j):
                known = ", ".join(list(model.names)[1:])
                raise ParameterError(f"{what}: no joint {j!r} in the model (joints: {known})")
            out.append(j)
        else:
            raise ParameterError(f"{what}: a joint is a name or a Pinocchio joint id, got {j!r}")
    return tuple(out)
