"""MPEG-4's facial animation parameter units (FAPU), once for the whole package.

A FAP's value is a count of its unit: rotations in angle units (AU) of 1e-5 rad, distances in 1/1024 of a
reference distance of the neutral face (IRISD0, ES0, ENS0, MNS0, MW0).

Examples
--------
>>> round(10 * AU_PER_DEGREE)
17453
>>> 512 / DISTANCE_UNITS_PER_REFERENCE  # half the reference distance
0.5
"""

from __future__ import annotations

import math

#: Radians per angular unit (AU).
RADIANS_PER_AU = 1e-5
#: Angular units per degree (about 1745.3).
AU_PER_DEGREE = math.radians(1.0) / RADIANS_PER_AU
#: Distance units per reference distance (IRISD, ES, ENS, MNS, MW are the distance / 1024).
DISTANCE_UNITS_PER_REFERENCE = 1024
#: The distance units, each a reference distance of the neutral face / 1024.
DISTANCE_UNITS = ("IRISD", "ES", "ENS", "MNS", "MW")
