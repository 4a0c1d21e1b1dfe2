"""The acoustic mouth model: mouth opening, rounding and spread from the sound's spectrum, in any language.

Spectral features (:mod:`audio_features.spectral`: 13 MFCCs and the log energy) are read at 13 offsets from
0.3 s before to 0.3 s after each frame, standardised over the recording (so the recording level and the
channel do not matter), and mapped by ridge regressions to the three mouth-shape tracks of
:mod:`prosody.motion.lips` (opening in MNS above the closed mouth, rounding, spread), which the same geometry
turns into lip FAPs. It is trained on recordings with a video-tracked ``<clip>.mouth.csv``
(``benchmarks/mouth_loco.py`` measures it on speakers left out).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from audio_features import Audio
from audio_features.spectral import N_SPECTRAL, cepstra, on_grid

from ..errors import ModelError
from .lips import MNS_PER_EYE_WIDTH, MouthShape
from .model_files import MAX_MODEL_MAGNITUDE, read_model_json, write_model_json

MODEL_FORMAT = "visual-prosody-mouth-model"
MODEL_VERSION = 1
#: Offsets at which the features are read, s.
CONTEXT_S = tuple(np.round(np.arange(-0.3, 0.301, 0.05), 3))
DEFAULT_MOUTH_MODEL_PATH = os.path.join(os.path.dirname(__file__), "models", "mouth_acoustic.json")


@dataclass(frozen=True, eq=False)
class MouthTrainingClip:
    """A recording's standardised context features and its tracked mouth targets (NaN: no face)."""

    name: str
    features: np.ndarray
    opening: np.ndarray
    rounding: np.ndarray
    spread: np.ndarray


def context_features(audio: Audio, n_frames: int, *, fps: float) -> np.ndarray:
    """Spectral features at :data:`CONTEXT_S` around each frame, standardised over the recording."""
    frames = cepstra(audio)
    spread = frames.std(axis=0)
    frames = (frames - frames.mean(axis=0)) / np.where(spread > 1e-9, spread, 1.0)
    return np.hstack([on_grid(frames, n_frames, fps=fps, offset_s=offset) for offset in CONTEXT_S])


def mouth_training_clip(audio: Audio, mouth, *, fps: float, name: str = "") -> MouthTrainingClip:
    """A training clip from audio and a :class:`~prosody.motion.ground_truth.RecordedMouth` on its grid."""
    opening = (mouth.lip_opening - np.nanquantile(mouth.lip_opening, 0.05)) / MNS_PER_EYE_WIDTH * 1024
    rounding = mouth.rounding - np.nanquantile(mouth.rounding, 0.05)
    spread = mouth.mouth_width / np.nanmedian(mouth.mouth_width) - 1
    return MouthTrainingClip(name or audio.source, context_features(audio, mouth.n_frames, fps=fps), opening,
                             rounding, spread)


