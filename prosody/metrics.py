"""Objective comparison of conditions (SPEC section 6): motion statistics, agreement with ground truth,
canonical correlation, and the thesis's mean/spread normalisation."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .errors import ConfigError
from .fap_table import HEAD_FAPS, PROSODY_FAPS
from .stream import FapStream

#: Spread below which a curve counts as constant (correlations are then undefined).
_CONSTANT = 1e-9


def pearson(a: np.ndarray, b: np.ndarray) -> float | None:
    """Pearson correlation of two curves; None where either is constant (undefined).

    Examples
    --------
    >>> pearson(np.array([1.0, 2.0, 3.0]), np.array([2.0, 4.0, 7.0]))
    0.9933992677987828
    >>> pearson(np.zeros(3), np.arange(3.0)) is None
    True
    """
    a = np.asarray(a, float) - np.mean(a)
    b = np.asarray(b, float) - np.mean(b)
    denominator = np.sqrt((a * a).sum() * (b * b).sum())
    if denominator <= _CONSTANT * max(1.0, np.sqrt(a.size)):
        return None
    return float(np.clip((a * b).sum() / denominator, -1.0, 1.0))


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean square difference of two curves of the same length."""
    return float(np.sqrt(np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)))


def canonical_correlations(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Canonical correlations between the columns of ``x`` (n, p) and ``y`` (n, q), largest first.

    The singular values of ``Qx.T @ Qy``, with ``Qx``, ``Qy`` orthonormal bases of the centred data;
    constant columns are dropped. Returns an empty array when either side has no varying column.

    Examples
    --------
    >>> t = np.arange(100.0)
    >>> x = np.column_stack([np.sin(t), np.cos(t)])
    >>> canonical_correlations(x, x @ [[1.0, 2.0], [0.5, -1.0]]).round(6).tolist()
    [1.0, 1.0]
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.ndim == 1:
        x = x[:, None]
    if y.ndim == 1:
        y = y[:, None]
    if x.shape[0] != y.shape[0]:
        raise ConfigError(f"CCA needs the same number of frames, got {x.shape[0]} and {y.shape[0]}")
    bases = []
    for data in (x, y):
        centred = data - data.mean(axis=0)
        centred = centred[:, centred.std(axis=0) > _CONSTANT]
        if centred.shape[1] == 0:
            return np.zeros(0)
        # an orthonormal basis of the column space, rank-revealing through the SVD
        u, s, _ = np.linalg.svd(centred, full_matrices=False)
        bases.append(u[:, s > s[0] * 1e-10])
    return np.clip(np.linalg.svd(bases[0].T @ bases[1], compute_uv=False), 0.0, 1.0)


def first_canonical_correlation(x: np.ndarray, y: np.ndarray) -> float | None:
    """The largest canonical correlation, None where undefined (a constant side)."""
    values = canonical_correlations(x, y)
    return float(values[0]) if values.size else None


def fap_statistics(stream: FapStream, truth: FapStream | None, faps=PROSODY_FAPS) -> dict[str, dict]:
    """Per FAP: mean and standard deviation over the frames where it is active; Pearson r and RMSE
    against ``truth`` where the truth has that FAP (None otherwise, or where r is undefined).

    Returns
    -------
    dict
        ``{"<fap>": {"mean": float or None, "std": float or None, "pearson_r": float or None,
        "rmse": float or None}}``; mean and std are None for a FAP the stream does not carry.
    """
    result: dict[str, dict] = {}
    for fap in faps:
        active = stream.mask[:, fap - 1]
        curve = stream.values[:, fap - 1]
        entry: dict[str, float | None] = {"mean": None, "std": None, "pearson_r": None, "rmse": None}
        if active.any():
            entry["mean"] = float(curve[active].mean())
            entry["std"] = float(curve[active].std())
        if truth is not None and active.any():
            both = active & truth.mask[:, fap - 1]
            if both.any():
                reference = truth.values[both, fap - 1]
                entry["pearson_r"] = pearson(curve[both], reference)
                entry["rmse"] = rmse(curve[both], reference)
        result[str(fap)] = entry
    return result


def normalization_targets(streams: Mapping[Any, FapStream], *, reference: FapStream | None = None,
                          given: Mapping[int, tuple[float, float]] | None = None,
                          faps=PROSODY_FAPS) -> dict[int, tuple[float, float]]:
    """Target ``(mean, std)`` per FAP: the reference's (ground truth) where it carries the FAP, else the
    ``given`` value, else the average of the streams' own means and spreads."""
    given = dict(given or {})
    targets: dict[int, tuple[float, float]] = {}
    for fap in faps:
        if reference is not None and reference.mask[:, fap - 1].any():
            curve = reference.values[reference.mask[:, fap - 1], fap - 1]
            targets[fap] = (float(curve.mean()), float(curve.std()))
        elif fap in given:
            targets[fap] = given[fap]
        else:
            stats = [(s.values[s.mask[:, fap - 1], fap - 1].mean(), s.values[s.mask[:, fap - 1], fap - 1].std())
                     for s in streams.values() if s.mask[:, fap - 1].any()]
            if stats:
                targets[fap] = (float(np.mean([m for m, _ in stats])), float(np.mean([d for _, d in stats])))
    return targets


def normalize_stream(stream: FapStream, targets: Mapping[int, tuple[float, float]]) -> FapStream:
    """Scale and offset each targeted FAP so that its mean and standard deviation equal the target
    (the thesis's second experiment). A constant curve can only be moved: it gets the target mean."""
    curves = {}
    for fap, (mean, std) in targets.items():
        active = stream.mask[:, fap - 1]
        if not active.any():
            continue
        curve = stream.values[:, fap - 1].copy()
        spread = curve[active].std()
        scale = std / spread if spread > _CONSTANT else 0.0
        curve[active] = (curve[active] - curve[active].mean()) * scale + mean
        curves[fap] = curve
    values = stream.values.copy()
    for fap, curve in curves.items():
        values[:, fap - 1] = curve
    return FapStream(values, stream.mask, stream.fps, stream.name)


def head_matrix(stream: FapStream) -> np.ndarray:
    """Head pitch, yaw, roll (AU) as columns, shape (n_frames, 3)."""
    return stream.curves(HEAD_FAPS)
