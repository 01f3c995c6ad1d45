# SPDX-License-Identifier: Apache-2.0
"""
Table II of the paper
=====================

The compliance of the H4 prototype at the paper's pose (all actuators at 45 deg), beside the
paper's computed and measured Table II: what ``h4pin table2`` prints, then the same numbers as
a figure. Why they differ, and why no spring constant closes the gap: :doc:`../gap`.
"""

import matplotlib.pyplot as plt
import numpy as np

import h4pin
from h4pin.kinematics.closed_form import centre_pose
from h4pin.studies.paper import PAPER_COMPUTED, PAPER_MEASURED
from h4pin.studies.table2 import report

h4 = h4pin.load("prototype")
print(report(h4))

# %%
# The translational block in um/N, and the four terms of eq. 30 that add up to it.
res = h4pin.compliance(h4, centre_pose(h4))
ours = res.translational * 1e6
entries = [(0, 0), (1, 1), (2, 2), (0, 2)]
labels = ["dx/Fx", "dy/Fy", "dz/Fz", "dx/Fz"]
x = np.arange(len(entries))
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
for k, (name, table) in enumerate((("h4pin", ours), ("paper, computed", PAPER_COMPUTED),
                                   ("paper, measured", PAPER_MEASURED))):
    left.bar(x + (k - 1) * 0.27, [table[e] for e in entries], 0.27, label=name)
left.set_xticks(x, labels)
left.set_ylabel("compliance [um/N]")
left.legend()
left.set_title("Table II")
bottom = np.zeros(len(entries))
for term, block in res.terms.items():
    values = np.array([block[e] * 1e6 for e in entries])
    right.bar(x, values, 0.6, bottom=bottom, label=term)
    bottom += values
right.set_xticks(x, labels)
right.set_title("h4pin, term by term (eq. 30)")
right.legend()
fig.tight_layout()
plt.show()
