"""Training head models on a folder of paired recordings (audio + recorded head motion).

Two kinds: ``prosodic`` (the default generator, :mod:`prosody.motion.heads.prosodic`), whose settings
cross-validation chooses by the held-out speed-envelope and pitch correlations, each read against the
mismatched-audio control; and ``arx`` (the thesis's model), whose orders it chooses by free-run error as
before, now reporting the same head measures beside it.
"""

from __future__ import annotations

import itertools
import logging
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from audio_features import AUDIO_EXTENSIONS, DEFAULT_FPS, Features, extract_features

from ...errors import ConfigError, GroundTruthError, ProsodyError, require_extra
from ...fap.recorded import fit_to_grid, read_motion
from ...fap.table import HEAD_FAPS
from ...measures import average_head_metrics, head_matrix, head_metrics, mean_of, pearson
from ..controls import shift_offsets, shifted_features
from .arx import DEFAULT_NA, DEFAULT_NB, DEFAULT_NK, DEFAULT_RIDGE, ArxHeadModel, arx_inputs
from .prosodic import ProsodicHeadModel

#: Where training reports its progress when no ``report`` callable is given (the library never prints).
_LOG = logging.getLogger("prosody.training")
#: Kinds of head model ``train`` fits.
MODEL_KINDS = ("prosodic", "arx", "pad")
#: Settings of the prosodic generator tried by cross-validation (the rest keep their defaults).
PROSODIC_GRID = {"pitch_share": (0.9, 0.95), "speed_iterations": (2, 3), "envelope_power": (1.0, 2.0, 3.0),
                 "pitch_follow_s": (0.0, 0.2)}
#: Seeds over which a stochastic model's held-out measures are averaged.
CV_SEEDS = 10

#: Orders tried by cross-validation.
DEFAULT_ORDER_GRID = {"na": (1, 2, 4), "nb": (1, 5, 15), "nk": (0, 5), "ridge": (0.01, 0.1, 1.0)}


@dataclass
class TrainingSet:
    """Paired recordings ready for fitting: ARX inputs and recorded head motion (AU) per recording."""

    names: list[str] = field(default_factory=list)
    inputs: list[np.ndarray] = field(default_factory=list)
    motion_au: list[np.ndarray] = field(default_factory=list)
    features: list[Features] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    fps: float = DEFAULT_FPS
    #: The speaker of each recording (cross-validation holds out a speaker's recordings together); empty:
    #: every recording its own speaker.
    speakers: list[str] = field(default_factory=list)

    def folds(self) -> list[list[int]]:
        """Recording indices grouped by speaker, in order of first appearance: the held-out folds."""
        speakers = self.speakers if len(self.speakers) == len(self.names) else self.names
        groups: dict[str, list[int]] = {}
        for index, speaker in enumerate(speakers):
            groups.setdefault(speaker, []).append(index)
        return list(groups.values())

    def subset(self, indices: Sequence[int]) -> TrainingSet:
        """The recordings at ``indices``."""
        pick = list(indices)
        speakers = [self.speakers[i] for i in pick] if len(self.speakers) == len(self.names) else []
        return TrainingSet([self.names[i] for i in pick], [self.inputs[i] for i in pick],
                           [self.motion_au[i] for i in pick], [self.features[i] for i in pick], fps=self.fps,
                           speakers=speakers)


#: The optional file of a training folder that names each recording's speaker (columns recording, speaker).
SPEAKERS_FILE = "speakers.csv"


def read_speakers(directory: str | os.PathLike[str]) -> dict[str, str]:
    """``{recording stem: speaker}`` from the folder's :data:`SPEAKERS_FILE`, or {} without one.

    Raises
    ------
    GroundTruthError
        The file exists but lacks the columns recording and speaker.
    """
    import csv

    path = Path(directory) / SPEAKERS_FILE
    if not path.is_file():
        return {}
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        if not reader.fieldnames or not {"recording", "speaker"} <= {name.strip() for name in reader.fieldnames}:
            raise GroundTruthError(f"{path}: expected the columns recording,speaker")
        return {row["recording"].strip(): row["speaker"].strip() for row in reader
                if row.get("recording") and row.get("speaker")}


