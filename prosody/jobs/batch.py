"""Batch processing: every audio file of a folder tree converted and compared, in parallel.

Work goes through the standard :class:`concurrent.futures.Executor` interface: the file itself with one job,
local processes with ``jobs > 1``, or a Dask distributed cluster given its scheduler address (Dask's
``Client.get_executor()`` is such an executor). Each file's outputs go to their own folder, mirroring the
input tree; ``metrics.json`` is written last, so a folder holding it with the same settings is complete and
is skipped on a re-run (``force`` redoes it). A broken file is reported and skipped, never fatal.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from audio_features import AUDIO_EXTENSIONS, AudioFeaturesError
from audio_features.atomic import atomic_write
from audio_features.inputs import file_sha256

from ..errors import ConfigError, ProsodyError, VisualProsodyError
from ..evaluation.metrics import BrowMeasures, HeadMeasures, Metrics, MouthMeasures
from ..fap.table import HEAD_FAPS, PROSODY_FAPS
from ..motion.conditions import CONDITION_ORDER, Condition
from ..motion.expressivity import NEUTRAL, Expressivity
from ..motion.eyebrows import AccentRule, EyebrowRule
from ..motion.settings import AnalysisSettings, ChannelSettings, FaceSettings, MotionSettings
from ..validate import valid_seeds
from .runner import one_line, run_tasks

#: Ground-truth file endings looked up beside an audio file's stem, in order of preference.
GROUND_TRUTH_SUFFIXES = (".head.csv", ".fap")
#: Each output folder's features (the ``prosody features`` CSV), read back for the cross-recording control.
FEATURES_FILE = "features.csv"
#: Other recordings whose audio drives the generator in the cross-recording control, per recording.
OTHER_RECORDINGS = 5
#: Bootstrap resamples of the 95% intervals in the summary.
BOOTSTRAP_RESAMPLES = 2000


@dataclass(frozen=True)
class BatchOptions:
    """Settings applied to every file (they are stored in each metrics.json to recognise complete outputs)."""

    conditions: tuple[str, ...] = tuple(c.value for c in CONDITION_ORDER)
    model: str | None = MotionSettings.model
    seed: int = MotionSettings.seed
    normalize: bool = False
    fps: float = AnalysisSettings.fps
    f0_floor_hz: float = AnalysisSettings.f0_floor_hz
    f0_ceiling_hz: float = AnalysisSettings.f0_ceiling_hz
    plots: bool = False
    video: bool = False
    seeds: int = 10
    brows: str = "accent"
    #: The brow rule's threshold in semitones above the speaker's median pitch (None: the rule's default).
    brow_semitones: float | None = None
    lips: str | None = FaceSettings.lips
    #: Greta's expressivity controls by name (see :class:`prosody.motion.expressivity.Expressivity`).
    expressivity: Mapping[str, float] = field(default_factory=lambda: dict(NEUTRAL))
    #: The eyebrow rule itself, any of its settings (None: ``brows`` with ``brow_semitones``).
    eyebrow_rule: AccentRule | EyebrowRule | None = None
    #: A facial expression over every recording (``NAME[:INTENSITY]``, as ``convert --expression``).
    expression: str | None = None
    #: Read ``<stem>.txt`` beside each recording, where there is one, as what it says (its transcript).
    transcripts: bool = False
    #: The transcripts' language (an eSpeak NG code; None: English, aligned by PocketSphinx).
    language: str | None = None
    #: Gains per channel and the channels left out, as ``convert`` applies them (on the generated conditions).
    gains: Mapping[str, float] | None = None
    disabled: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "expressivity", Expressivity().with_changes(**self.expressivity).as_dict())
        parsed = tuple(Condition.parse(name).value for name in self.conditions)
        if not parsed:
            raise ConfigError("choose at least one condition")
        object.__setattr__(self, "conditions", parsed)
        if self.brows not in ("accent", "thesis"):
            raise ConfigError(f"brows must be 'accent' or 'thesis', got {self.brows!r}")
        if self.brow_semitones is not None and not (isinstance(self.brow_semitones, (int, float))
                                                    and 0 < self.brow_semitones <= 24):
            raise ConfigError(f"brow_semitones must be a number of semitones in (0, 24], got {self.brow_semitones!r}",
                              parameter="brow_semitones")
        if self.eyebrow_rule is None:
            rule: AccentRule | EyebrowRule
            if self.brows == "accent":
                rule = AccentRule() if self.brow_semitones is None else AccentRule(
                    threshold_semitones=self.brow_semitones)
            else:
                rule = EyebrowRule() if self.brow_semitones is None else EyebrowRule(
                    threshold_semitones=self.brow_semitones)
            object.__setattr__(self, "eyebrow_rule", rule)
        elif not isinstance(self.eyebrow_rule, AccentRule if self.brows == "accent" else EyebrowRule):
            raise ConfigError(f"eyebrow_rule must be the rule brows={self.brows!r} names, got "
                              f"{type(self.eyebrow_rule).__name__}", parameter="brows")
        if self.language is not None and not self.transcripts:
            raise ConfigError("language is the transcripts' language: set transcripts=True (<stem>.txt beside each "
                              "recording)", parameter="transcripts")
        # the face's rules are the library's: an unknown expression or language, or a transcript the lips do not
        # read, is refused before any file
        FaceSettings(lips=self.lips)
        if self.language is not None:
            from audio_features.espeak import check_language

            check_language(self.language)
        if self.expression is not None:
            from ..motion.face.expressions import parse_expressions

            if not isinstance(self.expression, str) or self.expression.lower().endswith(".csv"):
                raise ConfigError(f"a batch's expression is NAME[:INTENSITY] for every recording, got "
                                  f"{self.expression!r}")
            parse_expressions(self.expression)
        channels = ChannelSettings(gains=self.gains, disabled=self.disabled)  # refuses what convert refuses
        object.__setattr__(self, "gains", dict(channels.gains or {}) or None)
        object.__setattr__(self, "disabled", tuple(channels.disabled))
        if self.transcripts and self.lips not in ("visemes", "combined"):
            raise ConfigError(f"transcripts are read by the visemes; lips={self.lips!r} does not use them",
                              parameter="lips")
        valid_seeds(self.seeds)


@dataclass
class FileOutcome:
    """What happened to one input file."""

    file: str
    status: str  # "done", "skipped" (already complete) or "failed"
    output: str
    ground_truth: str | None = None
    error: str | None = None
    seconds: float = 0.0
    metrics: dict | None = field(default=None, repr=False)
    warnings: list[str] = field(default_factory=list)
    #: the parameters its error and warnings name (``ParameterError.parameters``), for a command to say as options
    parameters: tuple[str, ...] = ()


def find_audio_files(indir: str | os.PathLike[str]) -> list[Path]:
    """Audio files under ``indir`` (recursively, hidden folders skipped), as paths relative to it, in natural
    order (clip2 before clip10)."""
    root = Path(indir)
    if not root.is_dir():
        raise ConfigError(f"{root}: not a folder")
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for filename in filenames:
            if not filename.startswith(".") and Path(filename).suffix.lower() in AUDIO_EXTENSIONS:
                found.append(Path(dirpath, filename).relative_to(root))
    return sorted(found, key=natural_key)


def find_ground_truth(relative: Path, directory: str | os.PathLike[str] | None) -> Path | None:
    """``<stem>.head.csv`` or ``<stem>.fap`` in ``directory`` at the audio's relative path, else at its top."""
    if directory is None:
        return None
    root = Path(directory)
    for folder in dict.fromkeys((root / relative.parent, root)):
        for suffix in GROUND_TRUTH_SUFFIXES:
            candidate = folder / (relative.stem + suffix)
            if candidate.is_file():
                return candidate
    return None


