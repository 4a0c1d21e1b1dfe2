"""The acoustic mouth model: mouth opening, rounding and spread from the sound's spectrum, in any language.

Spectral features (:mod:`audio_features.spectral`: 13 MFCCs and the log energy) are read at 13 offsets from
0.3 s before to 0.3 s after each frame, standardised over the recording (so the recording level and the
channel do not matter), and mapped by ridge regressions to the three mouth-shape tracks of
:mod:`prosody.motion.face.lips` (opening in MNS above the closed mouth, rounding, spread), which the same geometry
turns into lip FAPs. It is trained on recordings with a video-tracked ``<clip>.mouth.csv``
(``experiments/mouth_loco.py`` measures it on speakers left out).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from audio_features import Audio
from audio_features.spectral import N_SPECTRAL, cepstra, on_grid

from ...errors import ModelError
from ...fap.table import DISTANCE_UNITS_PER_REFERENCE
from ..model_files import MAX_MODEL_MAGNITUDE, MODELS_DIR, JsonModel, model_array, model_payload
from .lips import MNS_PER_EYE_WIDTH, MouthShape

MODEL_FORMAT = "visual-prosody-mouth-model"
MODEL_VERSION = 1
#: The mouth closes where the sound is this far below the recording's loud level (its 95th percentile of
#: 10 ms frame powers), opening fully 10 dB above it: the regression alone never closes it in a pause.
QUIET_BELOW_LOUD_DB = 35.0
GATE_RAMP_DB = 10.0
#: The mouth also closes in a dip: where the sound falls this far below its own peak within
#: :data:`DIP_WINDOW_FRAMES` 10 ms frames either side (a stop's closure, /p/ of "sharply" 40 dB down), fully
#: open while the dip is :data:`DIP_RAMP_DB` less: the regression averages over 0.6 s and never closes it there.
DIP_CLOSED_DB = 25.0
DIP_RAMP_DB = 10.0
DIP_WINDOW_FRAMES = 10
#: The voice gate and the dip gate are averaged over this many 10 ms frames either side of a grid frame.
VOICE_HALF_FRAMES = 5
DIP_HALF_FRAMES = 2
#: Offsets at which the features are read, s.
CONTEXT_S = tuple(np.round(np.arange(-0.3, 0.301, 0.05), 3))
#: The shipped acoustic mouth model: trained on the talking-heads clips and the tracked talking videos (37 speakers;
#: held out by speaker it reads 0.31 where the one trained on the talking-heads clips alone reads 0.26).
DEFAULT_MOUTH_MODEL_PATH = str(MODELS_DIR / "mouth_acoustic_videos.json")
#: The acoustic mouth model trained on the talking-heads clips alone (reproducible from the shared data alone).
HEADS_MOUTH_MODEL_PATH = str(MODELS_DIR / "mouth_acoustic.json")


@dataclass(frozen=True, eq=False)
class MouthTrainingClip:
    """A recording's standardised context features and its tracked mouth targets (NaN: no face)."""

    name: str
    features: np.ndarray
    opening: np.ndarray
    rounding: np.ndarray
    spread: np.ndarray


def frame_db(frames: np.ndarray) -> np.ndarray:
    """The 10 ms frames' power in dB (on the spectral analysis's own scale) from their log-energy column."""
    return frames[:, -1] * (10 / np.log(10))


def voice_gate(db: np.ndarray, loud_db: float | np.ndarray) -> np.ndarray:
    """0 where a frame is :data:`QUIET_BELOW_LOUD_DB` below the loud level, 1 from 10 dB above that."""
    return np.clip(_gate_ramp(db, loud_db), 0.0, 1.0)


def _gate_ramp(db, loud_db):
    """The voice gate before it is held to 0..1 (arrays or plain floats, the same arithmetic)."""
    return (db - (loud_db - QUIET_BELOW_LOUD_DB)) / GATE_RAMP_DB


def dip_gate(db: np.ndarray, peak_db: np.ndarray) -> np.ndarray:
    """0 where a frame is :data:`DIP_CLOSED_DB` below the local peak ``peak_db``, 1 from :data:`DIP_RAMP_DB`
    nearer to it."""
    return np.clip((DIP_CLOSED_DB - (peak_db - db)) / DIP_RAMP_DB, 0.0, 1.0)


def local_peak(db: np.ndarray) -> np.ndarray:
    """Each 10 ms frame's highest power within :data:`DIP_WINDOW_FRAMES` either side."""
    from numpy.lib.stride_tricks import sliding_window_view

    if not db.size:
        return db
    padded = np.pad(db, DIP_WINDOW_FRAMES, mode="edge")
    return sliding_window_view(padded, 2 * DIP_WINDOW_FRAMES + 1).max(axis=1)


