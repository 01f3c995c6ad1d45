# SPDX-License-Identifier: Apache-2.0
"""h4pin: the H4 parallel robot on Pinocchio, and its stiffness after Company et al. (ICRA 2005)."""

from h4pin import _compat  # noqa: F401  (gives Pinocchio 3.x a RigidConstraintModel.calc)
from h4pin.errors import (
    ConvergenceError,
    H4Error,
    InterferenceError,
    JointLimitError,
    LoadError,
    MalformedURDFError,
    ParameterError,
    PoseError,
    SingularPoseError,
    UnreachablePoseError,
    URDFNotFoundError,
)
from h4pin.model import H4Geometry
from h4pin.params import VARIANTS, H4Params, symmetric_params, toleranced_params
from h4pin.robot import H4, Kinematics, load
from h4pin.stiffness import Compliance, compliance

__version__ = "0.1.0"

# example_robot_data.load("h4") when example-robot-data-loaders is installed (no download).
from h4pin import erd as _erd  # noqa: E402

_erd.register()

__all__ = [
    "H4",
    "Compliance",
    "H4Geometry",
    "InterferenceError",
    "JointLimitError",
    "Kinematics",
    "URDFNotFoundError",
    "compliance",
    "toleranced_params",
    "VARIANTS",
    "LoadError",
    "ConvergenceError",
    "H4Error",
    "H4Params",
    "LoadError",
    "MalformedURDFError",
    "ParameterError",
    "PoseError",
    "SingularPoseError",
    "UnreachablePoseError",
    "compliance",
    "load",
    "symmetric_params",
]
