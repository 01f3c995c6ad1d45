# SPDX-License-Identifier: Apache-2.0
"""Any closed-loop robot on Pinocchio: the generic stiffness engine h4pin is built on.

It imports nothing of the H4 (``tests/test_architecture.py`` holds that rule); the H4's elastic
model (:mod:`h4pin.elastic`) is its first client. ``docs/mechanisms.md`` walks through a robot.

* :class:`Mechanism` (:mod:`~h4pin.mechanism.core`): a tree, its loop closures and motors, read
  from a URDF and its closed-loop sidecar, from MJCF, or built in code; assembly, compliance,
  natural frequencies (:mod:`~h4pin.mechanism.batch`: the compiled path over batches);
* :func:`compliance_matrix`, :func:`insert_joints` (:mod:`~h4pin.mechanism.engine`): the engine
  on any ``pin.Model`` with closures, locked and elastic joints;
* :class:`Beam` (flexible links), :class:`JointCoupling`, :class:`Payload`;
* :mod:`~h4pin.mechanism.atlas` (motor-space atlas), :mod:`~h4pin.mechanism.store` (the result
  store every atlas uses), :mod:`~h4pin.mechanism.scene` (the meshcat scene of any robot),
  :mod:`~h4pin.mechanism.mjcf_writer` (the elastic MuJoCo export).
"""

from h4pin.mechanism.beams import Beam
from h4pin.mechanism.core import Mechanism
from h4pin.mechanism.couplings import JointCoupling
from h4pin.mechanism.engine import (
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
from h4pin.mechanism.payload import Payload

__all__ = ["Beam", "FrameOutput", "Insertion", "JointCoupling", "JointOutput", "Mechanism", "Modes", "Payload",
           "UnassembledError", "UnrestrainedMotionError", "VirtualJoint", "compliance_matrix", "insert_joints"]
