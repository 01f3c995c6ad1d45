# SPDX-License-Identifier: Apache-2.0
"""Compatibility with older Pinocchio releases (see ``docs/interop.md``, "Pinocchio versions").

h4pin's closures are ``pin.RigidConstraintModel`` (``CONTACT_3D``). Since Pinocchio 4 (pip ``pin``),
their Python binding has ``calc(model, data, cdata)``, which fills the constraint data
(``oMc1``, ``oMc2``, ``c1Mc2``) that ``getConstraintJacobian(s)`` and the closure residuals read.
Pinocchio 3.x binds the same data fields but not ``calc``. :func:`constraint_calc` computes them
the way each version allows, and :func:`install` gives 3.x's ``RigidConstraintModel`` a ``calc``
method doing the same, so code written for Pinocchio 4 (``cm.calc(model, data, cd)``) runs on 3.x.

:func:`install` runs when this module is imported (``import h4pin`` does). It only adds the
method when it is missing; it never replaces Pinocchio's own.
"""

from __future__ import annotations

import pinocchio as pin

#: True when this Pinocchio binds ``RigidConstraintModel.calc`` itself (Pinocchio >= 4).
NATIVE_CALC = hasattr(pin.RigidConstraintModel, "calc")


def _calc_placements(cmodel: pin.RigidConstraintModel, model: pin.Model, data: pin.Data,
                     cdata: pin.RigidConstraintData) -> None:
    """Placements of the two contact frames, as Pinocchio 4's ``RigidConstraintModel::calc`` does.

    ``oMc1 = oMi[joint1] * joint1_placement``, ``oMc2 = oMi[joint2] * joint2_placement``,
    ``c1Mc2 = oMc1^-1 oMc2``. Needs ``data.oMi`` current (``pin.forwardKinematics``).
    """
    cdata.oMc1 = data.oMi[cmodel.joint1_id] * cmodel.joint1_placement
    cdata.oMc2 = data.oMi[cmodel.joint2_id] * cmodel.joint2_placement
    cdata.c1Mc2 = cdata.oMc1.actInv(cdata.oMc2)


def constraint_calc(cmodel: pin.RigidConstraintModel, model: pin.Model, data: pin.Data,
                    cdata: pin.RigidConstraintData) -> None:
    """``cmodel.calc(model, data, cdata)`` on any supported Pinocchio (needs forward kinematics first)."""
    if NATIVE_CALC:
        cmodel.calc(model, data, cdata)
    else:
        _calc_placements(cmodel, model, data, cdata)


def set_baumgarte(cmodel: pin.RigidConstraintModel, kp: float, kd: float) -> None:
    """Baumgarte stabilisation gains of a closure: Kp (1/s^2) and Kd (1/s), on any supported Pinocchio.

    Pinocchio 4 takes ``BaumgarteCorrectorParameters(Kp, Kd)`` through
    ``setBaumgarteCorrectorParameters``; Pinocchio 3.x has per-axis vectors in ``cmodel.corrector``.
    """
    if hasattr(cmodel, "setBaumgarteCorrectorParameters"):
        cmodel.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(kp, kd))
        return
    corrector = cmodel.corrector
    corrector.Kp[:] = kp
    corrector.Kd[:] = kd
    cmodel.corrector = corrector


def init_constraint_dynamics(model: pin.Model, data: pin.Data, cmodels, cdatas) -> None:
    """``pin.initConstraintDynamics``: Pinocchio 4 takes the constraint datas too, 3.x does not."""
    try:
        pin.initConstraintDynamics(model, data, cmodels, cdatas)
    except TypeError:  # Boost.Python.ArgumentError derives from TypeError
        pin.initConstraintDynamics(model, data, cmodels)


def install() -> None:
    """Give ``pin.RigidConstraintModel`` a ``calc`` method where the binding lacks one (Pinocchio 3.x)."""
    if not hasattr(pin.RigidConstraintModel, "calc"):

        def calc(self: pin.RigidConstraintModel, model: pin.Model, data: pin.Data,
                 cdata: pin.RigidConstraintData) -> None:
            _calc_placements(self, model, data, cdata)

        calc.__doc__ = "calc(model, data, cdata): contact placements (added by h4pin._compat for Pinocchio 3.x)."
        pin.RigidConstraintModel.calc = calc


install()

__all__ = ["NATIVE_CALC", "constraint_calc", "init_constraint_dynamics", "install", "set_baumgarte"]
