"""Training and leave-one-speaker-out measurement of the live head (:class:`prosody.motion.heads.live.LiveHeadModel`).

The live model is trained on the acoustic frames the live analysis gives
(:func:`audio_features.streaming.stream_file`), the same ones it will see when streaming.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from audio_features import DEFAULT_FPS
from audio_features.streaming import stream_file

from ...errors import ConfigError, GroundTruthError, ProsodyError
from ...fap.recorded import fit_to_grid, read_motion
from ...fap.table import HEAD_FAPS
from ...measures import average_head_metrics, head_matrix, head_metrics
from ..controls import shift_offsets
from .live import DEFAULT_LOOKAHEAD_MS, LiveHeadModel
from .training import CV_SEEDS, HeldOut, find_pairs, held_out_summary, signed

_LOG = logging.getLogger("prosody.training")


@dataclass(frozen=True)
class StreamedRecording:
    """A paired recording as the live head sees it: streamed F0 (NaN unvoiced) and energy per frame, and
    the recorded head motion (n_frames, 3) in AU, resting pose removed."""

    name: str
    f0_hz: np.ndarray
    energy_db: np.ndarray
    motion_au: np.ndarray
    #: Whose voice it is: cross-validation holds out a speaker's recordings together ("" : its own speaker).
    speaker: str = ""


def speaker_folds(recordings: Sequence[StreamedRecording]) -> list[list[int]]:
    """Recording indices grouped by speaker, in order of first appearance: the held-out folds."""
    groups: dict[str, list[int]] = {}
    for index, recording in enumerate(recordings):
        groups.setdefault(recording.speaker or recording.name, []).append(index)
    return list(groups.values())


def load_streamed(pairs: Iterable[tuple[Path, Path]], *, fps: float = DEFAULT_FPS,
                  report: Callable[[str], None] | None = None,
                  speakers: dict[str, str] | None = None) -> list[StreamedRecording]:
    """Analyse each pair's audio as a stream and read its motion; a pair that fails is reported and skipped.
    ``speakers`` names the speaker of each recording stem (default: the ``speakers.csv`` of each pair's folder;
    a recording not named there is its own speaker)."""
    from .training import read_speakers

    report = report or _LOG.info
    pairs = list(pairs)
    recordings = []
    folder_speakers: dict[Path, dict[str, str]] = {}
    for index, (audio, motion_path) in enumerate(pairs, start=1):
        try:
            f0, energy = stream_file(str(audio), fps=fps)
            motion = fit_to_grid(read_motion(motion_path), n_frames=f0.size, fps=fps, source=str(motion_path))
            if not all(fap in motion.active_faps for fap in HEAD_FAPS):
                raise GroundTruthError(f"{motion_path}: no head rotation (FAP 48-50) in the recorded motion")
        except (ProsodyError, ValueError) as error:  # audio errors derive from ValueError
            report(f"[{index}/{len(pairs)}] skipped {audio.stem}: {error}")
            continue
        table = speakers if speakers is not None else folder_speakers.setdefault(
            audio.parent, read_speakers(audio.parent))
        recordings.append(StreamedRecording(audio.stem, f0, energy, head_matrix(motion),
                                            table.get(audio.stem, audio.stem)))
        report(f"[{index}/{len(pairs)}] {audio.stem}: {f0.size} frames")
    return recordings


def fit_live(recordings: Sequence[StreamedRecording], *, fps: float = DEFAULT_FPS, **settings) -> LiveHeadModel:
    return LiveHeadModel(**settings).fit([r.f0_hz for r in recordings], [r.energy_db for r in recordings],
                                         [r.motion_au for r in recordings], fps=fps,
                                         names=[r.name for r in recordings])


def held_out_live(recordings: Sequence[StreamedRecording], *, fps: float = DEFAULT_FPS, seeds: int = CV_SEEDS,
                  **settings) -> HeldOut:
    """Fit on every other speaker's recordings, measure on this speaker's (``seeds`` seeds), for each speaker
    (:func:`speaker_folds`); the control is the same model driven by the held-out recording's own frames
    circularly shifted."""
    folds = speaker_folds(recordings)
    if len(folds) < 2:
        raise ConfigError("cross-validation needs recordings of at least two speakers")
    per_recording, controls = {}, {}
    for fold in folds:
        model = fit_live([r for i, r in enumerate(recordings) if i not in fold], fps=fps, **settings)
        for held in fold:
            recording = recordings[held]
            per_recording[recording.name], controls[recording.name] = _measure(model, recording, fps=fps,
                                                                                seeds=seeds)
    return HeldOut(dict(settings), seeds, per_recording, controls)


#: Settings of the live head tried by cross-validation, one at a time (the rest keep their defaults).
LIVE_GRID = {"presence_window_s": (2.0, 1.0, 0.5, 0.25), "pitch_follow_s": (0.0, 0.2)}


def select_live(recordings: Sequence[StreamedRecording], *, fps: float = DEFAULT_FPS, seeds: int = 3,
                report: Callable[[str], None] | None = None, **fixed) -> list[HeldOut]:
    """Score every setting of :data:`LIVE_GRID` by its held-out speed-envelope and pitch r above their
    controls (:attr:`HeldOut.score`), with the ``fixed`` settings; best first."""
    report = report or (lambda message: None)
    results = []
    for key, values in LIVE_GRID.items():
        for value in values:
            result = held_out_live(recordings, fps=fps, seeds=seeds, **fixed, **{key: value})
            results.append(result)
            report(f"[cv] {key}={value:g}: speed-envelope r {signed(result.mean('speed_envelope_r'))} "
                   f"(control {signed(result.mean('speed_envelope_r', control=True))}), pitch r "
                   f"{signed(result.mean('pitch_r'))} (control {signed(result.mean('pitch_r', control=True))})")
    return sorted(results, key=lambda r: -r.score)


def nested_held_out_live(recordings: Sequence[StreamedRecording], *, fps: float = DEFAULT_FPS,
                         seeds: int = CV_SEEDS, **fixed) -> HeldOut:
    """Leave-one-speaker-out where each fold chooses its settings by :func:`select_live` on the other
    speakers' recordings only: figures that the choice of settings cannot have inflated."""
    per_recording, controls = {}, {}
    for fold in speaker_folds(recordings):
        others = [r for i, r in enumerate(recordings) if i not in fold]
        chosen = select_live(others, fps=fps, **fixed)[0].settings
        model = fit_live(others, fps=fps, **chosen)
        for held in fold:
            recording = recordings[held]
            per_recording[recording.name], controls[recording.name] = _measure(model, recording, fps=fps,
                                                                                seeds=seeds)
    return HeldOut({"nested": True, **fixed}, seeds, per_recording, controls)


