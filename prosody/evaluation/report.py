"""Readable Markdown reports: one recording's comparison, and a batch summary over many recordings."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from ..fap.table import BY_NUMBER, HEAD_FAPS, PROSODY_FAPS, RADIANS_PER_AU
from .metrics import BrowMeasures, HeadMeasures, Metrics, MouthMeasures

if TYPE_CHECKING:
    from .compare import Comparison

CONDITION_NAMES = ("NO_PROSODY", "RANDOM", "SPEECH_DRIVEN", "GROUND_TRUTH")


def _number(value: float | None, digits: int = 0) -> str:
    if value is None:
        return "–"
    return f"{value:.{digits}f}"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return lines


def _unit(fap: int) -> str:
    """How a FAP's values are shown: angles in degrees, the rest in their FAP unit (ENS for the brows)."""
    return "deg" if BY_NUMBER[fap].fapu == "AU" else BY_NUMBER[fap].fapu


def _shown(fap: int, value: float | None) -> float | None:
    """A FAP-unit value in the unit of :func:`_unit`, without a negative zero."""
    if value is None:
        return None
    shown = math.degrees(value * RADIANS_PER_AU) if BY_NUMBER[fap].fapu == "AU" else value
    return shown + 0.0 if round(shown, 2) != 0 else 0.0


def _brow_rule_line(metrics: Mapping) -> str:
    events = len(metrics["eyebrow_events"])
    threshold, energy = metrics.get("eyebrow_threshold_hz"), metrics.get("energy_threshold_db")
    rule = metrics.get("eyebrow_rule", "thesis")
    if threshold is None or energy is None:
        return f"eyebrows ({rule} rule): no voice to judge raises by; {events} raise(s)"
    if rule == "accent":
        return (f"eyebrows (accent rule): raise where the voice goes above {threshold:.0f} Hz at >= "
                f"{energy:.0f} dB; {events} raise(s)")
    return (f"eyebrows (thesis rule): raise above {threshold:.0f} Hz, hold while energy >= {energy:.0f} dB; "
            f"{events} raise(s)")