def output_folder(outdir: str | os.PathLike[str], relative: Path, *, keep_suffix: bool = False) -> Path:
    """Where one input's outputs go: ``OUTDIR/<relative folder>/<stem>/``, or ``<stem>.<ending>/`` when
    another input in the same folder has the same stem (``take.wav`` and ``take.flac``)."""
    return Path(outdir) / relative.parent / (relative.name if keep_suffix else relative.stem)


def shared_stems(files: Iterable[Path]) -> set[Path]:
    """The inputs whose folder holds another input of the same stem: their outputs keep the ending."""
    seen: dict[tuple[Path, str], list[Path]] = {}
    for relative in files:
        seen.setdefault((relative.parent, relative.stem), []).append(relative)
    return {relative for group in seen.values() if len(group) > 1 for relative in group}


def natural_key(path: Path) -> list:
    """Sort key that orders numbers by value: clip2 before clip10."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part)
            for part in re.split(r"(\d+)", str(path)) if part]


def file_digest(path: str | os.PathLike[str] | None) -> str | None:
    """SHA-256 of a file's content (None for None): resume notices an input that changed under its name."""
    return None if path is None else file_sha256(path)


def transcript_file(audio: str | os.PathLike[str]) -> Path:
    """Where a recording's transcript is read from with ``transcripts``: ``<stem>.txt`` beside it."""
    return Path(audio).with_suffix(".txt")