def _measure(model: LiveHeadModel, recording: StreamedRecording, *, fps: float, seeds: int) -> tuple[dict, dict]:
    """A model's head measures on a recording over ``seeds`` seeds, and those of its mismatched-audio control."""
    f0, energy, recorded = recording.f0_hz, recording.energy_db, recording.motion_au
    own, mismatched = [], []
    for seed in range(seeds):
        own.append(head_metrics(model.generate_frames(f0, energy, seed=seed), recorded, fps=fps))
        for offset in shift_offsets(f0.size, fps=fps):
            index = (np.arange(f0.size) - offset) % f0.size
            mismatched.append(head_metrics(model.generate_frames(f0[index], energy[index], seed=seed), recorded,
                                           fps=fps))
    return average_head_metrics(own), average_head_metrics(mismatched)


def train_live(directory: str | os.PathLike[str], output: str | os.PathLike[str], *,
               lookahead_ms: float = DEFAULT_LOOKAHEAD_MS, cv: bool = False, fps: float = DEFAULT_FPS,
               report: Callable[[str], None] | None = None) -> LiveHeadModel:
    """Train a live head model reading ``lookahead_ms`` ahead on every pair in ``directory`` and save it;
    with ``cv`` its settings are chosen from :data:`LIVE_GRID` by leave-one-speaker-out (the folder's
    ``speakers.csv``; without one each recording is its own speaker), and the chosen
    setting's held-out measures and their control are stored in the file."""
    report = report or _LOG.info
    pairs = find_pairs(directory)
    if not pairs:
        raise ConfigError(f"{directory}: no <name>.wav with <name>.head.csv or <name>.fap found")
    recordings = load_streamed(pairs, fps=fps, report=report)
    if not recordings:
        raise GroundTruthError(f"{directory}: every pair was skipped; nothing to train on")
    settings: dict = {"lookahead_s": lookahead_ms / 1000}
    extra: dict = {}
    try:
        if cv:
            settings = select_live(recordings, fps=fps, report=report, **settings)[0].settings
            report(f"chosen {' '.join(f'{k}={v:g}' for k, v in settings.items())}")
            result = held_out_live(recordings, fps=fps, **settings)
            extra["cross_validation"] = held_out_summary(result)
            report(f"held out over {result.seeds} seeds: speed-envelope r {signed(result.mean('speed_envelope_r'))} "
                   f"(mismatched audio {signed(result.mean('speed_envelope_r', control=True))}), pitch r "
                   f"{signed(result.mean('pitch_r'))} "
                   f"(mismatched audio {signed(result.mean('pitch_r', control=True))})")
        model = fit_live(recordings, fps=fps, **settings)
    except ConfigError as error:
        raise GroundTruthError(f"{directory}: {error}") from None
    model.save(output, extra=extra)
    report(f"{output}: live head model ({lookahead_ms:g} ms look-ahead) trained on {len(recordings)} recordings "
           f"({sum(r.f0_hz.size for r in recordings) / fps:.1f} s)")
    return model
