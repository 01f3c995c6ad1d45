# SPDX-License-Identifier: Apache-2.0
"""The checks of the arguments a :class:`~h4pin.mechanism.Mechanism` call takes: joints given by
name or Pinocchio id, one item or several, each refused by name when it is not the model's."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.mechanism.engine import FrameOutput, JointOutput


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


def checked_springs(mech: Any, springs: Mapping[Any, Any], locked: Iterable[Any] = (),
                    free_root: bool = False) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``(springs, locked)`` of a :meth:`Mechanism.compliance` or :meth:`Mechanism.modes` call,
    checked as the call checks them (names, values, a joint both locked and sprung), by name."""
    stiff = springs_of(mech, springs)
    return stiff, locked_of(mech, locked, stiff, free_root)


def springs_of(mech: Any, springs: Mapping[Any, Any]) -> dict[str, Any]:
    """The checked springs of a call, the beams' included."""
    if not isinstance(springs, Mapping) or not (springs or mech.beam_springs):
        raise ParameterError(f"springs: a mapping {{joint: stiffness}} with at least one spring, got {springs!r}")
    names = joint_names(mech.model, list(springs), "springs")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"springs: joint {twice[0]!r} is given twice (by name and by id?)")
    return {**mech.beam_springs, **dict(zip(names, springs.values(), strict=True))}


def locked_of(mech: Any, locked: Iterable[Any], springs: Mapping[str, Any], free_root: bool) -> tuple[str, ...]:
    """The locked joints of a call: ``locked``, and the free-flyer roots unless freed or sprung."""
    if not isinstance(free_root, bool):
        raise ParameterError(f"free_root: True or False, got {free_root!r}")
    names = joint_names(mech.model, locked, "locked")
    both = sorted(set(names) & set(springs))
    if both:
        raise ParameterError(f"joint {both[0]!r} cannot be both locked and sprung")
    if not free_root:
        names = names + tuple(n for n in mech.free_flyers if n not in names and n not in springs)
    return names


def outputs_of(mech: Any, outputs: Sequence[Any]) -> list[Any]:
    """The outputs of a call as :class:`FrameOutput` and :class:`JointOutput` values (a frame name
    for a frame's 6 rows), each checked against the mechanism's model."""
    outputs = items(outputs, (str, FrameOutput, JointOutput), "outputs: frame names, FrameOutput or JointOutput")
    out = []
    for o in outputs:
        if isinstance(o, str):
            if not mech.model.existFrame(o):
                raise ParameterError(f"outputs: no frame {o!r} in {mech.name}")
            out.append(FrameOutput(o))
        elif isinstance(o, FrameOutput):
            if not mech.model.existFrame(o.frame):
                raise ParameterError(f"outputs: no frame {o.frame!r} in {mech.name}")
            out.append(o)
        elif isinstance(o, JointOutput):
            joint_names(mech.model, [o.joint], "outputs")
            out.append(o)
        else:
            raise ParameterError(f"outputs: frame names, FrameOutput or JointOutput, got {o!r}")
    if not out:
        raise ParameterError("outputs: give at least one frame")
    return out
