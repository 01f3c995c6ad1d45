# SPDX-License-Identifier: Apache-2.0
"""
A mechanism built in code: a planar five-bar
============================================

A ``pin.Model`` written joint by joint, one loop closure (``pin.RigidConstraintModel``,
``CONTACT_3D``) and the names of the motors make a :class:`h4pin.Mechanism`: assembled, its
compliance at the tip, its natural frequencies, and a check that owes nothing to the engine
(finite differences of the assembly). The conventions (joint placements, the closure's point in
each joint's frame, ``LOCAL_WORLD_ALIGNED``, ``actuated``, the springs): :doc:`../build_in_code`.
"""

import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

import h4pin

L1, L2, HALF = 0.20, 0.30, 0.10  # proximal and distal links, half the base (m)
model = pin.Model()
model.name = "five_bar"


def link(parent, name, xyz, length):
    """A revolute joint about z at xyz (in the parent joint's frame), carrying a 100 g rod along x."""
    joint = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array(xyz, float)), name)
    rod = pin.Inertia.FromCylinder(0.1, 0.005, length)  # a cylinder along its own z
    model.appendBodyToJoint(joint, rod, pin.SE3(pin.utils.rotate("y", np.pi / 2), np.array([length / 2, 0, 0])))
    return joint


motor_1 = link(0, "motor_1", [-HALF, 0, 0], L1)
elbow_1 = link(motor_1, "elbow_1", [L1, 0, 0], L2)
motor_2 = link(0, "motor_2", [HALF, 0, 0], L1)
elbow_2 = link(motor_2, "elbow_2", [L1, 0, 0], L2)

tip = pin.SE3(np.eye(3), np.array([L2, 0, 0]))  # the tip in each distal link's joint frame
model.addFrame(pin.Frame("tip", elbow_1, tip, pin.FrameType.OP_FRAME))
closure = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, elbow_1, tip, elbow_2, tip,
                                   pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
closure.name = "tip"

five_bar = h4pin.Mechanism(model, [closure], actuated=["motor_1", "motor_2"])
print(five_bar)
q = five_bar.assemble(np.array([1.2, 1.0, 1.9, -1.0]))  # motors held at 1.2 and 1.9 rad
print("assembled q:", q.round(4), "closure errors:", five_bar.closure_errors(q))

springs = {"motor_1": 900.0, "motor_2": 1500.0}  # the servos, N m/rad
C = five_bar.compliance(q, springs, ["tip"])
print("compliance of the tip in the plane [um/N]:\n", (C[:2, :2] * 1e6).round(3))
print("natural frequencies [Hz]:", five_bar.modes(q, springs).frequencies.round(2))

# %%
# An independent check. With the links rigid and only the servos compliant, the tip moves by
# ``G dtheta`` where ``G = dp/dtheta`` is the tip's motion per motor angle, so by virtual work
# ``C = G K^-1 G^T``. ``G`` by central differences of the assembly, motors held one step apart:
data = model.createData()


def tip_position(qk):
    pin.framesForwardKinematics(model, data, qk)
    return data.oMf[model.getFrameId("tip")].translation[:2].copy()


theta, step = q[[0, 2]], 1e-6
G = np.zeros((2, 2))
for k in range(2):
    plus, minus = five_bar.assemble(motors=np.array([theta + step * np.eye(2)[k], theta - step * np.eye(2)[k]]))
    G[:, k] = (tip_position(plus) - tip_position(minus)) / (2 * step)
by_hand = G @ np.diag([1 / springs["motor_1"], 1 / springs["motor_2"]]) @ G.T
print("relative difference to the engine:", np.abs(by_hand - C[:2, :2]).max() / np.abs(by_hand).max())

# %%
# The closure's rows in the frame of the point on joint 1 (``LOCAL``, what h4pin's file readers
# use) instead of world axes allow the same motions, hence the same compliance:
local = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, elbow_1, tip, elbow_2, tip,
                                 pin.ReferenceFrame.LOCAL)
same = h4pin.Mechanism(model, [local], actuated=["motor_1", "motor_2"]).compliance(q, springs, ["tip"])
print("LOCAL vs LOCAL_WORLD_ALIGNED:", np.abs(same - C).max(), "m/N")

# %%
# The linkage and the tip's deflection under 500 N in every direction of the plane (to scale).
pin.forwardKinematics(model, data, q)
joints = [data.oMi[j].translation[:2] for j in (motor_1, elbow_1, motor_2, elbow_2)]
p = tip_position(q)
t = np.linspace(0, 2 * np.pi, 80)
deflection = C[:2, :2] @ (500.0 * np.array([np.cos(t), np.sin(t)]))
fig, ax = plt.subplots(figsize=(5, 5))
for a, b in ((0, 1), (2, 3)):
    ax.plot(*np.array([joints[a], joints[b], p]).T, "o-", color="0.3")
ax.plot(p[0] + deflection[0], p[1] + deflection[1], color="tab:green", label="tip deflection under 500 N")
ax.set_aspect("equal")
ax.set_xlabel("x [m]")
ax.set_ylabel("y [m]")
ax.legend(loc="lower center")
fig.tight_layout()
plt.show()
