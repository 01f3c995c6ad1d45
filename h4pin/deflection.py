# SPDX-License-Identifier: Apache-2.0
"""Deflected shape of the H4 under a load, from the linear compliance (for drawing).

The plate moves by ``dtp = K Gamma_ext`` (:func:`h4pin.compliance`) and each forearm turns by
the rotation its actuator spring and bending take under the same load; the bars are re-aimed
from the moved A_ij to the moved B_ij. Torsion of the forearms and stretch of the bars are in
the plate motion but not drawn on the legs (the model's legs are rigid bodies).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from h4pin import geometry
from h4pin.errors import LoadError
from h4pin.robot import H4
from h4pin.stiffness import R_CONSISTENT, R_PAPER, matrices, terms_from_matrices


def as_load(load: np.ndarray | list | tuple) -> np.ndarray:
    """A force F (3,) or a full Gamma_ext = [F, T, t1, t2] (8,) as Gamma_ext (8,), SI.

    Raises:
        LoadError: ``load`` is not numeric, has another size, or holds NaN or infinity.
    """
    try:
        g = np.asarray(load, dtype=float)
    except (TypeError, ValueError):
        raise LoadError(f"load must be a force F (3,) in N or Gamma_ext = [F, T, t1, t2] (8,), "
                        f"got {load!r}") from None
    if g.shape == (3,):
        g = np.r_[g, np.zeros(5)]
    if g.shape != (8,):
        raise LoadError(f"load must be a force F (3,) in N or Gamma_ext = [F, T, t1, t2] (8,), got shape "
                        f"{np.shape(load)}")
    if not np.all(np.isfinite(g)):
        raise LoadError(f"load must be finite (no NaN or infinity), got {load!r}")
    return g


def deflection(h4: H4, pose: np.ndarray, load: np.ndarray, model: str = "consistent") -> tuple[np.ndarray, np.ndarray]:
    """Linear deflection under ``load``: plate ``dtp`` (8,) and actuator-side rotations ``dq`` (4,).

    ``load`` is a force F (3,) in N at D or Gamma_ext (8,); a NaN, infinite or wrongly sized
    load raises :class:`h4pin.LoadError`.

    ``dq`` is the rotation of each forearm tip about its actuator axis from control stiffness and
    bending, ``(1/kc + r/(3EI)) Gamma_act`` with ``Gamma_act = J^T R Gamma_ext`` (eqs. 10, 15).
    """
    x = geometry.as_poses(pose)
    g = as_load(load)
    mats = matrices(h4, x)
    dtp = sum(terms_from_matrices(mats, h4.params, model).values()) @ g
    r = R_PAPER if model == "paper" else R_CONSISTENT
    c = h4.params.compliances()
    dq = (c["control"] + c["bending"]) * (mats.J.T @ r @ g)
    return dtp, dq


def deflected_configuration(h4: H4, pose: np.ndarray, load: np.ndarray, *, scale: float = 1.0,
                            model: str = "consistent") -> np.ndarray:
    """Pinocchio configuration (nq,) of the robot deflected by ``scale`` times the linear
    deflection under ``load`` (force F (3,) in N, or Gamma_ext (8,)). ``scale`` exaggerates the
    (micrometre) deflection so that it can be seen; 1 is the true size."""
    x = geometry.as_poses(pose)
    dtp, dq = deflection(h4, x, load, model)
    dtp, dq = scale * dtp, scale * dq
    rotation = pin.exp3(dtp[3:6]) @ geometry.rot_z(x[3])
    omega = -x[3] + dtp[6:8]
    return h4.assemble(h4.inverse_geometry(x) + dq, x[:3] + dtp[:3], rotation, omega)
