"""Jia et al.'s (2013) head gestures: one sinusoid per prosodic word and axis, its size set by emotion.

What the paper gives, as this port reads it:

- Eq. 1: over the ``T`` frames of a prosodic word (PW), each head axis follows
  ``y(t) = Amp / 2 * sin(2 pi / T * (t - t_peak) + pi / 2) + Avg``, peaking at ``t_peak``;
- the peak falls on the stressed syllable if the PW has one, else on a falling-tone syllable, else on the
  PW's first syllable;
- Eq. 2: ``Amp(P, A) = P (C1 A^2 + C2 A + C3) + (1 - P)(C4 A^2 + C5 A + C6)``, with pleasure P in {-1, 0, 1} and
  arousal A in {-0.5 (silence), 0, 0.5, 1}; the paper does not print C1-C6;
- Table 3: amplitude means (pitch 9.83 deg, yaw 3.41, roll 3.35) and the PWs' mean pose (pitch -5.09 +- 3.48
  deg, yaw -0.47 +- 1.86, roll 0.57 +- 1.88);
- a 0.2 s moving average at every boundary between PWs;
- Eq. 13: pleasure, arousal and dominance from a twelve-item questionnaire (items -4..4).

What this port adds, because the paper works from Mandarin text and this project from audio:

- PWs from the audio: stretches of speech between pauses of 0.15 s or more, cut into PWs of at most about
  1.2 s or four syllable nuclei (energy peaks of voiced frames, at least 0.1 s apart), and at F0 resets (a
  nucleus 3 semitones or more above the one before it);
- the stressed syllable is the PW's most prominent nucleus (z-scored F0 plus z-scored energy over the
  recording) if that prominence is above 1; the falling-tone syllable the nucleus followed by the steepest F0
  fall of at least 2 semitones over 0.1 s;
- A from the PW's highest prominence: below 0: 0, below 1: 0.5, else 1; pauses are A = -0.5;
- C1-C6 (:data:`DEFAULT_COEFFICIENTS`, replaceable by a file): ``Amp(0, 0.5)`` is Table 3's mean, ``Amp(P, 0)``
  half of it, ``Amp(P, 1)`` one and a half times it, ``Amp(P, -0.5)`` 0; pleasure changes nothing until
  coefficients fitted on emotional speech are given;
- fitting (:func:`fit_arousal`, ``prosody train --kind pad``): recordings with head motion but no emotion
  labels fix the arousal part only. Each PW and pause of at least :data:`FIT_MIN_FRAMES` frames gives its A and
  the recorded head's peak-to-peak per axis; C4-C6 are the least-squares fit of Eq. 2 at P = 0 to them, and
  C1-C3 are set equal (pleasure changes nothing);
- the mean pose ``Avg`` of each PW is drawn from Table 3's spread about this project's rest pose (0, since
  recordings have their median pose removed); yaw and roll, whose direction the audio cannot tell, turn to a
  side drawn per PW. Seeded: the same seed gives the same motion.

The random baseline of the paper (``randomized=True``): the same sinusoids with the amplitude drawn between 0
and twice Table 3's mean, the pose as above, and the peak anywhere in the PW.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from audio_features import Features

from ...errors import ConfigError
from ...fap.table import HEAD_FAPS
from ...fap.units import AU_PER_DEGREE
from ..model_files import JsonModel, TrainingClip, model_payload

#: Table 3 of Jia et al. (2013): amplitude means, in degrees, per axis (pitch, yaw, roll).
TABLE3_AMPLITUDE_DEG = (9.83, 3.41, 3.35)
#: Table 3: mean pose of a PW, mean and standard deviation in degrees, per axis.
TABLE3_AVERAGE_DEG = ((-5.09, 3.48), (-0.47, 1.86), (0.57, 1.88))
#: C1..C6 of Eq. 2 per axis (see the module: Amp(0, 0.5) = Table 3's mean; pleasure changes nothing).
DEFAULT_COEFFICIENTS = tuple((0.0, m, m / 2, 0.0, m, m / 2) for m in TABLE3_AMPLITUDE_DEG)
#: Boundary smoothing: a moving average of 0.2 s.
BOUNDARY_SMOOTHING_S = 0.2
#: PWs: pauses that separate stretches, longest PW, most nuclei, nucleus spacing, F0 reset.
PAUSE_S, MAX_WORD_S, MAX_NUCLEI, NUCLEUS_SPACING_S, RESET_SEMITONES = 0.15, 1.2, 4, 0.1, 3.0
#: Speech frames: voiced, or within this many dB of the recording's loud level (unvoiced consonants).
SPEECH_BELOW_LOUD_DB = 25.0
MODEL_FORMAT = "visual-prosody-pad"
#: PWs and pauses shorter than this are left out of a fit: a peak-to-peak over a few frames says little.
FIT_MIN_FRAMES = 12


def sinusoid(n_frames: int, *, peak: float, amplitude: float, average: float) -> np.ndarray:
    """Jia et al.'s Eq. 1 over the ``n_frames`` of a PW (frames 0..n-1), peaking at frame ``peak``.

    Examples
    --------
    >>> y = sinusoid(30, peak=8, amplitude=9.83, average=-5.09)
    >>> int(np.argmax(y)), int(np.argmin(y)), round(float(y.max() - y.min()), 2), round(float(y.mean()), 2)
    (8, 23, 9.83, -5.09)
    """
    t = np.arange(n_frames)
    return amplitude / 2 * np.sin(2 * np.pi / n_frames * (t - peak) + np.pi / 2) + average


def amplitude(pleasure: float, arousal: float, coefficients: Sequence[float]) -> float:
    """Jia et al.'s Eq. 2, clamped at 0.

    Examples
    --------
    >>> [amplitude(p, a, (1, 2, 3, 4, 5, 6)) for p, a in ((1, 0), (0, 0), (1, 1), (0, -0.5))]
    [3.0, 6.0, 6.0, 4.5]
    """
    c1, c2, c3, c4, c5, c6 = coefficients
    value = pleasure * (c1 * arousal**2 + c2 * arousal + c3) + (1 - pleasure) * (c4 * arousal**2 + c5 * arousal + c6)
    return max(0.0, float(value))


def peak_frame(nuclei: Sequence[int], *, stressed: int | None, falling: int | None) -> int:
    """The peak rule: the stressed nucleus if any, else the falling-tone one, else the first (frames).

    Examples
    --------
    >>> peak_frame([3, 9, 14], stressed=9, falling=14), peak_frame([3, 9, 14], stressed=None, falling=14)
    (9, 14)
    >>> peak_frame([3, 9, 14], stressed=None, falling=None)
    3
    """
    if stressed is not None:
        return stressed
    if falling is not None:
        return falling
    return nuclei[0]


def smooth_boundaries(curve: np.ndarray, boundaries: Sequence[int], *, window: int) -> np.ndarray:
    """A ``window``-frame moving average of ``curve`` within ``window`` frames of each boundary, the curve
    itself elsewhere: a constant stays constant and a step becomes a ramp of ``window - 1`` frames.

    Examples
    --------
    >>> smooth_boundaries(np.r_[np.zeros(10), np.ones(10)], [10], window=6).round(3).tolist()[6:15]
    [0.0, 0.0, 0.167, 0.333, 0.5, 0.667, 0.833, 1.0, 1.0]
    """
    if window <= 1 or not len(boundaries):
        return np.asarray(curve, float).copy()
    values = np.asarray(curve, float)
    padded = np.concatenate([np.full(window, values[0]), values, np.full(window, values[-1])])
    averaged = np.convolve(padded, np.ones(window) / window, mode="same")[window:window + values.size]
    out = values.copy()
    for boundary in boundaries:
        lo, hi = max(0, boundary - window), min(values.size, boundary + window)
        out[lo:hi] = averaged[lo:hi]
    return out


def pad_from_questionnaire(answers: Sequence[float]) -> tuple[float, float, float]:
    """Jia et al.'s Eq. 13: pleasure, arousal and dominance (each -1..1) from twelve answers -4..4; items 1, 4, 7,
    10 ask for pleasure, 2, 5, 8, 11 arousal, 3, 6, 9, 12 dominance, the second and fourth of each reversed.

    Examples
    --------
    >>> pad_from_questionnaire((4, 0, 0, -4, 0, 0, 4, 0, 0, -4, 0, 0))
    (1.0, 0.0, 0.0)
    """
    q = [float(v) for v in answers]
    if len(q) != 12 or not all(-4 <= v <= 4 for v in q):
        raise ConfigError(f"the questionnaire has twelve answers from -4 to 4, got {answers!r}")
    return tuple((q[i] - q[i + 3] + q[i + 6] - q[i + 9]) / 16 for i in range(3))  # type: ignore[return-value]


@dataclass(frozen=True)
class ProsodicWord:
    """A PW: frames ``[start, end)``, its syllable nuclei (frames), peak frame and arousal A."""

    start: int
    end: int
    nuclei: tuple[int, ...]
    peak: int
    arousal: float


def _z(values: np.ndarray) -> np.ndarray:
    spread = values.std()
    return (values - values.mean()) / spread if spread > 1e-9 else np.zeros_like(values)


def _speech_runs(speech: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """(start, end) of the runs of speech frames, pauses shorter than ``gap`` frames bridged."""
    n = len(speech)
    runs, k = [], 0
    while k < n:
        if not speech[k]:
            k += 1
            continue
        start = k
        while k < n and (speech[k] or (k + gap < n and speech[k:k + gap].any())):
            k += 1
        runs.append((start, k))
    return runs


def _nuclei(smooth: np.ndarray, voiced: np.ndarray, spacing: int) -> list[int]:
    """Voiced loudness peaks at least ``spacing`` frames apart (the louder of two close peaks stays), in order."""
    n = len(smooth)
    peaks = [k for k in range(1, n - 1) if voiced[k] and smooth[k] >= smooth[k - 1] and smooth[k] > smooth[k + 1]]
    kept: list[int] = []
    for k in sorted(peaks, key=lambda j: -smooth[j]):
        if all(abs(k - j) >= spacing for j in kept):
            kept.append(k)
    return sorted(kept)


def _nucleus_groups(inside: list[int], semitones: np.ndarray, longest: int) -> list[list[int]]:
    """The nuclei of one run of speech split into PWs: at an F0 reset, after MAX_NUCLEI, or past ``longest``."""
    groups: list[list[int]] = [[inside[0]]]
    for k in inside[1:]:
        group = groups[-1]
        reset = semitones[k] - semitones[group[-1]] >= RESET_SEMITONES
        if len(group) >= MAX_NUCLEI or k - group[0] >= longest or reset:
            groups.append([k])
        else:
            group.append(k)
    return groups


def _word(group: list[int], lo: int, hi: int, prominence: dict[int, float], semitones: np.ndarray,
          fall_frames: int) -> ProsodicWord:
    """One PW over frames lo..hi: its stressed nucleus, its steepest F0 fall, its arousal and its peak."""
    best = max(group, key=lambda j: prominence[j])
    stressed = best if prominence[best] > 1.0 else None
    falls = {j: semitones[j] - np.nanmin(semitones[j:min(hi, j + fall_frames + 1)]) for j in group}
    steepest = max(falls, key=lambda j: falls[j])
    falling = steepest if falls[steepest] >= 2.0 else None
    top = max(prominence[j] for j in group)
    arousal = 0.0 if top < 0 else (0.5 if top < 1 else 1.0)
    return ProsodicWord(lo, hi, tuple(group), peak_frame(group, stressed=stressed, falling=falling), arousal)


def prosodic_words(features: Features) -> list[ProsodicWord]:
    """The PWs of a recording (see the module: pauses, nuclei, F0 resets, stress and arousal)."""
    fps, n = features.fps, features.n_frames
    voiced = features.f0.voiced
    energy = features.energy.values
    if n == 0 or not voiced.any():
        return []
    loud = float(np.quantile(energy, 0.95))
    runs = _speech_runs(voiced | (energy >= loud - SPEECH_BELOW_LOUD_DB), max(1, int(round(PAUSE_S * fps))))
    smooth = np.convolve(energy, np.ones(3) / 3, mode="same")
    semitones = np.where(voiced, 12 * np.log2(np.where(voiced, features.f0.values, 1.0)), np.nan)
    nuclei_all = _nuclei(smooth, voiced, max(1, int(round(NUCLEUS_SPACING_S * fps))))
    if not nuclei_all:
        return []
    prominence = dict(zip(nuclei_all, _z(np.array([semitones[k] for k in nuclei_all]))
                          + _z(np.array([smooth[k] for k in nuclei_all])), strict=True))
    words: list[ProsodicWord] = []
    longest = int(round(MAX_WORD_S * fps))
    fall_frames = max(1, int(round(0.1 * fps)))
    for start, end in runs:
        inside = [k for k in nuclei_all if start <= k < end]
        if not inside:
            continue
        groups = _nucleus_groups(inside, semitones, longest)
        edges = [start] + [(a[-1] + b[0]) // 2 for a, b in zip(groups, groups[1:], strict=False)] + [end]
        words += [_word(group, lo, hi, prominence, semitones, fall_frames)
                  for group, lo, hi in zip(groups, edges, edges[1:], strict=False)]
    return words


def stretches(features: Features) -> list[tuple[int, int, ProsodicWord | None]]:
    """(first frame, end frame, PW) of every PW and of every pause between them (PW None), covering the
    recording in order."""
    pieces: list[tuple[int, int, ProsodicWord | None]] = []
    cursor = 0
    for word in prosodic_words(features):
        if word.start > cursor:
            pieces.append((cursor, word.start, None))
        pieces.append((word.start, word.end, word))
        cursor = word.end
    if cursor < features.n_frames:
        pieces.append((cursor, features.n_frames, None))
    return pieces


def arousal_amplitudes(features: Features, motion_au: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A of every PW and pause of at least :data:`FIT_MIN_FRAMES` frames (pauses -0.5), and the recorded head's
    peak-to-peak over it per axis (pitch, yaw, roll; degrees): what :func:`fit_arousal` fits."""
    degrees = np.asarray(motion_au, dtype=float) / AU_PER_DEGREE
    chosen = [(lo, hi, -0.5 if word is None else word.arousal) for lo, hi, word in stretches(features)
              if hi - lo >= FIT_MIN_FRAMES]
    arousal = np.array([a for _, _, a in chosen], dtype=float)
    sizes = np.array([np.ptp(degrees[lo:hi], axis=0) for lo, hi, _ in chosen]).reshape(-1, 3)
    return arousal, sizes


