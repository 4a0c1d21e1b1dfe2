"""``prosody track``: talking-head videos into the recorded-motion files that train, compare and batch read.

For each video ``<stem>``, written into the output folder, each file atomically:

- ``<stem>.wav``: its sound, 16 kHz mono 16-bit (the time base of everything else);
- ``<stem>.head.csv``, ``<stem>.brows.csv``, ``<stem>.mouth.csv``: the talking-heads formats at 30 fps,
  frame k at k / 30 s of the sound, empty cells where the face was not found;
- ``<stem>.track.json``: what was done (the video's properties, the face followed, frames without it, the
  audio-video sync estimate, how well the two measures of the mouth's opening agree, the model's SHA-256),
  written last, so a folder holding it for the same video and settings is complete and is skipped on a re-run.

A video without sound takes the WAV of the same stem beside it (or given with ``audio=``), read as starting
with the first frame; with neither, the curves are timed from the first frame and no WAV is written.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from audio_features.atomic import atomic_path, atomic_write

from ..errors import ConfigError, TrackingError, VisualProsodyError, require_extra
from ..fap.recorded import HEAD_CSV_FPS
from ..measures import opening_agreement
from ..tracking.curves import (
    ALL_COLUMNS,
    MAX_GAP_S,
    EnvelopeAccumulator,
    SyncEstimate,
    estimate_sync,
    tracked_curves,
    write_curves,
)
from ..tracking.face import MODEL_SHA256, FaceTracker, face_measures, head_angles
from ..tracking.video import (
    DEFAULT_MAX_SIDE_PX,
    TRACK_AUDIO_RATE_HZ,
    VIDEO_EXTENSIONS,
    VideoInfo,
    iter_frames,
    probe_video,
    read_video_audio,
)
from .batch import file_digest, natural_key
from .runner import one_line, run_tasks

#: Version of the tracking method, stored in each track.json (a change redoes complete outputs).
TRACK_VERSION = 1
#: Largest difference between the sound's and the picture's lengths before a warning, in s.
LENGTH_WARNING_S = 0.5
#: Below this agreement of the two measures of the mouth's opening (:func:`prosody.measures.opening_agreement`)
#: a video's note says its mouth is a poor reference (4 of the 42 usable talking videos; their median is 0.83).
POOR_MOUTH_AGREEMENT = 0.6


class TrackWarning(UserWarning):
    """Something in a video that the tracker worked around (no sound, a long stretch without a face, ...)."""


@dataclass(frozen=True)
class TrackOptions:
    """Settings applied to every video (stored in each track.json to recognise complete outputs).

    av_offset_ms : float
        Added to every frame's time: positive when the picture runs ahead of the sound (moves it later).
    max_gap_s : float >= 0
        Longest stretch without the face bridged by interpolation.
    max_side_px : int > 0 or None
        Frames larger than this are scaled down before tracking.
    """

    av_offset_ms: float = 0.0
    max_gap_s: float = MAX_GAP_S
    max_side_px: int | None = DEFAULT_MAX_SIDE_PX

    def __post_init__(self) -> None:
        if not np.isfinite(self.av_offset_ms) or abs(self.av_offset_ms) > 5000:
            raise ConfigError(f"av_offset_ms must be within +-5000 ms, got {self.av_offset_ms!r}",
                              parameter="av_offset_ms")
        if not (np.isfinite(self.max_gap_s) and 0 <= self.max_gap_s <= 10):
            raise ConfigError(f"max_gap_s must be from 0 to 10 s, got {self.max_gap_s!r}")
        if self.max_side_px is not None and not (64 <= self.max_side_px <= 8192):
            raise ConfigError(f"max_side_px must be from 64 to 8192, got {self.max_side_px!r}")


@dataclass
class TrackOutcome:
    """What happened to one video."""

    video: str
    status: str  # "done", "skipped" (already complete) or "failed"
    stem: str
    error: str | None = None
    seconds: float = 0.0
    frames: int = 0
    missing_frames: int = 0
    sync: dict | None = None
    warnings: list[str] = field(default_factory=list)


def find_videos(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """The videos named, folders searched recursively (hidden ones skipped), in natural order per folder.

    Raises
    ------
    ConfigError
        A path that does not exist.
    """
    found: list[Path] = []
    for entry in paths:
        path = Path(entry)
        if path.is_dir():
            inside = []
            for dirpath, dirnames, filenames in os.walk(path):
                dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
                inside += [Path(dirpath, name) for name in filenames
                           if not name.startswith(".") and Path(name).suffix.lower() in VIDEO_EXTENSIONS]
            found += sorted(inside, key=natural_key)
        elif path.exists():
            found.append(path)
        else:
            raise ConfigError(f"{path}: no such file or folder")
    return found


def _write_wav(blocks: Iterable[np.ndarray], path: str | os.PathLike[str]) -> int:
    """Stream float blocks into a 16-bit WAV; returns the number of samples."""
    import soundfile

    total = 0
    with soundfile.SoundFile(str(path), "w", samplerate=TRACK_AUDIO_RATE_HZ, channels=1, subtype="PCM_16",
                             format="WAV") as out:
        for block in blocks:
            out.write(np.clip(block, -1.0, 1.0))
            total += block.size
    return total


def _audio_beside(video: Path, given: str | os.PathLike[str] | None) -> Path | None:
    if given is not None:
        return Path(given)
    candidate = video.with_suffix(".wav")
    return candidate if candidate.is_file() else None


def _load_16k(path: Path) -> np.ndarray:
    require_extra(("librosa",), "track", "resampling a video's sound")
    import librosa

    from audio_features import load_audio

    audio = load_audio(path)
    samples = audio.samples.astype(np.float32)
    if audio.sample_rate_hz != TRACK_AUDIO_RATE_HZ:
        samples = librosa.resample(samples, orig_sr=audio.sample_rate_hz, target_sr=TRACK_AUDIO_RATE_HZ)
    return samples


def _settings(video: Path, options: TrackOptions, audio: Path | None) -> dict:
    return {"version": TRACK_VERSION, "video_sha256": file_digest(video), "model_sha256": MODEL_SHA256,
            "audio_sha256": file_digest(audio) if audio is not None else None, "options": asdict(options)}


def _complete(record: Path, settings: dict) -> bool:
    try:
        stored = json.loads(record.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(stored, dict) and stored.get("settings") == settings


def track_video(video: str | os.PathLike[str], outdir: str | os.PathLike[str], *,
                options: TrackOptions = TrackOptions(), audio: str | os.PathLike[str] | None = None,
                force: bool = False, progress: Callable[[int, int], None] | None = None) -> TrackOutcome:
    """Track one video into ``outdir`` (see the module for the files).

    Parameters
    ----------
    audio : path, optional
        The sound of a video that has none in it (default: ``<stem>.wav`` beside the video, if any).
    force : bool
        Redo a video whose outputs are already complete.
    progress : callable(done, total), optional
        Called as frames are tracked (total is the estimated frame count).

    Raises
    ------
    TrackingError
        The video (or its sound) cannot be read, or the tracker is not installed.
    """
    started = time.monotonic()
    path = Path(video)
    out = Path(outdir)
    stem = out / path.stem
    notes: list[str] = []

    def note(text: str) -> None:
        notes.append(text)
        warnings.warn(TrackWarning(f"{path}: {text}"), stacklevel=3)

    info = probe_video(path)
    sound = None if info.has_audio else _audio_beside(path, audio)
    if info.has_audio and audio is not None:
        raise ConfigError(f"{path}: has its own sound; audio= is for videos without one", parameter="audio")
    record = Path(f"{stem}.track.json")
    settings = _settings(path, options, sound)
    if not force and _complete(record, settings):
        stored = json.loads(record.read_text())
        return TrackOutcome(str(path), "skipped", str(stem), frames=stored.get("frames", 0),
                            missing_frames=stored.get("missing_frames", 0), sync=stored.get("sync"))
    _refuse_files_of_others(path, stem, record, writes_wav=info.has_audio or (
        sound is not None and sound.resolve() != Path(f"{stem}.wav").resolve()))
    out.mkdir(parents=True, exist_ok=True)
    # every file goes to a temporary name, renamed only once all of them are complete
    with contextlib.ExitStack() as pending:
        outcome, summary = _track(path, stem, info, sound, options, pending, note, progress)
        summary = {"settings": settings, **summary, "notes": notes}
        outcome.warnings = notes
    # written last: its presence says the folder is complete for this video and these settings
    with atomic_write(record, newline="\n") as handle:
        json.dump(_jsonable(summary), handle, indent=2)
        handle.write("\n")
    outcome.seconds = time.monotonic() - started
    return outcome


#: The endings of the files a video's tracking writes besides its record (and its WAV).
CURVE_ENDINGS = (".head.csv", ".brows.csv", ".mouth.csv")


def _refuse_files_of_others(video: Path, stem: Path, record: Path, *, writes_wav: bool) -> None:
    """A file the tracking would write that is already there and not of an earlier tracking (named in the
    record's file list) is the user's own, e.g. ``clip.wav`` beside ``clip.mp4`` tracked into its own folder:
    never replaced."""
    try:
        stored = json.loads(record.read_text())
        ours = set(stored.get("files", [])) if isinstance(stored, dict) else set()
    except (OSError, ValueError, TypeError):
        ours = set()
    endings = (".wav",) * writes_wav + CURVE_ENDINGS
    theirs = [Path(f"{stem}{ending}") for ending in endings
              if os.path.lexists(f"{stem}{ending}") and f"{stem.name}{ending}" not in ours]
    if theirs:
        were = "was" if len(theirs) == 1 else "were"
        raise ConfigError(f"{video}: {', '.join(map(str, theirs))} already exist(s) and {were} not written by "
                          "'prosody track': nothing is replaced; track into another folder (-o OUT)")


def _track_sound(path: Path, stem: Path, info: VideoInfo, sound: Path | None, pending: contextlib.ExitStack,
                 note: Callable[[str], None]) -> EnvelopeAccumulator:
    """The sound first (it sets the time base and the length of the grid): the video's own, written beside the
    curves, or the WAV given for a silent video; its loudness envelope."""
    envelope = EnvelopeAccumulator(sample_rate_hz=TRACK_AUDIO_RATE_HZ)
    if info.has_audio:
        wav = pending.enter_context(atomic_path(f"{stem}.wav"))
        samples_written = _write_wav(envelope.passing(read_video_audio(path)), wav)
        if samples_written == 0:
            raise TrackingError(f"{path}: its sound track is empty")
    elif sound is not None:
        samples = _load_16k(sound)
        if sound.resolve() != Path(f"{stem}.wav").resolve():
            _write_wav([samples], pending.enter_context(atomic_path(f"{stem}.wav")))
        envelope.add(samples)
        note(f"no sound in the video: {sound} is taken as its sound, starting with the first frame")
    else:
        note("no sound in the video and no WAV beside it: the curves are timed from the first frame, no .wav "
             "written")
    has_sound = envelope.samples > 0
    duration_s = envelope.samples / TRACK_AUDIO_RATE_HZ
    if has_sound and np.isfinite(info.duration_s) and \
            abs(info.duration_s + info.video_start_s - duration_s) > LENGTH_WARNING_S:
        note(f"the picture ({info.duration_s:.2f} s from {info.video_start_s:+.2f} s) and the sound "
             f"({duration_s:.2f} s) differ in length; frames beyond the sound are left out")
    return envelope


def _track_faces(path: Path, info: VideoInfo, options: TrackOptions,
                 progress: Callable[[int, int], None] | None) -> tuple[list[float], list[np.ndarray], int, int]:
    """Every frame's time and measured row (NaN without a face), the most faces seen at once, the frames with one."""
    times, rows, faces_seen, with_face = [], [], 0, 0
    estimate = int(round(info.duration_s * info.fps)) if np.isfinite(info.duration_s * info.fps) else 0
    blank = np.full(len(ALL_COLUMNS), np.nan)
    with FaceTracker() as tracker:
        for index, (time_s, image) in enumerate(iter_frames(path, info=info, max_side_px=options.max_side_px)):
            observation = tracker.observe(image, time_s)
            times.append(time_s)
            if observation is None:
                rows.append(blank)
            else:
                with_face += 1
                faces_seen = max(faces_seen, observation.faces)
                measures = face_measures(observation)
                angles = dict(zip(("rx_rad", "ry_rad", "rz_rad"), head_angles(observation.rotation), strict=True))
                rows.append(np.array([{**angles, **measures}.get(name, np.nan) for name in ALL_COLUMNS]))
            if progress is not None:
                progress(index + 1, max(estimate, index + 1))
    return times, rows, faces_seen, with_face


def _track(path: Path, stem: Path, info: VideoInfo, sound: Path | None, options: TrackOptions,
           pending: contextlib.ExitStack, note: Callable[[str], None],
           progress: Callable[[int, int], None] | None) -> tuple[TrackOutcome, dict]:
    envelope = _track_sound(path, stem, info, sound, pending, note)
    has_sound = envelope.samples > 0
    duration_s = envelope.samples / TRACK_AUDIO_RATE_HZ
    times, rows, faces_seen, with_face = _track_faces(path, info, options, progress)
    if not times:
        raise TrackingError(f"{path}: its video has no frames")
    if not has_sound:  # the picture's length as decoded: browser recorders' headers give none, or 0 s
        step = float(np.median(np.diff(times))) if len(times) > 1 else \
            1.0 / info.fps if np.isfinite(info.fps) and info.fps > 0 else 1.0 / HEAD_CSV_FPS
        duration_s = times[-1] + step
    if with_face == 0:
        raise TrackingError(f"{path}: no face found in any of its {len(times)} frames")
    if faces_seen > 1:
        note(f"up to {faces_seen} faces in view: the largest face of the first frame with one is followed")

    curves = tracked_curves(np.array(times), np.vstack(rows), duration_s=duration_s,
                            offset_s=options.av_offset_ms / 1000.0, max_gap_s=options.max_gap_s)
    if curves.missing_frames:
        note(f"{curves.missing_frames} of {curves.n_frames} frames have no face (empty cells): it was not found "
             "there, or the sound outlasts the picture")
    sync = (estimate_sync(curves.columns["lip_opening"], envelope.envelope(curves.n_frames))
            if has_sound else SyncEstimate(None, None, None, "no sound"))
    agreement = opening_agreement(curves.columns["lip_opening"], curves.columns["jaw_open"], fps=curves.fps)
    if agreement is not None and agreement < POOR_MOUTH_AGREEMENT:
        note(f"the two measures of the mouth's opening (inner-lip landmarks, jawOpen) agree only r {agreement:.2f}: "
             "a poor reference for training or measuring lips")
    written = write_curves(curves, stem, pending=pending)
    summary = {
        "video": {key: value for key, value in asdict(info).items() if key != "path"} | {"file": path.name},
        "frames": curves.n_frames, "fps": curves.fps, "video_frames": len(times),
        "video_frames_with_face": with_face, "faces_seen": faces_seen,
        "bridged_frames": curves.bridged_frames, "missing_frames": curves.missing_frames,
        "sync": asdict(sync) | {"description": sync.describe()},
        "mouth_agreement": None if agreement is None else round(agreement, 3),
        "files": [Path(name).name for name in written] + ([f"{path.stem}.wav"] if has_sound else []),
    }
    return TrackOutcome(str(path), "done", str(stem), frames=curves.n_frames, missing_frames=curves.missing_frames,
                        sync=asdict(sync)), summary


def _jsonable(value):
    if isinstance(value, dict):
        return {key: _jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(item) for item in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _track_one(video: str, outdir: str, options: TrackOptions, audio: str | None, force: bool) -> TrackOutcome:
    """One video in a worker: every failure becomes a failed outcome (one line), never an exception."""
    started = time.monotonic()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrackWarning)  # the outcome carries them
        try:
            return track_video(video, outdir, options=options, audio=audio, force=force)
        except (VisualProsodyError, OSError, ValueError) as error:
            line = one_line(error).removeprefix(f"{video}: ")  # the report names the video already
            return TrackOutcome(video, "failed", str(Path(outdir) / Path(video).stem), error=line,
                                seconds=time.monotonic() - started)


def track_videos(videos: Iterable[str | os.PathLike[str]], outdir: str | os.PathLike[str], *,
                 options: TrackOptions = TrackOptions(), audio: str | os.PathLike[str] | None = None,
                 jobs: int = 1, scheduler: str | None = None, force: bool = False,
                 on_outcome: Callable[[TrackOutcome], None] | None = None) -> list[TrackOutcome]:
    """Track videos (files, or folders searched recursively) into ``outdir``: one process per video with
    ``jobs > 1``, or a Dask cluster given its scheduler address. A video that fails is reported, never fatal.

    Raises
    ------
    ConfigError
        No video found, two videos with the same stem (their outputs would collide), or ``audio`` with more
        than one video.
    """
    found = find_videos(videos)
    if not found:
        raise ConfigError("no video found (looked for " + ", ".join(VIDEO_EXTENSIONS) + ")")
    stems: dict[str, Path] = {}
    for path in found:
        if path.stem in stems:
            raise ConfigError(f"{stems[path.stem]} and {path} would both write {path.stem}.*: track them into "
                              "different folders")
        stems[path.stem] = path
    if audio is not None and len(found) > 1:
        raise ConfigError("--audio goes with one video only")
    if not (isinstance(jobs, int) and 1 <= jobs <= 256):
        raise ConfigError(f"jobs must be a whole number from 1 to 256, got {jobs!r}")
    tasks = [(str(path), str(outdir), options, str(audio) if audio is not None else None, force) for path in found]
    outcomes: list[TrackOutcome] = []

    def done(outcome: TrackOutcome) -> None:
        outcomes.append(outcome)
        if on_outcome is not None:
            on_outcome(outcome)

    def failed(task: tuple, why: str) -> TrackOutcome:
        return TrackOutcome(task[0], "failed", str(Path(task[1]) / Path(task[0]).stem), error=why)

    for _, outcome in run_tasks(_track_one, tasks, failed=failed, jobs=jobs, scheduler=scheduler):
        done(outcome)
    order = {str(path): index for index, path in enumerate(found)}
    return sorted(outcomes, key=lambda outcome: order.get(outcome.video, 0))


