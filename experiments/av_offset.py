"""Does correcting each tracked clip's audio-video offset improve the held-out head figures? (``make evaluate``)

``prosody track`` estimates, per video, how far the mouth leads the sound (``<stem>.track.json``, ``sync``).
Where that estimate is reliable, this shifts the clip's recorded motion by it (the motion delayed by the
mouth's lead, its first or last frame held), then measures the prosodic generator fitted on every other speaker
(leave one speaker out, 5 seeds) with and without the correction, on all 49 clips and on the corrected ones.
The clips must have been tracked by ``experiments/head_loso.py`` first.

Usage: python -m experiments.av_offset
"""

from __future__ import annotations

import json
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from experiments.common import record, shipped_settings, talking_heads
from experiments.head_loso import TRACKED, speakers
from prosody.motion.heads.training import find_pairs, held_out_prosodic, load_training_set

SEEDS = 5


def reliable_leads(folder: Path) -> dict[str, float]:
    """Stem -> the mouth's lead over the sound in ms, for the clips whose estimate is reliable."""
    leads = {}
    for path in sorted(folder.glob("*.track.json")):
        sync = json.loads(path.read_text()).get("sync") or {}
        if sync.get("lead_ms") is not None and "unreliable" not in sync.get("description", "unreliable"):
            leads[path.name.removesuffix(".track.json")] = float(sync["lead_ms"])
    return leads


def delayed(motion: np.ndarray, frames: int) -> np.ndarray:
    """``motion`` delayed by ``frames`` (advanced if negative), the edge frame held."""
    if frames == 0:
        return motion
    index = np.clip(np.arange(motion.shape[0]) - frames, 0, motion.shape[0] - 1)
    return motion[index]


def _mean(table: dict, names: list[str], key: str) -> str:
    values = [table[name][key] for name in names if table[name][key] is not None]
    return f"{np.mean(values):+.3f}"


def main(argv: list[str]) -> int:
    warnings.simplefilter("ignore")
    if not TRACKED.is_dir():
        raise SystemExit(f"{TRACKED}: not found; run python -m experiments.head_loso first to track the "
                         "talking-videos clips")
    data = load_training_set(find_pairs(talking_heads()) + find_pairs(TRACKED), speakers=speakers(),
                             report=lambda message: None)
    leads = reliable_leads(TRACKED)
    shifts = {name: int(round(leads[name] / 1000 * data.fps)) for name in data.names if name in leads}
    print(f"{len(data.names)} clips; reliable offsets on {len(shifts)}: "
          + ", ".join(f"{name} {leads[name]:+.0f} ms" for name in shifts))
    corrected = replace(data, motion_au=[delayed(m, shifts.get(name, 0)) for name, m in
                                         zip(data.names, data.motion_au, strict=True)])
    print()
    print("| recorded motion | clips | speed-envelope r | pitch r | control: speed-envelope r | control: pitch r |")
    print("|---|---|---|---|---|---|")
    for label, chosen in (("as tracked", data), ("offsets corrected", corrected)):
        result = held_out_prosodic(chosen, shipped_settings(), seeds=SEEDS)
        for clips, names in (("all", data.names), ("the corrected ones", list(shifts))):
            cells = [_mean(table, names, key) for key in ("speed_envelope_r", "pitch_r")
                     for table in (result.per_recording, result.controls)]
            print(f"| {label} | {clips} | {cells[0]} | {cells[2]} | {cells[1]} | {cells[3]} |")
    return 0


if __name__ == "__main__":
    sys.exit(record("av_offset", lambda: main(sys.argv[1:]), lambda: [talking_heads(), TRACKED]))