def _arousal_design(arousal: np.ndarray) -> np.ndarray:
    return np.column_stack([arousal ** 2, arousal, np.ones_like(arousal)])


def fit_arousal(arousal: np.ndarray, amplitudes: np.ndarray) -> tuple[tuple[float, ...], ...]:
    """C1..C6 per axis from stretches' A and recorded amplitudes (degrees): C4-C6 fitted by least squares to
    Eq. 2 at P = 0, C1-C3 the same (recordings without emotion labels cannot tell pleasure's part).

    Examples
    --------
    >>> a = np.array([-0.5, 0.0, 0.5, 1.0, 1.0])
    >>> sizes = np.column_stack([2 * a ** 2 + 3 * a + 4] * 3)
    >>> [round(c, 6) for c in fit_arousal(a, sizes)[0]]
    [2.0, 3.0, 4.0, 2.0, 3.0, 4.0]
    """
    arousal = np.asarray(arousal, dtype=float)
    if len(set(arousal.tolist())) < 3:
        raise ConfigError(f"fitting C4-C6 needs stretches of at least three arousal levels; found "
                          f"{sorted(set(arousal.tolist()))}")
    solution = np.linalg.lstsq(_arousal_design(arousal), np.asarray(amplitudes, dtype=float), rcond=None)[0]
    return tuple(tuple(float(c) for c in (*solution[:, axis], *solution[:, axis])) for axis in range(3))