def find_pairs(directory: str | os.PathLike[str]) -> list[tuple[Path, Path]]:
    """``(<name>.wav, <name>.head.csv or <name>.fap)`` pairs in a folder, sorted by name."""
    folder = Path(directory)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: not a folder")
    pairs = []
    for audio in sorted(p for p in folder.iterdir() if p.suffix.lower() in AUDIO_EXTENSIONS):
        for candidate in (audio.with_name(audio.stem + ".head.csv"), audio.with_suffix(".fap")):
            if candidate.exists():
                pairs.append((audio, candidate))
                break
    return pairs


def load_training_set(pairs: Iterable[tuple[Path, Path]], *, fps: float = DEFAULT_FPS,
                      report: Callable[[str], None] | None = None, speakers: dict[str, str] | None = None,
                      **analysis: Any) -> TrainingSet:
    """Extract features and read motion for each pair; a pair that fails or whose durations disagree by
    more than two frames is reported by name and skipped, never silently trimmed. ``speakers`` names the
    speaker of each recording stem (default: the :data:`SPEAKERS_FILE` of each pair's folder; a recording
    not named there is its own speaker)."""
    report = report or _LOG.info
    pairs = list(pairs)
    data = TrainingSet(fps=fps)
    folder_speakers: dict[Path, dict[str, str]] = {}
    for index, (audio, motion_path) in enumerate(pairs, start=1):
        try:
            features = extract_features(audio, fps=fps, **analysis)
            motion = fit_to_grid(read_motion(motion_path), n_frames=features.n_frames, fps=fps,
                                 source=str(motion_path))
            if not all(fap in motion.active_faps for fap in HEAD_FAPS):
                raise GroundTruthError(f"{motion_path}: no head rotation (FAP 48-50) in the recorded motion")
        except ProsodyError as error:
            data.skipped.append(f"{audio.stem}: {error}")
            report(f"[{index}/{len(pairs)}] skipped {audio.stem}: {error}")
            continue
        except ValueError as error:  # audio errors derive from ValueError too
            data.skipped.append(f"{audio.stem}: {error}")
            report(f"[{index}/{len(pairs)}] skipped {audio.stem}: {error}")
            continue
        data.names.append(audio.stem)
        known = speakers if speakers is not None else folder_speakers.setdefault(
            audio.parent, read_speakers(audio.parent))
        data.speakers.append(known.get(audio.stem, audio.stem))
        data.inputs.append(arx_inputs(features))
        data.features.append(features)
        data.motion_au.append(head_matrix(motion))  # stretches without a face bridged
        report(f"[{index}/{len(pairs)}] {audio.stem}: {features.n_frames} frames")
    return data


@dataclass(frozen=True)
class CrossValidation:
    """Leave-one-recording-out scores of one set of orders."""

    na: int
    nb: int
    nk: int
    ridge: float
    rmse_au: float
    pearson_per_axis: tuple[float, float, float]
    speed_envelope_r: float | None = None
    pitch_r: float | None = None


def leave_one_out(data: TrainingSet, *, na: int, nb: int, nk: int,
                  ridge: float = DEFAULT_RIDGE) -> CrossValidation:
    """Fit on every speaker but one, run free on that speaker's recordings; average over recordings."""
    folds = data.folds()
    if len(folds) < 2:
        raise ConfigError("cross-validation needs recordings of at least two speakers")
    errors, correlations, measures = [], [], []
    for fold in folds:
        keep = [i for i in range(len(data.names)) if i not in fold]
        model = ArxHeadModel(na, nb, nk, ridge=ridge).fit_arrays(
            [data.inputs[i] for i in keep], [data.motion_au[i] for i in keep], fps=data.fps)
        for held in fold:
            predicted = model.simulate_arrays(data.inputs[held])
            recorded = data.motion_au[held]
            errors.append(np.sqrt(np.mean((predicted - recorded) ** 2)))
            correlations.append([pearson(predicted[:, axis], recorded[:, axis]) or 0.0 for axis in range(3)])
            measures.append(head_metrics(predicted, recorded, fps=data.fps))
    mean_r = np.mean(correlations, axis=0)
    return CrossValidation(na, nb, nk, ridge, float(np.mean(errors)), (float(mean_r[0]), float(mean_r[1]),
                                                                  float(mean_r[2])),
                           mean_of(measures, "speed_envelope_r"), mean_of(measures, "pitch_r"))


