"""How close ``prosody track`` comes to the reference curves of ../shared/data/talking-heads.

The references' videos are not in the shared data: they are the StyleTalk repository's
``samples/source_video/video/<clip>.mp4`` (github.com/FuxiVirtualHuman/styletalk; 256x256, 30 fps, no sound).
Give the folder that holds them. The head reference comes from another tracker (Deep3DFaceRecon), the brows and
mouth from the same MediaPipe model run on the same clips; the references were aligned to the sound by head
roll, so each clip's curves are compared at the lag (within +-5 frames) where the roll agrees best, and that
lag is printed. Aims: head r >= 0.85 pitch, 0.95 yaw, 0.95 roll; brows r >= 0.95.

Usage: python -m experiments.track_accuracy VIDEO_DIR
"""

from __future__ import annotations

import csv
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from experiments.common import record, talking_heads

CLIPS = ("KristiNoem", "Obama_clip1", "Obama_clip2", "andrew_clip_1", "feifeili_clip1", "feifeili_clip3",
         "reagan_clip1")
MAX_LAG = 5
COLUMNS = {"head": ("rx_rad", "ry_rad", "rz_rad"),
           "brows": ("brow_inner_up", "brow_outer_up_l", "brow_outer_up_r", "inner_height_l", "inner_height_r",
                     "outer_height_l", "outer_height_r"),
           "mouth": ("jaw_open", "mouth_funnel", "mouth_pucker", "lip_opening", "mouth_width")}


def read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) if row[key] else np.nan for row in rows]) for key in rows[0]}


def r_at(ours: np.ndarray, theirs: np.ndarray, lag: int) -> float:
    """r(ours[t + lag], theirs[t])."""
    t = np.arange(theirs.size)
    t = t[(t + lag >= 0) & (t + lag < ours.size)]
    a, b = ours[t + lag], theirs[t]
    keep = np.isfinite(a) & np.isfinite(b)
    return float(np.corrcoef(a[keep], b[keep])[0, 1]) if keep.sum() > 10 and b[keep].std() > 0 else float("nan")


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    videos = Path(argv[0])
    reference = talking_heads()
    from prosody.jobs.track import track_video

    warnings.simplefilter("ignore")
    table: dict[str, list[list[float]]] = {name: [] for name in sum(COLUMNS.values(), ())}
    with tempfile.TemporaryDirectory() as out:
        for clip in CLIPS:
            video = videos / f"{clip}.mp4"
            if not video.is_file():
                print(f"{video}: missing, skipped")
                continue
            # the reference clips' sound is the talking-heads WAV, beside the video in the StyleTalk folder
            track_video(video, out, audio=reference / f"{clip}.wav")
            ours = {kind: read(Path(out) / f"{clip}.{kind}.csv") for kind in COLUMNS}
            theirs = {kind: read(reference / f"{clip}.{kind}.csv") for kind in COLUMNS}
            lag = max(range(-MAX_LAG, MAX_LAG + 1), key=lambda k: r_at(ours["head"]["rz_rad"],
                                                                       theirs["head"]["rz_rad"], k))
            print(f"{clip}: compared at a lag of {lag:+d} frames")
            for kind, names in COLUMNS.items():
                for name in names:
                    table[name].append([r_at(ours[kind][name], theirs[kind][name], lag)])
    print()
    print("| curve | r per clip | mean r |")
    print("|---|---|---|")
    for name, values in table.items():
        rs = [v[0] for v in values]
        print(f"| {name} | {' '.join(f'{r:.2f}' for r in rs)} | {np.nanmean(rs):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(record("track_accuracy", lambda: main(sys.argv[1:]), lambda: [Path(sys.argv[1]), talking_heads()]))
