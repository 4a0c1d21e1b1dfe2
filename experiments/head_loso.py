"""Leave-one-speaker-out head measures on every speaker at hand (``make evaluate``).

The talking-videos clips are tracked first with ``prosody track`` (into ``out/talking-videos-tracked``; complete
outputs are reused), then joined with the talking-heads clips; ``experiments/speakers.csv`` names each clip's
speaker, so two clips of one speaker are always held out together. Rows (means over held-out clips; the
stochastic generator over 5 seeds; the mismatched-audio control and its chance spread beside each
speech-driven row):

- the shipped default model, which was trained on the talking-heads clips only, measured on the tracked
  clips (speakers it never saw);
- the prosodic generator fitted on every speaker but one and measured on that speaker's clips, over all
  clips and over each source;
- the same fitted on the talking-heads clips only (leave one speaker out among them), for the same clips;
- Perlin noise and a still head.

Speed columns: generated / recorded 10th, 50th and 90th percentiles of the angular speed, and the time
nearly still (under 2 deg/s) and how far from its median pose the head holds while nearly still (deg), generated
vs recorded.

Usage: python -m experiments.head_loso [--no-track]
"""

from __future__ import annotations

import csv
import sys
import warnings
from pathlib import Path

import numpy as np

from experiments.common import TRACKED_VIDEOS, record, shipped_settings, talking_heads, tracked_videos
from experiments.head_loco import seeded_measures
from prosody.measures import average_head_metrics, head_metrics
from prosody.motion.heads.training import find_pairs, held_out_prosodic, load_training_set
from prosody.motion.perlin import perlin_curves

SEEDS = 5
TRACKED = TRACKED_VIDEOS


def speakers() -> dict[str, str]:
    with open(Path(__file__).parent / "speakers.csv", newline="") as handle:
        return {row["recording"]: row["speaker"] for row in csv.DictReader(handle)}


def _array(curves: dict) -> np.ndarray:
    return np.column_stack([curves[fap] for fap in (48, 49, 50)])


def _mean(rows: list[dict], key: str, nested: str | None = None) -> float | None:
    values = [(row[nested] if nested else row)[key] for row in rows]
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _cell(value: float | None, form: str = "+.3f") -> str:
    return "–" if value is None else format(value, form)


def row(label: str, rows: list[dict], control: list[dict] | None = None) -> str:
    ratios = " / ".join(_cell(_mean(rows, axis, "std_ratio"), ".2f") for axis in ("48", "49", "50"))
    speeds = " / ".join(_cell(_mean(rows, f"speed_p{p}_ratio"), ".2f") for p in (10, 50, 90))
    still = f"{_cell(_mean(rows, 'still_fraction'), '.2f')} vs {_cell(_mean(rows, 'recorded_still_fraction'), '.2f')}"
    held = (f"{_cell(_mean(rows, 'still_offset_deg'), '.1f')} vs "
            f"{_cell(_mean(rows, 'recorded_still_offset_deg'), '.1f')}")
    cells = [label, str(len(rows)), _cell(_mean(rows, "speed_envelope_r")), _cell(_mean(rows, "pitch_r")), ratios,
             _cell(_mean(rows, "velocity_spectrum_distance_db"), ".1f"), speeds, still, held]
    if control:
        def spread(key: str) -> str:
            values = [r[key] for r in control if r[key] is not None]
            return f"±{np.std(values):.2f}" if values else ""

        cells += [f"{_cell(_mean(control, 'speed_envelope_r'))} {spread('speed_envelope_r')}",
                  f"{_cell(_mean(control, 'pitch_r'))} {spread('pitch_r')}"]
    else:
        cells += ["", ""]
    return "| " + " | ".join(cells) + " |"


def measured(model, features, recorded, fps: float) -> tuple[dict, dict]:
    return seeded_measures(model, features, recorded, fps, SEEDS)


def main(argv: list[str]) -> int:
    warnings.simplefilter("ignore")
    heads = talking_heads()
    if "--no-track" not in argv:
        tracked_videos()
    table = speakers()
    pairs = find_pairs(heads) + find_pairs(TRACKED)
    data = load_training_set(pairs, speakers=table, report=lambda message: None)
    fps = data.fps
    source = {name: ("talking-heads" if (heads / f"{name}.wav").is_file() else "talking-videos")
              for name in data.names}
    print(f"{len(data.names)} clips, {len(data.folds())} speakers, "
          f"{sum(f.n_frames for f in data.features) / fps:.0f} s; leave-one-speaker-out")
    print()
    print("| head | clips | speed-envelope r | pitch r | std ratio pitch / yaw / roll "
          "| velocity-spectrum distance (dB) "
          "| speed p10 / p50 / p90 ratio | still: generated vs recorded | held pose from median (deg): generated vs "
          "recorded | control: speed-envelope r (chance spread) "
          "| control: pitch r (chance spread) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    from prosody.motion.heads.models import load_head_model

    shipped = load_head_model("prosodic")
    unseen = [i for i, name in enumerate(data.names) if source[name] == "talking-videos"]
    pairs_unseen = [measured(shipped, data.features[i], data.motion_au[i], fps) for i in unseen]
    print(row("shipped default (trained on talking-heads), on the tracked clips", [p[0] for p in pairs_unseen],
              [p[1] for p in pairs_unseen]))
    settings = shipped_settings()
    everyone = held_out_prosodic(data, settings, seeds=SEEDS)
    by_source = {kind: [n for n in data.names if source[n] == kind] for kind in ("talking-heads", "talking-videos")}
    for label, chosen in (("all", data.names), *by_source.items()):
        print(row(f"prosodic fitted on every other speaker: {label} clips",
                  [everyone.per_recording[n] for n in chosen], [everyone.controls[n] for n in chosen]))
    heads_only = [i for i, name in enumerate(data.names) if source[name] == "talking-heads"]
    small = held_out_prosodic(data.subset(heads_only), settings, seeds=SEEDS)
    print(row("prosodic fitted on the other talking-heads speakers only: talking-heads clips",
              list(small.per_recording.values()), list(small.controls.values())))
    perlin = [average_head_metrics([head_metrics(_array(perlin_curves(m.shape[0], fps=fps, seed=seed)), m, fps=fps)
                                    for seed in range(SEEDS)]) for m in data.motion_au]
    print(row("Perlin noise", perlin))
    print(row("still head", [head_metrics(np.zeros_like(m), m, fps=fps) for m in data.motion_au]))
    print()
    recorded_speed = [np.percentile(np.degrees(_speed(m, fps)), (10, 50, 90)) for m in data.motion_au]
    print("Recorded angular speed (deg/s), median over clips of p10 / p50 / p90: "
          + " / ".join(f"{v:.1f}" for v in np.median(recorded_speed, axis=0)))
    return 0


def _speed(motion_au: np.ndarray, fps: float) -> np.ndarray:
    from prosody.dsp import head_speed

    return head_speed(motion_au * 1e-5, fps=fps)


if __name__ == "__main__":
    sys.exit(record("head_loso", lambda: main(sys.argv[1:]), lambda: [talking_heads(), TRACKED]))
