# SPDX-License-Identifier: Apache-2.0
"""An independent route to a closed-loop robot's compliance and natural frequencies, in plain
Pinocchio and numpy/scipy, for the tests (none of h4pin's engine):

* the constraint rows A: each closure's Jacobian from its two frames (3-D: the world gap of the two
  frames' origins; 6-D: frame 2's motion relative to frame 1 in frame 1's axes), and the locked
  joints as identity rows;
* compliance: the KKT system ``[[K, Aᵀ], [A, 0]]`` on the independent rows of A, solved densely
  for an output Jacobian;
* frequencies: the generalized eigenproblem on the null space N of A (scipy.linalg.null_space),
  solved for ``mu = 1 / w²`` as ``Nᵀ M N x = mu Nᵀ K N x`` (Nᵀ K N positive definite where the
  springs hold every admissible motion): massless directions have mu = 0 and drop out.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pinocchio as pin
from scipy import linalg as scipy_linalg


def closure_rows(model: pin.Model, d: pin.Data, cm) -> np.ndarray:
    """The closure's Jacobian from its two frames (placements on their parent joints); needs
    ``pin.computeJointJacobians`` at the configuration in ``d``."""
    if cm.type == pin.ContactType.CONTACT_3D:
        j1 = pin.getFrameJacobian(model, d, cm.joint1_id, cm.joint1_placement, pin.LOCAL_WORLD_ALIGNED)[:3]
        j2 = pin.getFrameJacobian(model, d, cm.joint2_id, cm.joint2_placement, pin.LOCAL_WORLD_ALIGNED)[:3]
        return j1 - j2
    o1 = d.oMi[cm.joint1_id] * cm.joint1_placement
    o2 = d.oMi[cm.joint2_id] * cm.joint2_placement
    j1 = pin.getFrameJacobian(model, d, cm.joint1_id, cm.joint1_placement, pin.LOCAL)
    j2 = pin.getFrameJacobian(model, d, cm.joint2_id, cm.joint2_placement, pin.LOCAL)
    return (o1.inverse() * o2).toActionMatrix() @ j2 - j1


def constraint_rows(model: pin.Model, constraint_models: Iterable, q: np.ndarray,
                    locked: Iterable[str] = ()) -> tuple[np.ndarray, pin.Data]:
    """A (rows, nv): every closure's rows and the locked joints' identity rows at q; and the
    ``pin.Data`` with the joint Jacobians and frame placements at q."""
    d = model.createData()
    pin.computeJointJacobians(model, d, q)
    pin.updateFramePlacements(model, d)
    rows = [closure_rows(model, d, cm) for cm in constraint_models]
    eye = np.eye(model.nv)
    for name in locked:
        jm = model.joints[model.getJointId(name)]
        rows.append(eye[jm.idx_v:jm.idx_v + jm.nv])
    return np.vstack(rows), d


def spring_vector(model: pin.Model, springs: Mapping[str, float]) -> np.ndarray:
    """(nv,) each joint's stiffness on its velocity coordinates, 0 elsewhere."""
    k = np.zeros(model.nv)
    for name, value in springs.items():
        jm = model.joints[model.getJointId(name)]
        k[jm.idx_v:jm.idx_v + jm.nv] = value
    return k


def kkt_compliance(a: np.ndarray, k: np.ndarray, jo: np.ndarray) -> np.ndarray:
    """``jo C jo^T``-style compliance of the outputs ``jo`` (m, nv): ``jo dq`` for the unit loads
    ``jo^T``, dq from the KKT system on the independent rows of ``a`` (a redundant closure set has
    dependent rows)."""
    _, sv, vt = np.linalg.svd(a, full_matrices=False)
    a = vt[sv > 1e-10 * sv[0]]
    n_c, nv = a.shape[0], a.shape[1]
    kkt = np.block([[np.diag(k), a.T], [a, np.zeros((n_c, n_c))]])
    sol = np.linalg.solve(kkt, np.vstack([jo.T, np.zeros((n_c, jo.shape[0]))]))
    return jo @ sol[:nv]


def mass_matrix(model: pin.Model, d: pin.Data, q: np.ndarray) -> np.ndarray:
    """The joint-space inertia matrix (``pin.crba``, both triangles)."""
    mass = pin.crba(model, d, q)
    return np.triu(mass) + np.triu(mass, 1).T


def nullspace_frequencies(a: np.ndarray, k: np.ndarray, mass: np.ndarray, massless: float = 1e-10) -> np.ndarray:
    """The natural frequencies (Hz, ascending) of springs ``k`` (nv,) and inertia ``mass`` on the
    null space of ``a``: every direction whose ``mu = 1 / w²`` exceeds ``massless`` times the
    largest (the others move no mass)."""
    n = scipy_linalg.null_space(a, rcond=1e-10)
    kz, mz = n.T @ (k[:, None] * n), n.T @ mass @ n
    mu = scipy_linalg.eigh(0.5 * (mz + mz.T), 0.5 * (kz + kz.T), eigvals_only=True)[::-1]
    mu = mu[mu > massless * mu[0]]
    return 1.0 / (2.0 * np.pi * np.sqrt(mu))
