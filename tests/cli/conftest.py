# SPDX-License-Identifier: GPL-2.0-or-later
"""tests/tsutil.py (where things are, running terrasynth) importable by these tests."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