def held_out_arousal(per_recording: Sequence[tuple[np.ndarray, np.ndarray]], folds: Sequence[Sequence[int]], *,
                     shuffles: int = 200, seed: int = 0) -> dict:
    """Eq. 2's arousal part held out by speaker: for each fold, C4-C6 fitted on the other folds' stretches
    predict this fold's amplitudes from their A.

    Returns, per axis (pitch, yaw, roll): ``r`` of the predictions with the recorded amplitudes over every
    held-out stretch, the chance level of that r (``chance_r`` mean and ``chance_spread``: each fold's A
    shuffled among its own stretches, ``shuffles`` times), and the mean absolute errors (degrees) of the fitted
    coefficients (``mae_fitted``), of :data:`DEFAULT_COEFFICIENTS` (``mae_default``) and of one constant for
    speech and one for pauses fitted the same way (``mae_constant``, which ignores A); ``stretches`` counts them.
    """
    held: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # A, amplitudes, the fold's C4-C6 (3 x 3)
    errors: dict[str, list[np.ndarray]] = {key: [] for key in ("fitted", "default", "constant")}
    for fold in folds:
        train = [per_recording[i] for i in range(len(per_recording)) if i not in fold]
        a_test = np.concatenate([per_recording[i][0] for i in fold])
        if a_test.size == 0 or not train:
            continue
        y_test = np.vstack([per_recording[i][1] for i in fold])
        a_train = np.concatenate([a for a, _ in train])
        y_train = np.vstack([y for _, y in train])
        coef = np.array(fit_arousal(a_train, y_train))[:, 3:].T  # rows C4, C5, C6; a column per axis
        predicted = np.maximum(_arousal_design(a_test) @ coef, 0.0)
        default = np.array([[amplitude(0.0, a, DEFAULT_COEFFICIENTS[axis]) for axis in range(3)] for a in a_test])
        speech = a_train >= 0
        constant = np.where((a_test >= 0)[:, None], y_train[speech].mean(axis=0), y_train[~speech].mean(axis=0))
        errors["fitted"].append(np.abs(predicted - y_test))
        errors["default"].append(np.abs(default - y_test))
        errors["constant"].append(np.abs(constant - y_test))
        held.append((a_test, y_test, coef))
    if not held:
        raise ConfigError("no fold has stretches to hold out")
    recorded = np.vstack([y for _, y, _ in held])

    def pooled_r(arousals: list[np.ndarray]) -> np.ndarray:
        predicted = np.vstack([np.maximum(_arousal_design(a) @ c, 0.0)
                               for a, (_, _, c) in zip(arousals, held, strict=True)])
        return np.array([np.corrcoef(predicted[:, axis], recorded[:, axis])[0, 1] for axis in range(3)])

    rng = np.random.default_rng(seed)
    observed = pooled_r([a for a, _, _ in held])
    chance = np.array([pooled_r([rng.permutation(a) for a, _, _ in held]) for _ in range(shuffles)])
    mae = {key: np.vstack(value).mean(axis=0) for key, value in errors.items()}
    return {"stretches": int(recorded.shape[0]), "folds": len(held), **{
        name: {"r": float(observed[axis]), "chance_r": float(chance[:, axis].mean()),
               "chance_spread": float(chance[:, axis].std()),
               **{f"mae_{key}": float(value[axis]) for key, value in mae.items()}}
        for axis, name in enumerate(("pitch", "yaw", "roll"))}}


