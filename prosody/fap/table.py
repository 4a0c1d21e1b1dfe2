"""The 68 MPEG-4 facial animation parameters (ISO/IEC 14496-2, Annex C): numbers, names and units.

FAPU (facial animation parameter units): distances of the neutral face divided by 1024 (IRISD, ES, ENS, MNS,
MW), and AU = 1e-5 rad for rotations. FAP 1 and 2 are the high-level viseme and expression parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from ..errors import UnknownFapError
from .units import DISTANCE_UNITS_PER_REFERENCE, RADIANS_PER_AU

__all__ = ["BY_NAME", "BY_NUMBER", "DISTANCE_UNITS_PER_REFERENCE", "EYEBROW_FAPS", "FAPS", "HEAD_FAPS", "N_FAPS",
           "PROSODY_FAPS", "RADIANS_PER_AU", "Fap", "FapInfo", "fap_info"]

#: Number of FAPs in a mask line.
N_FAPS = 68


@dataclass(frozen=True)
class FapInfo:
    """One row of the FAP table: number (1..68), name, unit, uni/bidirectional, positive motion, group."""

    number: int
    name: str
    fapu: str
    direction: str
    positive_motion: str
    group: int

    @property
    def physical_unit(self) -> str:
        """Unit after :meth:`to_physical`: ``rad`` for AU FAPs, the reference distance (e.g. ``ENS0``) else."""
        if self.fapu == "AU":
            return "rad"
        return "na" if self.fapu == "na" else f"{self.fapu}0"

    def to_physical(self, value: float) -> float:
        """Convert a value in FAP units to radians (AU) or to a fraction of the reference distance."""
        if self.fapu == "AU":
            return value * RADIANS_PER_AU
        if self.fapu == "na":
            return value
        return value / DISTANCE_UNITS_PER_REFERENCE


_ROWS = (
    (1, 'viseme', 'na', 'na', 'na', 1),
    (2, 'expression', 'na', 'na', 'na', 1),
    (3, 'open_jaw', 'MNS', 'U', 'down', 2),
    (4, 'lower_t_midlip', 'MNS', 'B', 'down', 2),
    (5, 'raise_b_midlip', 'MNS', 'B', 'up', 2),
    (6, 'stretch_l_cornerlip', 'MW', 'B', 'left', 2),
    (7, 'stretch_r_cornerlip', 'MW', 'B', 'right', 2),
    (8, 'lower_t_lip_lm', 'MNS', 'B', 'down', 2),
    (9, 'lower_t_lip_rm', 'MNS', 'B', 'down', 2),
    (10, 'raise_b_lip_lm', 'MNS', 'B', 'up', 2),
    (11, 'raise_b_lip_rm', 'MNS', 'B', 'up', 2),
    (12, 'raise_l_cornerlip', 'MNS', 'B', 'up', 2),
    (13, 'raise_r_cornerlip', 'MNS', 'B', 'up', 2),
    (14, 'thrust_jaw', 'MNS', 'U', 'forward', 2),
    (15, 'shift_jaw', 'MW', 'B', 'right', 2),
    (16, 'push_b_lip', 'MNS', 'B', 'forward', 2),
    (17, 'push_t_lip', 'MNS', 'B', 'forward', 2),
    (18, 'depress_chin', 'MNS', 'B', 'up', 2),
    (19, 'close_t_l_eyelid', 'IRISD', 'B', 'down', 3),
    (20, 'close_t_r_eyelid', 'IRISD', 'B', 'down', 3),
    (21, 'close_b_l_eyelid', 'IRISD', 'B', 'up', 3),
    (22, 'close_b_r_eyelid', 'IRISD', 'B', 'up', 3),
    (23, 'yaw_l_eyeball', 'AU', 'B', 'left', 3),
    (24, 'yaw_r_eyeball', 'AU', 'B', 'left', 3),
    (25, 'pitch_l_eyeball', 'AU', 'B', 'down', 3),
    (26, 'pitch_r_eyeball', 'AU', 'B', 'down', 3),
    (27, 'thrust_l_eyeball', 'ES', 'B', 'forward', 3),
    (28, 'thrust_r_eyeball', 'ES', 'B', 'forward', 3),
    (29, 'dilate_l_pupil', 'IRISD', 'B', 'growing', 3),
    (30, 'dilate_r_pupil', 'IRISD', 'B', 'growing', 3),
    (31, 'raise_l_i_eyebrow', 'ENS', 'B', 'up', 4),
    (32, 'raise_r_i_eyebrow', 'ENS', 'B', 'up', 4),
    (33, 'raise_l_m_eyebrow', 'ENS', 'B', 'up', 4),
    (34, 'raise_r_m_eyebrow', 'ENS', 'B', 'up', 4),
    (35, 'raise_l_o_eyebrow', 'ENS', 'B', 'up', 4),
    (36, 'raise_r_o_eyebrow', 'ENS', 'B', 'up', 4),
    (37, 'squeeze_l_eyebrow', 'ES', 'B', 'right', 4),
    (38, 'squeeze_r_eyebrow', 'ES', 'B', 'left', 4),
    (39, 'puff_l_cheek', 'ES', 'B', 'left', 5),
    (40, 'puff_r_cheek', 'ES', 'B', 'right', 5),
    (41, 'lift_l_cheek', 'ENS', 'U', 'up', 5),
    (42, 'lift_r_cheek', 'ENS', 'U', 'up', 5),
    (43, 'shift_tongue_tip', 'MW', 'B', 'right', 6),
    (44, 'raise_tongue_tip', 'MNS', 'B', 'up', 6),
    (45, 'thrust_tongue_tip', 'MW', 'B', 'forward', 6),
    (46, 'raise_tongue', 'MNS', 'B', 'up', 6),
    (47, 'tongue_roll', 'AU', 'U', 'concave upward', 6),
    (48, 'head_pitch', 'AU', 'B', 'down', 7),
    (49, 'head_yaw', 'AU', 'B', 'left', 7),
    (50, 'head_roll', 'AU', 'B', 'right', 7),
    (51, 'lower_t_midlip_o', 'MNS', 'B', 'down', 8),
    (52, 'raise_b_midlip_o', 'MNS', 'B', 'up', 8),
    (53, 'stretch_l_cornerlip_o', 'MW', 'B', 'left', 8),
    (54, 'stretch_r_cornerlip_o', 'MW', 'B', 'right', 8),
    (55, 'lower_t_lip_lm_o', 'MNS', 'B', 'down', 8),
    (56, 'lower_t_lip_rm_o', 'MNS', 'B', 'down', 8),
    (57, 'raise_b_lip_lm_o', 'MNS', 'B', 'up', 8),
    (58, 'raise_b_lip_rm_o', 'MNS', 'B', 'up', 8),
    (59, 'raise_l_cornerlip_o', 'MNS', 'B', 'up', 8),
    (60, 'raise_r_cornerlip_o', 'MNS', 'B', 'up', 8),
    (61, 'stretch_l_nose', 'ENS', 'B', 'left', 9),
    (62, 'stretch_r_nose', 'ENS', 'B', 'right', 9),
    (63, 'raise_nose', 'ENS', 'B', 'up', 9),
    (64, 'bend_nose', 'ENS', 'B', 'right', 9),
    (65, 'raise_l_ear', 'ENS', 'B', 'up', 10),
    (66, 'raise_r_ear', 'ENS', 'B', 'up', 10),
    (67, 'pull_l_ear', 'ENS', 'B', 'left', 10),
    (68, 'pull_r_ear', 'ENS', 'B', 'right', 10),
)

FAPS: tuple[FapInfo, ...] = tuple(FapInfo(*row) for row in _ROWS)
BY_NUMBER: dict[int, FapInfo] = {info.number: info for info in FAPS}
BY_NAME: dict[str, FapInfo] = {info.name: info for info in FAPS}

def _fap_enum() -> Any:
    """The enum of every FAP; its members come from the table, so type checkers see it as Any."""
    return IntEnum("Fap", {info.name.upper(): info.number for info in FAPS})


#: Every FAP by its MPEG-4 name in capitals, an int: ``Fap.OPEN_JAW == 3``, ``Fap.HEAD_PITCH == 48``.
Fap = _fap_enum()

#: The prosody FAPs this project generates (docs/fap.md).
EYEBROW_FAPS = tuple(int(fap) for fap in (Fap.RAISE_L_I_EYEBROW, Fap.RAISE_R_I_EYEBROW, Fap.RAISE_L_M_EYEBROW,
                                          Fap.RAISE_R_M_EYEBROW))
HEAD_FAPS = tuple(int(fap) for fap in (Fap.HEAD_PITCH, Fap.HEAD_YAW, Fap.HEAD_ROLL))
PROSODY_FAPS = EYEBROW_FAPS + HEAD_FAPS


def fap_info(fap: int | str) -> FapInfo:
    """Look up a FAP by number (1..68) or by name; raises KeyError naming the unknown FAP."""
    table = BY_NAME if isinstance(fap, str) else BY_NUMBER
    try:
        return table[fap]  # type: ignore[index]
    except KeyError:
        raise UnknownFapError(f"unknown FAP {fap!r}: FAPs are numbered 1..{N_FAPS} or named as in MPEG-4") from None