def select_orders(data: TrainingSet, *, grid: dict[str, Sequence[float]] | None = None,
                  report: Callable[[str], None] | None = None) -> list[CrossValidation]:
    """Score every combination of orders and ridge penalties; best (lowest free-run RMSE) first."""
    chosen: dict[str, Sequence[float]] = dict(grid or DEFAULT_ORDER_GRID)
    report = report or _LOG.info
    combos = list(itertools.product(chosen["na"], chosen["nb"], chosen["nk"], chosen["ridge"]))
    results = []
    for index, (na, nb, nk, ridge) in enumerate(combos, start=1):
        result = leave_one_out(data, na=int(na), nb=int(nb), nk=int(nk), ridge=float(ridge))
        results.append(result)
        report(f"[cv {index}/{len(combos)}] na={na} nb={nb} nk={nk} ridge={ridge:g}: "
               f"free-run RMSE {result.rmse_au:.0f} AU, "
               f"r = {result.pearson_per_axis[0]:+.3f} {result.pearson_per_axis[1]:+.3f} "
               f"{result.pearson_per_axis[2]:+.3f}; speed-envelope r {signed(result.speed_envelope_r)}")
    return sorted(results, key=lambda r: r.rmse_au)


def signed(value: float | None) -> str:
    return "-" if value is None else f"{value:+.3f}"


def _head_array(curves: dict[int, np.ndarray]) -> np.ndarray:
    return np.column_stack([curves[fap] for fap in HEAD_FAPS])


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-recording-out measures of one prosodic setting: per recording, averaged over seeds, for
    the recording's own audio and for the mismatched-audio control."""

    settings: dict
    seeds: int
    per_recording: dict[str, dict]
    controls: dict[str, dict]

    def mean(self, key: str, *, control: bool = False) -> float | None:
        table = self.controls if control else self.per_recording
        return mean_of(list(table.values()), key)

    @property
    def score(self) -> float:
        """What cross-validation maximises: the held-out speed-envelope and pitch r, each above its control."""
        total = 0.0
        for key in ("speed_envelope_r", "pitch_r"):
            total += (self.mean(key) or 0.0) - (self.mean(key, control=True) or 0.0)
        return total


def held_out_prosodic(data: TrainingSet, settings: dict | None = None, *, seeds: int = CV_SEEDS,
                      controls: bool = True) -> HeldOut:
    """Fit the prosodic generator on every speaker but one and measure it on that speaker's recordings,
    each averaged over ``seeds`` seeds; with ``controls``, also driven by the held-out recording's own
    features circularly shifted (:func:`prosody.motion.controls.shift_offsets`)."""
    folds = data.folds()
    if len(folds) < 2:
        raise ConfigError("cross-validation needs recordings of at least two speakers")
    settings = dict(settings or {})
    per_recording, control_rows = {}, {}
    models = {}
    for fold in folds:
        keep = [i for i in range(len(data.names)) if i not in fold]
        fitted = ProsodicHeadModel(**settings).fit([data.features[i] for i in keep],
                                                   [data.motion_au[i] for i in keep])
        models.update({held: fitted for held in fold})
    for held, name in enumerate(data.names):
        model = models[held]
        features, recorded = data.features[held], data.motion_au[held]
        own, mismatched = [], []
        for seed in range(seeds):
            own.append(head_metrics(_head_array(model.generate(features, seed=seed)), recorded, fps=data.fps))
            if controls:
                for offset in shift_offsets(features.n_frames, fps=features.fps):
                    moved = model.generate(shifted_features(features, offset), seed=seed)
                    mismatched.append(head_metrics(_head_array(moved), recorded, fps=data.fps))
        per_recording[name] = average_head_metrics(own)
        if mismatched:
            control_rows[name] = average_head_metrics(mismatched)
    return HeldOut(settings, seeds, per_recording, control_rows)


