# SPDX-License-Identifier: Apache-2.0
"""The stiffness model: the paper's matrices, eq. 30 (one numpy reference, one compiled core),
the optional elements' terms, and the public :func:`h4pin.compliance`.

Layer 3 of h4pin (``docs/architecture.md``).
"""
