"""Our mouth cues beside Rhubarb Lip Sync's own, against the tracked mouths of the talking videos (30 speakers).

Rhubarb Lip Sync (github.com/DanielSWolf/rhubarb-lip-sync) is not part of this project: build or download it
and give its ``rhubarb`` program. Each clip of ``../shared/data/talking-videos`` (tracked by ``prosody track``
into ``out/talking-videos-tracked``, as ``experiments/mouth_videos_loso.py`` does) is given to it with each of
its recognisers (``pocketSphinx``, its default, and ``phonetic``), no transcript, its default extended shapes; its
cues are kept in ``out/rhubarb-cues/`` for the next run. Every set of cues, Rhubarb's and ours
(``prosody convert -o X.rhubarb.json``: the default visemes, and ``--lips combined`` with the acoustic model
refitted without the clip's speaker), is played back as a 2D player shows it: each shape held for its cue at
the visemes' size (``experiments.mouth_loco.CUE_SHAPES``). The continuous lips they come from are measured
beside them. Measures as ``experiments/mouth_videos_loso.py``: opening r at the best lag within +-0.25 s and
closure F1, each speaker's clips averaged first; the mismatched-audio control (the same curve shifted against
the recording) and its spread beside each; women and men apart.

Usage: python -m experiments.rhubarb_side_by_side RHUBARB  (the path of the ``rhubarb`` program)
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from audio_features.phones import recognise_phones
from experiments.common import REPO, data_folder, record
from experiments.mouth_loco import CUE_SHAPES, FPS, cue_curves
from experiments.mouth_videos_loso import (
    TRACKED,
    heads_training,
    load_clips,
    measured,
    reference_table,
    summary_table,
)
from prosody.motion.face.layer import COMBINED_CLOSED_MNS
from prosody.motion.face.lips import VISEME_FAP, inner_opening, shape_faps, shapes_from_phones
from prosody.motion.face.mouth_model import AcousticMouthModel

CUES = REPO / "out" / "rhubarb-cues"
RECOGNISERS = ("pocketSphinx", "phonetic")


def rhubarb_cues(program: Path, stem: str, recogniser: str) -> list[dict]:
    """Rhubarb's mouth cues of a tracked clip's audio (run once, then read from ``out/rhubarb-cues``)."""
    out = CUES / recogniser / f"{stem}.json"
    if not out.is_file():
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_suffix(".part")
        subprocess.run([str(program), "-q", "-f", "json", "-r", recogniser, "-o", str(partial),
                        str(TRACKED / f"{stem}.wav")], check=True, capture_output=True)
        partial.replace(out)
    return json.loads(out.read_text())["mouthCues"]


def played(cues: list[dict], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cues (``start``, ``end``, ``value``) as a player shows them: (opening MNS, rounding) per frame."""
    opening, rounding = np.zeros(n), np.zeros(n)
    times = np.arange(n) / FPS
    for cue in cues:
        inside = (times >= cue["start"] - 1e-9) & (times < cue["end"] - 1e-9)
        opening[inside], rounding[inside] = CUE_SHAPES[cue["value"]]
    return opening, rounding


def main(argv: list[str]) -> None:
    if len(argv) != 1 or not Path(argv[0]).is_file():
        sys.exit(__doc__.strip().splitlines()[-1])
    program = Path(argv[0])
    version = subprocess.run([str(program), "--version"], capture_output=True, text=True).stdout.strip()
    clips = load_clips()
    heads = heads_training()
    names = sorted({clip["speaker"] for clip in clips})
    sexes = {clip["speaker"]: clip["sex"] for clip in clips}
    print(f"{version}; {len(clips)} clips, {len(names)} speakers\n")
    keys = ("visemes", "visemes cues", "combined", "combined cues", *RECOGNISERS, "loudness")
    rows: dict[str, dict[str, list]] = {key: defaultdict(list) for key in keys}
    shapes_used: dict[str, dict[str, int]] = {name: defaultdict(int) for name in RECOGNISERS}
    for speaker in names:
        model = AcousticMouthModel().fit(heads + [c["training"] for c in clips if c["speaker"] != speaker])
        for clip in [c for c in clips if c["speaker"] == speaker]:
            n = clip["mouth"].n_frames
            visemes = shape_faps(shapes_from_phones(recognise_phones(clip["audio"]), n, fps=FPS))
            acoustic = shape_faps(model.predict(clip["audio"], n, fps=FPS))
            combined = {fap: 0.5 * (visemes[fap][:n] + acoustic[fap][:n]) for fap in acoustic}
            closed = inner_opening(visemes)[:n] < COMBINED_CLOSED_MNS
            combined = {fap: np.where(closed, visemes[fap][:n], combined[fap]) for fap in combined}
            combined[VISEME_FAP] = visemes[VISEME_FAP][:n]  # as `--lips combined` carries the visemes said
            for key, faps in (("visemes", visemes), ("combined", combined)):
                rows[key][speaker].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
                rows[f"{key} cues"][speaker].append(measured(*cue_curves(faps, n), clip))
            for recogniser in RECOGNISERS:
                cues = rhubarb_cues(program, clip["name"], recogniser)
                for cue in cues:
                    shapes_used[recogniser][cue["value"]] += 1
                rows[recogniser][speaker].append(measured(*played(cues, n), clip))
            rows["loudness"][speaker].append(measured(clip["energy"], clip["energy"], clip))
    labels = {"pocketSphinx": "Rhubarb Lip Sync, PocketSphinx recogniser (its default)",
              "phonetic": "Rhubarb Lip Sync, phonetic recogniser",
              "visemes cues": "ours: default visemes as cues (`-o X.rhubarb.json`)",
              "combined cues": "ours: `--lips combined` as cues (acoustic held out)",
              "visemes": "ours: default visemes, continuous",
              "combined": "ours: `--lips combined`, continuous",
              "loudness": "loudness envelope (baseline)"}
    summary_table("lips, played back as cues unless said", labels, rows, sexes)
    for recogniser in RECOGNISERS:
        total = sum(shapes_used[recogniser].values())
        print(f"\nRhubarb {recogniser}: {total} cues, shapes "
              + ", ".join(f"{shape} {count / total:.0%}" for shape, count in sorted(shapes_used[recogniser].items())))
    print("\nPaired by speaker (each speaker's clips averaged first): ours minus Rhubarb's, opening r, mean ± standard "
          "error, and the speakers where ours is higher")
    for ours in ("visemes cues", "combined cues", "visemes", "combined"):
        print(f"- {labels[ours]}: " + "; ".join(f"against {recogniser}: {paired(rows[ours], rows[recogniser])}"
                                                for recogniser in RECOGNISERS))
    reference_table(rows, labels, clips)


def paired(ours: dict[str, list], theirs: dict[str, list]) -> str:
    """The per-speaker difference of the opening r of two sets of lips: mean ± standard error, and how many
    speakers it favours."""
    def speaker_r(per_speaker: dict[str, list], speaker: str) -> float:
        values = [r["opening_r"] for r, _ in per_speaker[speaker] if r["opening_r"] is not None]
        return float(np.mean(values)) if values else float("nan")

    differences = np.array([speaker_r(ours, s) - speaker_r(theirs, s) for s in sorted(ours)])
    differences = differences[np.isfinite(differences)]
    error = differences.std(ddof=1) / np.sqrt(differences.size) if differences.size > 1 else float("nan")
    return (f"{differences.mean():+.3f} ± {error:.3f}, higher for {int((differences > 0).sum())} of "
            f"{differences.size}")


if __name__ == "__main__":
    sys.exit(record("rhubarb_side_by_side", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking videos")]))
