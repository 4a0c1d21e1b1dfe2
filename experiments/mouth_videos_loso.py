"""The lips against the mouths of the shared talking videos, leave one speaker out (``make evaluate``).

The 43 public talking-head clips of ``../shared/data/talking-videos`` (about 25 speakers, none of them in
``talking-heads``) are tracked once by ``prosody track`` into ``out/talking-videos-tracked/`` (kept for the next
run). For each speaker, every method's lips are measured against that speaker's tracked mouths: the opening r at
the best lag within +-0.25 s, the closure F1 and the relative closure F1 (each curve's own lowest 15 % in runs of
two frames or more, matched within 2 frames: ``prosody.measures.relative_closures``), and beside each the
mismatched-audio control (the same lips
circularly shifted against the recording) and its spread. Figures are means over speakers (each speaker's clips
averaged first), then again for women and for men apart (``videos_speakers.csv`` gives who speaks; the GRID clips
count as one speaker of unknown sex). Methods:

- visemes: phones recognised without a transcript (the default lips; the English model, also on the French and
  German clips), the visemes' openings fitted without the held-out speaker (``experiments/viseme_fit.py``: the
  shipped openings' recipe on every other speaker's clips);
- acoustic, shipped: the acoustic mouth model ``prosody`` ships (fitted on the talking-heads clips);
- acoustic, held out: the same model refitted on the talking-heads clips and every other video speaker;
- combined: the mean of the visemes' and the held-out acoustic model's mouths (opening and rounding);
- combined, closures kept: the same, but where the visemes close the lips (opening under 30 MNS) they stay closed;
- loudness: the intensity envelope alone (a baseline).

Usage: python -m experiments.mouth_videos_loso
"""

from __future__ import annotations

import csv
import sys
import warnings
from collections import defaultdict
from pathlib import Path

import numpy as np

from audio_features import extract_features, load_audio
from experiments.common import TRACKED_VIDEOS, data_folder, record, tracked_videos
from experiments.mouth_loco import measured
from prosody.fap.recorded import read_mouth_csv
from prosody.measures import opening_agreement
from prosody.motion.face.lips import inner_opening, shape_faps, shapes_from_phones
from prosody.motion.face.mouth_model import HEADS_MOUTH_MODEL_PATH, AcousticMouthModel, mouth_training_clip

FPS = 30.0
TRACKED = TRACKED_VIDEOS


def speakers() -> dict[str, dict]:
    with open(Path(__file__).with_name("videos_speakers.csv"), newline="") as handle:
        return {row["clip"]: row for row in csv.DictReader(handle)}


def load_clips() -> list[dict]:
    tracked_videos()
    who = speakers()
    clips = []
    for mouth_file in sorted(TRACKED.glob("*.mouth.csv")):
        stem = mouth_file.name[:-len(".mouth.csv")]
        if stem not in who:
            continue
        mouth = read_mouth_csv(mouth_file)
        if np.isfinite(mouth.lip_opening).mean() < 0.8:  # the face was not found often enough
            continue
        audio = load_audio(TRACKED / f"{stem}.wav")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            features = extract_features(audio, fps=FPS)
        agreement = (opening_agreement(mouth.lip_opening, mouth.jaw_open, fps=FPS)
                     if mouth.jaw_open is not None else None)
        clips.append({"name": stem, "speaker": who[stem]["speaker"], "sex": who[stem]["sex"], "mouth": mouth,
                      "agreement": agreement,
                      "audio": audio, "energy": np.resize(features.energy.values, mouth.n_frames),
                      "training": mouth_training_clip(audio, mouth, fps=FPS, name=stem)})
    return clips


def heads_training() -> list:
    folder = data_folder("talking-heads", needs="the talking-heads clips")
    out = []
    for wav in sorted(folder.glob("*.wav")):
        mouth_file = wav.with_name(wav.stem + ".mouth.csv")
        if mouth_file.is_file():
            mouth = read_mouth_csv(mouth_file)
            out.append(mouth_training_clip(load_audio(wav), mouth, fps=FPS, name=wav.stem))
    return out


def cell(per_speaker: dict[str, list], names: list[str]) -> str:
    """The measures of the named speakers (each speaker's clips averaged first), as one table cell."""
    def mean_of(results, key, sub=None):
        values = [(r[sub] if sub else r)[key] for r in results]
        values = [v for v in values if v is not None]
        return float(np.mean(values)) if values else float("nan")

    speech = [mean_of([r for r, _ in per_speaker[s]], "opening_r") for s in names]
    control = [mean_of([c for _, c in per_speaker[s]], "opening_r") for s in names]
    f1 = [mean_of([r for r, _ in per_speaker[s]], "f1", "closures") for s in names]
    relative = [mean_of([r for r, _ in per_speaker[s]], "f1", "relative") for s in names]
    chance = [mean_of([c for _, c in per_speaker[s]], "f1", "relative") for s in names]
    return (f"{np.nanmean(speech):.3f} (control {np.nanmean(control):+.3f} ± {np.nanstd(control):.2f}), "
            f"F1 {np.nanmean(f1):.2f}, relative F1 {np.nanmean(relative):.2f} (control {np.nanmean(chance):.2f}), "
            f"n {len(names)}")


def summary(label: str, per_speaker: dict[str, list], sexes: dict[str, str]) -> str:
    cells = [cell(per_speaker, [s for s in per_speaker if group == "all" or sexes[s] == group])
             for group in ("all", "F", "M")]
    return f"| {label} | " + " | ".join(cells) + " |"


def summary_table(first_column: str, labels: dict[str, str], rows: dict[str, dict[str, list]],
                  sexes: dict[str, str]) -> None:
    """Print a table of :func:`summary` rows: each method's label and its measures, all speakers, women, men."""
    print(f"| {first_column} | all speakers: opening r (control ± spread), closure F1, relative closure F1 | women "
          "| men |")
    print("|---|---|---|---|")
    for key, label in labels.items():
        print(summary(label, rows[key], sexes))


