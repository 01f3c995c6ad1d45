# SPDX-License-Identifier: Apache-2.0
"""Closed-loop stiffness from Pinocchio's Jacobians: a generic engine and the H4's elastic model.

* :mod:`h4pin.elastic.engine`: the compliance of any Pinocchio model with loop closures, locked
  joints and elastic joints (:func:`~h4pin.elastic.engine.compliance_matrix`; the old name
  ``compliance`` is deprecated), and
  :func:`~h4pin.elastic.engine.insert_joints` to add virtual elastic joints to a model;
* :mod:`h4pin.elastic.h4`: :func:`~h4pin.elastic.h4.elastic_model`, the H4 with every compliance of
  eq. 30 and of its optional elements as virtual joints; an independent route to
  :func:`h4pin.compliance` (``model="consistent"``). See ``docs/elastic.md``;
* :mod:`h4pin.elastic.mechanism`: :class:`~h4pin.elastic.mechanism.Mechanism`, any closed-loop
  robot read from a URDF and its closed-loop sidecar or from MJCF: assembly, compliance and
  natural frequencies through the engine. See ``docs/mechanisms.md``;
* :mod:`h4pin.elastic.modal` (formerly ``h4pin.elastic.modes``, a name now the function's alone):
  :func:`~h4pin.elastic.modal.modes`, the natural frequencies and mode
  shapes of the elastic H4 with the URDF's link inertias and a payload. See ``docs/modes.md``.
"""

import sys as _sys
import types as _types
import warnings as _warnings

from h4pin.elastic import modal as _modal
from h4pin.elastic.beams import Beam
from h4pin.elastic.couplings import JointCoupling
from h4pin.elastic.engine import (
    FrameOutput,
    Insertion,
    JointOutput,
    Modes,
    UnassembledError,
    UnrestrainedMotionError,
    VirtualJoint,
    compliance_matrix,
    insert_joints,
)
from h4pin.elastic.h4 import ElasticH4, elastic_model
from h4pin.elastic.mechanism import Mechanism
from h4pin.elastic.modal import modes
from h4pin.elastic.payload import Payload


def __getattr__(name: str):
    if name == "compliance":  # one meaning per name: h4pin.compliance returns a Compliance
        _warnings.warn("h4pin.elastic.compliance is now h4pin.elastic.compliance_matrix (it returns an array; "
                       "h4pin.compliance returns a Compliance); the old name goes in the next release",
                       DeprecationWarning, stacklevel=2)
        return compliance_matrix
    if name == "MechanismModes":
        _warnings.warn("h4pin.elastic.MechanismModes is now h4pin.elastic.Modes (one result type for natural "
                       "frequencies); the old name goes in the next release", DeprecationWarning, stacklevel=2)
        return Modes
    raise AttributeError(f"module 'h4pin.elastic' has no attribute {name!r}")


class _OldModesModule(_types.ModuleType):
    """``h4pin.elastic.modes`` is the function; its module is now ``h4pin.elastic.modal``: an
    import of the old module path still works one release, with a warning."""

    def __getattr__(self, name: str):
        if name.startswith("__"):  # tools that walk sys.modules (inspect, pytest) ask for __file__ etc.
            raise AttributeError(name)
        _warnings.warn("the module h4pin.elastic.modes is now h4pin.elastic.modal (h4pin.elastic.modes is the "
                       "function); the old module path goes in the next release", DeprecationWarning, stacklevel=2)
        return getattr(_modal, name)


_sys.modules.setdefault("h4pin.elastic.modes", _OldModesModule("h4pin.elastic.modes"))

__all__ = ["Beam", "ElasticH4", "FrameOutput", "Insertion", "JointCoupling", "JointOutput", "Mechanism",
           "Modes", "Payload",
           "UnassembledError", "UnrestrainedMotionError", "VirtualJoint", "compliance_matrix", "elastic_model",
           "insert_joints", "modes"]