class PadHeadModel(JsonModel):
    """Jia et al.'s head gestures as a head model (``--model pad``; ``pad-random`` for its random baseline).

    Parameters
    ----------
    pleasure : float in [-1, 1]
        P of Eq. 2 for the whole recording.
    coefficients : sequence of three (C1..C6), optional
        Eq. 2's coefficients for pitch, yaw and roll (default :data:`DEFAULT_COEFFICIENTS`).
    randomized : bool
        The paper's random baseline: amplitude, pose and peak drawn at random.
    states : sequence of PadSegment
        A PAD state over time (:mod:`prosody.motion.face.pad`): where one covers a PW's peak, its P replaces
        ``pleasure`` and its A shifts the PW's arousal by ``A / 2`` (within 0..1; pauses stay at -0.5).
    """

    kind = "pad"
    fps_ = 30.0  # any rate works: the PWs are found on the features' own grid
    #: The motion depends on the seed (each PW's mean pose and side are drawn).
    stochastic: ClassVar[bool] = True

    def __init__(self, pleasure: float = 0.0, coefficients: Sequence[Sequence[float]] | None = None,
                 randomized: bool = False, states: Sequence = ()) -> None:
        self.pleasure = pleasure
        self.coefficients = coefficients
        self.randomized = randomized
        self.states = tuple(states)
        self.training_: list = []
        if not (isinstance(pleasure, (int, float)) and -1 <= pleasure <= 1):
            raise ConfigError(f"pleasure must be a number in [-1, 1], got {pleasure!r}")
        chosen = DEFAULT_COEFFICIENTS if coefficients is None else coefficients
        if len(chosen) != 3 or any(len(axis) != 6 or not all(math.isfinite(c) for c in axis) for axis in chosen):
            raise ConfigError("coefficients must be three rows (pitch, yaw, roll) of six finite numbers C1..C6")
        self.coefficients_ = tuple(tuple(float(c) for c in axis) for axis in chosen)

    def rest_pose_au(self) -> np.ndarray:
        """The pose the gestures are about: the rest pose itself, AU (3,) of zeros."""
        return np.zeros(len(HEAD_FAPS))

    def generate(self, features: Features, *, seed: int = 0) -> dict[int, np.ndarray]:
        """Head pitch, yaw and roll (FAP 48-50, AU) of a recording."""
        rng = np.random.default_rng(seed)
        fps, n = features.fps, features.n_frames
        curves = np.zeros((3, n))
        boundaries: list[int] = []
        for lo, hi, word in stretches(features):
            length = hi - lo
            if length <= 0:
                continue
            boundaries.append(lo)
            arousal = -0.5 if word is None else word.arousal
            peak = (length // 2 if word is None else word.peak - lo)
            pleasure = self.pleasure
            if self.states and word is not None:
                from ..face.pad import pad_at

                pleasure, shift, _ = pad_at(self.states, word.peak / fps)
                arousal = min(1.0, max(0.0, arousal + shift / 2))
            if self.randomized and word is not None:
                peak = int(rng.integers(0, length))
            for axis in range(3):
                size = amplitude(pleasure, arousal, self.coefficients_[axis])
                if self.randomized and word is not None:
                    size = float(rng.uniform(0, 2 * TABLE3_AMPLITUDE_DEG[axis]))
                mean, spread = TABLE3_AVERAGE_DEG[axis]
                average = float(rng.normal(0.0, spread)) if word is not None else 0.0
                side = 1.0 if axis == 0 else float(rng.choice((-1.0, 1.0)))
                curves[axis, lo:hi] = side * sinusoid(length, peak=peak, amplitude=size, average=0.0) + average
        window = max(1, int(round(BOUNDARY_SMOOTHING_S * fps)))
        return {fap: smooth_boundaries(curves[axis], boundaries[1:], window=window) * AU_PER_DEGREE
                for axis, fap in enumerate(HEAD_FAPS)}

    def with_states(self, states: Sequence) -> PadHeadModel:
        """The same model driven by a PAD state over time (see ``states``)."""
        model = PadHeadModel(self.pleasure, self.coefficients_, self.randomized, states)
        model.training_ = self.training_
        return model

    def to_dict(self) -> dict:
        """The model's data (``--model FILE`` reads its file), with the clips it was fitted on."""
        return {"format": MODEL_FORMAT, "version": 1, "kind": self.kind, "pleasure": self.pleasure,
                "randomized": self.randomized, "coefficients": [list(axis) for axis in self.coefficients_],
                **({"training": [clip.__dict__ for clip in self.training_]} if self.training_ else {})}

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> PadHeadModel:
        from ...errors import ModelError

        payload = model_payload(payload, format_name=MODEL_FORMAT, source=source, version=1)
        try:
            model = cls(float(payload.get("pleasure", 0.0)), payload.get("coefficients"),
                        bool(payload.get("randomized", False)))
            model.training_ = [TrainingClip.from_dict(c) for c in payload.get("training", [])]
            return model
        except (ValueError, TypeError, KeyError, OverflowError, ConfigError) as error:
            raise ModelError(f"{source}: not a PAD head model ({error})") from None
