"""Eq. 2's arousal coefficients (C4-C6, at P = 0) fitted to recorded head motion, leave one speaker out
(``make evaluate``; the fit is ``prosody train --kind pad``, ``prosody.motion.heads.pad.fit_arousal``).

Jia et al. (2013) does not print C1-C6. The recordings here carry no emotion labels, so pleasure cannot be fitted;
the arousal part can: each prosodic word (PW) the pad model finds in the audio has an arousal A in {0, 0.5, 1}
(its prominence) and each pause A = -0.5, and the recorded head has a peak-to-peak amplitude per axis over
the same stretch. For every speaker, C4..C6 are fitted by least squares on the other speakers' stretches and
the held-out speaker's amplitudes are predicted from their A alone. Measures, per axis, on the held-out
speakers:

- r, over all held-out stretches, between Amp(0, A) and the recorded amplitude, beside the same r with each
  speaker's A values shuffled among its own stretches (the chance level: mean and spread of 200 shuffles);
- the mean absolute error of Amp(0, A), beside that of the default coefficients (Table 3's amplitude at
  A = 0.5, see ``prosody.motion.heads.pad``) and that of one constant for speech and one for pauses (fitted
  the same way), which ignores A.

Usage: python -m experiments.pad_fit [--no-tracked]  (the talking-heads clips, and the talking-videos clips
tracked by experiments/head_loso.py when it has run)
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from experiments.common import record, talking_heads
from experiments.head_loso import TRACKED, speakers
from prosody.motion.heads.pad import FIT_MIN_FRAMES, arousal_amplitudes, fit_arousal, held_out_arousal
from prosody.motion.heads.training import find_pairs, load_training_set


def main(argv: list[str]) -> int:
    warnings.simplefilter("ignore")
    pairs = find_pairs(talking_heads())
    if "--no-tracked" not in argv and TRACKED.is_dir():
        pairs += find_pairs(TRACKED)
    data = load_training_set(pairs, speakers=speakers(), report=lambda message: None)
    per_recording = [arousal_amplitudes(f, m) for f, m in zip(data.features, data.motion_au, strict=True)]
    arousal = np.concatenate([a for a, _ in per_recording])
    sizes = np.vstack([y for _, y in per_recording])
    print(f"{len(data.names)} clips, {len(data.folds())} speakers, {arousal.size} stretches (PWs and pauses of at "
          f"least {FIT_MIN_FRAMES} frames); leave one speaker out")
    print("stretches by A: " + ", ".join(f"{a:g}: {int(np.sum(arousal == a))}" for a in (-0.5, 0.0, 0.5, 1.0)))
    held = held_out_arousal(per_recording, data.folds())
    print()
    print("| axis | r of Amp(0, A) with the recorded amplitude (all held-out stretches) "
          "| chance: A shuffled within each speaker, mean ± spread "
          "| mean abs. error, deg: fitted C4-C6 | Table 3 defaults | one constant for speech, one for pauses |")
    print("|---|---|---|---|---|---|")
    for axis in ("pitch", "yaw", "roll"):
        row = held[axis]
        print(f"| {axis} | {row['r']:+.3f} | {row['chance_r']:+.3f} ± {row['chance_spread']:.3f} "
              f"| {row['mae_fitted']:.2f} | {row['mae_default']:.2f} | {row['mae_constant']:.2f} |")
    print()
    print("Recorded amplitude by A (deg, mean over stretches; pitch / yaw / roll): "
          + "; ".join(f"A {a:g}: " + " / ".join(f"{v:.2f}" for v in sizes[arousal == a].mean(axis=0))
                      for a in (-0.5, 0.0, 0.5, 1.0)))
    fitted = fit_arousal(arousal, sizes)
    print("C4, C5, C6 fitted on every speaker (pitch; yaw; roll): "
          + "; ".join(", ".join(f"{c:.2f}" for c in axis[3:]) for axis in fitted))
    return 0


if __name__ == "__main__":
    sys.exit(record("pad_fit", lambda: main(sys.argv[1:]), lambda: [talking_heads(), TRACKED]))