def _transcript(audio: str) -> str | None:
    from audio_features.phones import read_transcript

    path = transcript_file(audio)
    return read_transcript(path) if path.is_file() else None


def _settings(options: BatchOptions, ground_truth: Path | None, audio: str) -> dict:
    """What makes an output folder current: the options, the paths, and the content of every input."""
    model = options.model
    if model is not None:
        from ..motion.heads.models import SHIPPED_MODELS

        model = str(SHIPPED_MODELS.get(model, model))
    transcript = transcript_file(audio) if options.transcripts and transcript_file(audio).is_file() else None
    rule = options.eyebrow_rule
    assert rule is not None  # set by BatchOptions from brows where not given
    # as metrics.json will hold it (tuples as lists), so that a finished folder compares equal
    return json.loads(json.dumps({**asdict(options), "conditions": list(options.conditions),
            "eyebrow_rule": {"rule": type(rule).__name__, **asdict(rule)},
            "ground_truth": str(ground_truth) if ground_truth else None,
            "content": {"audio": file_digest(audio), "ground_truth": file_digest(ground_truth),
                        "model": file_digest(model), "transcript": file_digest(transcript)}}))


def _complete(folder: Path, settings: dict) -> dict | None:
    """The stored metrics if ``folder`` holds a complete output made with the same settings."""
    try:
        metrics = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    from ..evaluation.metrics import METRICS_VERSION

    current = metrics.get("settings") == settings and metrics.get("version") == METRICS_VERSION
    return metrics if current else None


def process_file(audio: str, relative: str, outdir: str, ground_truth: str | None, options: BatchOptions,
                 force: bool = False, keep_suffix: bool = False) -> FileOutcome:
    """Convert and compare one file; every failure is caught and returned, never raised.

    A top-level function, so process pools and Dask workers can run it. The folder is redone when its
    metrics.json was made with other settings or from inputs whose content has changed since; files an
    earlier run wrote there that the new settings do not write are removed.
    """
    from ..evaluation.compare import compare, write_comparison

    started = time.perf_counter()
    folder = output_folder(outdir, Path(relative), keep_suffix=keep_suffix)
    truth = Path(ground_truth) if ground_truth else None
    outcome = FileOutcome(relative, "done", str(folder), ground_truth)
    conditions = [c for c in options.conditions if truth is not None or c != Condition.GROUND_TRUTH.value]
    try:
        settings = _settings(options, truth, audio)
        if not force:
            stored = _complete(folder, settings)
            if stored is not None:
                outcome.status, outcome.metrics = "skipped", stored
                return outcome
        with contextlib.suppress(FileNotFoundError):
            (folder / "metrics.json").unlink()  # from here on the folder is not complete
        if not conditions:
            raise ConfigError("only GROUND_TRUTH was asked for and no ground truth was found")
        transcript = _transcript(audio) if options.transcripts else None
        with warnings.catch_warnings(record=True) as caught:
            # a file's warnings are reported with the file, not raised or printed by a worker
            warnings.simplefilter("always")
            comparison = compare(audio, ground_truth=truth, model=options.model, seed=options.seed,
                                 seeds=options.seeds, eyebrow_rule=options.eyebrow_rule,
                                 normalize=options.normalize, conditions=conditions, fps=options.fps,
                                 f0_floor_hz=options.f0_floor_hz, f0_ceiling_hz=options.f0_ceiling_hz,
                                 lips=options.lips, expressivity=Expressivity(**options.expressivity),
                                 expression=options.expression, transcript=transcript,
                                 language=options.language if transcript is not None else None,
                                 gains=options.gains, disabled=options.disabled)
        outcome.warnings = list(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))
        outcome.parameters = tuple(name for w in caught for name in getattr(w.message, "parameters", ()))
        folder.mkdir(parents=True, exist_ok=True)
        # the features let the summary drive the generator with this recording's audio against other ones
        comparison.features.write_csv(folder / FEATURES_FILE)
        # write_comparison removes what an earlier run with other settings wrote there and this one does not
        write_comparison(comparison, folder, plots=options.plots, report=options.plots, video=options.video,
                         extra={"settings": settings})
        outcome.metrics = comparison.metrics
    except (VisualProsodyError, OSError, ValueError) as error:
        outcome.status, outcome.error = "failed", one_line(error)
        outcome.parameters += getattr(error, "parameters", ())
    except Exception as error:  # noqa: BLE001 - one broken file must never stop the others
        outcome.status, outcome.error = "failed", f"unexpected {type(error).__name__}: {one_line(error)}"
    outcome.seconds = time.perf_counter() - started
    return outcome


