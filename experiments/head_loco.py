"""Leave-one-speaker-out table of the head measures on paired recordings (``make evaluate``).

For each speaker (``experiments/speakers.csv``; a recording not named there is its own speaker), models are
fitted on the other speakers' recordings and measured on this speaker's; every row is the mean over
recordings, stochastic rows over several seeds, with the chance spread (the standard deviation over
recordings of the control's figure) and each speech-driven row's control beside it:

- prosodic: the default generator (10 seeds), and the same driven by the recording's own audio shifted
  by 5 s or more (the mismatched-audio control);
- arx: the thesis's model with the shipped orders, and its control;
- Jia et al.'s PAD-driven gestures and their random baseline (nothing fitted; 10 seeds), with their control;
- Perlin noise (20 seeds), a still head, and another recording's real motion (trimmed or tiled).

Usage: python -m experiments.head_loco [DIR]  (default ../shared/data/talking-heads)
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
from prosody.motion.heads.arx import ArxHeadModel, arx_inputs
from prosody.motion.heads.pad import PadHeadModel, arousal_amplitudes, fit_arousal
from prosody.motion.heads.prosodic import ProsodicHeadModel
from prosody.motion.heads.training import (
    find_pairs,
    held_out_prosodic,
    load_training_set,
    select_prosodic,
)
from prosody.motion.perlin import perlin_curves


def _shipped_arx_orders() -> dict:
    import json

    from prosody.motion.heads.arx import DEFAULT_MODEL_PATH

    shipped = json.loads(Path(DEFAULT_MODEL_PATH).read_text())
    return {**shipped["orders"], "ridge": float(shipped["ridge"])}


#: The orders and ridge of the shipped ARX model (chosen by `prosody train --kind arx --cv`).
SHIPPED_ARX = _shipped_arx_orders()


def _array(curves: dict) -> np.ndarray:
    return np.column_stack([curves[fap] for fap in (48, 49, 50)])


def seeded_measures(model, features, recorded: np.ndarray, fps: float, seeds: int = 10) -> tuple[dict, dict]:
    """A stochastic model's head measures on a clip averaged over ``seeds`` seeds, and those of its control
    (the clip's own audio shifted by 5 s or more)."""
    own = average_head_metrics([head_metrics(_array(model.generate(features, seed=seed)), recorded, fps=fps)
                                for seed in range(seeds)])
    control = average_head_metrics([
        head_metrics(_array(model.generate(shifted_features(features, k), seed=seed)), recorded, fps=fps)
        for seed in range(seeds) for k in shift_offsets(features.n_frames, fps=fps)])
    return own, control


def _row(label: str, per_recording: list[dict], control: list[dict] | None = None) -> str:
    def mean(rows: list[dict], key: str) -> str:
        values = [row[key] for row in rows if row[key] is not None]
        return f"{np.mean(values):+.3f}" if values else "–"

    def spread(rows: list[dict], key: str) -> str:
        values = [row[key] for row in rows if row[key] is not None]
        return f"±{np.std(values):.2f}" if values else ""

    ratios = " / ".join(
        f"{np.mean([row['std_ratio'][axis] for row in per_recording if row['std_ratio'][axis] is not None]):.2f}"
        if any(row["std_ratio"][axis] is not None for row in per_recording) else "–" for axis in ("48", "49", "50"))
    cells = [label, mean(per_recording, "speed_envelope_r"), mean(per_recording, "pitch_r"), ratios,
             mean(per_recording, "velocity_spectrum_distance_db").lstrip("+")]
    if control:
        cells += [f"{mean(control, 'speed_envelope_r')} {spread(control, 'speed_envelope_r')}",
                  f"{mean(control, 'pitch_r')} {spread(control, 'pitch_r')}"]
    else:
        cells += ["", ""]
    return "| " + " | ".join(cells) + " |"


def main(argv: list[str]) -> int:
    directory = Path(argv[0]) if argv else default_data()
    warnings.simplefilter("ignore")
    from experiments.head_loso import speakers

    data = load_training_set(find_pairs(directory), speakers=speakers(), report=lambda message: None)
    names, fps = data.names, data.fps
    held_with = {held: fold for fold in data.folds() for held in fold}
    seconds = sum(f.n_frames for f in data.features) / fps
    print(f"{len(names)} recordings, {len(data.folds())} speakers, {seconds:.0f} s, "
          "leave-one-speaker-out")
    print()
    print("| head | speed-envelope r | pitch r | std ratio pitch / yaw / roll | velocity-spectrum distance (dB) "
          "| control: speed-envelope r (chance spread) | control: pitch r (chance spread) |")
    print("|---|---|---|---|---|---|---|")
    prosodic = held_out_prosodic(data, shipped_settings(), seeds=10)
    print(_row("prosodic (default), 10 seeds", list(prosodic.per_recording.values()),
               list(prosodic.controls.values())))
    # nested: the settings for each held-out recording are chosen by cross-validation on the others only
    nested, nested_control = [], []
    for held in range(len(names)):
        keep = [i for i in range(len(names)) if i not in held_with[held]]
        inner = data.subset(keep)
        settings = select_prosodic(inner)[0].settings
        model = ProsodicHeadModel(**settings).fit(inner.features, inner.motion_au)
        own, control = seeded_measures(model, data.features[held], data.motion_au[held], fps)
        nested.append(own)
        nested_control.append(control)
    print(_row("prosodic, settings chosen per fold (nested), 10 seeds", nested, nested_control))
    arx_rows, arx_control = [], []
    for held in range(len(names)):
        keep = [i for i in range(len(names)) if i not in held_with[held]]
        model = ArxHeadModel(**SHIPPED_ARX).fit([data.features[i] for i in keep], [data.motion_au[i] for i in keep])
        recorded = data.motion_au[held]
        arx_rows.append(head_metrics(model.simulate_arrays(data.inputs[held]), recorded, fps=fps))
        shifted = [head_metrics(model.simulate_arrays(arx_inputs(shifted_features(data.features[held], k))),
                                recorded, fps=fps)
                   for k in shift_offsets(data.features[held].n_frames, fps=fps)]
        arx_control.append(average_head_metrics(shifted))
    print(_row("thesis ARX (na={na}, nb={nb}, nk={nk}, ridge {ridge:g}: the shipped orders)".format(**SHIPPED_ARX),
               arx_rows, arx_control))
    # Jia et al.'s gestures have nothing fitted: every clip is held out by construction
    for label, model in (("Jia et al.'s PAD gestures (pad), 10 seeds", PadHeadModel()),
                         ("Jia et al.'s random baseline (pad-random), 10 seeds", PadHeadModel(randomized=True))):
        rows, controls = [], []
        for features, recorded in zip(data.features, data.motion_au, strict=True):
            own, control = seeded_measures(model, features, recorded, fps)
            rows.append(own)
            controls.append(control)
        print(_row(label, rows, controls))
    # the same gestures with Eq. 2's arousal part (C4-C6) fitted on the other speakers' clips
    amplitudes = [arousal_amplitudes(f, m) for f, m in zip(data.features, data.motion_au, strict=True)]
    rows, controls = [], []
    for held in range(len(names)):
        keep = [i for i in range(len(names)) if i not in held_with[held]]
        model = PadHeadModel(coefficients=fit_arousal(np.concatenate([amplitudes[i][0] for i in keep]),
                                                      np.vstack([amplitudes[i][1] for i in keep])))
        own, control = seeded_measures(model, data.features[held], data.motion_au[held], fps)
        rows.append(own)
        controls.append(control)
    print(_row("Jia et al.'s PAD gestures, C4-C6 fitted on the other speakers (train --kind pad), 10 seeds", rows,
               controls))
    perlin = []
    for recorded in data.motion_au:
        runs = [head_metrics(_array(perlin_curves(recorded.shape[0], fps=fps, seed=seed)), recorded, fps=fps)
                for seed in range(20)]
        perlin.append(average_head_metrics(runs))
    print(_row("Perlin noise, 20 seeds", perlin))
    print(_row("still head", [head_metrics(np.zeros_like(m), m, fps=fps) for m in data.motion_au]))
    other = []
    for held, recorded in enumerate(data.motion_au):
        source = data.motion_au[(held + 1) % len(names)]
        tiled = source[np.arange(recorded.shape[0]) % source.shape[0]]
        other.append(head_metrics(tiled, recorded, fps=fps))
    print(_row("another recording's real motion", other))
    print()
    print("Per recording (prosodic): " + ", ".join(
        f"{name} {row['speed_envelope_r']:+.2f}/{row['pitch_r']:+.2f}" for name, row in prosodic.per_recording.items()))
    return 0


if __name__ == "__main__":
    given = [Path(argument) for argument in sys.argv[1:2] if not argument.startswith("-")]
    sys.exit(record("head_loco", lambda: main(sys.argv[1:]), lambda: given or [talking_heads()]))
