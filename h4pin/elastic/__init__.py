# SPDX-License-Identifier: Apache-2.0
"""Closed-loop stiffness from Pinocchio's Jacobians: a generic engine and the H4's elastic model.

* :mod:`h4pin.elastic.engine`: the compliance of any Pinocchio model with loop closures, locked
  joints and elastic joints (:func:`~h4pin.elastic.engine.compliance`), and
  :func:`~h4pin.elastic.engine.insert_joints` to add virtual elastic joints to a model;
* :mod:`h4pin.elastic.h4`: :func:`~h4pin.elastic.h4.elastic_model`, the H4 with every compliance of
  eq. 30 and of its optional elements as virtual joints; an independent route to
  :func:`h4pin.compliance` (``model="consistent"``). See ``docs/elastic.md``;
* :mod:`h4pin.elastic.mechanism`: :class:`~h4pin.elastic.mechanism.Mechanism`, any closed-loop
  robot read from a URDF and its closed-loop sidecar or from MJCF: assembly, compliance and
  natural frequencies through the engine. See ``docs/mechanisms.md``;
* :mod:`h4pin.elastic.modes`: :func:`~h4pin.elastic.modes.modes`, the natural frequencies and mode
  shapes of the elastic H4 with the URDF's link inertias and a payload. See ``docs/modes.md``.
"""

from h4pin.elastic.engine import (
    FrameOutput,
    Insertion,
    JointOutput,
    UnassembledError,
    UnrestrainedMotionError,
    VirtualJoint,
    compliance,
    insert_joints,
)
from h4pin.elastic.h4 import ElasticH4, elastic_model
from h4pin.elastic.mechanism import Mechanism, MechanismModes
from h4pin.elastic.modes import Modes, Payload, modes

__all__ = ["ElasticH4", "FrameOutput", "Insertion", "JointOutput", "Mechanism", "MechanismModes", "Modes", "Payload",
           "UnassembledError", "UnrestrainedMotionError", "VirtualJoint", "compliance", "elastic_model",
           "insert_joints", "modes"]