def gated(shape: MouthShape, gate: np.ndarray, closing: np.ndarray | float = 1.0) -> MouthShape:
    """A mouth shape brought to rest (closed, neither rounded nor spread) where ``gate`` is 0, and its opening
    also closed where ``closing`` (the dip gate) is 0."""
    return MouthShape(shape.opening * gate * closing, shape.rounding * gate, shape.spread * gate)


def context_features(frames: np.ndarray, n_frames: int, *, fps: float) -> np.ndarray:
    """A recording's cepstra (:func:`audio_features.spectral.cepstra`) at :data:`CONTEXT_S` around each grid
    frame, standardised over the recording."""
    spread = frames.std(axis=0)
    frames = (frames - frames.mean(axis=0)) / np.where(spread > 1e-9, spread, 1.0)
    return np.hstack([on_grid(frames, n_frames, fps=fps, offset_s=offset) for offset in CONTEXT_S])


def mouth_training_clip(audio: Audio, mouth, *, fps: float, name: str = "") -> MouthTrainingClip:
    """A training clip from audio and a :class:`~prosody.fap.recorded.RecordedMouth` on its grid."""
    opening = (mouth.lip_opening - np.nanquantile(mouth.lip_opening, 0.05)) / MNS_PER_EYE_WIDTH \
        * DISTANCE_UNITS_PER_REFERENCE
    rounding = mouth.rounding - np.nanquantile(mouth.rounding, 0.05)
    spread = mouth.mouth_width / np.nanmedian(mouth.mouth_width) - 1
    return MouthTrainingClip(name or audio.source, context_features(cepstra(audio), mouth.n_frames, fps=fps),
                             opening, rounding, spread)


class AcousticMouthModel(JsonModel):
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

    def predict(self, audio: Audio | str | os.PathLike[str], n_frames: int, *, fps: float) -> MouthShape:
        """The mouth's shape at every frame of a grid, closed where there is no sound (see :func:`voice_gate`);
        ``audio`` in memory or a file (read block by block)."""
        from audio_features.spectral import file_cepstra

        frames = file_cepstra(audio)
        features = context_features(frames, n_frames, fps=fps)
        db = frame_db(frames)
        gates = np.column_stack([voice_gate(db, float(np.quantile(db, 0.95))), dip_gate(db, local_peak(db))])
        # the gates at each grid frame: their 10 ms frames over +-50 ms (voice) and +-20 ms (dips), averaged
        smooth = np.column_stack([np.convolve(gate, np.ones(2 * half + 1) / (2 * half + 1), mode="same")
                                  for gate, half in zip(gates.T, (VOICE_HALF_FRAMES, DIP_HALF_FRAMES), strict=True)])
        voice, dip = on_grid(smooth, n_frames, fps=fps).T
        return gated(self.predict_features(features), voice, dip)

    def to_dict(self) -> dict:
        """The model's data as plain JSON values."""
        return {"format": MODEL_FORMAT, "version": MODEL_VERSION, "kind": "mouth-acoustic",
                "context_s": list(CONTEXT_S), "features": N_SPECTRAL, "ridge": self.ridge,
                "outputs": ["opening_mns", "rounding", "spread"], "weights": self.weights_.tolist(),
                "training": self.training_}

    @classmethod
    def load(cls, path: str | os.PathLike[str] = DEFAULT_MOUTH_MODEL_PATH) -> AcousticMouthModel:
        """The model of a file (default: the shipped one)."""
        return super().load(path)

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> AcousticMouthModel:
        """The model from :meth:`to_dict`'s data; :class:`ModelError` naming ``source`` if it is not one."""
        name = source
        payload = model_payload(payload, format_name=MODEL_FORMAT, source=name, version=MODEL_VERSION)
        try:
            weights = np.array(payload["weights"], dtype=float)
            ridge = float(payload["ridge"])
            training = [str(item) for item in payload["training"]]
        except (KeyError, TypeError, ValueError) as error:
            raise ModelError(f"{name}: missing or malformed field ({error!r})") from None
        shape = (len(CONTEXT_S) * N_SPECTRAL + 1, 3)
        context = payload.get("context_s")
        if not isinstance(context, list) or context != [float(x) for x in CONTEXT_S]:
            raise ModelError(f"{name}: field 'context_s' must list this release's offsets ({CONTEXT_S[0]:g} to "
                             f"{CONTEXT_S[-1]:g} s in steps of 0.05 s), got {str(context)[:60]}")
        if weights.shape != shape:
            raise ModelError(f"{name}: weights of shape {weights.shape!r} for other features; expected {shape!r}")
        if not np.all(np.isfinite(weights)) or np.any(np.abs(weights) > MAX_MODEL_MAGNITUDE):
            raise ModelError(f"{name}: weights must be finite numbers within {MAX_MODEL_MAGNITUDE:g}")
        model = cls(ridge)
        model.weights_, model.training_ = weights, training
        return model