def comparison_markdown(comparison: Comparison, *, figures: Mapping[str, str] | None = None) -> str:
    """The report of one recording: statistics, agreement with ground truth, CCA, eyebrow raises, figures."""
    metrics = comparison.metrics
    conditions = metrics["conditions"]
    fps = metrics["fps"]
    lines = [
        f"# Visual prosody: {os.path.basename(comparison.source)}",
        "",
        f"- audio: `{comparison.source}`, {metrics['duration_s']:.2f} s, {metrics['frames']} frames at {fps:g} fps",
        f"- ground truth: `{metrics['ground_truth']}`" if metrics["ground_truth"] else "- ground truth: none given",
        f"- RANDOM seed {metrics['seed']}; normalisation to a common mean and spread: "
        + ("on" if metrics["normalized"] else "off"),
        *(["- note: the head model was trained on this recording, so its agreement here is not a held-out "
           "figure"] if metrics.get("model_trained_on_this_recording") else []),
        f"- {_brow_rule_line(metrics)}",
    ]
    measures = Metrics.from_json(metrics)
    lines += _head_section(measures)
    lines += _brow_section(measures)
    lines += _mouth_section(measures)
    lines += [
        "",
        "## Motion statistics (mean ± standard deviation; head angles in degrees, brows in ENS)",
        "",
    ]
    header = ["condition", *(f"{fap} {BY_NUMBER[fap].name} ({_unit(fap)})" for fap in PROSODY_FAPS)]
    rows = []
    for name, stats in conditions.items():
        cells = [name]
        for fap in PROSODY_FAPS:
            entry = stats[str(fap)]
            digits = 2 if _unit(fap) == "deg" else 1
            mean, spread = _shown(fap, entry["mean"]), _shown(fap, entry["std"])
            cells.append("–" if mean is None else f"{_number(mean, digits)} ± {_number(spread, digits)}")
        rows.append(cells)
    lines += _table(header, rows)
    if comparison.ground_truth is not None:
        lines += ["", "## Agreement with the ground truth", "",
                  "Pearson r (and RMSE: degrees for the head, ENS for the brows) of each condition against the "
                  "recorded motion; "
                  "– where undefined (a still curve, or a FAP the recording lacks).", ""]
        rows = []
        for name, stats in conditions.items():
            cells = [name]
            for fap in PROSODY_FAPS:
                entry = stats[str(fap)]
                digits = 2 if _unit(fap) == "deg" else 1
                cells.append("–" if entry["rmse"] is None else
                             f"{_number(entry['pearson_r'], 3)} ({_number(_shown(fap, entry['rmse']), digits)})")
            rows.append(cells)
        lines += _table(header, rows)
    lines += ["", "## Canonical correlation (first canonical r)", "",
              "A secondary measure: on clips of under a minute it is high for any motion (noise, or another "
              "recording's real motion, scores 0.4-0.5), so it does not show whether motion follows the speech.",
              ""]
    cca = metrics["cca"]
    lines += _table(["condition", "head (48-50) vs recorded head", "audio (energy, F0) vs head"],
                    [[name, _number(cca["head_vs_ground_truth"].get(name), 3),
                      _number(cca["audio_vs_head"].get(name), 3)] for name in conditions])
    if metrics["eyebrow_events"]:
        lines += ["", "## Eyebrow raises (SPEECH_DRIVEN)", "", "Each raise's onset and the frame its return to "
                  "neutral starts.", ""]
        lines += _table(["raise", "onset (s)", "release (s)"],
                        [[str(i + 1), f"{onset / fps:.2f}", f"{release / fps:.2f}"]
                         for i, (onset, release) in enumerate(metrics["eyebrow_events"])])
    for key, title in (("features", "Acoustics and eyebrow raises"), ("head", "Head rotation per condition")):
        if figures and key in figures:
            lines += ["", f"## {title}", "", f"![{title}]({figures[key]})"]
    return "\n".join(lines) + "\n"


def _head_row(name: str, head: HeadMeasures) -> list[str]:
    return [name, _number(head.speed_envelope_r, 3), _number(head.pitch_r, 3),
            " / ".join(_number(head.std_ratio[axis], 2) for axis in ("48", "49", "50")),
            _number(head.velocity_spectrum_distance_db, 1)]


HEAD_HEADER = ["condition", "speed-envelope r", "pitch r", "std ratio pitch / yaw / roll",
               "velocity-spectrum distance (dB)"]


def _head_section(metrics: Metrics) -> list[str]:
    """The lead table: head measures per condition against the recording, with the control beside them."""
    conditions = metrics.conditions
    if not any(block.head.std_ratio["48"] is not None for block in conditions.values()):
        return ["", "## Head motion", "", "No recorded head motion was given, so the head measures are undefined "
                "(give the recorded motion: --ground-truth FILE, or ground_truth= in Python)."]
    seeds = metrics.settings.get("seeds", 1)
    lines = ["", "## Head motion against the recording", "",
             "How much the head moves over time (speed envelope: angular speed averaged over 0.5 s, angles "
             "low-passed at 4 Hz) and head pitch, each as Pearson r with the recording; the spread of each axis "
             "as a ratio to the recording's (1 = a person's size); and the velocity-spectrum distance (0 dB = "
             "the recording's size and tempo; a still or jittery head scores high). "
             f"RANDOM{' and SPEECH_DRIVEN' if metrics.settings.get('head_model') == 'prosodic' else ''} are "
             f"averaged over {seeds} seed(s). The control drives the same speech-driven generator with this "
             "recording's own audio shifted in time by 5 s or more: it keeps the audio's statistics and breaks its "
             "timing, so a figure counts by how far it rises above the control.", ""]
    rows = [_head_row(name, block.head) for name, block in conditions.items()]
    if "SPEECH_DRIVEN" not in conditions:
        return lines + _table(HEAD_HEADER, rows)
    control = metrics.controls.head
    rows.append(_head_row("SPEECH_DRIVEN with mismatched audio (control)", control))
    for label, other in metrics.other_head_models.items():
        rows.append(_head_row(f"head model {label} ({other['kind']})", other["head"]))
        rows.append(_head_row(f"head model {label} with mismatched audio (control)", other["mismatched_audio"]))
    speech = conditions["SPEECH_DRIVEN"].head
    rises = [f"{label} {getattr(speech, key) - getattr(control, key):+.3f}"
             for key, label in (("speed_envelope_r", "speed-envelope r"), ("pitch_r", "pitch r"))
             if getattr(speech, key) is not None and getattr(control, key) is not None]
    lines += _table(HEAD_HEADER, rows)
    if rises:
        lines += ["", f"Rise of SPEECH_DRIVEN above the control: {', '.join(rises)}."]
    return lines