def select_prosodic(data: TrainingSet, *, grid: dict[str, Sequence[float]] | None = None, seeds: int = 3,
                    report: Callable[[str], None] | None = None) -> list[HeldOut]:
    """Score every combination of :data:`PROSODIC_GRID` by :attr:`HeldOut.score`; best first."""
    chosen = dict(grid or PROSODIC_GRID)
    report = report or (lambda message: None)
    keys = list(chosen)
    combos = list(itertools.product(*(chosen[key] for key in keys)))
    results = []
    for index, values in enumerate(combos, start=1):
        settings = dict(zip(keys, values, strict=True))
        result = held_out_prosodic(data, settings, seeds=seeds)
        results.append(result)
        report(f"[cv {index}/{len(combos)}] {' '.join(f'{k}={v:g}' for k, v in settings.items())}: "
               f"speed-envelope r {signed(result.mean('speed_envelope_r'))} "
               f"(control {signed(result.mean('speed_envelope_r', control=True))}), "
               f"pitch r {signed(result.mean('pitch_r'))} (control {signed(result.mean('pitch_r', control=True))})")
    return sorted(results, key=lambda r: -r.score)


#: Lags of the Ljung-Box test on a fitted regression's residuals (a third of a second at 30 fps).
LJUNG_BOX_LAGS = 10


def _ljung_box(residuals: np.ndarray) -> float | None:
    """Ljung-Box p-value (statsmodels) that the residuals are uncorrelated up to :data:`LJUNG_BOX_LAGS`."""
    from statsmodels.stats.diagnostic import acorr_ljungbox  # checked by train(): the stats extra

    residuals = np.asarray(residuals, float)
    if residuals.size <= LJUNG_BOX_LAGS + 1 or residuals.std() == 0:
        return None
    return float(acorr_ljungbox(residuals, lags=[LJUNG_BOX_LAGS])["lb_pvalue"].iloc[0])


def diagnostics(model: ArxHeadModel | ProsodicHeadModel, data: TrainingSet) -> dict:
    """What a model file keeps about its fit: the Ljung-Box p-value of each fitted regression's residuals on
    each training recording (small: the residuals are correlated in time, so the regressions' own standard
    errors would be too small; the held-out measures are the figures to trust), and for an ARX model its poles.
    """
    if isinstance(model, ArxHeadModel):
        per_axis: dict[str, dict[str, float | None]] = {str(fap): {} for fap in HEAD_FAPS}
        for name, inputs, motion in zip(data.names, data.inputs, data.motion_au, strict=True):
            residuals = model.one_step_residuals(inputs, motion)
            for axis, fap in enumerate(HEAD_FAPS):
                per_axis[str(fap)][name] = _ljung_box(residuals[:, axis])
        poles = model.poles()
        return {"ljung_box_lags": LJUNG_BOX_LAGS, "ljung_box_p": per_axis,
                "poles": [[float(pole.real), float(pole.imag)] for pole in poles],
                "largest_pole_modulus": float(np.abs(poles).max()) if poles.size else 0.0}
    regressions: dict[str, dict[str, float | None]] = {"speed_envelope": {}, "pitch": {}}
    for name, features, motion in zip(data.names, data.features, data.motion_au, strict=True):
        for key, residuals in model.regression_residuals(features, motion).items():
            regressions[key][name] = _ljung_box(residuals)
    return {"ljung_box_lags": LJUNG_BOX_LAGS, "ljung_box_p": regressions}


