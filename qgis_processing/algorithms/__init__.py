# SPDX-License-Identifier: GPL-2.0-or-later
"""One module per algorithm (one per `terrasynth` stage); base.py holds what they share."""
