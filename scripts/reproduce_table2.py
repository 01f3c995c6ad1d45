#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Reproduce Table II of the paper (same as ``h4pin table2``).

    python scripts/reproduce_table2.py [--model paper|consistent] [--variant NAME | --urdf PATH]
"""

from __future__ import annotations

import sys

from h4pin.cli import main

if __name__ == "__main__":
    sys.argv[1:1] = ["table2"]
    main()
