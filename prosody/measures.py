"""Objective comparison of conditions (docs/evaluation.md): motion statistics, agreement with ground truth,
canonical correlation, and the thesis's mean/spread normalisation."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .dsp import head_speed, lowpass_head, speed_envelope
from .errors import ConfigError
from .fap.stream import FapStream
from .fap.table import HEAD_FAPS, PROSODY_FAPS, RADIANS_PER_AU

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


def head_measured(stream: FapStream) -> np.ndarray:
    """Frames whose head rotation (FAP 48-50) is all there, shape (n_frames,): False in stretches a face
    tracker lost (see :func:`prosody.fap.recorded.read_head_csv`)."""
    return np.asarray(stream.mask[:, [fap - 1 for fap in HEAD_FAPS]].all(axis=1), dtype=bool)


def head_matrix(stream: FapStream) -> np.ndarray:
    """Head pitch, yaw, roll (AU) as columns, shape (n_frames, 3); frames without them (masked off) are
    bridged by linear interpolation between the frames that have them."""
    angles = stream.curves(HEAD_FAPS)
    known = head_measured(stream)
    if known.any() and not known.all():
        frames = np.arange(angles.shape[0])
        angles = np.column_stack([np.interp(frames, frames[known], angles[known, axis]) for axis in range(3)])
    return angles


# Head-motion measures that discriminate at our data sizes (docs/evaluation.md) --------------------
#: Welch segment length and frequency band of the velocity-spectrum distance.
SPECTRUM_SEGMENT_FRAMES = 64
SPECTRUM_BAND_HZ = (0.25, 4.0)


def velocity_spectrum_distance_db(generated_rad: np.ndarray, recorded_rad: np.ndarray, *, fps: float) -> float | None:
    """RMS over 0.25-4 Hz of ``10 log10(P_generated / P_recorded)``, P the Welch spectrum (64-frame
    segments) of each axis's frame-to-frame velocity of the raw angles, averaged over the axes, in dB.

    0 dB is a head whose motion has the recording's size and tempo; a still head or a jittery one scores
    high. None where a spectrum is zero (a still axis) or the curves are too short for one segment.
    """
    from scipy.signal import welch

    generated = np.atleast_2d(np.asarray(generated_rad, float).T).T
    recorded = np.atleast_2d(np.asarray(recorded_rad, float).T).T
    if generated.shape[0] < SPECTRUM_SEGMENT_FRAMES + 1:
        return None
    distances = []
    for axis in range(generated.shape[1]):
        frequencies, p_generated = welch(np.diff(generated[:, axis]), fs=fps, nperseg=SPECTRUM_SEGMENT_FRAMES)
        _, p_recorded = welch(np.diff(recorded[:, axis]), fs=fps, nperseg=SPECTRUM_SEGMENT_FRAMES)
        band = (frequencies >= SPECTRUM_BAND_HZ[0]) & (frequencies <= SPECTRUM_BAND_HZ[1])
        if np.any(p_generated[band] <= 0) or np.any(p_recorded[band] <= 0):
            return None
        ratio_db = 10 * np.log10(p_generated[band] / p_recorded[band])
        distances.append(float(np.sqrt(np.mean(ratio_db**2))))
    return float(np.mean(distances))


#: Percentiles of the angular speed compared, and the speed below which the head counts as nearly still.
SPEED_PERCENTILES = (10, 50, 90)
STILL_DEG_S = 2.0


def speed_distribution(angles_rad: np.ndarray, *, fps: float, measured: np.ndarray | None = None) -> dict:
    """How the head moves in bursts and holds: the 10th, 50th and 90th percentiles of its angular speed
    (deg/s, of the 4 Hz low-passed angles), the fraction of time it is nearly still (under 2 deg/s), and
    where it holds: the median, over the nearly still frames, of the angle between the head and its median
    pose (deg, the three axes together; None without a still frame). People hold the head turned or tilted
    as often as straight; a head that only holds at its rest pose scores near 0.

    Examples
    --------
    >>> fps = 30.0
    >>> t = np.arange(300) / fps
    >>> still_then_turning = np.column_stack([np.where(t < 5, 0.0, np.radians(10) * (t - 5)), 0 * t, 0 * t])
    >>> d = speed_distribution(still_then_turning, fps=fps)
    >>> round(d["still_fraction"], 1), round(d["p90_deg_s"], 1)
    (0.5, 10.0)

    Held turned 10 degrees left, a turn of 1 s, held 10 degrees right: still 89 % of the time, 10 degrees
    from the median pose (straight ahead) while still, less the turn's ends softened by the low-pass:

    >>> left_then_right = np.column_stack([0 * t, np.radians(np.clip(20 * (t - 5), -10, 10)), 0 * t])
    >>> d = speed_distribution(left_then_right, fps=fps)
    >>> round(d["still_fraction"], 2), round(d["still_offset_deg"], 1)
    (0.89, 9.8)
    """
    smooth = lowpass_head(np.asarray(angles_rad, float), fps=fps)
    speed = np.degrees(head_speed(np.asarray(angles_rad, float), fps=fps))
    keep = np.ones(speed.size, bool) if measured is None else np.asarray(measured, bool)
    speed, smooth = speed[keep], smooth[keep]
    if speed.size == 0:
        return {**{f"p{p}_deg_s": None for p in SPEED_PERCENTILES}, "still_fraction": None,
                "still_offset_deg": None}
    values = np.percentile(speed, SPEED_PERCENTILES)
    still = speed < STILL_DEG_S
    offset = None
    if still.any():
        away = smooth[still] - np.median(smooth, axis=0)
        offset = float(np.degrees(np.median(np.sqrt((away.reshape(away.shape[0], -1) ** 2).sum(axis=1)))))
    return {**{f"p{p}_deg_s": float(v) for p, v in zip(SPEED_PERCENTILES, values, strict=True)},
            "still_fraction": float(np.mean(still)), "still_offset_deg": offset}


def head_metrics(generated_au: np.ndarray, recorded_au: np.ndarray, *, fps: float,
                 measured: np.ndarray | None = None) -> dict:
    """The head measures of one generated motion against the recording, both (n_frames, 3) in AU
    (FAP 48, 49, 50).

    ``measured`` (bool, (n_frames,)) leaves the other frames out of the correlations and spreads: stretches
    where the recording lost the face. Speeds are taken on the whole (bridged) curves and then compared on
    the measured frames only; the velocity spectrum uses the whole curves.

    Returns
    -------
    dict
        ``{"speed_envelope_r", "pitch_r", "std_ratio": {"48", "49", "50"}, "velocity_spectrum_distance_db",
        "yaw_r", "roll_r", "speed_p10_ratio", "speed_p50_ratio", "speed_p90_ratio", "still_fraction",
        "recorded_still_fraction", "still_offset_deg", "recorded_still_offset_deg"}``: the ratios are
        generated / recorded percentiles of the angular speed, the fractions the time each is nearly still, the
        offsets how far from its median pose each holds (deg; :func:`speed_distribution`); None where
        undefined (a still head has no correlation).
    """
    generated = np.asarray(generated_au, float) * RADIANS_PER_AU
    recorded = np.asarray(recorded_au, float) * RADIANS_PER_AU
    if generated.shape != recorded.shape or generated.ndim != 2 or generated.shape[1] != len(HEAD_FAPS):
        raise ConfigError(f"head motion must be (n_frames, 3) on one grid, got {generated.shape} and "
                          f"{recorded.shape}")
    keep = np.ones(generated.shape[0], bool) if measured is None else np.asarray(measured, bool)
    if keep.shape != (generated.shape[0],):
        raise ConfigError(f"measured must be (n_frames,) = ({generated.shape[0]},), got {keep.shape}")
    recorded_std = recorded[keep].std(axis=0)
    ratios = {str(fap): (float(generated[keep, axis].std() / recorded_std[axis]) if recorded_std[axis] > 0
                         else None)
              for axis, fap in enumerate(HEAD_FAPS)}
    own = speed_distribution(generated, fps=fps, measured=keep)
    theirs = speed_distribution(recorded, fps=fps, measured=keep)

    def ratio(key: str) -> float | None:
        mine, reference = own[key], theirs[key]
        return float(mine / reference) if mine is not None and reference else None

    return {
        "speed_envelope_r": pearson(speed_envelope(generated, fps=fps)[keep], speed_envelope(recorded, fps=fps)[keep]),
        "pitch_r": pearson(generated[keep, 0], recorded[keep, 0]),
        "std_ratio": ratios,
        "velocity_spectrum_distance_db": velocity_spectrum_distance_db(generated, recorded, fps=fps),
        "yaw_r": pearson(generated[keep, 1], recorded[keep, 1]),
        "roll_r": pearson(generated[keep, 2], recorded[keep, 2]),
        **{f"speed_p{p}_ratio": ratio(f"p{p}_deg_s") for p in SPEED_PERCENTILES},
        "still_fraction": own["still_fraction"],
        "recorded_still_fraction": theirs["still_fraction"],
        "still_offset_deg": own["still_offset_deg"],
        "recorded_still_offset_deg": theirs["still_offset_deg"],
    }


# Eyebrow measures against recorded brow motion ---------------------------------------------------------
#: Recorded brow height above its running baseline that counts as a raise, in units of the recording's
#: robust spread (median absolute deviation x 1.4826), with a floor in ENS.
BROW_EVENT_SPREADS = 1.0
BROW_EVENT_FLOOR_ENS = 3.0
#: Shortest recorded raise (s); running-baseline window (s); onset matching tolerance (s).
BROW_EVENT_MIN_S = 0.15
BROW_BASELINE_S = 3.0
ONSET_TOLERANCE_S = 0.3


def _runs(active: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of each run of True (stop exclusive)."""
    edges = np.diff(np.concatenate([[0], active.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True))


def brow_events(brow_ens: np.ndarray, *, fps: float) -> list[tuple[int, int]]:
    """Raises in a recorded brow curve: runs of at least 150 ms where the 4 Hz low-passed height stands
    above its running median (3 s) by more than one robust spread (and at least 3 ENS).

    Returns
    -------
    list of (onset_frame, end_frame)
    """
    from scipy.ndimage import median_filter

    curve = lowpass_head(np.asarray(brow_ens, float), fps=fps)
    if curve.size == 0:
        return []
    baseline = median_filter(curve, size=max(1, int(round(BROW_BASELINE_S * fps))), mode="nearest")
    excess = curve - baseline
    spread = 1.4826 * float(np.median(np.abs(excess - np.median(excess))))
    threshold = max(BROW_EVENT_SPREADS * spread, BROW_EVENT_FLOOR_ENS)
    shortest = max(1, int(round(BROW_EVENT_MIN_S * fps)))
    return [(a, b) for a, b in _runs(excess > threshold) if b - a >= shortest]


def generated_brow_events(brow_ens: np.ndarray) -> list[tuple[int, int]]:
    """Raises of a generated brow curve: the runs where it is above zero (its rest)."""
    return _runs(np.asarray(brow_ens, float) > 1e-9)


def onset_agreement(generated: list[tuple[int, int]], recorded: list[tuple[int, int]], *, fps: float) -> dict:
    """How well raise onsets match: precision (generated onsets within 0.3 s of a recorded one), recall
    (recorded onsets within 0.3 s of a generated one) and their F1; None where a side has no raise."""
    tolerance = ONSET_TOLERANCE_S * fps
    if not generated or not recorded:
        return {"precision": None, "recall": None, "f1": None}
    ours = np.array([a for a, _ in generated], float)
    theirs = np.array([a for a, _ in recorded], float)
    precision = float(np.mean([np.min(np.abs(theirs - a)) <= tolerance for a in ours]))
    recall = float(np.mean([np.min(np.abs(ours - a)) <= tolerance for a in theirs]))
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return {"precision": precision, "recall": recall, "f1": f1}


def brow_metrics(generated_ens: np.ndarray, recorded_ens: np.ndarray, *, fps: float) -> dict:
    """Eyebrow measures of a generated inner-brow curve (FAP 31, ENS) against a recorded one.

    Raises of a curve that never goes below 0 are its runs above 0 (generated brows rest at 0); those of a
    curve that does (recorded brows, about their median) are found as in the recording (:func:`brow_events`).

    Returns
    -------
    dict
        ``{"raise_r"}``: Pearson r of the generated raise with the 4 Hz low-passed recorded height;
        ``"onsets": {"precision", "recall", "f1"}`` (see :func:`onset_agreement`); ``"raises"`` and
        ``"recorded_raises"``: counts; ``"median_raise_s"`` and ``"recorded_median_raise_s"``: durations.
        None where undefined.
    """
    generated = np.asarray(generated_ens, float)
    recorded = np.asarray(recorded_ens, float)
    # a generated raise rests at 0; a curve that goes below it is recorded motion, read as the recording is
    recorded_like = generated.size > 0 and generated.min() < 0
    ours = brow_events(generated, fps=fps) if recorded_like else generated_brow_events(generated)
    theirs = brow_events(recorded, fps=fps)

    def median_s(events: list[tuple[int, int]]) -> float | None:
        return float(np.median([b - a for a, b in events]) / fps) if events else None

    return {
        "raise_r": pearson(generated, lowpass_head(recorded, fps=fps)) if recorded.size else None,
        "onsets": onset_agreement(ours, theirs, fps=fps),
        "raises": len(ours),
        "recorded_raises": len(theirs),
        "median_raise_s": median_s(ours),
        "recorded_median_raise_s": median_s(theirs),
    }


# averaging measures over runs (seeds, control offsets, recordings) ------------------------------------------
HEAD_MEASURES = ("speed_envelope_r", "pitch_r", "velocity_spectrum_distance_db", "yaw_r", "roll_r",
                 "speed_p10_ratio", "speed_p50_ratio", "speed_p90_ratio", "still_fraction", "recorded_still_fraction",
                 "still_offset_deg", "recorded_still_offset_deg")
BROW_MEASURES = ("raise_r", "raises", "recorded_raises", "median_raise_s", "recorded_median_raise_s")


def mean_of(rows: Sequence[dict], key: str) -> float | None:
    """Mean of ``row[key]`` over the rows where it is not None; None if it is None everywhere."""
    values = [row[key] for row in rows if row.get(key) is not None]
    return float(np.mean(values)) if values else None


#: Each block of measures: its single values, and the name and keys of its one nested group.
_HEAD_LAYOUT = (HEAD_MEASURES, "std_ratio", ("48", "49", "50"))
_BROW_LAYOUT = (BROW_MEASURES, "onsets", ("precision", "recall", "f1"))


def _empty_block(layout: tuple) -> dict:
    values, nested, keys = layout
    return {**dict.fromkeys(values), nested: dict.fromkeys(keys)}


def _average_block(rows: Sequence[dict], layout: tuple) -> dict:
    """The mean of blocks of measures (None entries left out), in their layout."""
    values, nested, keys = layout
    if not rows:
        return _empty_block(layout)
    result: dict = {key: mean_of(rows, key) for key in values}
    result[nested] = {key: mean_of([row[nested] for row in rows], key) for key in keys}
    return result


def empty_head_metrics() -> dict:
    """The head block where it is undefined (no recorded head to compare with)."""
    return _empty_block(_HEAD_LAYOUT)


def empty_brow_metrics() -> dict:
    """The brow block where it is undefined (no recorded brows, or a condition without brows)."""
    return _empty_block(_BROW_LAYOUT)


def average_head_metrics(rows: Sequence[dict]) -> dict:
    """The mean of :func:`head_metrics` results (None entries left out), in the same layout."""
    return _average_block(rows, _HEAD_LAYOUT)


def average_brow_metrics(rows: Sequence[dict]) -> dict:
    """The mean of :func:`brow_metrics` results (None entries left out), in the same layout."""
    return _average_block(rows, _BROW_LAYOUT)


# the mouth (docs/evaluation.md: lips) ------------------------------------------------------------
#: Low-pass of the recorded lip opening, Hz.
MOUTH_LOWPASS_HZ = 8.0
#: Largest audio-video lag searched for the mouth's agreement, s.
MOUTH_MAX_LAG_S = 0.25
#: Recorded closures: frames in this lowest fraction of the lip opening.
CLOSED_FRACTION = 0.2
#: Generated closures: an inner-lip opening at or below this, MNS (under a millimetre on an adult face).
CLOSED_OPENING_MNS = 40.0
MOUTH_MEASURES = ("opening_r", "lag_s", "rounding_r")


def _filled(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``values`` with missing frames (NaN) interpolated for filtering, and the mask of the known ones."""
    values = np.asarray(values, float)
    known = np.isfinite(values)
    if not known.any():
        return np.zeros_like(values), known
    index = np.arange(values.size)
    return np.interp(index, index[known], values[known]), known


def _lagged(generated: np.ndarray, recorded: np.ndarray, lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Recorded frame ``k`` against generated frame ``k + lag``."""
    if lag >= 0:
        return generated[lag:], recorded[:recorded.size - lag]
    return generated[:generated.size + lag], recorded[-lag:]


def mouth_metrics(generated_opening_mns: np.ndarray, generated_rounding: np.ndarray, recorded_opening: np.ndarray,
                  recorded_rounding: np.ndarray, *, fps: float, lag_frames: int | None = None) -> dict:
    """How well generated lips follow recorded ones.

    Parameters
    ----------
    generated_opening_mns : array (n,)
        Inner-lip opening ``FAP 3 - FAP 4 - FAP 5``, MNS.
    generated_rounding : array (n,)
        Lip protrusion (FAP 16 + 17 or any monotone measure of it).
    recorded_opening, recorded_rounding : array (n,)
        The tracked ``lip_opening`` and ``mouth_funnel + mouth_pucker``; NaN where no face was found (left out).
    fps : float > 0
    lag_frames : int, optional
        Use this lag instead of searching (a control is measured at the lag of the speech it stands beside).

    Returns
    -------
    dict
        ``opening_r`` (Pearson r of the opening with the recorded one low-passed at 8 Hz, at the best lag
        within +-0.25 s), ``lag_s`` (that lag: positive when the recording moves earlier than the generated
        lips), ``closures`` (``precision``, ``recall``, ``f1`` of generated closures, opening <= 40 MNS,
        against the recorded lowest fifth, at that lag), ``rounding_r`` (at that lag).
    """
    recorded, known = _filled(recorded_opening)
    recorded = lowpass_head(recorded, fps=fps, cutoff_hz=MOUTH_LOWPASS_HZ)
    generated = np.asarray(generated_opening_mns, float)
    n = min(generated.size, recorded.size)
    generated, recorded, known = generated[:n], recorded[:n], known[:n]
    max_lag = int(round(MOUTH_MAX_LAG_S * fps))

    def r_at(lag: int, a: np.ndarray, b: np.ndarray) -> float | None:
        x, y = _lagged(a, b, lag)
        _, mask = _lagged(a, known, lag)
        return pearson(x[mask], y[mask]) if mask.sum() > 2 else None

    if lag_frames is None:
        scored = [(r, lag) for lag in range(-max_lag, max_lag + 1) if (r := r_at(lag, generated, recorded)) is not None]
        best_r, lag_frames = max(scored) if scored else (None, 0)
    else:
        best_r = r_at(lag_frames, generated, recorded)
    rounding, _ = _filled(recorded_rounding)
    rounding = lowpass_head(rounding, fps=fps, cutoff_hz=MOUTH_LOWPASS_HZ)[:n]
    rounding_r = r_at(lag_frames, np.asarray(generated_rounding, float)[:n], rounding)
    x, y = _lagged(generated, np.where(known, np.asarray(recorded_opening, float)[:n], np.nan), lag_frames)
    valid = np.isfinite(y)
    closed_recorded = y[valid] <= np.quantile(y[valid], CLOSED_FRACTION) if valid.any() else np.zeros(0, bool)
    closed_generated = x[valid] <= CLOSED_OPENING_MNS
    hits = int(np.sum(closed_recorded & closed_generated))
    precision = hits / closed_generated.sum() if closed_generated.any() else None
    recall = hits / closed_recorded.sum() if closed_recorded.any() else None
    f1 = (2 * precision * recall / (precision + recall) if precision is not None and recall is not None
          and precision + recall > 0 else None)
    return {"opening_r": best_r, "lag_s": lag_frames / fps, "rounding_r": rounding_r,
            "closures": {"precision": precision, "recall": recall, "f1": f1}}


def opening_agreement(first: np.ndarray, second: np.ndarray, *, fps: float) -> float | None:
    """How well two tracked measures of the same mouth's opening agree: the Pearson r of the two, each low-passed
    at 8 Hz as the recorded opening is for :func:`mouth_metrics`, over the frames where both are known.

    ``prosody track`` measures the opening twice, by the gap between the inner-lip landmarks (``lip_opening``)
    and by the face model's ``jawOpen`` blendshape. Where they disagree (a face turned away, a hand, a smile
    that stretches the lips, a tracker that lost the lips) the recording is a poor reference for lips made from
    the sound, whatever makes them: every method's opening r is bounded by how much of the recorded curve is the
    mouth itself.

    Parameters
    ----------
    first, second : array (n,)
        Two measures of the opening (any units); NaN where unknown.
    fps : float > 0

    Returns
    -------
    float or None
        None where fewer than 3 frames are known in both, or where either is constant.
    """
    a, known_a = _filled(first)
    b, known_b = _filled(second)
    n = min(a.size, b.size)
    both = known_a[:n] & known_b[:n]
    if both.sum() < 3:
        return None
    a = lowpass_head(a[:n], fps=fps, cutoff_hz=MOUTH_LOWPASS_HZ)
    b = lowpass_head(b[:n], fps=fps, cutoff_hz=MOUTH_LOWPASS_HZ)
    return pearson(a[both], b[both])


#: The relative closure measure: each curve's frames at or below its own 15th percentile, in runs of this many
#: frames or more, matched within this many frames.
RELATIVE_CLOSED_PERCENTILE, CLOSURE_MIN_RUN, CLOSURE_TOLERANCE_FRAMES = 15.0, 2, 2


def relative_closures(generated_opening: np.ndarray, recorded_opening: np.ndarray, *, fps: float,
                      lag_frames: int = 0) -> dict:
    """Closures found by each curve against itself: the frames at or below the curve's own 15th percentile (runs
    of 2 frames or more), the generated ones against the recorded ones (low-passed at 8 Hz, as for the opening r),
    each counted as found when the other has a closure within 2 frames. Unlike the ``closures`` of
    :func:`mouth_metrics`, it needs no threshold in MNS, so any curve of the opening (cues, a loudness envelope)
    is measured alike.

    Parameters
    ----------
    generated_opening, recorded_opening : array (n,)
        The two openings (any units); NaN where unknown (left out).
    fps : float > 0
    lag_frames : int
        Recorded frame ``k`` is compared with generated frame ``k + lag_frames`` (the lag of the opening r).

    Returns
    -------
    dict
        ``precision`` (the generated closure frames near a recorded one), ``recall`` (the recorded ones near a
        generated one) and ``f1``; None where a curve has no closure.
    """
    recorded, known = _filled(recorded_opening)
    recorded = np.where(known, lowpass_head(recorded, fps=fps, cutoff_hz=MOUTH_LOWPASS_HZ), np.nan)
    generated = np.asarray(generated_opening, float)
    n = min(generated.size, recorded.size)
    x, y = _lagged(generated[:n], recorded[:n], lag_frames)
    valid = np.isfinite(x) & np.isfinite(y)
    if valid.sum() < 2:
        return {"precision": None, "recall": None, "f1": None}

    def closed(values: np.ndarray) -> np.ndarray:
        low = valid & (values <= np.percentile(values[valid], RELATIVE_CLOSED_PERCENTILE))
        kept = np.zeros(values.size, bool)
        for start, end in _runs(low):
            if end - start >= CLOSURE_MIN_RUN:
                kept[start:end] = True
        return kept

    def near(mask: np.ndarray) -> np.ndarray:
        spread = np.convolve(mask.astype(float), np.ones(2 * CLOSURE_TOLERANCE_FRAMES + 1), mode="same")
        return spread > 0

    ours, theirs = closed(x), closed(y)
    precision = float((ours & near(theirs)).sum() / ours.sum()) if ours.any() else None
    recall = float((theirs & near(ours)).sum() / theirs.sum()) if theirs.any() else None
    f1 = (2 * precision * recall / (precision + recall) if precision is not None and recall is not None
          and precision + recall > 0 else None)
    return {"precision": precision, "recall": recall, "f1": f1}


_MOUTH_LAYOUT = (MOUTH_MEASURES, "closures", ("precision", "recall", "f1"))


def empty_mouth_metrics() -> dict:
    """The mouth block where it is undefined (no recorded mouth, or a stream without lips)."""
    return _empty_block(_MOUTH_LAYOUT)


def average_mouth_metrics(rows: Sequence[dict]) -> dict:
    """The mean of :func:`mouth_metrics` results (None entries left out), in the same layout."""
    return _average_block(rows, _MOUTH_LAYOUT)