def held_out_summary(result: HeldOut) -> dict:
    """The JSON form of a held-out evaluation: settings, seeds, means, and the per-recording tables."""
    keys = ("speed_envelope_r", "pitch_r", "velocity_spectrum_distance_db")
    return {
        "settings": result.settings,
        "seeds": result.seeds,
        "mean": {key: result.mean(key) for key in keys}
        | {"std_ratio": {axis: mean_of([r["std_ratio"] for r in result.per_recording.values()], axis)
                         for axis in ("48", "49", "50")}},
        "mean_mismatched_audio": {key: result.mean(key, control=True) for key in keys},
        "per_recording": result.per_recording,
        "mismatched_audio": result.controls,
    }


def train(directory: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], output: str | os.PathLike[str], *,
          kind: str = "prosodic",
          cv: bool = False, na: int = DEFAULT_NA, nb: int = DEFAULT_NB, nk: int = DEFAULT_NK,
          ridge: float = DEFAULT_RIDGE, fps: float = DEFAULT_FPS,
          report: Callable[[str], None] | None = None) -> ArxHeadModel | ProsodicHeadModel:
    """Train a head model on every pair in ``directory`` (a folder, or several) and save it to ``output``
    (JSON). Cross-validation holds out one speaker at a time: each folder's :data:`SPEAKERS_FILE`, if any,
    says which recordings share a speaker (otherwise every recording is its own).

    Parameters
    ----------
    kind : {"prosodic", "arx", "pad"}
        ``prosodic``: the default generator; with ``cv`` its settings are chosen from
        :data:`PROSODIC_GRID` by leave-one-recording-out speed-envelope and pitch r above the
        mismatched-audio control, and the chosen setting's held-out measures (over :data:`CV_SEEDS` seeds)
        are stored in the model file. ``arx``: the thesis's model; with ``cv`` the orders and the ridge
        penalty are chosen over :data:`DEFAULT_ORDER_GRID` by free-run error, otherwise ``na``, ``nb``,
        ``nk``, ``ridge`` are used as given. ``pad``: Jia et al.'s gestures with Eq. 2's arousal coefficients
        fitted to the recordings (:func:`prosody.motion.heads.pad.fit_arousal`); with ``cv`` their held-out
        figures (:func:`prosody.motion.heads.pad.held_out_arousal`) are stored in the model file.
    """
    if kind not in MODEL_KINDS:
        raise ConfigError(f"kind must be one of {', '.join(MODEL_KINDS)}, got {kind!r}")
    if kind != "pad":  # the regressions' residual diagnostics (Ljung-Box) are statsmodels'
        require_extra(("statsmodels",), "stats", f"training a {kind} head model")
    report = report or _LOG.info
    folders = [directory] if isinstance(directory, (str, os.PathLike)) else list(directory)
    pairs = [pair for folder in folders for pair in find_pairs(folder)]
    if not pairs:
        raise ConfigError(f"{', '.join(map(str, folders))}: no <name>.wav with <name>.head.csv or <name>.fap found")
    stems: dict[str, Path] = {}
    for audio, _ in pairs:
        if audio.stem in stems:
            raise ConfigError(f"{stems[audio.stem]} and {audio} have the same name; recordings must be told apart "
                              "by name")
        stems[audio.stem] = audio
    directory = ", ".join(map(str, folders))
    data = load_training_set(pairs, fps=fps, report=report)
    if not data.names:
        raise GroundTruthError(f"{directory}: every pair was skipped; nothing to train on")
    try:
        return _train_loaded(data, directory, output, kind=kind, cv=cv, na=na, nb=nb, nk=nk, ridge=ridge, fps=fps,
                             report=report)
    except ConfigError as error:
        # what the recordings cannot give (too short, too still, too few) is a problem of the data: name it
        raise GroundTruthError(f"{directory}: {error}") from None