def train_mouth(folders: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], output: str | os.PathLike[str], *,
                fps: float = 30.0, report=None) -> AcousticMouthModel:
    """Fit the acoustic mouth model and write it to ``output``.

    Parameters
    ----------
    folders : path or sequence of paths
        Folders of recordings: every ``<name>.wav`` with a ``<name>.mouth.csv`` beside it (columns as the
        talking-heads data define them, 30 fps; ``prosody track`` writes them) is a training clip.
    output : path
        The model file (JSON).
    fps : float
        The frame rate of the mouth files.
    report : callable, optional
        Called with a line per clip read or skipped.

    Returns
    -------
    AcousticMouthModel
    """
    from pathlib import Path

    from audio_features import AUDIO_EXTENSIONS, load_audio

    from ...errors import ConfigError, GroundTruthError
    from ...fap.recorded import read_mouth_csv

    roots = [Path(folders)] if isinstance(folders, (str, os.PathLike)) else [Path(f) for f in folders]
    clips = []
    for root in roots:
        if not root.is_dir():
            raise ConfigError(f"{root}: not a folder")
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
        raise ConfigError(f"{', '.join(map(str, roots))}: no <name>.wav with a <name>.mouth.csv beside it")
    model = AcousticMouthModel().fit(clips)
    model.save(output)
    return model


# the live form -----------------------------------------------------------------------------------------------
LIVE_MODEL_FORMAT = "visual-prosody-live-mouth-model"
#: Look-aheads of the shipped live mouth models, ms.
SHIPPED_LIVE_MOUTH_MS = (0, 100)
#: Half-life of the running feature statistics of the live model, in 10 ms frames (30 s).
RUNNING_HALF_LIFE_FRAMES = 3000
#: Weight of the training data's feature statistics at the start of a stream, in 10 ms frames (0.5 s).
PRIOR_FRAMES = 50
#: The live loud level is that of the last minute of 10 ms frames.
LOUD_WINDOW_FRAMES = 6000
LOUD_EVERY_FRAMES = 10


def live_mouth_path(lookahead_ms: int) -> str:
    return str(MODELS_DIR / f"live_mouth_{lookahead_ms}ms.json")


class RunningStandardizer:
    """Features standardised by their mean and spread so far (exponential forgetting), starting from a prior:
    the causal counterpart of standardising over the whole recording."""

    def __init__(self, prior_mean: np.ndarray, prior_var: np.ndarray) -> None:
        self.mean = np.array(prior_mean, float)
        self.var = np.array(prior_var, float)
        self.count = float(PRIOR_FRAMES)
        self.floor = 1.0 - 0.5 ** (1.0 / RUNNING_HALF_LIFE_FRAMES)

    def push(self, frames: np.ndarray) -> np.ndarray:
        out = np.empty_like(frames)
        for i, frame in enumerate(frames):
            self.count += 1.0
            rate = max(1.0 / self.count, self.floor)
            delta = frame - self.mean
            self.mean = self.mean + rate * delta
            self.var = (1 - rate) * (self.var + rate * delta * delta)
            out[i] = (frame - self.mean) / np.sqrt(np.maximum(self.var, 1e-6))
        return out


def _live_offsets(lookahead_s: float) -> tuple[float, ...]:
    return tuple(float(x) for x in np.round(np.arange(-0.3, lookahead_s + 1e-9, 0.05), 3))


