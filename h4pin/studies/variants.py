# SPDX-License-Identifier: Apache-2.0
"""How each shipped variant is made (``scripts/generate_urdf.py`` writes ``urdf/h4_<name>.urdf``).

The ``measured_match`` variant comes out of a (saturated) fit of the paper's measured Table II
(:func:`h4pin.studies.identify.fitted_params`, ``docs/gap.md``), which needs the stiffness model:
that is why the generators live here, above it, and :data:`h4pin.VARIANTS` holds only the names.
"""

from __future__ import annotations

from collections.abc import Callable

from h4pin.description.params import H4Params, symmetric_params, toleranced_params
from h4pin.studies.identify import fitted_params

#: Variant name -> function that returns its :class:`h4pin.H4Params`.
GENERATORS: dict[str, Callable[[], H4Params]] = {
    "prototype": H4Params,
    "symmetric": symmetric_params,
    "toleranced": toleranced_params,
    "measured_match": fitted_params,
}

__all__ = ["GENERATORS"]
