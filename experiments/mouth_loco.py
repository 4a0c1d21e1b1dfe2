"""Leave-one-speaker-out table of the mouth measures on video-tracked mouths (``make evaluate``), and the fit
of the viseme shapes that ``prosody/motion/face/lips.py`` ships.

For each speaker, the viseme shapes (opening, rounding, spread) are fitted on the other speakers' clips and
the lips of the held-out speaker's clips are generated and measured (mouth-opening r at the best lag within
+-0.25 s, closures, rounding r). Every row is the mean over clips; beside each, its mismatched-audio control:
the same generated lips circularly shifted by 5 s or more against the recording (the mean over four shifts,
and its spread over clips). Rows:

- visemes: phones recognised without a transcript, the shipped viseme shapes, dominance blending: the default.
  Their openings are fitted to these clips and the talking videos, so here they are fitted again without the
  held-out speaker by the same recipe (``experiments/viseme_fit.py``);
- visemes with shapes fitted on the other speakers (least squares on the dominance weights);
- acoustic: the acoustic mouth model (spectral features, ridge), trained on the other speakers;
- Rhubarb cues: the default lips written as Rhubarb Lip Sync's mouth cues (``convert -o X.rhubarb.tsv``), played
  back as a 2D player shows them: each shape's opening and rounding held for its cue (:data:`CUE_SHAPES`);
- loudness: the intensity envelope alone (a baseline).

Then the phones against the hand-checked alignment of ``speech/arctic_a0009`` (viseme class agreement per 10 ms
frame, and the median distance from each labelled boundary to the nearest recognised one), without and with
the transcript, and the shapes fitted on every clip, for comparison with ``VISEMES``.

Usage: python -m experiments.mouth_loco [DIR]  (default ../shared/data/talking-heads)
"""

from __future__ import annotations

import re
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from audio_features import extract_features, load_audio
from audio_features.espeak import align_transcript
from audio_features.phones import Phone, recognise_phones
from experiments.common import record
from experiments.common import talking_heads as default_data
from prosody.fap.recorded import read_mouth_csv
from prosody.measures import average_mouth_metrics, mouth_metrics, relative_closures
from prosody.motion.face.lips import (
    MNS_PER_EYE_WIDTH,
    VISEMES,
    fit_shapes,
    inner_opening,
    shape_faps,
    shapes_from_phones,
    viseme_of,
    viseme_weights,
)
from prosody.motion.face.mouth_model import AcousticMouthModel, mouth_training_clip

FPS = 30.0
#: What a player of Rhubarb's cues shows, as (opening MNS, rounding): each shape at the visemes' size.
CUE_SHAPES = {"A": (0.0, 0.0), "X": (0.0, 0.0), "B": (150.0, 0.0), "C": (260.0, 0.0), "D": (330.0, 0.0),
              "E": (240.0, 0.11), "F": (170.0, 0.2), "G": (45.0, 0.0), "H": (250.0, 0.0)}