class LiveMouthModel(JsonModel):
    """The acoustic mouth model in causal form, for ``prosody stream``: spectral features standardised by
    their running statistics and read from 0.3 s before each frame to ``lookahead_s`` after it.

    Parameters
    ----------
    lookahead_s : float in [0, 0.5], in s
    ridge : float >= 0
    """

    def __init__(self, lookahead_s: float = 0.1, ridge: float = 100.0) -> None:
        self.lookahead_s = lookahead_s
        self.ridge = ridge

    @property
    def offsets_s(self) -> tuple[float, ...]:
        return _live_offsets(self.lookahead_s)

    def features(self, standardized: np.ndarray, n_frames: int, *, fps: float) -> np.ndarray:
        return np.hstack([on_grid(standardized, n_frames, fps=fps, offset_s=o) for o in self.offsets_s])

    def fit(self, clips: list[tuple[np.ndarray, MouthTrainingClip]]) -> LiveMouthModel:
        """Fit on (cepstra of the recording, its training clip) pairs; the cepstra are standardised causally
        here, starting from the pooled statistics of all of them."""
        pooled = np.vstack([frames for frames, _ in clips])
        self.prior_mean_, self.prior_var_ = pooled.mean(axis=0), pooled.var(axis=0)
        self.prior_loud_db_ = float(np.median([np.quantile(frame_db(frames), 0.95) for frames, _ in clips]))
        designs = []
        for frames, clip in clips:
            standardized = RunningStandardizer(self.prior_mean_, self.prior_var_).push(frames)
            designs.append(MouthTrainingClip(clip.name, self.features(standardized, clip.opening.size, fps=30.0),
                                             clip.opening, clip.rounding, clip.spread))
        inner = AcousticMouthModel(self.ridge).fit(designs)
        self.weights_, self.training_ = inner.weights_, inner.training_
        return self

    def start(self, sample_rate_hz: int, *, fps: float) -> LiveMouth:
        return LiveMouth(self, sample_rate_hz, fps=fps)

    def to_dict(self) -> dict:
        """The model's data as plain JSON values."""
        return {"format": LIVE_MODEL_FORMAT, "version": MODEL_VERSION, "kind": "mouth-live",
                "lookahead_s": self.lookahead_s, "offsets_s": list(self.offsets_s), "ridge": self.ridge,
                "prior_mean": self.prior_mean_.tolist(), "prior_var": self.prior_var_.tolist(),
                "prior_loud_db": self.prior_loud_db_, "weights": self.weights_.tolist(), "training": self.training_}

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> LiveMouthModel:
        """The model from :meth:`to_dict`'s data; :class:`ModelError` naming ``source`` if it is not one."""
        name = source
        payload = model_payload(payload, format_name=LIVE_MODEL_FORMAT, source=name)
        try:
            model = cls(float(payload["lookahead_s"]), float(payload["ridge"]))
            model.weights_ = np.array(payload["weights"], dtype=float)
            model.prior_mean_ = np.array(payload["prior_mean"], dtype=float)
            model.prior_var_ = np.array(payload["prior_var"], dtype=float)
            model.prior_loud_db_ = float(payload["prior_loud_db"])
            model.training_ = [str(item) for item in payload["training"]]
        except (KeyError, TypeError, ValueError) as error:
            raise ModelError(f"{name}: missing or malformed field ({error!r})") from None
        if not 0 <= model.lookahead_s <= 0.5:
            raise ModelError(f"{name}: lookahead_s must be in [0, 0.5], got {model.lookahead_s!r}")
        shapes = {"weights": (len(model.offsets_s) * N_SPECTRAL + 1, 3), "prior_mean": (N_SPECTRAL,),
                  "prior_var": (N_SPECTRAL,)}
        for key, shape in shapes.items():
            model_array({key: getattr(model, key + "_")}, key, shape, lambda problem: ModelError(f"{name}: {problem}"))
        if not abs(model.prior_loud_db_) <= 1000:
            raise ModelError(f"{name}: field 'prior_loud_db' must be a number of dB, got {model.prior_loud_db_!r}")
        if np.any(model.prior_var_ <= 0):
            raise ModelError(f"{name}: field 'prior_var' must be positive")
        return model