class AcousticMouthModel:
    """Ridge regressions from spectral context to the mouth's shape.

    Parameters
    ----------
    ridge : float >= 0
        Penalty of the regressions (on standardised features).
    """

    def __init__(self, ridge: float = 100.0) -> None:
        self.ridge = ridge

    def fit(self, clips: list[MouthTrainingClip]) -> AcousticMouthModel:
        """Fit on training clips (frames without a tracked face are left out)."""
        features = np.vstack([clip.features for clip in clips])
        design = np.hstack([features, np.ones((features.shape[0], 1))])
        penalty = self.ridge * np.eye(design.shape[1])
        penalty[-1, -1] = 0.0
        weights = []
        for key in ("opening", "rounding", "spread"):
            target = np.concatenate([getattr(clip, key) for clip in clips])
            known = np.isfinite(target)
            rows = design[known]
            weights.append(np.linalg.solve(rows.T @ rows + penalty, rows.T @ target[known]))
        self.weights_ = np.column_stack(weights)
        self.training_ = [clip.name for clip in clips]
        return self

    def predict_features(self, features: np.ndarray) -> MouthShape:
        shape = np.hstack([features, np.ones((features.shape[0], 1))]) @ self.weights_
        return MouthShape(np.clip(shape[:, 0], 0.0, None), shape[:, 1], shape[:, 2])

    def predict_clip(self, clip: MouthTrainingClip) -> MouthShape:
        return self.predict_features(clip.features)

    def predict(self, audio: Audio, n_frames: int, *, fps: float) -> MouthShape:
        """The mouth's shape at every frame of a grid."""
        return self.predict_features(context_features(audio, n_frames, fps=fps))

    def save(self, path: str | os.PathLike[str]) -> None:
        write_model_json({"format": MODEL_FORMAT, "version": MODEL_VERSION, "kind": "mouth-acoustic",
                          "context_s": list(CONTEXT_S), "features": N_SPECTRAL, "ridge": self.ridge,
                          "outputs": ["opening_mns", "rounding", "spread"], "weights": self.weights_.tolist(),
                          "training": self.training_}, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str] = DEFAULT_MOUTH_MODEL_PATH) -> AcousticMouthModel:
        payload = read_model_json(path)
        name = str(path)
        if not isinstance(payload, dict) or payload.get("format") != MODEL_FORMAT:
            raise ModelError(f"{name}: not a mouth model file (format {MODEL_FORMAT!r})")
        if payload.get("version") != MODEL_VERSION:
            raise ModelError(f"{name}: mouth model version {payload.get('version')!r}; this release reads "
                             f"version {MODEL_VERSION}")
        try:
            weights = np.array(payload["weights"], dtype=float)
            ridge = float(payload["ridge"])
            training = [str(item) for item in payload["training"]]
        except (KeyError, TypeError, ValueError) as error:
            raise ModelError(f"{name}: missing or malformed field ({error!r})") from None
        shape = (len(CONTEXT_S) * N_SPECTRAL + 1, 3)
        if weights.shape != shape or list(payload.get("context_s", ())) != list(CONTEXT_S):
            raise ModelError(f"{name}: weights of shape {weights.shape!r} for other features; expected {shape!r}")
        if not np.all(np.isfinite(weights)) or np.any(np.abs(weights) > MAX_MODEL_MAGNITUDE):
            raise ModelError(f"{name}: weights must be finite numbers within {MAX_MODEL_MAGNITUDE:g}")
        model = cls(ridge)
        model.weights_, model.training_ = weights, training
        return model


def train_mouth(folder: str | os.PathLike[str], output: str | os.PathLike[str], *, fps: float = 30.0,
                report=None) -> AcousticMouthModel:
    """Fit the acoustic mouth model on every ``<name>.wav`` in ``folder`` with a ``<name>.mouth.csv`` beside it
    (columns as the talking-heads data define them, 30 fps) and write it to ``output``."""
    from pathlib import Path

    from audio_features import AUDIO_EXTENSIONS, load_audio

    from ..errors import ConfigError, GroundTruthError
    from .ground_truth import read_mouth_csv

    root = Path(folder)
    if not root.is_dir():
        raise ConfigError(f"{root}: not a folder")
    clips = []
    for audio_path in sorted(p for p in root.iterdir() if p.suffix.lower() in AUDIO_EXTENSIONS):
        mouth_path = audio_path.with_name(audio_path.stem + ".mouth.csv")
        if not mouth_path.is_file():
            continue
        try:
            mouth = read_mouth_csv(mouth_path)
        except GroundTruthError as error:
            if report:
                report(f"skipped {audio_path.stem}: {error}")
            continue
        clips.append(mouth_training_clip(load_audio(audio_path), mouth, fps=fps, name=audio_path.stem))
        if report:
            report(f"[{len(clips)}] {audio_path.stem}: {mouth.n_frames} frames")
    if not clips:
        raise ConfigError(f"{root}: no <name>.wav with a <name>.mouth.csv beside it")
    model = AcousticMouthModel().fit(clips)
    model.save(output)
    return model