def cue_curves(faps: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The lips written as mouth cues and played back: (opening MNS, rounding) per frame."""
    from prosody.fap.mouth_cues import mouth_cues
    from prosody.fap.stream import FapStream

    return played_cues(mouth_cues(FapStream.from_curves({fap: values[:n] for fap, values in faps.items()}, fps=FPS)),
                       n)


def played_cues(cues, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Mouth cues (``MouthCue``) as a player shows them on ``n`` frames at :data:`FPS`: (opening MNS, rounding)."""
    opening, rounding = np.zeros(n), np.zeros(n)
    times = np.arange(n) / FPS
    for cue in cues:
        inside = (times >= cue.start_s - 1e-9) & (times < cue.end_s - 1e-9)
        opening[inside], rounding[inside] = CUE_SHAPES[cue.shape]
    return opening, rounding


def speaker_of(name: str) -> str:
    """Clips of one speaker share a fold: ``Obama_clip1`` and ``Obama_clip2`` are ``Obama``."""
    return re.sub(r"_?clip_?\d+$", "", name)


def targets(mouth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Opening (MNS above the clip's closed level), rounding (above its low level), spread (width change)."""
    opening = (mouth.lip_opening - np.nanquantile(mouth.lip_opening, 0.05)) / MNS_PER_EYE_WIDTH * 1024
    rounding = mouth.rounding - np.nanquantile(mouth.rounding, 0.05)
    spread = mouth.mouth_width / np.nanmedian(mouth.mouth_width) - 1
    return opening, rounding, spread


def fitted_visemes(clips: list[dict]):
    weights = [clip["weights"] for clip in clips]
    opening = fit_shapes(weights, [clip["targets"][0] for clip in clips], nonnegative=True)
    rounding = fit_shapes(weights, [clip["targets"][1] for clip in clips], closed=())
    spread = fit_shapes(weights, [clip["targets"][2] for clip in clips], closed=())
    return tuple(replace(v, opening=float(o), rounding=float(r), spread=float(s), phone_openings=None)
                 for v, o, r, s in zip(VISEMES, opening, rounding, spread, strict=True))


def measured(opening: np.ndarray, rounding: np.ndarray, clip: dict) -> tuple[dict, dict]:
    """The mouth measures of one clip and of its control (the lips shifted against the recording), with the
    relative closures (``relative``: each curve's own lowest 15 %, matched within 2 frames)."""
    mouth = clip["mouth"]

    def at(shift: int, lag: int | None) -> dict:
        shifted, turned = np.roll(opening, shift), np.roll(rounding, shift)
        result = mouth_metrics(shifted, turned, mouth.lip_opening, mouth.rounding, fps=FPS, lag_frames=lag)
        result["relative"] = relative_closures(shifted, mouth.lip_opening, fps=FPS,
                                               lag_frames=int(round(result["lag_s"] * FPS)))
        return result

    result = at(0, None)
    lag = int(round(result["lag_s"] * FPS))
    n = opening.size
    shifts = [int(n * f) for f in (0.25, 0.4, 0.6, 0.75)] if n > 20 * FPS else [int(n * f) for f in (1 / 3, 2 / 3)]
    controls = [at(s, lag) for s in shifts]
    control = average_mouth_metrics(controls)
    values = [c["relative"]["f1"] for c in controls if c["relative"]["f1"] is not None]
    control["relative"] = {"f1": float(np.mean(values)) if values else None}
    return result, control


def row(label: str, results: list[tuple[dict, dict]]) -> str:
    def mean(rows, key, sub=None):
        values = [(r[sub] if sub else r)[key] for r in rows]
        values = [v for v in values if v is not None]
        return np.mean(values) if values else float("nan")

    speech = [r for r, _ in results]
    control = [c for _, c in results]
    spread = np.std([c["opening_r"] for c in control if c["opening_r"] is not None])
    return (f"| {label} | {mean(speech, 'opening_r'):.3f} | {mean(speech, 'lag_s'):+.2f} | "
            f"{mean(speech, 'f1', 'closures'):.2f} ({mean(speech, 'precision', 'closures'):.2f} / "
            f"{mean(speech, 'recall', 'closures'):.2f}) | {mean(speech, 'f1', 'relative'):.2f} | "
            f"{mean(speech, 'rounding_r'):.3f} | {mean(control, 'opening_r'):+.3f} ± {spread:.2f} | "
            f"{mean(control, 'f1', 'closures'):.2f} | {mean(control, 'f1', 'relative'):.2f} |")


#: The header of :func:`row`'s table.
HEADER = ("| lips | opening r | lag (s) | closure F1 (P / R) | relative closure F1 | rounding r | control: opening r | "
          "control: F1 | control: relative F1 |\n|---|---|---|---|---|---|---|---|---|")


def read_lab(path: Path) -> list[Phone]:
    """An HTS full-context label file (times in 100 ns) as phones."""
    phones = []
    for line in path.read_text().splitlines():
        start, end, label = line.split(maxsplit=2)
        phone = label.split("-", 1)[1].split("+", 1)[0].upper()
        phones.append(Phone("SIL" if phone in ("SIL", "PAU") else phone, int(start) / 1e7, int(end) / 1e7))
    return phones


def labelled_phones(folder: Path) -> None:
    """Viseme-class agreement and boundary error of the recognised phones against labelled ones."""
    print("\n| phones of arctic_a0009 against its labels | viseme class agreement (10 ms frames) | "
          "control: the same classes shifted by half the recording | median boundary error (ms) |\n|---|---|---|---|")
    wav, lab = folder / "arctic_a0009.wav", folder / "arctic_a0009_phone.lab"
    if not lab.is_file():
        print("| (no labelled speech found) | | |")
        return
    truth = read_lab(lab)
    audio = load_audio(wav)
    times = np.arange(int(audio.duration_s * 100)) / 100

    def classes(phones: list[Phone]) -> np.ndarray:
        out = np.zeros(times.size, int)
        for phone in phones:
            out[(times >= phone.start_s) & (times < phone.end_s)] = viseme_of(phone.label).number
        return out

    edges = np.array([phone.start_s for phone in truth[1:]])
    words = "he turned sharply and faced gregson across the table"
    for label, transcript in (("phone loop", None), ("aligned transcript (PocketSphinx)", words),
                              ("transcript through eSpeak NG (--language en-us)", words)):
        if label.startswith("transcript through"):
            phones = align_transcript(audio, words, "en-us")
        else:
            phones = recognise_phones(audio, transcript=transcript)
        found = np.array([phone.start_s for phone in phones[1:]])
        error_ms = np.median([np.min(np.abs(found - edge)) for edge in edges]) * 1000
        found_classes = classes(phones)
        shifted = np.roll(found_classes, found_classes.size // 2)
        agreement, control = np.mean(found_classes == classes(truth)), np.mean(shifted == classes(truth))
        print(f"| {label} | {agreement:.2f} | {control:.2f} | {error_ms:.0f} |")


def main(folder: Path) -> None:
    from experiments.viseme_fit import held_out_openings

    clips = []
    for wav in sorted(folder.glob("*.wav")):
        mouth_file = wav.with_name(wav.stem + ".mouth.csv")
        if not mouth_file.is_file():
            continue
        mouth = read_mouth_csv(mouth_file)
        audio = load_audio(wav)
        phones = recognise_phones(audio)
        n = mouth.n_frames
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            features = extract_features(audio, fps=FPS)
        clips.append({"name": wav.stem, "speaker": speaker_of(wav.stem), "mouth": mouth, "phones": phones,
                      "weights": viseme_weights(np.arange(n) / FPS, phones), "targets": targets(mouth),
                      "energy": np.resize(features.energy.values, n),
                      "training": mouth_training_clip(audio, mouth, fps=FPS), "audio": audio})
    if not clips:
        sys.exit(f"{folder}: no <clip>.wav with a <clip>.mouth.csv beside it (see docs/evaluation.md)")
    speakers = sorted({clip["speaker"] for clip in clips})
    print(f"{len(clips)} clips, {len(speakers)} speakers: {', '.join(speakers)}\n")
    rows: dict[str, list] = {"visemes": [], "shipped": [], "acoustic": [], "loudness": [], "cues": []}
    openings = held_out_openings()  # the shipped openings' recipe, without the speaker
    for speaker in speakers:
        held = [clip for clip in clips if clip["speaker"] == speaker]
        rest = [clip for clip in clips if clip["speaker"] != speaker]
        visemes = fitted_visemes(rest)
        shipped = openings.get(f"heads: {speaker}", VISEMES)
        acoustic = AcousticMouthModel().fit([clip["training"] for clip in rest])
        for clip in held:
            n = clip["mouth"].n_frames
            for key, table in (("visemes", visemes), ("shipped", shipped)):
                faps = shape_faps(shapes_from_phones(clip["phones"], n, fps=FPS, visemes=table))
                rows[key].append(measured(inner_opening(faps), faps[16], clip))
                if key == "shipped":
                    rows["cues"].append(measured(*cue_curves(faps, n), clip))
            shape = acoustic.predict(clip["audio"], n, fps=FPS)
            faps = shape_faps(shape)
            rows["acoustic"].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
            rows["loudness"].append(measured(clip["energy"], clip["energy"], clip))
    print(HEADER)
    print(row("visemes (default: phones, shipped shapes, openings fitted without the speaker)", rows["shipped"]))
    print(row("visemes, shapes fitted on the other speakers", rows["visemes"]))
    print(row("acoustic model, trained on the other speakers", rows["acoustic"]))
    print(row("Rhubarb cues of the default visemes, played back", rows["cues"]))
    print(row("loudness envelope (baseline)", rows["loudness"]))
    order = [c for s in speakers for c in clips if c["speaker"] == s]
    print("\nper clip, default visemes (opening r):",
          ", ".join(f"{c['name']} {r['opening_r']:.2f}" for c, (r, _) in zip(order, rows["shipped"], strict=True)))
    labelled_phones(folder.parent / "speech")
    print("\nshapes fitted on every clip (opening MNS, rounding, spread):")
    for viseme in fitted_visemes(clips):
        print(f"    {viseme.number:2d} {viseme.name:9s} {viseme.opening:6.1f} {viseme.rounding:+.3f} "
              f"{viseme.spread:+.3f}")


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else default_data()
    sys.exit(record("mouth_loco", lambda: main(folder), lambda: [folder]))
