"""The live lips on the 30 speakers of the talking videos, each held out (``make evaluate``).

The live acoustic mouth model (:class:`prosody.motion.face.mouth_model.LiveMouthModel`, 0 and 100 ms look-ahead) is
fitted either on the seven talking-heads clips alone or on them and the other speakers of the talking videos
(as ``experiments/mouth_videos_loso.py`` tracks them), then streams each held-out clip from its start, as
``prosody stream`` does. Means over speakers of the opening r (with the control: the lips shifted in time, and
its spread) and the closure F1, for women and men apart.
"""

from __future__ import annotations

import sys
from collections import defaultdict

import numpy as np

from audio_features.spectral import cepstra
from experiments.common import data_folder, record
from experiments.mouth_videos_loso import FPS, load_clips, measured, summary
from prosody.motion.face.lips import MouthShape, inner_opening, shape_faps
from prosody.motion.face.mouth_model import SHIPPED_LIVE_MOUTH_MS, LiveMouthModel, live_mouth_clips


def streamed(model: LiveMouthModel, clip: dict) -> dict[int, np.ndarray]:
    """The lip FAPs of a clip streamed through ``model`` from its start, on the clip's mouth grid."""
    live = model.start(clip["audio"].sample_rate_hz, fps=FPS)
    live.push(clip["audio"].samples)
    live.finish()
    n = clip["mouth"].n_frames
    shapes = [live.shape(k) for k in range(n)]
    return shape_faps(MouthShape(*(np.concatenate([getattr(shape, key) for shape in shapes])
                                   for key in ("opening", "rounding", "spread"))))


def main() -> int:
    clips = load_clips()
    heads = live_mouth_clips(data_folder("talking-heads", needs="the talking-heads clips"), fps=FPS)
    pairs = {clip["name"]: (cepstra(clip["audio"]), clip["training"]) for clip in clips}
    speakers = sorted({clip["speaker"] for clip in clips})
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    rows: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for ms in SHIPPED_LIVE_MOUTH_MS:
        alone = LiveMouthModel(ms / 1000).fit(heads)
        for speaker in speakers:
            others = [pairs[clip["name"]] for clip in clips if clip["speaker"] != speaker]
            many = LiveMouthModel(ms / 1000).fit(heads + others)
            for clip in (c for c in clips if c["speaker"] == speaker):
                n = clip["mouth"].n_frames
                for label, model in ((f"live {ms} ms, talking-heads clips alone", alone),
                                     (f"live {ms} ms, talking-heads clips and the other speakers", many)):
                    faps = streamed(model, clip)
                    rows[label][speaker].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
    print(f"{len(clips)} clips, {len(speakers)} speakers held out in turn\n")
    print("| live lips | all speakers: opening r (control ± spread), closure F1, relative closure F1 | women | men |")
    print("|---|---|---|---|")
    for label, per_speaker in rows.items():
        print(summary(label, per_speaker, sexes))
    return 0


if __name__ == "__main__":
    sys.exit(record("live_mouth_videos_loso", main,
                    lambda: [data_folder("talking-videos", needs="the talking videos"),
                             data_folder("talking-heads", needs="the talking-heads clips")]))
