"""Leave-one-speaker-out measures of the expressivity controls on the default head (``make evaluate``).

For each speaker (``experiments/speakers.csv``), the prosodic generator with the shipped settings is fitted on
the other speakers' recordings; its motion on this speaker's recordings (5 seeds) is shaped by each setting of
the controls and measured against the recorded motion: speed-envelope r, pitch r, spread, the angular speed's
10th / 50th / 90th percentiles as ratios to the recording's, and the share of time nearly still (under 2 deg/s;
the recordings' own share beside it). The control is the same, driven by the recording's audio shifted by 5 s
or more.

Usage: python -m experiments.expressivity_loso [DIR]  (default ../shared/data/talking-heads)
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from experiments.common import record, shipped_settings, talking_heads
from experiments.common import talking_heads as default_data
from prosody.measures import average_head_metrics, head_metrics
from prosody.motion.controls import shift_offsets, shifted_features
from prosody.motion.expressivity import Expressivity, shape_head
from prosody.motion.heads.prosodic import ProsodicHeadModel
from prosody.motion.heads.training import find_pairs, load_training_set

SEEDS = 5
SETTINGS = (
    ("as generated (neutral)", Expressivity()),
    ("activation 0.7", Expressivity(activation=0.7)),
    ("activation 0.5", Expressivity(activation=0.5)),
    ("power 0.5", Expressivity(power=0.5)),
    ("power 1", Expressivity(power=1)),
    ("activation 0.7, power 0.5", Expressivity(activation=0.7, power=0.5)),
    ("still (activation 0)", Expressivity.still()),
)


def _array(curves: dict) -> np.ndarray:
    return np.column_stack([curves[fap] for fap in (48, 49, 50)])


def _mean(rows: list[dict], key: str) -> float:
    values = [row[key] for row in rows if row[key] is not None]
    return float(np.mean(values)) if values else float("nan")


def _spread(rows: list[dict], key: str) -> float:
    """The standard deviation over recordings: the chance spread of a control's mean."""
    values = [row[key] for row in rows if row[key] is not None]
    return float(np.std(values)) if values else float("nan")


def main(argv: list[str]) -> int:
    directory = Path(argv[0]) if argv else default_data()
    warnings.simplefilter("ignore")
    from experiments.head_loso import speakers

    data = load_training_set(find_pairs(directory), speakers=speakers(), report=lambda message: None)
    fps = data.fps
    settings = shipped_settings()
    rows: dict[str, list[dict]] = {label: [] for label, _ in SETTINGS}
    controls: dict[str, list[dict]] = {label: [] for label, _ in SETTINGS}
    for fold in data.folds():
        keep = [i for i in range(len(data.names)) if i not in fold]
        inner = data.subset(keep)
        model = ProsodicHeadModel(**settings).fit(inner.features, inner.motion_au)
        for held in fold:
            features, recorded = data.features[held], data.motion_au[held]
            own = [_array(model.generate(features, seed=seed)) for seed in range(SEEDS)]
            shifted = [_array(model.generate(shifted_features(features, k), seed=seed))
                       for seed in range(SEEDS) for k in shift_offsets(features.n_frames, fps=fps)]
            for label, controls_set in SETTINGS:
                rows[label].append(average_head_metrics([
                    head_metrics(shape_head(m, fps=fps, expressivity=controls_set), recorded, fps=fps) for m in own]))
                controls[label].append(average_head_metrics([
                    head_metrics(shape_head(m, fps=fps, expressivity=controls_set), recorded, fps=fps)
                    for m in shifted]))
    print(f"{len(data.names)} recordings, {len(data.folds())} speakers, leave-one-speaker-out, {SEEDS} seeds")
    print()
    print("| controls | speed-envelope r | pitch r | std ratio (mean of axes) | speed p10 / p50 / p90 ratio | "
          "still share (recorded) | control: speed-envelope r / pitch r (chance spread) |")
    print("|---|---|---|---|---|---|---|")
    for label, _ in SETTINGS:
        own, control = rows[label], controls[label]
        spread = np.mean([np.mean([v for v in row["std_ratio"].values() if v is not None]) for row in own])
        print(f"| {label} | {_mean(own, 'speed_envelope_r'):+.3f} | {_mean(own, 'pitch_r'):+.3f} | {spread:.2f} | "
              f"{_mean(own, 'speed_p10_ratio'):.2f} / {_mean(own, 'speed_p50_ratio'):.2f} / "
              f"{_mean(own, 'speed_p90_ratio'):.2f} | {_mean(own, 'still_fraction'):.2f} "
              f"({_mean(own, 'recorded_still_fraction'):.2f}) | {_mean(control, 'speed_envelope_r'):+.3f} "
              f"± {_spread(control, 'speed_envelope_r'):.2f} / {_mean(control, 'pitch_r'):+.3f} "
              f"± {_spread(control, 'pitch_r'):.2f} |")
    return 0


if __name__ == "__main__":
    given = [Path(argument) for argument in sys.argv[1:2] if not argument.startswith("-")]
    sys.exit(record("expressivity_loso", lambda: main(sys.argv[1:]), lambda: given or [talking_heads()]))
