"""The visemes' openings fitted to people's tracked mouths, held out by speaker (``make evaluate``), and the fit
that ``prosody/motion/face/lips.py`` ships.

Data: the clips of the talking videos tracked by ``prosody track`` (30 speakers, as
``experiments/mouth_videos_loso.py`` uses them) and the seven talking-heads clips (five speakers).

The recipe (:func:`fit_openings`):

- the phones recognised without a transcript (the default lips), each frame's viseme weights at 30 fps by the
  shipped dominance functions (``viseme_weights``);
- the target: the person's inner-lip opening in MNS above the clip's own closed level (its 5th percentile), as
  ``experiments/mouth_loco.py`` converts it;
- each clip's target moved by its own sound-to-picture lag, the best lag within +-0.25 s of the hand-set
  shapes' opening against it (the mouth measure's lag): the clips' offsets differ by up to a quarter of a second,
  and a fit without it follows the held-out speakers less well (the variant "without the lags");
- least squares of the targets on the weights (``fit_shapes``): silence and /p b m/ held at 0 (MPEG-4's neutral
  mouth is closed, and a bilabial closes it), every other viseme but /f v/ at least ``MIN_OPEN_MNS`` apart (the
  lips never shut on a /th/ or an /n/, and mouth cues keep those open), openings >= 0. Rounding and spread stay
  as set by hand.

Held out: for each speaker, the openings fitted on every other speaker's clips (videos and talking heads) make
that speaker's lips, beside the hand-set shapes (the default before, :data:`HAND_SET_OPENINGS`); the measures of
``experiments/mouth_videos_loso.py`` (opening r at the best lag within +-0.25 s, closure F1, relative closure F1,
each beside its mismatched-audio control and chance spread), and the paired difference by speaker; three
variants beside them (no floor; silence free to open; without the lags). Then the fit on every clip: the
openings ``VISEMES`` ships, compared with it; and the dominance rates scaled, chosen on the talking-heads clips
alone.

Usage: python -m experiments.viseme_fit
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections import defaultdict
from collections.abc import Iterator, Sequence
from dataclasses import replace

import numpy as np

from audio_features import load_audio
from audio_features.phones import recognise_phones
from experiments.common import data_folder, record, talking_heads
from experiments.mouth_loco import measured, speaker_of, targets
from experiments.mouth_videos_loso import cell, load_clips, reference_table, summary_table
from prosody.fap.recorded import read_mouth_csv
from prosody.measures import mouth_metrics
from prosody.motion.face import lips
from prosody.motion.face.lips import (
    MIN_OPEN_MNS,
    PHONE_ORDER,
    VISEMES,
    Viseme,
    fit_shapes,
    inner_opening,
    phone_weights,
    shape_faps,
    shapes_from_phones,
    viseme_weights,
)

FPS = 30.0
#: The openings shipped before the fit (MNS, viseme 0-14): set by hand from phonetic descriptions, times 1.75
#: (people's size through render and tracker, ``experiments/likeness.py``).
HAND_SET_OPENINGS = tuple(1.75 * value for value in (0.0, 0.0, 45.0, 150.0, 150.0, 190.0, 130.0, 110.0, 160.0,
                                                      150.0, 330.0, 260.0, 190.0, 280.0, 170.0))
HAND_SET = tuple(replace(viseme, opening=opening, phone_openings=None)
                 for viseme, opening in zip(VISEMES, HAND_SET_OPENINGS, strict=True))
#: Held closed (silence, /p b m/), and free of the least opening (/f v/: the lower lip under the teeth).
CLOSED_PHONES, NEARLY_CLOSED_PHONES = ("SIL", "P", "B", "M"), ("F", "V")
#: The dominance rates tried, as multiples of the shipped ones.
RATE_SCALES = (0.6, 0.8, 1.0, 1.25, 1.6, 2.0, 3.0)


def _bounds(names: list[tuple[str, ...]], *, open_pauses: bool, floor: bool) -> tuple[list[int], np.ndarray]:
    """For columns that each stand for ``names`` (a viseme's phones, or one phone): which are held closed, and
    every column's least opening."""
    closed_phones = set(CLOSED_PHONES) - ({"SIL"} if open_pauses else set())
    closed = [k for k, phones in enumerate(names) if set(phones) <= closed_phones]
    free = set(NEARLY_CLOSED_PHONES) | ({"SIL"} if open_pauses else set())
    minimum = np.array([0.0 if not floor or set(phones) <= free | closed_phones else MIN_OPEN_MNS
                        for phones in names])
    return closed, minimum


def prepared(clip: dict, table: Sequence[Viseme] = VISEMES) -> dict:
    """A clip (``mouth``, ``phones``) with its viseme and phone weights (by ``table``'s dominance), its target
    and its sound-to-picture lag."""
    n = clip["mouth"].n_frames
    clip["weights"] = viseme_weights(np.arange(n) / FPS, clip["phones"], visemes=table)
    clip["phone weights"] = phone_weights(np.arange(n) / FPS, clip["phones"], visemes=table)
    clip["target"] = targets(clip["mouth"])[0]
    if "lag" not in clip:
        opening = inner_opening(shape_faps(shapes_from_phones(clip["phones"], n, fps=FPS, visemes=HAND_SET)))[:n]
        flat = np.zeros(n)
        result = mouth_metrics(opening, flat, clip["mouth"].lip_opening, flat, fps=FPS)
        clip["lag"] = int(round(result["lag_s"] * FPS))
    return clip


def fitting_clips(videos: Sequence[dict] | None = None) -> list[dict]:
    """The talking videos' clips (``videos``, as ``experiments.mouth_videos_loso.load_clips`` gives them; loaded
    when not given) and the talking-heads clips, each :func:`prepared`, with ``set`` ("videos" or "heads")."""
    clips = []
    for clip in load_clips() if videos is None else videos:
        clips.append(prepared({**clip, "phones": clip.get("phones") or recognise_phones(clip["audio"]),
                               "set": "videos"}))
    for wav in sorted(talking_heads().glob("*.wav")):
        mouth_file = wav.with_name(wav.stem + ".mouth.csv")
        if mouth_file.is_file():
            clips.append(prepared({"name": wav.stem, "speaker": f"heads: {speaker_of(wav.stem)}", "sex": "?",
                                   "set": "heads", "mouth": read_mouth_csv(mouth_file),
                                   "phones": recognise_phones(load_audio(wav))}))
    return clips


def fit_openings(clips: Sequence[dict], *, table: Sequence[Viseme] = VISEMES, open_pauses: bool = False,
                 floor: bool = True) -> tuple[Viseme, ...]:
    """``table`` with its openings fitted to ``clips`` (:func:`prepared` by that table), as the module doc says:
    each viseme's own and each phone's own (``open_pauses``, ``floor``: the variants' bounds)."""
    aligned = [np.roll(clip["target"], clip["lag"]) for clip in clips]  # recorded frame k - lag at frame k
    closed, minimum = _bounds([v.phones for v in table], open_pauses=open_pauses, floor=floor)
    by_viseme = fit_shapes([clip["weights"] for clip in clips], aligned, closed=closed, nonnegative=True,
                           minimum=minimum)
    closed, minimum = _bounds([(phone,) for phone in PHONE_ORDER], open_pauses=open_pauses, floor=floor)
    by_phone = dict(zip(PHONE_ORDER, fit_shapes([clip["phone weights"] for clip in clips], aligned, closed=closed,
                                                nonnegative=True, minimum=minimum), strict=True))
    return tuple(replace(viseme, opening=float(opening),
                         phone_openings=tuple(float(by_phone[phone]) for phone in viseme.phones))
                 for viseme, opening in zip(table, by_viseme, strict=True))


def one_opening_a_viseme(table: Sequence[Viseme]) -> tuple[Viseme, ...]:
    """``table`` with every phone at its viseme's opening (the fit of one opening a viseme)."""
    return tuple(replace(viseme, phone_openings=None) for viseme in table)


def held_out_openings(videos: Sequence[dict] | None = None) -> dict[str, tuple[Viseme, ...]]:
    """Per speaker, the shipped openings' recipe on every other speaker's clips: the talking videos (``videos``,
    as ``load_clips`` gives them, each given its recognised ``phones`` here where it has none; loaded when not
    given) and the talking-heads clips."""
    for clip in videos or ():
        if "phones" not in clip:
            clip["phones"] = recognise_phones(clip["audio"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return held_out_visemes(fitting_clips(videos))


def held_out_visemes(clips: Sequence[dict], **options) -> dict[str, tuple[Viseme, ...]]:
    """Per speaker of ``clips``, the openings fitted on every other speaker's clips (``options``: as
    :func:`fit_openings` takes them)."""
    return {speaker: fit_openings([clip for clip in clips if clip["speaker"] != speaker], **options)
            for speaker in sorted({clip["speaker"] for clip in clips})}


def coarticulation_rates(clips: Sequence[dict]) -> None:
    """The dominance rates (every theta) scaled, the openings refitted each time, on the talking-heads clips held
    out by speaker among themselves (the videos are not used to choose)."""
    heads = [clip for clip in clips if clip["set"] == "heads"]
    print("\nThe dominance rates scaled (talking-heads clips, openings refitted on the other heads speakers): "
          "opening r, mean over clips")
    for scale in RATE_SCALES:
        table = tuple(replace(v, theta_before=v.theta_before * scale, theta_after=v.theta_after * scale)
                      for v in VISEMES)
        scaled = [prepared(dict(clip), table) for clip in heads]
        values = []
        for speaker, fitted in held_out_visemes(scaled, table=table).items():
            values += [measured(*_mouth(clip, fitted), clip)[0]["opening_r"] for clip in scaled
                       if clip["speaker"] == speaker]
        print(f"  rates x {scale:g}: {np.mean(values):.3f}")


@contextlib.contextmanager
def using_visemes(table: Sequence[Viseme]) -> Iterator[None]:
    """Lips made inside (``prosody convert`` and the rest) take ``table`` for the shipped visemes."""
    shipped = lips.VISEMES
    lips.VISEMES = tuple(table)
    try:
        yield
    finally:
        lips.VISEMES = shipped


def _mouth(clip: dict, table: Sequence[Viseme]) -> tuple[np.ndarray, np.ndarray]:
    n = clip["mouth"].n_frames
    faps = shape_faps(shapes_from_phones(clip["phones"], n, fps=FPS, visemes=table))
    return inner_opening(faps)[:n], faps[16][:n]


def _speaker_r(results: list) -> float:
    values = [r["opening_r"] for r, _ in results if r["opening_r"] is not None]
    return float(np.mean(values)) if values else float("nan")


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clips = fitting_clips()
    videos = [clip for clip in clips if clip["set"] == "videos"]
    names = sorted({clip["speaker"] for clip in videos})
    heads = sorted({clip["speaker"] for clip in clips if clip["set"] == "heads"})
    sexes = {clip["speaker"]: clip["sex"] for clip in videos}
    print(f"{len(videos)} clips of {len(names)} video speakers, {len(clips) - len(videos)} talking-heads clips of "
          f"{len(heads)} speakers; each speaker held out in turn\n")
    held = {"fitted": held_out_visemes(clips),
            "open pauses": held_out_visemes(clips, open_pauses=True, floor=False),
            "no floor": held_out_visemes(clips, floor=False),
            "no lags": held_out_visemes([{**clip, "lag": 0} for clip in clips])}
    held["viseme"] = {speaker: one_opening_a_viseme(table) for speaker, table in held["fitted"].items()}
    rows: dict[str, dict[str, list]] = {key: defaultdict(list) for key in ("hand", *held)}
    for clip in clips:
        rows["hand"][clip["speaker"]].append(measured(*_mouth(clip, HAND_SET), clip))
        for key, tables in held.items():
            rows[key][clip["speaker"]].append(measured(*_mouth(clip, tables[clip["speaker"]]), clip))
    labels = {"hand": "hand-set openings (the default before)",
              "viseme": "one opening a viseme, fitted on the other speakers",
              "fitted": "an opening a phone, fitted on the other speakers (the shipped recipe)",
              "no floor": "the same without the floor of MIN_OPEN_MNS (a variant)",
              "open pauses": "the same, silence free to open too (a variant)",
              "no lags": "the same without the clips' lags (a variant)"}
    video_rows = {key: {s: v for s, v in per.items() if s in names} for key, per in rows.items()}
    print("The talking videos:\n")
    summary_table("lips", labels, video_rows, sexes)
    reference_table(video_rows, labels, videos)
    print("\nThe talking-heads clips (each clip a row of the mean):\n")
    print("| lips | opening r (control ± spread), closure F1, relative closure F1 |\n|---|---|")
    for key, label in labels.items():
        print(f"| {label} | {cell(rows[key], heads)} |")
    by_speaker = {key: np.array([_speaker_r(rows[key][s]) for s in names]) for key in ("hand", "viseme", "fitted")}
    print("\nvideo speakers, opening r by speaker: " + ", ".join(
        f"{labels[key].split(',')[0]} median {np.median(values):.3f} ({np.mean(values >= 0.3):.0%} at 0.3 or more)"
        for key, values in by_speaker.items()))
    for other in ("hand", "viseme"):
        gain = by_speaker["fitted"] - by_speaker[other]
        print(f"an opening a phone minus {labels[other].split(',')[0]}: {gain.mean():+.3f} ± "
              f"{gain.std(ddof=1) / np.sqrt(gain.size):.3f} (mean ± standard error), higher for "
              f"{int((gain > 0).sum())} of {gain.size} speakers")
    every = fit_openings(clips)
    spread = {p: [dict(zip(v.phones, v.phone_openings or (), strict=True)).get(p, np.nan)
                  for table in held["fitted"].values() for v in table] for p in PHONE_ORDER}
    print("\n| viseme | hand-set (MNS) | one opening a viseme, fitted on every clip | each phone, fitted on every clip "
          "(held-out fits: range) |")
    print("|---|---|---|---|")
    for k, viseme in enumerate(every):
        phones = ", ".join(f"{p} {o:.0f} ({np.nanmin(spread[p]):.0f}-{np.nanmax(spread[p]):.0f})"
                           for p, o in zip(viseme.phones, viseme.phone_openings or (), strict=True))
        print(f"| {viseme.number} {viseme.name} | {HAND_SET_OPENINGS[k]:.0f} | {viseme.opening:.0f} | {phones} |")
    largest = max(abs(a.opening_of(phone) - b.opening_of(phone)) for a, b in zip(every, VISEMES, strict=True)
                  for phone in a.phones)
    largest = max(largest, *(abs(a.opening - b.opening) for a, b in zip(every, VISEMES, strict=True)))
    print(f"\nthe shipped openings {'are' if largest <= 0.5 else 'are NOT'} this fit (largest difference "
          f"{largest:.2f} MNS)")
    coarticulation_rates(clips)


if __name__ == "__main__":
    sys.exit(record("viseme_fit", main, lambda: [data_folder("talking-videos", needs="the talking videos"),
                                                  talking_heads()]))
