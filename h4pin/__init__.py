# SPDX-License-Identifier: Apache-2.0
"""h4pin: the H4 parallel robot on Pinocchio, and its stiffness after Company et al. (ICRA 2005).

Layers (``docs/architecture.md``): :mod:`h4pin.description` (params, URDF, geometry, elements,
reading) -> :mod:`h4pin.robot` (``load``, the immutable :class:`H4`) and :mod:`h4pin.kinematics`
(closed forms, Pinocchio) -> :mod:`h4pin.stiffness` (matrices, eq. 30: numpy reference and
compiled core; elements; :func:`compliance`) -> :mod:`h4pin.studies` and :mod:`h4pin.io`;
:mod:`h4pin.checks` holds the independent validation routes. Under all of them,
:mod:`h4pin.mechanism` is the generic engine of any closed-loop robot (``Mechanism``), which
imports nothing of the H4.
"""

from h4pin import _numba_cache

_numba_cache.configure()  # a read-only install caches compiled code elsewhere (before any is defined)

from h4pin import _compat  # noqa: E402, F401  (gives Pinocchio 3.x a RigidConstraintModel.calc)
from h4pin._version import __version__  # noqa: E402, F401
from h4pin.description.elements import Elements  # noqa: E402
from h4pin.description.geometry import H4Geometry  # noqa: E402
from h4pin.description.params import VARIANTS, H4Params, symmetric_params, toleranced_params  # noqa: E402
from h4pin.elastic import ElasticH4, elastic_model  # noqa: E402
from h4pin.errors import (  # noqa: E402
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

# Import-time registration (documented in docs/descriptions.md, tested in tests/test_erd.py): with
# example-robot-data-loaders installed, example_robot_data.load("h4") works after `import h4pin`;
# the names are h4pin.io.erd.NAMES. Without the loaders nothing happens (and nothing is imported).
from h4pin.io import erd as _erd  # noqa: E402
from h4pin.kinematics.pinocchio import Kinematics  # noqa: E402
from h4pin.mechanism import Mechanism, Modes, Payload  # noqa: E402
from h4pin.mechanism.calibration import Calibration, calibrate  # noqa: E402
from h4pin.mechanism.measurements import Measurements  # noqa: E402
from h4pin.robot import H4, load  # noqa: E402
from h4pin.stiffness.api import Compliance, compliance  # noqa: E402
from h4pin.vibration import modes  # noqa: E402

if _erd.available():
    _erd.register()



__all__ = [
    "H4",
    "VARIANTS",
    "Calibration",
    "Compliance",
    "ConvergenceError",
    "ElasticH4",
    "Elements",
    "H4Error",
    "H4Geometry",
    "H4Params",
    "InterferenceError",
    "JointLimitError",
    "Kinematics",
    "Mechanism",
    "LoadError",
    "MalformedURDFError",
    "Measurements",
    "Modes",
    "ParameterError",
    "Payload",
    "PoseError",
    "SingularPoseError",
    "URDFNotFoundError",
    "UnreachablePoseError",
    "calibrate",
    "compliance",
    "elastic_model",
    "load",
    "modes",
    "symmetric_params",
    "toleranced_params",
]
