# SPDX-License-Identifier: Apache-2.0
"""Deflected shape of the H4 under a load, from the linear compliance (for drawing).

The plate moves by ``dtp = K Gamma_ext`` (:func:`h4pin.compliance`) and each forearm turns by
the rotation its actuator spring and bending take under the same load; the bars are re-aimed
from the moved A_ij to the moved B_ij. Torsion of the forearms and stretch of the bars are in
the plate motion but not drawn on the legs (the model's legs are rigid bodies).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics import pinocchio as kin
from h4pin.kinematics.closed_form import PlateState
from h4pin.stiffness.api import as_load, check_options, compliance, matrices_at
from h4pin.stiffness.matrices import R_CONSISTENT, R_PAPER


def deflection(h4, pose: np.ndarray, load: np.ndarray, model: str = "consistent", *,
               result: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Linear deflection under ``load``: plate ``dtp`` (8,) and actuator-side rotations ``dq`` (4,).

    ``load`` is a force F (3,) in N at D or Gamma_ext (8,); a NaN, infinite or wrongly sized
    load raises :class:`h4pin.LoadError`.

    ``dq`` is the rotation of each forearm tip about its actuator axis from control stiffness and
    bending, ``(1/kc + r/(3EI)) Gamma_act`` with ``Gamma_act = J^T R Gamma_ext`` (eqs. 10, 15).
    ``result``: the robot's :class:`~h4pin.stiffness.api.Compliance` at ``pose`` with ``model``,
    computed once by the caller (default: computed here).

    Raises:
        h4pin.ParameterError: a load that is not a finite F (3,) or Gamma_ext (8,).
        UnreachablePoseError, SingularPoseError: as :func:`h4pin.compliance`.
    """
    check_options(model, "raise", "auto")
    x = geometry.as_pose(pose)
    g = as_load(load)
    res = compliance(h4, x, model) if result is None else result
    if res.model != model or res.matrix.shape != (8, 8):
        raise ParameterError(f"result: the compliance at this one pose with model {model!r}, got model {res.model!r}")
    dtp = res.matrix @ g  # the robot's compliance, elements included
    comp = h4.geometry.compliances()
    r = R_PAPER if model == "paper" else R_CONSISTENT
    dq = (comp["control"] + comp["bending"]) * (matrices_at(h4, x).J.T @ r @ g)
    return dtp, dq


def deflected_configuration(h4, pose: np.ndarray, load: np.ndarray, *, scale: float = 1.0,
                            model: str = "consistent", deflected: tuple[np.ndarray, np.ndarray] | None = None
                            ) -> np.ndarray:
    """Pinocchio configuration (nq,) of the robot deflected by ``scale`` times the linear
    deflection under ``load`` (force F (3,) in N, or Gamma_ext (8,)). ``scale`` exaggerates the
    (micrometre) deflection so that it can be seen; 1 is the true size. ``deflected``: the
    :func:`deflection` ``(dtp, dq)`` under ``load``, computed once by the caller (default: here)."""
    x = geometry.as_pose(pose)
    dtp, dq = deflection(h4, x, load, model) if deflected is None else deflected
    dtp, dq = scale * dtp, scale * dq
    st = kin.state(h4, x)
    return kin.assemble(h4, PlateState(st.q + dq, st.D + dtp[:3], pin.exp3(dtp[3:6]) @ st.R, st.omega + dtp[6:8]))
