"""What the right transcript is worth to the lips: the GRID clips of the talking videos, whose sentences are known.

A GRID sentence follows one grammar, and its clip's name spells it (``bbaf2n``: "bin blue at f two now"): command,
colour, preposition, letter, digit, adverb. The ten GRID clips of ``../shared/data/talking-videos`` (tracked into
``out/talking-videos-tracked`` as ``experiments/mouth_videos_loso.py`` does) are made into lips four ways, none
fitted to these clips: the phone loop without a transcript (the default), the transcript aligned by PocketSphinx
(``--transcript``), the transcript's phones from eSpeak NG aligned by time warping (``--transcript --language
en-us``, the path of every other language), and the loudness envelope (a baseline); with a ``rhubarb`` program
given, Rhubarb Lip Sync's cues without and with the sentence as its dialog file (``-d``), played back as
``experiments/rhubarb_side_by_side.py`` plays them. Measures as ``experiments/mouth_videos_loso.py`` (opening r at
the best lag within +-0.25 s, closure F1, the shifted control and its spread), means over the clips.

Usage: python -m experiments.grid_transcripts [RHUBARB]
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from experiments.common import data_folder, record
from experiments.mouth_loco import FPS, HEADER, measured, row
from experiments.mouth_videos_loso import TRACKED, load_clips
from experiments.rhubarb_side_by_side import played
from prosody.motion.face.layer import lip_curves
from prosody.motion.face.lips import inner_opening

COMMANDS = {"b": "bin", "l": "lay", "p": "place", "s": "set"}
COLOURS = {"b": "blue", "g": "green", "r": "red", "w": "white"}
PREPOSITIONS = {"a": "at", "b": "by", "i": "in", "w": "with"}
DIGITS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
ADVERBS = {"a": "again", "n": "now", "p": "please", "s": "soon"}


def grid_sentence(code: str) -> str:
    """The sentence a GRID clip's six-letter code spells (``bbaf2n`` -> ``bin blue at f two now``; ``z`` is zero)."""
    if len(code) != 6 or not (code[4].isdigit() or code[4] == "z"):
        raise ValueError(f"{code!r} is not a GRID sentence code")
    digit = DIGITS[0 if code[4] == "z" else int(code[4])]  # the corpus writes zero as z
    return " ".join([COMMANDS[code[0]], COLOURS[code[1]], PREPOSITIONS[code[2]], code[3], digit, ADVERBS[code[5]]])


def rhubarb_played(program: Path, wav: Path, n: int, dialog: str | None) -> tuple[np.ndarray, np.ndarray]:
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "cues.json"
        command = [str(program), "-q", "-f", "json", "-o", str(out), str(wav)]
        if dialog is not None:
            (Path(folder) / "dialog.txt").write_text(dialog + "\n")
            command[1:1] = ["-d", str(Path(folder) / "dialog.txt")]
        subprocess.run(command, check=True, capture_output=True)
        return played(json.loads(out.read_text())["mouthCues"], n)


def main(argv: list[str]) -> None:
    program = Path(argv[0]) if argv else None
    clips = [clip for clip in load_clips() if clip["name"].startswith("LipNet_GRID_")]
    if not clips:
        sys.exit("no GRID clip among the tracked talking videos")
    keys = ["phone loop", "transcript, PocketSphinx", "transcript, eSpeak NG", "loudness"]
    if program is not None:
        keys += ["Rhubarb", "Rhubarb with the dialog"]
    rows: dict[str, list] = {key: [] for key in keys}
    for clip in clips:
        sentence = grid_sentence(clip["name"].removeprefix("LipNet_GRID_"))
        n = clip["mouth"].n_frames
        print(f"{clip['name']}: {sentence}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for key, transcript, language in (("phone loop", None, None), ("transcript, PocketSphinx", sentence, None),
                                              ("transcript, eSpeak NG", sentence, "en-us")):
                faps = lip_curves(clip["audio"], n, fps=FPS, transcript=transcript, language=language)
                rows[key].append(measured(inner_opening(faps)[:n], faps[16][:n], clip))
        rows["loudness"].append(measured(clip["energy"], clip["energy"], clip))
        if program is not None:
            wav = TRACKED / f"{clip['name']}.wav"
            rows["Rhubarb"].append(measured(*rhubarb_played(program, wav, n, None), clip))
            rows["Rhubarb with the dialog"].append(measured(*rhubarb_played(program, wav, n, sentence), clip))
    print(f"\n{len(clips)} GRID clips\n")
    print(HEADER)
    for key in keys:
        print(row(key, rows[key]))


if __name__ == "__main__":
    sys.exit(record("grid_transcripts", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking videos")]))