def run_batch(indir: str | os.PathLike[str], outdir: str | os.PathLike[str], *,
              ground_truth_dir: str | os.PathLike[str] | None = None, options: BatchOptions | None = None,
              jobs: int = 1, scheduler: str | None = None, force: bool = False,
              on_outcome: Callable[[FileOutcome], None] | None = None) -> dict:
    """Process every audio file under ``indir`` and write ``summary.json`` and ``summary.md`` to ``outdir``.

    Parameters
    ----------
    indir : path
        Folder searched recursively for audio files.
    outdir : path
        Output folder; each input gets ``OUTDIR/<relative folder>/<stem>/``.
    ground_truth_dir : path, optional
        Where ``<stem>.head.csv`` or ``<stem>.fap`` are looked up (same relative path, or the top).
    options : BatchOptions, optional
    jobs : int >= 1
        Local worker processes (ignored with ``scheduler``).
    scheduler : str, optional
        Address of a Dask distributed scheduler (e.g. ``tcp://10.0.0.5:8786``).
    force : bool
        Redo files whose outputs are already complete.
    on_outcome : callable, optional
        Called with each :class:`FileOutcome` as it finishes (progress display, logging).

    Returns
    -------
    dict
        The summary (also written as ``summary.json``): ``files``, ``counts``, ``aggregate``.
    """
    options = options or BatchOptions()
    if not (isinstance(jobs, int) and jobs >= 1):
        raise ConfigError(f"jobs must be a whole number >= 1, got {jobs!r}")
    if options.model is not None:
        from ..motion.heads.models import SHIPPED_MODELS, load_head_model

        load_head_model(options.model)  # a bad model is one error up front, not one per file
        if options.model not in SHIPPED_MODELS:
            options = BatchOptions(**{**asdict(options), "model": str(Path(options.model).resolve())})
    if ground_truth_dir is not None and not Path(ground_truth_dir).is_dir():
        raise ConfigError(f"ground_truth_dir: {ground_truth_dir} is not a folder", parameter="ground_truth_dir")
    files = find_audio_files(indir)
    shared = shared_stems(files)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    tasks = []
    for relative in files:
        truth = find_ground_truth(relative, ground_truth_dir)
        tasks.append((str(Path(indir) / relative), str(relative), str(out), str(truth) if truth else None))
    suffixed = {str(relative) for relative in shared}
    outcomes: dict[str, FileOutcome] = {}
    report = on_outcome or (lambda outcome: None)
    def failed(task: tuple, why: str) -> FileOutcome:
        folder = output_folder(out, Path(task[1]), keep_suffix=task[1] in suffixed)
        return FileOutcome(task[1], "failed", str(folder), task[3], error=why)

    runs = [(*task, options, force, task[1] in suffixed) for task in tasks]
    for _, outcome in run_tasks(process_file, runs, failed=failed, jobs=jobs, scheduler=scheduler):
        outcomes[outcome.file] = outcome
        report(outcome)
    ordered = [outcomes[str(relative)] for relative in files]
    summary = summarize(ordered, indir=str(indir), outdir=str(out), options=options)
    from ..evaluation.report import batch_markdown

    with atomic_write(out / "summary.json", newline="\n") as handle:
        json.dump(summary, handle, indent=1, allow_nan=False)
        handle.write("\n")
    with atomic_write(out / "summary.md", newline="\n") as handle:
        handle.write(batch_markdown(summary))
    return summary


