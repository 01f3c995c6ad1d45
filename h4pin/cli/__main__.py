# SPDX-License-Identifier: Apache-2.0
"""``python -m h4pin.cli``: the ``h4pin`` console script."""

from h4pin.cli import main

main()
