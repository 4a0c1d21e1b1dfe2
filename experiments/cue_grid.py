"""Mouth cues on Rhubarb's 0.01 s grid beside cues on the 1/30 s frames, against the tracked mouths of the talking
videos (30 speakers).

``prosody convert -o X.rhubarb.json`` makes its cues at 100 frames a second (``prosody.fap.mouth_cues.CUE_FPS``),
so that they start and end on Rhubarb Lip Sync's own 0.01 s grid; before, they changed on the motion's 30 fps
frames. Both are made here from the same recognised phones (the default visemes, no transcript, their openings
fitted without the held-out speaker as ``experiments/viseme_fit.py`` fits them) and played back
as a 2D player shows cues (each shape held for its cue at the visemes' size, ``experiments.mouth_loco.CUE_SHAPES``)
on the tracked mouth's 30 fps frames. Measures as ``experiments/mouth_videos_loso.py`` (opening r at the best lag
within +-0.25 s, closure F1, relative closure F1, each beside its mismatched-audio control), plus the cues' own
timing: the shortest cue but the last (which may be the recording's last 0.01 s), and the shortest idle run (X)
inside the speech, which Rhubarb keeps at 0.12 s or more.
Nothing here is fitted: the grid is Rhubarb's, and the shortest shape (``MIN_SHAPE_S``) keeps the 30 fps rule
(one frame joins its neighbour).

Usage: python -m experiments.cue_grid
"""

from __future__ import annotations

import sys
from collections import defaultdict

import numpy as np

from experiments.common import data_folder, record
from experiments.mouth_loco import FPS, measured, played_cues
from experiments.mouth_videos_loso import load_clips, reference_table, summary_table
from experiments.viseme_fit import held_out_openings
from prosody.fap.mouth_cues import CUE_FPS, mouth_cues
from prosody.fap.stream import FapStream
from prosody.motion.face.lips import shape_faps, shapes_from_phones

GRIDS = {"frames": FPS, "grid": CUE_FPS}


def main() -> None:
    clips = load_clips()
    visemes = held_out_openings(clips)  # the shipped openings' recipe without the speaker; gives clips phones
    names = sorted({clip["speaker"] for clip in clips})
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    print(f"{len(clips)} clips, {len(names)} speakers\n")
    rows: dict[str, dict[str, list]] = {key: defaultdict(list) for key in GRIDS}
    timing: dict[str, dict[str, list]] = {key: defaultdict(list) for key in GRIDS}
    for clip in clips:
        n = clip["mouth"].n_frames
        duration = n / FPS
        phones = clip["phones"]
        for key, fps in GRIDS.items():
            frames = int(np.ceil(duration * fps))
            faps = shape_faps(shapes_from_phones(phones, frames, fps=fps, visemes=visemes[clip["speaker"]]))
            cues = mouth_cues(FapStream.from_curves(faps, fps=fps), duration_s=duration)
            rows[key][clip["speaker"]].append(measured(*played_cues(cues, n), clip))
            lengths = [cue.end_s - cue.start_s for cue in cues[:-1]]  # the last: up to the recording's end
            timing[key]["cues"].append(len(cues))
            timing[key]["shortest"].append(min(lengths))
            inner = [cue.end_s - cue.start_s for cue in cues[1:-1] if cue.shape == "X"]
            timing[key]["inner idle"].extend(inner)
    labels = {"frames": "cues on the 30 fps frames (`--fps 30`)", "grid": "cues on Rhubarb's 0.01 s grid (the default)"}
    summary_table("default visemes as cues", labels, rows, sexes)
    print("\n| cues | cues per clip (median) | shortest cue, median over clips (s) | shortest cue anywhere (s) | "
          "inner idle runs (X): count, shortest (s) |")
    print("|---|---|---|---|---|")
    for key, label in labels.items():
        t = timing[key]
        inner = t["inner idle"]
        print(f"| {label} | {np.median(t['cues']):.0f} | {np.median(t['shortest']):.2f} | {min(t['shortest']):.2f} | "
              f"{len(inner)}, {min(inner) if inner else float('nan'):.2f} |")
    reference_table(rows, labels, clips)


if __name__ == "__main__":
    sys.exit(record("cue_grid", main, lambda: [data_folder("talking-videos", needs="the talking videos")]))
