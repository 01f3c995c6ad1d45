# SPDX-License-Identifier: Apache-2.0
"""Natural frequencies and mode shapes of the elastic H4 at a pose: :func:`modes`.

The mechanism is the elastic H4 of :func:`h4pin.elastic.elastic_model` (every compliance a
virtual elastic joint, the four actuators locked), with the inertia of every link from the robot's
URDF (Pinocchio's ``model.inertias``) and an optional rigid :class:`Payload` fixed to the central
bar. At the assembled configuration q of a rigid pose:

1. the admissible small motions are ``dq = N z``, N a basis of the null space of the closure
   Jacobian stacked on the locked rows (as :func:`h4pin.mechanism.engine.compliance_matrix`; the same
   scaling, rank and singularity decisions);
2. stiffness ``Kz = N^T Ke N`` (the springs, Ke diagonal); mass ``Mz = N^T M N``, with M the joint
   space inertia matrix of ``pin.crba`` plus the payload's ``J_D^T I_p J_D`` (I_p its 6x6 spatial
   inertia in frame D, J_D the LOCAL Jacobian of frame D);
3. massless motions (virtual joints carry no mass, and a spring in series with another leaves a
   motion that moves no mass) are **condensed statically**: with ``Mz = V diag(mu) V^T``, the
   directions of ``mu <= MASSLESS_TOL * max(mu)`` are massless (index s), the others massive
   (index m), and ``K* = Kmm - Kms Kss^-1 Ksm`` (the massless coordinates follow the massive ones
   in static equilibrium, ``z_s = -Kss^-1 Ksm z_m``); ``M* = diag(mu_m)``;
4. the undamped modes solve ``K* a = lambda M* a``; the frequencies are ``sqrt(lambda) / (2 pi)``
   (Hz). A shape is the full motion ``dq = N (V_m a + V_s z_s)``, mass-normalised
   (``dq^T M dq = 1``), and the plate's ``dtp = Jo dq`` through the outputs of
   :attr:`ElasticH4.outputs <h4pin.elastic.h4.ElasticH4>` (dtp = [dD, dOmega, domega_1, domega_2]).

Assumptions: small vibrations about the rigid pose (linear), no damping, no preload (no geometric
stiffness, no gravity stiffness), locked actuators (the motor angle is held; its servo stiffness
kc is the ``actuator_i_elastic`` spring), rigid links with the URDF's inertias. The locked
actuator's own body (the forearm) would not move at all on the locked joint, but the forearm turns
with the actuator's elastic rotation (servo and bending lumped into one spring): its inertia is
carried by ``actuator_i_elastic`` (a rigid forearm on that spring). See ``docs/modes.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.elastic.h4 import ElasticH4, elastic_model, mass_model  # noqa: F401  (mass_model: re-exported)
from h4pin.errors import ParameterError
from h4pin.kinematics.closed_form import as_pose
from h4pin.mechanism import engine
from h4pin.mechanism.engine import MASSLESS_TOL, Modes, admissible_basis, undamped_modes  # noqa: F401  (re-exported)
from h4pin.mechanism.payload import Payload

#: Length (m) that turns the rotations of dtp into lengths when the sign of a shape is chosen.
_SIGN_LENGTH = 0.1


def modes(robot: Any, pose: np.ndarray, payload: Payload | None = None, *, link_inertias: bool = True,
          data: pin.Data | None = None) -> Modes:
    """Natural frequencies and mode shapes of the elastic H4 at a rigid pose (module docstring).

    Args:
        robot: an :class:`h4pin.H4` (its elastic model is built, about 15 ms) or an
            :class:`~h4pin.elastic.h4.ElasticH4` (``h4pin.elastic_model(h4)``, reused: faster for
            many poses; its elements are the robot's).
        pose: [x, y, z, theta] (m, rad).
        payload: a rigid body on the central bar (:class:`Payload`), or None.
        link_inertias: True: the URDF's link inertias (module docstring); False: massless links, so
            that only the payload has mass.
        data: a ``pin.Data`` of the elastic model to work in (default: the calling thread's own,
            :attr:`ElasticH4.data <h4pin.elastic.h4.ElasticH4>`).

    Returns:
        :class:`~h4pin.mechanism.engine.Modes`: frequencies (m,) Hz ascending, shapes_tp (m, 8),
        shapes_q (m, nv).

    Raises:
        PoseError, UnreachablePoseError: a bad pose, or one the robot cannot take.
        UnrestrainedMotionError: a singular pose (a motion strains no spring).
        ParameterError: ``payload`` is not a :class:`Payload`, or nothing has mass
            (``link_inertias=False`` without a payload of mass > 0).
    """
    em = robot if isinstance(robot, ElasticH4) else elastic_model(robot)
    if payload is not None and not isinstance(payload, Payload):
        raise ParameterError(f"payload must be an h4pin.mechanism.Payload or None, got {type(payload).__name__}")
    x = as_pose(pose).copy()
    mm = mass_model(em, bool(link_inertias))
    d = em.data if data is None else data
    q = em.configuration(x)
    k = engine.stiffness_vector(mm, em.stiffness)
    pin.computeJointJacobians(mm, d, q)
    n = admissible_basis(mm, em.constraint_models, q, em.locked, k, d)
    jo = engine.output_jacobian(mm, d, em.outputs)
    jd = pin.getFrameJacobian(mm, d, mm.getFrameId("D"), pin.LOCAL)  # from data.J, before crba
    mass = pin.crba(mm, d, q)
    mass = np.triu(mass) + np.triu(mass, 1).T  # Pinocchio may fill the upper triangle only
    if payload is not None and payload.mass > 0:
        mass = mass + jd.T @ payload.spatial() @ jd
    freq, shapes_q, massless = undamped_modes(n, k, mass)
    shapes_tp = shapes_q @ jo.T
    sized = shapes_tp * np.r_[np.ones(3), np.full(5, _SIGN_LENGTH)]
    sign = np.sign(sized[np.arange(len(sized)), np.argmax(np.abs(sized), axis=1)])
    sign[sign == 0] = 1.0
    shapes_q *= sign[:, None]
    shapes_tp *= sign[:, None]
    for a in (freq, shapes_tp, shapes_q, x):
        a.setflags(write=False)
    return Modes(freq, len(freq), 0, payload, x, (shapes_tp, shapes_q), massless)


__all__ = ["MASSLESS_TOL", "Modes", "Payload", "admissible_basis", "mass_model", "modes", "undamped_modes"]
