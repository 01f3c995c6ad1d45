# SPDX-License-Identifier: Apache-2.0
"""Joint couplings of a closed-loop robot (MJCF ``<equality><joint polycoef>``): constraints
like its closures, for :class:`h4pin.mechanism.Mechanism`."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError


@dataclasses.dataclass(frozen=True)
class JointCoupling:
    """A joint coupling (MJCF ``<equality><joint polycoef>``): ``u1 = sum_k poly[k] u2**k`` with
    ``u = q - origin`` each (Pinocchio's coordinates); no ``joint2``: ``u1 = poly[0]``."""

    joint1: str
    joint2: str | None
    poly: tuple[float, ...]
    origin1: float = 0.0
    origin2: float = 0.0

    def _index(self, model: pin.Model, name: str) -> int:
        jm = model.joints[model.getJointId(name)]
        if jm.nq != 1 or jm.nv != 1:
            raise ParameterError(f"coupling: joint {name!r} has {jm.nv} coordinates (one only)")
        return jm.idx_q

    def residual_row(self, model: pin.Model, q: np.ndarray) -> tuple[float, np.ndarray]:
        """The coupling's residual at q and its row (nv,) of d(residual)/dq (:meth:`residual_rows`
        of one configuration)."""
        r, rows = self.residual_rows(model, np.asarray(q, float)[None])
        return float(r[0]), rows[0]

    def residual_rows(self, model: pin.Model, Q: np.ndarray, out: np.ndarray | None = None) -> tuple[np.ndarray,
                                                                                                    np.ndarray]:
        """:meth:`residual_row` at each configuration of Q (N, nq) at once, the polynomial and its
        slope evaluated over the batch: residuals (N,) and rows (N, nv), written into ``out``
        (N, nv), zero but on the two joints' columns, when given."""
        rows = np.zeros((len(Q), model.nv)) if out is None else out
        i1 = self._index(model, self.joint1)
        rows[:, model.joints[model.getJointId(self.joint1)].idx_v] = 1.0
        if self.joint2 is None:
            return Q[:, i1] - self.origin1 - self.poly[0], rows
        u2 = Q[:, self._index(model, self.joint2)] - self.origin2
        value, slope = np.zeros(len(Q)), np.zeros(len(Q))
        for k, c in enumerate(self.poly):
            value = value + c * u2**k
            if k:
                slope = slope + k * c * u2 ** (k - 1)
        rows[:, model.joints[model.getJointId(self.joint2)].idx_v] = -slope
        return Q[:, i1] - self.origin1 - value, rows


__all__ = ["JointCoupling"]
