"""Training the ARX head model on a folder of paired recordings, with order selection by
leave-one-recording-out cross-validation scored on free-run error."""

from __future__ import annotations

import itertools
import os
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from audio_features import AUDIO_EXTENSIONS, extract_features

from .errors import ConfigError, GroundTruthError, ProsodyError
from .fap_table import HEAD_FAPS
from .ground_truth import fit_to_grid, read_motion
from .head import ArxHeadModel, arx_inputs
from .metrics import pearson

#: Orders tried by cross-validation.
DEFAULT_ORDER_GRID = {"na": (1, 2, 4), "nb": (1, 5, 15), "nk": (0, 5), "ridge": (0.01, 0.1, 1.0)}


@dataclass
class TrainingSet:
    """Paired recordings ready for fitting: ARX inputs and recorded head motion (AU) per recording."""

    names: list[str] = field(default_factory=list)
    inputs: list[np.ndarray] = field(default_factory=list)
    motion_au: list[np.ndarray] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    fps: float = 30.0


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


def load_training_set(pairs: Iterable[tuple[Path, Path]], *, fps: float = 30.0,
                      report: Callable[[str], None] | None = None, **analysis: float) -> TrainingSet:
    """Extract features and read motion for each pair; a pair that fails or whose durations disagree by
    more than two frames is reported by name and skipped, never silently trimmed."""
    report = report or (lambda message: print(message, file=sys.stderr))
    pairs = list(pairs)
    data = TrainingSet(fps=fps)
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
        data.inputs.append(arx_inputs(features))
        data.motion_au.append(motion.curves(HEAD_FAPS))
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


def leave_one_out(data: TrainingSet, *, na: int, nb: int, nk: int, ridge: float = 0.1) -> CrossValidation:
    """Fit on all recordings but one, run free on the one left out; average over recordings."""
    if len(data.names) < 2:
        raise ConfigError("cross-validation needs at least two recordings")
    errors, correlations = [], []
    for held in range(len(data.names)):
        keep = [i for i in range(len(data.names)) if i != held]
        model = ArxHeadModel(na, nb, nk, ridge=ridge).fit_arrays(
            [data.inputs[i] for i in keep], [data.motion_au[i] for i in keep], fps=data.fps)
        predicted = model.simulate_arrays(data.inputs[held])
        recorded = data.motion_au[held]
        errors.append(np.sqrt(np.mean((predicted - recorded) ** 2)))
        correlations.append([pearson(predicted[:, axis], recorded[:, axis]) or 0.0 for axis in range(3)])
    mean_r = np.mean(correlations, axis=0)
    return CrossValidation(na, nb, nk, ridge, float(np.mean(errors)), (float(mean_r[0]), float(mean_r[1]),
                                                                  float(mean_r[2])))


def select_orders(data: TrainingSet, *, grid: dict[str, Sequence[float]] | None = None,
                  report: Callable[[str], None] | None = None) -> list[CrossValidation]:
    """Score every combination of orders and ridge penalties; best (lowest free-run RMSE) first."""
    chosen: dict[str, Sequence[float]] = dict(grid or DEFAULT_ORDER_GRID)
    report = report or (lambda message: print(message, file=sys.stderr))
    combos = list(itertools.product(chosen["na"], chosen["nb"], chosen["nk"], chosen["ridge"]))
    results = []
    for index, (na, nb, nk, ridge) in enumerate(combos, start=1):
        result = leave_one_out(data, na=int(na), nb=int(nb), nk=int(nk), ridge=float(ridge))
        results.append(result)
        report(f"[cv {index}/{len(combos)}] na={na} nb={nb} nk={nk} ridge={ridge:g}: "
               f"free-run RMSE {result.rmse_au:.0f} AU, "
               f"r = {result.pearson_per_axis[0]:+.3f} {result.pearson_per_axis[1]:+.3f} "
               f"{result.pearson_per_axis[2]:+.3f}")
    return sorted(results, key=lambda r: r.rmse_au)


def train(directory: str | os.PathLike[str], output: str | os.PathLike[str], *, cv: bool = False,
          na: int = 1, nb: int = 5, nk: int = 0, ridge: float = 0.1, fps: float = 30.0,
          report: Callable[[str], None] | None = None) -> ArxHeadModel:
    """Train a head model on every pair in ``directory`` and save it to ``output`` (JSON).

    With ``cv`` the orders and the ridge penalty are chosen by leave-one-recording-out cross-validation
    over :data:`DEFAULT_ORDER_GRID`; otherwise ``na``, ``nb``, ``nk``, ``ridge`` are used as given.
    """
    report = report or (lambda message: print(message, file=sys.stderr))
    pairs = find_pairs(directory)
    if not pairs:
        raise ConfigError(f"{directory}: no <name>.wav with <name>.head.csv or <name>.fap found")
    data = load_training_set(pairs, fps=fps, report=report)
    if not data.names:
        raise GroundTruthError(f"{directory}: every pair was skipped; nothing to train on")
    extra: dict = {"skipped": data.skipped}
    if cv:
        ranking = select_orders(data, report=report)
        best = ranking[0]
        na, nb, nk, ridge = best.na, best.nb, best.nk, best.ridge
        extra["cross_validation"] = [result.__dict__ | {"pearson_per_axis": list(result.pearson_per_axis)}
                                     for result in ranking]
        report(f"chosen orders na={na} nb={nb} nk={nk}, ridge {ridge:g} (free-run RMSE {best.rmse_au:.0f} AU)")
    model = ArxHeadModel(na, nb, nk, ridge=ridge).fit_arrays(data.inputs, data.motion_au, fps=fps,
                                                             names=data.names)
    model.save(output, extra=extra)
    report(f"{output}: trained on {len(data.names)} recordings "
           f"({sum(c.duration_s for c in model.training_):.1f} s), spectral radius {model.spectral_radius_:.3f}")
    return model