class LiveMouth:
    """A live mouth model running on a stream: push audio, then ask for any frame whose look-ahead is in."""

    def __init__(self, model: LiveMouthModel, sample_rate_hz: int, *, fps: float) -> None:
        from audio_features.spectral import CepstraStream

        self.model, self.fps = model, fps
        self._offsets_s = np.array(model.offsets_s)
        self._cepstra = CepstraStream(sample_rate_hz)
        self._standardizer = RunningStandardizer(model.prior_mean_, model.prior_var_)
        self._frames = np.zeros((0, N_SPECTRAL))
        self._gates = np.zeros(0)
        self._db = np.zeros(0)
        self._first = 0  # absolute index of self._frames[0]
        # the last minute's levels, oldest overwritten (the quantile does not depend on their order)
        self._recent_db = np.empty(LOUD_WINDOW_FRAMES)
        self._loud: float | None = None
        self._heard = 0  # 10 ms frames heard

    def _add(self, frames: np.ndarray) -> None:
        if not frames.size:
            return
        gates = []
        levels = frame_db(frames)
        for db in levels.tolist():
            # the loud level of the last minute (its 95th percentile), as the whole recording's offline, taken
            # anew every LOUD_EVERY_FRAMES frames (0.1 s: a minute's level moves little in that time)
            self._recent_db[self._heard % LOUD_WINDOW_FRAMES] = db
            self._heard += 1
            if self._loud is None or self._heard % LOUD_EVERY_FRAMES == 0:
                # at the start of a stream the training recordings' loud level stands in for one not yet heard
                self._loud = max(float(np.quantile(self._recent_db[:min(self._heard, LOUD_WINDOW_FRAMES)], 0.95)),
                                 self.model.prior_loud_db_)
            # voice_gate of one value, in plain floats (without an array a frame)
            gates.append(min(max(_gate_ramp(db, self._loud), 0.0), 1.0))
        self._frames = np.vstack([self._frames, self._standardizer.push(frames)])
        self._gates = np.concatenate([self._gates, gates])
        self._db = np.concatenate([self._db, levels])

    def push(self, samples: np.ndarray) -> None:
        self._add(self._cepstra.push(samples))

    def finish(self) -> None:
        self._add(self._cepstra.finish())

    def shape(self, k: int) -> MouthShape:
        """The mouth's shape at grid frame ``k`` (features beyond those in are held at the newest)."""
        opening, rounding, spread = self.values(k)
        return MouthShape(np.array([opening]), np.array([rounding]), np.array([spread]))

    def values(self, k: int) -> tuple[float, float, float]:
        """The opening, rounding and spread of :meth:`shape` as plain floats; frames before ``k`` are let go."""
        last = self._first + self._frames.shape[0] - 1
        index = np.round((k / self.fps + self._offsets_s) * 100).astype(int)
        index = np.clip(index, 0, max(last, 0)) - self._first
        row = self._frames[np.clip(index, 0, self._frames.shape[0] - 1)].reshape(-1) if self._frames.size else \
            np.zeros(len(self.model.offsets_s) * N_SPECTRAL)
        opening, rounding, spread = np.append(row, 1.0) @ self.model.weights_
        # the voice gate over the 10 ms frames within 50 ms of this one that are in, and the dip gate (each
        # frame's peak over the frames within DIP_WINDOW_FRAMES that are in) over those within 20 ms
        centre = int(np.round(k / self.fps * 100)) - self._first
        near = self._gates[max(centre - VOICE_HALF_FRAMES, 0):max(centre + VOICE_HALF_FRAMES + 1, 0)]
        gate = float(near.mean()) if near.size else 0.0
        low = max(centre - DIP_HALF_FRAMES, 0)
        dips = self._db[low:max(centre + DIP_HALF_FRAMES + 1, 0)]
        peaks = [self._db[max(i - DIP_WINDOW_FRAMES, 0):i + DIP_WINDOW_FRAMES + 1].max()
                 for i in range(low, low + dips.size)]
        closing = float(dip_gate(dips, np.array(peaks)).mean()) if dips.size else 0.0
        opening, rounding, spread = max(opening, 0.0) * gate * closing, rounding * gate, spread * gate
        # what no later frame reads any more is let go
        oldest = int(np.round((k / self.fps + self.model.offsets_s[0]) * 100)) - self._first
        if oldest > 200:
            self._frames = self._frames[oldest - 100:]
            self._gates = self._gates[oldest - 100:]
            self._db = self._db[oldest - 100:]
            self._first += oldest - 100
        return float(opening), float(rounding), float(spread)


def live_mouth_clips(folder: str | os.PathLike[str], *,
                     fps: float = 30.0) -> list[tuple[np.ndarray, MouthTrainingClip]]:
    """The clips of ``folder`` (``<name>.wav`` + ``<name>.mouth.csv``) as (cepstra, training clip) pairs."""
    from pathlib import Path

    from audio_features import AUDIO_EXTENSIONS, load_audio

    from ...fap.recorded import read_mouth_csv

    pairs = []
    for audio_path in sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in AUDIO_EXTENSIONS):
        mouth_path = audio_path.with_name(audio_path.stem + ".mouth.csv")
        if mouth_path.is_file():
            audio = load_audio(audio_path)
            clip = mouth_training_clip(audio, read_mouth_csv(mouth_path), fps=fps, name=audio_path.stem)
            pairs.append((cepstra(audio), clip))
    return pairs