def _brow_row(name: str, brows: BrowMeasures) -> list[str]:
    onsets = brows.onsets
    return [name, _number(brows.raise_r, 3), _number(onsets.f1, 2), _number(onsets.precision, 2),
            _number(onsets.recall, 2), _number(brows.raises, 1), _number(brows.median_raise_s, 2)]


def _brow_section(metrics: Metrics) -> list[str]:
    """Eyebrows of each condition against recorded brow motion, with the control."""
    blocks = {name: block.brows for name, block in metrics.conditions.items()}
    first = next((brows for brows in blocks.values() if brows.recorded_raises is not None), None)
    if first is None:
        return []
    lines = ["", "## Eyebrows against the recording", "",
             "Raise r: Pearson r of the inner-brow raise with the recorded brow height (4 Hz low-passed). Onsets: "
             "a raise onset within 0.3 s of a recorded one counts (precision: share of the condition's onsets "
             "matched; recall: share of the recorded ones). The recording has "
             f"{_number(first.recorded_raises, 0)} raise(s) with a median length of "
             f"{_number(first.recorded_median_raise_s, 2)} s. The recorded brows are tracked from video: "
             "a noisy reference.", ""]
    rows = [_brow_row(name, brows) for name, brows in blocks.items()]
    if metrics.controls.brows.recorded_raises is not None:
        rows.append(_brow_row("SPEECH_DRIVEN with mismatched audio (control)", metrics.controls.brows))
    lines += _table(["condition", "raise r", "onset F1", "precision", "recall", "raises", "median length (s)"],
                    rows)
    return lines


def _mouth_row(name: str, mouth: MouthMeasures) -> list[str]:
    closures, lag = mouth.closures, mouth.lag_s
    return [name, _number(mouth.opening_r, 3), "–" if lag is None else f"{lag:+.2f}",
            _number(closures.f1, 2), _number(closures.precision, 2), _number(closures.recall, 2),
            _number(mouth.rounding_r, 3)]


def _mouth_section(metrics: Metrics) -> list[str]:
    """The lips of each condition against a tracked mouth, with the control."""
    measured = {name: block.mouth for name, block in metrics.conditions.items() if block.mouth.opening_r is not None}
    if not measured:
        return []
    lines = ["", "## Lips against the recording", "",
             f"The recorded mouth: `{metrics.settings.get('mouth_reference') or 'given'}` (tracked from video). "
             "Opening r: Pearson r of the inner-lip opening (FAP 3 - 4 - 5) with the recorded lip opening (8 Hz "
             "low-passed), at the best lag within ±0.25 s (positive: the video moves first). Closures: generated "
             "opening at most 40 MNS against the recording's lowest fifth. Rounding r: lip protrusion against "
             "funnel + pucker. Every condition has the same lips.", ""]
    rows = [_mouth_row(name, mouth) for name, mouth in measured.items()]
    if metrics.controls.mouth.opening_r is not None:
        rows.append(_mouth_row("lips shifted in time (control)", metrics.controls.mouth))
    lines += _table(["condition", "opening r", "lag (s)", "closure F1", "precision", "recall", "rounding r"], rows)
    return lines


