"""Can the speech tell how animated a speaker's head is? (``make evaluate``)

Per clip: the recorded head's level of animation (its median angular speed, deg/s, and its spread, the mean
standard deviation of pitch, yaw and roll in degrees) and four descriptors of the speech (pitch range: the 10th
to 90th percentile of voiced F0 in semitones; loudness range: the same of the intensity of speech frames in dB;
syllable rate: the prosodic model's nuclei per second of speech; voiced share). A linear model of the log level
on the descriptors is fitted on every other speaker's clips and predicts this speaker's (leave one speaker
out). Measures: r between predicted and recorded log level over the clips, beside the chance level (the
descriptors shuffled among speakers, 500 times) and the mean absolute log2 error against that of the other
speakers' mean level (a constant).

Usage: python -m experiments.animation_level  (the talking-heads clips and the clips tracked by
experiments/head_loso.py)
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from experiments.common import record, talking_heads
from experiments.head_loso import TRACKED, speakers
from prosody.motion.heads.pad import AU_PER_DEGREE, prosodic_words
from prosody.motion.heads.training import find_pairs, load_training_set

SHUFFLES = 500
DESCRIPTORS = ("pitch range (st)", "loudness range (dB)", "syllable rate (/s)", "voiced share")


def descriptors(features) -> np.ndarray:
    voiced = features.f0.voiced
    semitones = 12 * np.log2(features.f0.values[voiced])
    energy = features.energy.values
    speech = voiced | (energy >= np.quantile(energy, 0.95) - 25)
    words = prosodic_words(features)
    nuclei = sum(len(word.nuclei) for word in words)
    return np.array([np.ptp(np.percentile(semitones, (10, 90))), np.ptp(np.percentile(energy[speech], (10, 90))),
                     nuclei / max(speech.sum() / features.fps, 1e-9), voiced.mean()])


def levels(motion_au: np.ndarray, fps: float) -> np.ndarray:
    degrees = motion_au / AU_PER_DEGREE
    speed = np.linalg.norm(np.diff(degrees, axis=0), axis=1) * fps
    return np.array([np.median(speed), degrees.std(axis=0).mean()])


def held_out(x: np.ndarray, y: np.ndarray, folds: list[list[int]]) -> np.ndarray:
    predicted = np.zeros_like(y)
    for fold in folds:
        train = np.array([i for i in range(len(y)) if i not in fold])
        mean, spread = x[train].mean(axis=0), x[train].std(axis=0) + 1e-9
        design = np.column_stack([np.ones(train.size), (x[train] - mean) / spread])
        coef = np.linalg.lstsq(design, y[train], rcond=None)[0]
        predicted[fold] = np.column_stack([np.ones(len(fold)), (x[fold] - mean) / spread]) @ coef
    return predicted


def main(argv: list[str]) -> int:
    warnings.simplefilter("ignore")
    pairs = find_pairs(talking_heads()) + (find_pairs(TRACKED) if TRACKED.is_dir() else [])
    data = load_training_set(pairs, speakers=speakers(), report=lambda message: None)
    folds = data.folds()
    x = np.array([descriptors(f) for f in data.features])
    y = np.log2(np.array([levels(m, data.fps) for m in data.motion_au]))
    print(f"{len(data.names)} clips, {len(folds)} speakers; leave one speaker out")
    print("descriptor ranges over the clips: " + "; ".join(
        f"{name} {lo:.2f}-{hi:.2f}" for name, lo, hi in zip(DESCRIPTORS, x.min(axis=0), x.max(axis=0), strict=True)))
    rng = np.random.default_rng(0)
    print()
    print("| level | recorded range | r, predicted with recorded (log) | chance: mean ± spread "
          "| mean abs. log2 error: predicted | constant (the other speakers' mean) |")
    print("|---|---|---|---|---|---|")
    for column, name in enumerate(("median angular speed, deg/s", "spread of the angles, deg")):
        target = y[:, column]
        predicted = held_out(x, target, folds)
        constant = held_out(np.zeros((len(target), 0)), target, folds)
        r = np.corrcoef(predicted, target)[0, 1]
        chance = []
        for _ in range(SHUFFLES):
            order = rng.permutation(len(folds))  # whole speakers' descriptors swapped
            shuffled = x.copy()
            for fold, other in zip(folds, [folds[i] for i in order], strict=True):
                shuffled[fold] = x[other].mean(axis=0)
            chance.append(np.corrcoef(held_out(shuffled, target, folds), target)[0, 1])
        print(f"| {name} | {2 ** target.min():.1f}-{2 ** target.max():.1f} | {r:+.3f} "
              f"| {np.mean(chance):+.3f} ± {np.std(chance):.3f} | {np.abs(predicted - target).mean():.2f} "
              f"| {np.abs(constant - target).mean():.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(record("animation_level", lambda: main(sys.argv[1:]), lambda: [talking_heads(), TRACKED]))
