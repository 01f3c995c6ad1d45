# SPDX-License-Identifier: Apache-2.0
"""The paper's numbers that the studies compare with: Table II, computed and measured."""

from __future__ import annotations

import numpy as np

#: Table II of the paper, um/N (erratum 5: the print says m/N). Rows: displacement x, y, z;
#: columns: force along x, y, z.
PAPER_COMPUTED = np.array([[40.0, 0.0, 21.0], [0.0, 21.0, 0.0], [21.0, 0.0, 19.0]])
PAPER_MEASURED = np.array([[51.0, 0.0, 11.0], [-3.0, 15.0, -1.0], [15.0, 0.0, 9.0]])
for _table in (PAPER_COMPUTED, PAPER_MEASURED):
    _table.setflags(write=False)

__all__ = ["PAPER_COMPUTED", "PAPER_MEASURED"]
