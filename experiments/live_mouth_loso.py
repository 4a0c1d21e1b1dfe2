"""The live mouth models (0 and 100 ms of look-ahead) held out by speaker on the talking-heads clips: each
speaker's clips streamed through a model fitted on the other speakers' (``make evaluate``; the shipped models
are written by ``scripts/retrain_models.py``).

Usage: python -m experiments.live_mouth_loso [DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from experiments.common import record
from experiments.mouth_loco import default_data, speaker_of
from prosody.fap.recorded import read_mouth_csv
from prosody.measures import mouth_metrics
from prosody.motion.face.lips import inner_opening, shape_faps
from prosody.motion.face.mouth_model import (
    SHIPPED_LIVE_MOUTH_MS,
    LiveMouthModel,
    live_mouth_clips,
)


def main(folder: Path) -> None:
    from audio_features import load_audio

    pairs = live_mouth_clips(folder)
    print("| mouth model | opening r | closure F1 | rounding r |\n|---|---|---|---|")
    for ms in SHIPPED_LIVE_MOUTH_MS:
        results = []
        for _, clip in pairs:
            rest = [pair for pair in pairs if speaker_of(pair[1].name) != speaker_of(clip.name)]
            model = LiveMouthModel(ms / 1000).fit(rest)
            live = model.start(16000, fps=30.0)
            audio = load_audio(folder / f"{clip.name}.wav")
            live.push(audio.samples)
            live.finish()
            shapes = [live.shape(k) for k in range(clip.opening.size)]
            faps = shape_faps(type(shapes[0])(*(np.concatenate([getattr(s, key) for s in shapes])
                                                 for key in ("opening", "rounding", "spread"))))
            mouth = read_mouth_csv(folder / f"{clip.name}.mouth.csv")
            results.append(mouth_metrics(inner_opening(faps), faps[16], mouth.lip_opening, mouth.rounding, fps=30))
        print(f"| live, {ms} ms look-ahead, held out by speaker | {np.mean([r['opening_r'] for r in results]):.3f} | "
              f"{np.mean([r['closures']['f1'] or 0 for r in results]):.2f} | "
              f"{np.mean([r['rounding_r'] for r in results]):.3f} |")


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else default_data()
    sys.exit(record("live_mouth_loso", lambda: main(folder), lambda: [folder]))