def _train_loaded(data: TrainingSet, directory: str | os.PathLike[str], output: str | os.PathLike[str], *,
                  kind: str, cv: bool, na: int, nb: int, nk: int, ridge: float, fps: float,
                  report: Callable[[str], None]) -> ArxHeadModel | ProsodicHeadModel:
    extra: dict = {"skipped": data.skipped}
    model: ArxHeadModel | ProsodicHeadModel
    if kind == "prosodic":
        settings: dict = {}
        if cv:
            ranking = select_prosodic(data, report=report)
            settings = ranking[0].settings
            final = held_out_prosodic(data, settings, seeds=CV_SEEDS)
            extra["cross_validation"] = held_out_summary(final)
            report(f"chosen {' '.join(f'{k}={v:g}' for k, v in settings.items())}; held out over {CV_SEEDS} seeds: "
                   f"speed-envelope r {signed(final.mean('speed_envelope_r'))} "
                   f"(mismatched audio {signed(final.mean('speed_envelope_r', control=True))}), "
                   f"pitch r {signed(final.mean('pitch_r'))} "
                   f"(mismatched audio {signed(final.mean('pitch_r', control=True))})")
        model = ProsodicHeadModel(**settings).fit(data.features, data.motion_au, names=data.names)
        extra["diagnostics"] = diagnostics(model, data)
        model.save(output, extra=extra)
        report(f"{output}: prosodic head model trained on {len(data.names)} recordings "
               f"({sum(c.duration_s for c in model.training_):.1f} s)")
        return model
    if kind == "pad":
        return _train_pad(data, output, cv=cv, fps=fps, extra=extra, report=report)
    if cv:
        ranking_arx = select_orders(data, report=report)
        best = ranking_arx[0]
        na, nb, nk, ridge = best.na, best.nb, best.nk, best.ridge
        extra["cross_validation"] = [result.__dict__ | {"pearson_per_axis": list(result.pearson_per_axis)}
                                     for result in ranking_arx]
        report(f"chosen orders na={na} nb={nb} nk={nk}, ridge {ridge:g} (free-run RMSE {best.rmse_au:.0f} AU)")
    model = ArxHeadModel(na, nb, nk, ridge=ridge).fit_arrays(data.inputs, data.motion_au, fps=fps,
                                                             names=data.names,
                                                             sources=[f.source for f in data.features])
    extra["diagnostics"] = diagnostics(model, data)
    model.save(output, extra=extra)
    report(f"{output}: trained on {len(data.names)} recordings "
           f"({sum(c.duration_s for c in model.training_):.1f} s), spectral radius {model.spectral_radius_:.3f}")
    return model


def _train_pad(data: TrainingSet, output: str | os.PathLike[str], *, cv: bool, fps: float, extra: dict,
               report: Callable[[str], None]):
    """Jia et al.'s gestures with C1-C6 fitted to the recordings' amplitude per PW and pause (see ``train``)."""
    from ..model_files import TrainingClip
    from .pad import PadHeadModel, amplitude, arousal_amplitudes, fit_arousal, held_out_arousal

    per_recording = [arousal_amplitudes(f, m) for f, m in zip(data.features, data.motion_au, strict=True)]
    arousal = np.concatenate([a for a, _ in per_recording])
    if arousal.size < 12:
        raise ConfigError(f"only {arousal.size} prosodic words and pauses long enough to measure; fitting Eq. 2 "
                          "needs at least 12")
    model = PadHeadModel(coefficients=fit_arousal(arousal, np.vstack([y for _, y in per_recording])))
    model.training_ = [TrainingClip.of(name, f.n_frames, fps, f.source)
                       for name, f in zip(data.names, data.features, strict=True)]
    if cv:
        held = held_out_arousal(per_recording, data.folds())
        extra["cross_validation"] = held
        report(f"held out by speaker ({held['folds']} folds, {held['stretches']} stretches): r of Amp(0, A) with the "
               "recorded amplitude " + ", ".join(
                   f"{axis} {held[axis]['r']:+.2f} (chance {held[axis]['chance_r']:+.2f} ± "
                   f"{held[axis]['chance_spread']:.2f})" for axis in ("pitch", "yaw", "roll")))
    model.save(output, extra=extra)
    neutral = ", ".join(f"{name} {amplitude(0.0, 0.5, c):.2f}" for name, c in zip(
        ("pitch", "yaw", "roll"), model.coefficients_, strict=True))
    report(f"{output}: PAD gesture model fitted on {len(data.names)} recordings ({arousal.size} PWs and pauses); "
           f"Amp(0, 0.5) {neutral} deg")
    return model