def bootstrap_interval(values: Iterable[float], *, resamples: int = BOOTSTRAP_RESAMPLES,
                       seed: int = 0) -> tuple[float, float] | None:
    """95% percentile bootstrap interval of the mean (recordings resampled with replacement, seeded);
    None without values.

    Examples
    --------
    >>> bootstrap_interval([0.5, 0.5, 0.5])
    (0.5, 0.5)
    """
    data = np.asarray([v for v in values if v is not None], float)
    if data.size == 0:
        return None
    generator = np.random.default_rng(seed)
    means = data[generator.integers(0, data.size, size=(resamples, data.size))].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return float(low), float(high)


def _summary_entry(values: list[float | None]) -> dict:
    present = [v for v in values if v is not None]
    interval = bootstrap_interval(present)
    return {"mean": float(np.mean(present)) if present else None,
            "ci95": list(interval) if interval is not None else None, "recordings": len(present)}


def _measure_summary(blocks: list[HeadMeasures]) -> dict:
    """Mean over recordings with a bootstrap 95% interval of each head measure in ``blocks``."""
    summary = {key: _summary_entry([getattr(b, key) for b in blocks])
               for key in ("speed_envelope_r", "pitch_r", "velocity_spectrum_distance_db")}
    summary["std_ratio"] = {axis: _summary_entry([b.std_ratio[axis] for b in blocks]) for axis in ("48", "49", "50")}
    return summary


def _brow_summary(blocks: list[BrowMeasures]) -> dict:
    return {"raise_r": _summary_entry([b.raise_r for b in blocks]),
            "onset_f1": _summary_entry([b.onsets.f1 for b in blocks])}


def _mouth_summary(blocks: list[MouthMeasures]) -> dict:
    return {"opening_r": _summary_entry([b.opening_r for b in blocks]),
            "closure_f1": _summary_entry([b.closures.f1 for b in blocks]),
            "rounding_r": _summary_entry([b.rounding_r for b in blocks])}


def other_recordings_control(outcomes: list[FileOutcome], options: BatchOptions, *,
                             others: int = OTHER_RECORDINGS) -> dict[str, dict]:
    """The cross-recording control: for each recording with recorded head motion, the speech-driven head
    driven by the audio of up to ``others`` other inputs (the next ones in order, trimmed or tiled to this
    recording's length), against this recording's motion; head measures averaged over those inputs and
    ``options.seeds`` seeds. Keyed by file."""
    from audio_features import read_features_csv

    from ..fap.recorded import fit_to_grid, read_motion
    from ..measures import average_head_metrics, empty_head_metrics, head_matrix, head_measured, head_metrics
    from ..motion.conditions import head_motion
    from ..motion.controls import fitted_features
    from ..motion.heads.models import is_stochastic, resolve_head_model

    usable = [o for o in outcomes if o.metrics is not None and (Path(o.output) / FEATURES_FILE).is_file()]
    if len(usable) < 2 or Condition.SPEECH_DRIVEN.value not in options.conditions:
        return {}
    model = resolve_head_model(options.model)
    seeds = range(options.seed, options.seed + (options.seeds if is_stochastic(model) else 1))
    features = {}
    for outcome in usable:
        try:
            features[outcome.file] = read_features_csv(Path(outcome.output) / FEATURES_FILE, fps=options.fps)
        except (AudioFeaturesError, OSError):
            continue
    result: dict[str, dict] = {}
    names = [o.file for o in usable if o.file in features]
    for outcome in usable:
        if outcome.ground_truth is None or outcome.file not in features:
            continue
        own = features[outcome.file]
        try:
            truth = fit_to_grid(read_motion(outcome.ground_truth), n_frames=own.n_frames, fps=own.fps,
                                source=outcome.ground_truth)
        except (ProsodyError, OSError, ValueError):
            continue
        measured = head_measured(truth)
        if not measured.any():
            continue
        recorded = head_matrix(truth)
        chosen = [names[(names.index(outcome.file) + k) % len(names)] for k in range(1, len(names))][:others]
        rows = []
        for other in chosen:
            driven = fitted_features(features[other], own.n_frames)
            for seed in seeds:
                curves = head_motion(model, driven, seed=seed)
                rows.append(head_metrics(np.column_stack([curves[fap] for fap in HEAD_FAPS]), recorded,
                                         fps=own.fps, measured=measured))
        result[outcome.file] = average_head_metrics(rows) if rows else empty_head_metrics()
    return result