def _interval(entry: Mapping | None, digits: int) -> str:
    if not entry or entry.get("mean") is None:
        return "–"
    low, high = entry["ci95"]
    return f"{entry['mean']:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _batch_head_row(name: str, head: Mapping) -> list[str]:
    ratios = head.get("std_ratio") or {}
    return [name, _interval(head.get("speed_envelope_r"), 3), _interval(head.get("pitch_r"), 3),
            " / ".join(_number((ratios.get(axis) or {}).get("mean"), 2) for axis in ("48", "49", "50")),
            _interval(head.get("velocity_spectrum_distance_db"), 1)]


def _batch_measures(summary: Mapping) -> list[str]:
    """The lead tables of a batch: head and brow measures over recordings, with the controls."""
    measures = summary.get("measures") or {}
    if not measures:
        return []
    controls = summary.get("controls") or {}
    lines = ["", "## Head motion over recordings with ground truth", "",
             "Mean over recordings with a bootstrap 95% interval [low, high] of each measure against the recorded "
             f"motion (stochastic conditions averaged over {summary.get('seeds', 1)} seed(s) per recording). The "
             "controls drive the same speech-driven generator with audio that is not the recording's: its own "
             "audio shifted by 5 s or more, and other inputs' audio trimmed or tiled to its length. A "
             "speech-driven figure counts by how far it rises above them. If the head model was trained on these "
             "recordings, the figures are not held-out ones (see the files table).", ""]
    rows = [_batch_head_row(name, block["head"]) for name, block in measures.items()]
    if "mismatched_audio" in controls:
        rows.append(_batch_head_row("SPEECH_DRIVEN, own audio shifted (control)", controls["mismatched_audio"]))
    if "other_recordings" in controls:
        rows.append(_batch_head_row("SPEECH_DRIVEN, other recordings' audio (control)", controls["other_recordings"]))
    lines += _table(["condition", "speed-envelope r", "pitch r", "std ratio pitch / yaw / roll",
                     "velocity-spectrum distance (dB)"], rows)
    brow_rows = [[name, _interval(block["brows"]["raise_r"], 3), _interval(block["brows"]["onset_f1"], 2)]
                 for name, block in measures.items() if block["brows"]["raise_r"]["recordings"]]
    if brow_rows:
        if "mismatched_audio_brows" in controls:
            brow = controls["mismatched_audio_brows"]
            brow_rows.append(["SPEECH_DRIVEN, own audio shifted (control)", _interval(brow["raise_r"], 3),
                              _interval(brow["onset_f1"], 2)])
        lines += ["", "## Eyebrows over recordings with recorded brows", ""]
        lines += _table(["condition", "raise r", "onset F1"], brow_rows)

    def mouth_row(name: str, block: Mapping) -> list[str]:
        return [name, _interval(block["opening_r"], 3), _interval(block["closure_f1"], 2),
                _interval(block["rounding_r"], 3)]

    mouth_rows = [mouth_row(name, block["mouth"]) for name, block in measures.items()
                  if "mouth" in block and block["mouth"]["opening_r"]["recordings"]]
    if mouth_rows:
        control = controls.get("mismatched_audio_mouth")
        if control and control["opening_r"]["recordings"]:
            mouth_rows.append(mouth_row("the lips shifted in time (control)", control))
        lines += ["", "## Lips over recordings with a recorded mouth (`<clip>.mouth.csv`)", "",
                  "Every condition has the same lips; the control shifts them by 5 s or more.", ""]
        lines += _table(["condition", "opening r", "closure F1", "rounding r"], mouth_rows)
    return lines


