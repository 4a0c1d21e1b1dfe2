"""The brow rules against the video-tracked brows of the talking-heads clips (``make evaluate``).

Each rule (the accent rule, the default; the thesis's 207 Hz rule) raises the brows of the seven clips from their
audio, and ``prosody.measures.brow_metrics`` compares the raises with the recorded inner-brow height: raise r
(Pearson r with the 4 Hz low-passed height), onset F1 (raise onsets within 0.3 s of recorded ones), the number
and the median length of the raises. The control is the same rule driven by the clip's own audio shifted by 5 s
or more (``prosody compare``'s mismatched-audio control); beside it, the spread of its onset F1 over clips. The
rules have no fitted parameters, but the accent rule's 4 semitones were chosen among 2 to 4 by its scores on
these clips, so its figures are mildly optimistic.

Usage: python -m experiments.brows_heads [DIR]  (default ../shared/data/talking-heads)
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from experiments.common import record, talking_heads
from prosody.evaluation.compare import compare
from prosody.motion.eyebrows import AccentRule, EyebrowRule

RULES = (("accent rule (default)", AccentRule), ("thesis rule (207 Hz)", EyebrowRule))


def _mean(values: list) -> float:
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else float("nan")


def main(folder: Path) -> None:
    clips = sorted(wav for wav in folder.glob("*.wav") if wav.with_name(wav.stem + ".brows.csv").is_file())
    if not clips:
        sys.exit(f"{folder}: no <clip>.wav with a <clip>.brows.csv beside it")
    print(f"{len(clips)} clips with tracked brows\n")
    print("| brows | raise r | onset F1 | control: raise r | control: onset F1 (spread) | clips with a raise | "
          "median raise, s (mean over clips) | recorded median raise, s |")
    print("|---|---|---|---|---|---|---|---|")
    for label, rule in RULES:
        rows, controls = [], []
        for wav in clips:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                comparison = compare(wav, ground_truth=wav.with_name(wav.stem + ".head.csv"), conditions=["speech"],
                                     seeds=1, lips=None, eyebrow_rule=rule())
            rows.append(comparison.metrics["conditions"]["SPEECH_DRIVEN"]["brows"])
            controls.append(comparison.metrics["controls"]["mismatched_audio_brows"])
        control_f1 = [c["onsets"]["f1"] for c in controls if c["onsets"]["f1"] is not None]
        print(f"| {label} | {_mean([r['raise_r'] for r in rows]):.3f} | {_mean([r['onsets']['f1'] for r in rows]):.2f} "
              f"| {_mean([c['raise_r'] for c in controls]):.3f} | {_mean(control_f1):.2f} ± {np.std(control_f1):.2f} "
              f"| {sum(1 for r in rows if r['raises'])} of {len(rows)} | "
              f"{_mean([r['median_raise_s'] for r in rows]):.2f} | "
              f"{_mean([r['recorded_median_raise_s'] for r in rows]):.2f} |")


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else None
    sys.exit(record("brows_heads", lambda: main(target or talking_heads()), lambda: [target or talking_heads()]))