#: A clip's tracked mouth counts as a reliable reference where its two measures of the opening (inner-lip
#: landmarks and the jawOpen blendshape) agree at least this well (:func:`prosody.measures.opening_agreement`);
#: a round bar near the median clip's agreement (0.83).
RELIABLE_AGREEMENT = 0.8


def reference_table(rows: dict[str, dict[str, list]], labels: dict[str, str], clips: list[dict]) -> None:
    """Every method again, on the clips whose tracked mouth is a reliable reference and on the others.

    The split is made from the video alone (the two tracked openings), never from any method's lips; both sides
    are shown."""
    def split(per_speaker: dict[str, list], reliable: bool) -> dict[str, list]:
        out: dict[str, list] = defaultdict(list)
        for speaker, results in per_speaker.items():
            own = [clip for clip in clips if clip["speaker"] == speaker]
            for clip, result in zip(own, results, strict=True):
                if (clip["agreement"] is not None and clip["agreement"] >= RELIABLE_AGREEMENT) == reliable:
                    out[speaker].append(result)
        return out

    def described(group: list[dict]) -> str:
        values = [c["agreement"] for c in group if c["agreement"] is not None]
        return f"{len(group)} clips, agreement median {np.median(values):.2f}" if values else f"{len(group)} clips"

    women = [c for c in clips if c["sex"] == "F"]
    men = [c for c in clips if c["sex"] == "M"]
    print(f"\nThe reference itself: the two tracked measures of each clip's opening (inner-lip landmarks, jawOpen "
          f"blendshape) agree with r: all {described(clips)}; women {described(women)}; men {described(men)}.")
    good = [c for c in clips if c["agreement"] is not None and c["agreement"] >= RELIABLE_AGREEMENT]
    print(f"\n| lips | reliable reference, agreement >= {RELIABLE_AGREEMENT} ({len(good)} clips, "
          f"{len({c['speaker'] for c in good})} speakers, {sum(c['sex'] == 'F' for c in good)} clips of women) | "
          f"the other {len(clips) - len(good)} clips |")
    print("|---|---|---|")
    for key, label in labels.items():
        sides = [split(rows[key], reliable) for reliable in (True, False)]
        print(f"| {label} | " + " | ".join(cell(side, sorted(side)) for side in sides) + " |")


def main() -> None:
    from experiments.viseme_fit import held_out_openings

    clips = load_clips()
    heads = heads_training()
    names = sorted({clip["speaker"] for clip in clips})
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    print(f"{len(clips)} clips tracked, {len(names)} speakers ({sum(s == 'F' for s in sexes.values())} women, "
          f"{sum(s == 'M' for s in sexes.values())} men); {len(heads)} talking-heads clips in every training set\n")
    rows: dict[str, dict[str, list]] = {key: defaultdict(list)
                                        for key in ("visemes", "shipped", "held", "combined", "closing", "loudness")}
    shipped = AcousticMouthModel.load(HEADS_MOUTH_MODEL_PATH)  # no speaker of these videos in its training
    visemes = held_out_openings(clips)  # the shipped openings' recipe without the speaker; gives clips phones
    for speaker in names:
        held = [clip for clip in clips if clip["speaker"] == speaker]
        model = AcousticMouthModel().fit(heads + [c["training"] for c in clips if c["speaker"] != speaker])
        for clip in held:
            n = clip["mouth"].n_frames
            faps = shape_faps(shapes_from_phones(clip["phones"], n, fps=FPS, visemes=visemes[speaker]))
            phones_mouth = (inner_opening(faps)[:n], faps[16][:n])
            rows["visemes"][speaker].append(measured(*phones_mouth, clip))
            for key, chosen in (("shipped", shipped), ("held", model)):
                faps = shape_faps(chosen.predict(clip["audio"], n, fps=FPS))
                rows[key][speaker].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
            acoustic_mouth = (inner_opening(faps)[:n], faps[16][:n])
            mean_opening = 0.5 * (phones_mouth[0] + acoustic_mouth[0])
            mean_rounding = 0.5 * (phones_mouth[1] + acoustic_mouth[1])
            rows["combined"][speaker].append(measured(mean_opening, mean_rounding, clip))
            closed = phones_mouth[0] < 30.0
            rows["closing"][speaker].append(measured(np.where(closed, phones_mouth[0], mean_opening), mean_rounding,
                                                     clip))
            rows["loudness"][speaker].append(measured(clip["energy"], clip["energy"], clip))
    labels = {"visemes": "visemes (default, phone loop; openings fitted without the speaker)",
              "shipped": "acoustic, trained on the talking-heads clips alone",
              "held": "acoustic, refitted without the held-out speaker (the shipped model's recipe)",
              "combined": "combined: mean of visemes and acoustic held out",
              "closing": "combined, the visemes' closures kept (`--lips combined`)",
              "loudness": "loudness envelope (baseline)"}
    summary_table("lips", labels, rows, sexes)
    reference_table(rows, labels, clips)
    print("\nper speaker, visemes / acoustic held out (opening r):")
    def mean_r(key: str, speaker: str) -> float:
        values = [r["opening_r"] for r, _ in rows[key][speaker] if r["opening_r"] is not None]
        return float(np.mean(values)) if values else float("nan")

    for speaker in names:
        print(f"  {speaker} ({sexes[speaker]}): {mean_r('visemes', speaker):.2f} / {mean_r('held', speaker):.2f}")


if __name__ == "__main__":
    sys.exit(record("mouth_videos_loso", main, lambda: [data_folder("talking-videos", needs="the talking videos")]))