def summarize(outcomes: Iterable[FileOutcome], *, indir: str, outdir: str,
              options: BatchOptions | None = None) -> dict:
    """Counts, one entry per file, and per condition the mean over recordings (with a bootstrap 95% interval)
    of the head and brow measures, beside the mismatched-audio and cross-recording controls; the older
    per-FAP mean Pearson r stays in ``aggregate``."""
    outcomes = list(outcomes)
    options = options or BatchOptions()
    cross = other_recordings_control(outcomes, options)
    entries = [{"file": o.file, "status": o.status, "output": o.output, "ground_truth": o.ground_truth,
                "error": o.error, "warnings": o.warnings, "seconds": round(o.seconds, 3),
                "metrics": _compact(o.metrics),
                "other_recordings_control": cross.get(o.file)}
               for o in outcomes]
    with_truth = [Metrics.from_json(o.metrics) for o in outcomes if o.metrics is not None and o.ground_truth]
    aggregate, measures = _per_condition(with_truth)
    controls = {}
    if with_truth:
        controls["mismatched_audio"] = _measure_summary([m.controls.head for m in with_truth])
        controls["mismatched_audio_brows"] = _brow_summary([m.controls.brows for m in with_truth])
        controls["mismatched_audio_mouth"] = _mouth_summary([m.controls.mouth for m in with_truth])
    if cross:
        controls["other_recordings"] = _measure_summary([HeadMeasures.from_json(block) for block in cross.values()])
    counts = {status: sum(o.status == status for o in outcomes) for status in ("done", "skipped", "failed")}
    counts["files"] = len(outcomes)
    counts["with_ground_truth"] = sum(o.ground_truth is not None for o in outcomes)
    return {"input": indir, "output": outdir, "counts": counts, "seeds": options.seeds, "files": entries,
            "measures": measures, "controls": controls, "aggregate": aggregate}


def _per_condition(with_truth: list[Metrics]) -> tuple[dict[str, dict], dict[str, dict]]:
    """Per condition over the recordings with recorded motion: the mean r per FAP and CCA (``aggregate``), and the
    head, brow and mouth measures with their intervals (``measures``)."""
    aggregate: dict[str, dict] = {}
    measures: dict[str, dict] = {}
    for condition in CONDITION_ORDER:
        name = condition.value
        present = [m.conditions[name] for m in with_truth if name in m.conditions]
        if not present:
            continue
        faps = {}
        for fap in PROSODY_FAPS:
            values = [block.faps[str(fap)]["pearson_r"] for block in present]
            values = [v for v in values if v is not None]
            faps[str(fap)] = {"pearson_r": float(np.mean(values)) if values else None, "files": len(values)}
        cca = [m.settings["cca"]["head_vs_ground_truth"].get(name) for m in with_truth if name in m.conditions]
        cca = [v for v in cca if v is not None]
        aggregate[name] = {"faps": faps, "cca_head_vs_ground_truth": float(np.mean(cca)) if cca else None}
        measures[name] = {"head": _measure_summary([block.head for block in present]),
                          "brows": _brow_summary([block.brows for block in present]),
                          "mouth": _mouth_summary([block.mouth for block in present])}
    return aggregate, measures


def _compact(metrics: dict | None) -> dict | None:
    """The part of a file's metrics the summary keeps (statistics and CCA, not the settings)."""
    if metrics is None:
        return None
    return {key: metrics[key] for key in ("version", "duration_s", "frames", "conditions", "cca", "controls",
                                          "seeds", "head_model", "model_trained_on_this_recording") if key in metrics}