def batch_markdown(summary: Mapping) -> str:
    """The summary report of a batch: counts, a table per file, aggregates over files with ground truth."""
    counts = summary["counts"]
    lines = [
        "# Visual prosody: batch summary",
        "",
        f"- input: `{summary['input']}`; output: `{summary['output']}`",
        f"- {counts['files']} file(s): {counts['done']} processed, {counts['skipped']} already complete, "
        f"{counts['failed']} failed; {counts['with_ground_truth']} with ground truth",
    ]
    lines += _batch_measures(summary)
    lines += [
        "",
        "## Files",
        "",
        "Per recording with ground truth: the speech-driven head's speed-envelope r and pitch r against the "
        "recording, and the same for its mismatched-audio control; then head Pearson r (pitch / yaw / roll) "
        "for SPEECH_DRIVEN and RANDOM, and the first canonical correlation of the head axes with the recorded "
        "ones (secondary measures).",
        "",
    ]

    def measure(metrics: Mapping | None, key: str, control: bool = False) -> str:
        if not metrics:
            return "–"
        typed = Metrics.from_json(metrics)
        if control:
            return _number(getattr(typed.controls.head, key), 2)
        speech = typed.conditions.get("SPEECH_DRIVEN")
        return _number(getattr(speech.head, key), 2) if speech is not None else "–"

    def head_r(metrics: Mapping | None, condition: str) -> str:
        if not metrics or condition not in metrics["conditions"]:
            return "–"
        stats = metrics["conditions"][condition]
        return " / ".join(_number(stats[str(fap)]["pearson_r"], 2) for fap in HEAD_FAPS)

    def cca(metrics: Mapping | None, condition: str) -> str:
        if not metrics:
            return "–"
        return _number(metrics["cca"]["head_vs_ground_truth"].get(condition), 2)

    rows = []
    for entry in summary["files"]:
        metrics = entry.get("metrics")
        status = entry["status"] if not entry.get("error") else f"{entry['status']}: {entry['error']}"
        duration = _number(metrics["duration_s"], 1) if metrics else "–"
        seen = "yes (model trained on it)" if metrics and metrics.get("model_trained_on_this_recording") else "yes"
        rows.append([f"`{entry['file']}`", status.replace("|", "\\|"), duration,
                     seen if entry.get("ground_truth") else "no",
                     f"{measure(metrics, 'speed_envelope_r')} ({measure(metrics, 'speed_envelope_r', True)})",
                     f"{measure(metrics, 'pitch_r')} ({measure(metrics, 'pitch_r', True)})",
                     head_r(metrics, "SPEECH_DRIVEN"), head_r(metrics, "RANDOM"), cca(metrics, "SPEECH_DRIVEN"),
                     cca(metrics, "RANDOM")])
    lines += _table(["file", "status", "s", "truth", "speed-envelope r (control)", "pitch r (control)",
                     "r speech", "r random", "CCA speech", "CCA random"], rows)
    aggregate = summary.get("aggregate") or {}
    if aggregate:
        lines += ["", "## Aggregates over files with ground truth", "",
                  "Mean over files (and number of files) of the Pearson r against the recorded motion.", ""]
        header = ["condition", *(f"{fap} {BY_NUMBER[fap].name}" for fap in PROSODY_FAPS), "CCA head"]
        rows = []
        for name in CONDITION_NAMES:
            if name not in aggregate:
                continue
            cells = [name]
            for fap in PROSODY_FAPS:
                entry = aggregate[name]["faps"][str(fap)]
                cells.append("–" if entry["pearson_r"] is None else
                             f"{entry['pearson_r']:.3f} ({entry['files']})")
            cells.append(_number(aggregate[name]["cca_head_vs_ground_truth"], 3))
            rows.append(cells)
        lines += _table(header, rows)
    return "\n".join(lines) + "\n"
