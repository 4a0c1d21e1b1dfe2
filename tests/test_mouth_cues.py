"""The lips as Rhubarb Lip Sync's mouth cues: shapes with known answers from designed lip FAPs, and each file
read back by a parser written from Rhubarb's description of its formats (README, "Output formats" and the
Moho switch file of its ``dat`` exporter)."""

from __future__ import annotations

import dataclasses
import json
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from prosody.cli import main
from prosody.fap.mouth_cues import OPENING_SCALE, PRESTON_BLAIR, mouth_cues
from prosody.fap.stream import FapStream
from prosody.outputs import format_for, write_stream

FPS = 30.0
#: (frames, opening MNS, rounding 0..1) -> the shape it must give.
SEGMENTS = [(10, 0.0, 0.0, "X"), (6, 330.0, 0.0, "D"), (2, 0.0, 0.0, "A"), (6, 260.0, 0.0, "C"),
            (6, 170.0, 0.2, "F"), (6, 280.0, 0.1, "E"), (6, 150.0, 0.0, "B"), (12, 0.0, 0.0, "X")]


def _stream(segments=SEGMENTS) -> FapStream:
    """The segments' lips, their openings (the visemes' hand-set sizes) at the visemes' scale."""
    opening = OPENING_SCALE * np.concatenate([np.full(n, value) for n, value, _, _ in segments])
    rounding = np.concatenate([np.full(n, value) for n, _, value, _ in segments])
    # the opening shared as the visemes share it: jaw 60 %, top lip up 15 %, bottom lip down 25 %
    curves = {3: 0.60 * opening, 4: -0.15 * opening, 5: -0.25 * opening, 16: 300 * rounding, 17: 300 * rounding}
    return FapStream.from_curves(curves, fps=FPS, name="hello")


def _expected() -> list[tuple[float, float, str]]:
    out, frame = [], 0
    for n, _, _, shape in SEGMENTS:
        out.append((round(frame / FPS, 2), round((frame + n) / FPS, 2), shape))
        frame += n
    return out


def test_designed_lips_give_rhubarbs_shapes_at_their_times() -> None:
    cues = [(cue.start_s, cue.end_s, cue.shape) for cue in mouth_cues(_stream())]
    expected = _expected()
    expected[-1] = (expected[-1][0], 1.8, "X")  # the duration, truncated to 0.01 s
    assert cues == expected


def test_a_single_frame_does_not_flicker_but_a_short_closure_stays() -> None:
    segments = [(6, 150.0, 0.0, "B"), (1, 330.0, 0.0, "-"), (6, 150.0, 0.0, "B"), (1, 0.0, 0.0, "A"),
                (6, 150.0, 0.0, "B")]
    shapes = [cue.shape for cue in mouth_cues(_stream(segments))]
    assert shapes == ["B", "A", "B", "X"]  # and the recording's last frame is idle


def test_at_100_fps_a_shape_shorter_than_a_twentieth_of_a_second_joins_its_neighbour() -> None:
    """On Rhubarb's 0.01 s grid the rule is the same in time as a single frame at 30 fps: a shape held under
    0.05 s (4 frames) joins the one before it; 5 frames stay; a closure of 2 frames stays, lengthened to 0.05 s
    into the shape before it (a 24 fps player would miss 0.02 s), and into the one after where the one before is
    itself short."""
    from prosody.fap.mouth_cues import CUE_FPS

    def shapes(segments):
        opening = OPENING_SCALE * np.concatenate([np.full(n, value) for n, value in segments])
        curves = {3: 0.60 * opening, 4: -0.15 * opening, 5: -0.25 * opening}
        return [(cue.start_s, cue.shape) for cue in mouth_cues(FapStream.from_curves(curves, fps=CUE_FPS))]

    assert shapes([(20, 150.0), (4, 330.0), (20, 150.0), (2, 0.0), (20, 150.0)]) == [
        (0.0, "B"), (0.41, "A"), (0.46, "B"), (0.65, "X")]
    assert shapes([(20, 150.0), (5, 330.0), (2, 0.0), (20, 150.0)]) == [
        (0.0, "B"), (0.2, "D"), (0.25, "A"), (0.3, "B"), (0.46, "X")]
    assert shapes([(20, 150.0), (5, 330.0), (20, 150.0)]) == [(0.0, "B"), (0.2, "D"), (0.25, "B"), (0.44, "X")]


def test_the_viseme_said_gives_its_shape_whatever_the_lips_opening() -> None:
    # FAP 1 (the viseme said) over lips held half open: the cues follow the visemes, as Rhubarb follows phones
    said = [(10, 0), (6, 10), (3, 1), (6, 10), (4, 2), (6, 13), (5, 11), (6, 12), (6, 14), (12, 0)]
    numbers = np.concatenate([np.full(n, number, float) for n, number in said])
    stream = FapStream.from_curves({1: numbers, 3: np.full(numbers.size, 0.6 * 200.0 * OPENING_SCALE),
                                    4: np.full(numbers.size, -0.15 * 200.0 * OPENING_SCALE),
                                    5: np.full(numbers.size, -0.25 * 200.0 * OPENING_SCALE)},
                                   fps=FPS)
    shapes = [cue.shape for cue in mouth_cues(stream)]
    # silence at the ends idle (X), /a/ D, /p b m/ A, /f v/ G, /o/ F, /e/ C, /i/ B, /u/ F
    assert shapes == ["X", "D", "A", "D", "G", "F", "C", "B", "F", "X"]
    starts = [cue.start_s for cue in mouth_cues(stream)]
    assert starts == [round(sum(n for n, _ in said[:k]) / FPS, 2) for k in range(len(said))]
    # where the stream does not say the viseme (FAP 1 masked off), the lips' opening chooses the shape
    mask = stream.mask.copy()
    mask[:19, 0] = False  # the silence, /a/ and /p b m/: the lips are 200 MNS open there
    partial = FapStream(stream.values, mask, FPS)
    assert [cue.shape for cue in mouth_cues(partial)][:3] == ["B", "D", "G"]
    # and where the lips are closed (a /p/'s closure carried onto the vowel before it), the viseme is closed too
    values = stream.values.copy()
    values[13:16, 2:5] = 0.0  # the last three frames of the first /a/
    closing = [(cue.start_s, cue.shape) for cue in mouth_cues(FapStream(values, stream.mask, FPS))]
    assert closing[1:3] == [(round(10 / FPS, 2), "D"), (round(13 / FPS, 2), "A")]


def test_every_file_ends_idle_as_rhubarbs_do(tmp_path: Path) -> None:
    """Speech to the last frame: the last cue is still X (on 4 of 9 clips the JSON and XML ended with B)."""
    stream = _stream([(10, 0.0, 0.0, "X"), (20, 330.0, 0.0, "D")])
    cues = mouth_cues(stream)
    assert cues[-1].shape == "X" and cues[-1].end_s == pytest.approx(1.0) and cues[-2].shape == "D"
    write_stream(stream, tmp_path / "end.rhubarb.json")
    assert json.loads((tmp_path / "end.rhubarb.json").read_text())["mouthCues"][-1]["value"] == "X"


def test_a_dat_file_at_the_projects_frame_rate(tmp_path: Path) -> None:
    """The .dat was always 24 fps, so a 30 fps Moho project played it 25 % slow: --dat-frame-rate."""
    from prosody.fap.mouth_cues import write_moho_dat

    stream = _stream()
    write_moho_dat(stream, tmp_path / "a.dat", dat_fps=30)
    rows = [line.split() for line in (tmp_path / "a.dat").read_text().splitlines()[1:]]
    starts = {shape: int(frame) for frame, shape in rows[::-1]}  # each shape's first frame
    # Rhubarb's frame rule: the frame a cue's start (on its 0.01 s grid) falls in, from 1
    assert starts["D"] == 1 + int(30 * round(10 / FPS, 2)) and starts["A"] == 1 + int(30 * round(16 / FPS, 2))
    assert starts["D"] != 1 + int(24 * round(10 / FPS, 2))  # not the 24 fps frames
    from prosody.errors import ConfigError

    with pytest.raises(ConfigError, match="1-1000"):
        write_moho_dat(stream, tmp_path / "b.dat", dat_fps=0)
    assert main(["convert", str(Path(__file__).parents[1] / "samples" / "arctic_a0009.wav"), "-o",
                 str(tmp_path / "c.fap"), "--dat-frame-rate", "30"]) == 2
    assert not (tmp_path / "c.fap").exists()


def test_a_stream_without_lips_is_idle() -> None:
    stream = FapStream.from_curves({48: np.zeros(45)}, fps=FPS)
    assert [(c.start_s, c.end_s, c.shape) for c in mouth_cues(stream)] == [(0.0, 1.5, "X")]


def _read_tsv(path: Path) -> list[tuple[float, str]]:
    rows = []
    for line in path.read_text().splitlines():
        time, shape = line.split("\t")
        assert len(time.split(".")[1]) == 2  # seconds with two decimals
        rows.append((float(time), shape))
    return rows


def test_each_file_is_what_rhubarbs_description_says(tmp_path: Path) -> None:
    stream = _stream()
    expected = _expected()
    expected[-1] = (expected[-1][0], 1.8, "X")
    for ending, name in ((".rhubarb.tsv", "rhubarb-tsv"), (".rhubarb.json", "rhubarb-json"),
                         (".rhubarb.xml", "rhubarb-xml"), (".dat", "moho-dat"),
                         (".prestonblair.dat", "prestonblair-dat")):
        assert format_for(f"talk{ending}") == name
        write_stream(stream, tmp_path / f"hello{ending}")
    # TSV: a line per cue from 0.00, then the end of the recording with the closed mouth
    rows = _read_tsv(tmp_path / "hello.rhubarb.tsv")
    assert rows[:-1] == [(start, shape) for start, _, shape in expected]
    assert rows[-1] == (1.8, "X")
    # JSON: metadata (soundFile, duration) and mouthCues whose ends are the next starts
    document = json.loads((tmp_path / "hello.rhubarb.json").read_text())
    assert document["metadata"] == {"soundFile": "hello", "duration": 1.8}
    assert [(c["start"], c["end"], c["value"]) for c in document["mouthCues"]] == expected
    # XML: rhubarbResult > metadata, mouthCues > mouthCue(start, end) with the shape as text
    root = ElementTree.parse(tmp_path / "hello.rhubarb.xml").getroot()
    assert root.tag == "rhubarbResult"
    assert root.findtext("metadata/soundFile") == "hello" and root.findtext("metadata/duration") == "1.80"
    cues = [(float(c.get("start")), float(c.get("end")), c.text) for c in root.iterfind("mouthCues/mouthCue")]
    assert cues == expected
    # Moho switch: MohoSwitch1, then "frame shape" at 24 fps from frame 1, the closed mouth at the end
    lines = (tmp_path / "hello.dat").read_text().splitlines()
    assert lines[0] == "MohoSwitch1"
    frames = [(int(line.split()[0]), line.split()[1]) for line in lines[1:]]
    assert frames[:-1] == [(1 + int(24 * start + 1e-9), shape) for start, _, shape in expected]
    assert frames[-1] == (1 + int(24 * 1.8 + 1e-9), "X")
    named = (tmp_path / "hello.prestonblair.dat").read_text().splitlines()
    assert [line.split()[1] for line in named[1:]] == [PRESTON_BLAIR[shape] for _, shape in frames]


def test_convert_writes_rhubarb_cues_of_a_recording(tmp_path: Path) -> None:
    from conftest import REPO

    out = tmp_path / "a9.rhubarb.tsv"
    assert main(["convert", str(REPO / "samples" / "arctic_a0009.wav"), "-o", str(out), "-q"]) == 0
    rows = _read_tsv(out)
    # the end is the recording's (49,520 samples at 16 kHz: 3.095 s) truncated to 0.01 s, as Rhubarb's is
    assert rows[0][0] == 0.0 and rows[-1] == (3.09, "X")
    assert all(a[0] < b[0] for a, b in zip(rows, rows[1:], strict=False))
    shapes = {shape for _, shape in rows}
    assert shapes <= set("ABCDEFGX") and len(shapes) >= 4  # speech moves through several shapes
    assert "A" in shapes  # "He turned sharply, and faced Gregson across the table": the /p/ and /b/ close
    assert "G" in shapes  # the /f/ of "faced": the lower lip under the teeth, known from the phones' visemes


def test_the_viseme_said_is_in_json_outputs_and_never_in_fap_files(tmp_path: Path, capsys) -> None:
    from conftest import REPO

    from prosody.fap.fapfile import read_fap

    speech = str(REPO / "samples" / "arctic_a0009.wav")
    assert main(["convert", speech, "-o", str(tmp_path / "a9.json")]) == 0
    said = capsys.readouterr()
    assert "FAPs 1 3 4 5" in said.out + said.err
    document = json.loads((tmp_path / "a9.json").read_text())
    visemes = next(entry for entry in document["faps"] if entry["fap"] == 1)
    assert visemes["name"] == "viseme" and set(visemes["values"]) <= set(range(15)) and 1 in visemes["values"]
    assert main(["convert", speech, "-o", str(tmp_path / "a9.fap")]) == 0
    said = capsys.readouterr()
    assert "FAPs 3 4 5" in said.out + said.err  # the message names what the file holds
    assert 1 not in read_fap(tmp_path / "a9.fap").stream.active_faps


def test_convert_puts_cues_on_rhubarbs_grid_unless_a_frame_rate_is_given(tmp_path: Path) -> None:
    """Rhubarb's cues start on any 0.01 s; ours changed only on the 1/30 s frames. Now the cue formats are made at
    100 fps, on the command line and in the library alike; --fps 30 (or fps=30) keeps the 30 fps frames."""
    from conftest import REPO

    from prosody.jobs.pipeline import convert

    speech = str(REPO / "samples" / "arctic_a0009.wav")

    def off_the_frames(rows) -> int:
        # a frame k/30 s written to 0.01 s is within 0.15 frames of k; the other starts on the 0.01 s grid are 0.2+ off
        return sum(abs(start * 30 - round(start * 30)) > 0.16 for start, _ in rows)

    assert main(["convert", speech, "-o", str(tmp_path / "a.rhubarb.tsv"), "-q"]) == 0
    assert main(["convert", speech, "-o", str(tmp_path / "b.rhubarb.tsv"), "-q", "--fps", "30"]) == 0
    assert off_the_frames(_read_tsv(tmp_path / "a.rhubarb.tsv")) >= 3
    # (at 30 fps the last cue but one, the closing X, may take the recording's last 0.01 s: off the frames)
    assert off_the_frames(_read_tsv(tmp_path / "b.rhubarb.tsv")[:-2]) == 0
    assert convert(speech, tmp_path / "c.rhubarb.json").fps == 100
    assert convert(speech, tmp_path / "d.rhubarb.json", fps=30).fps == 30
    assert convert(speech, tmp_path / "e.fap").fps == 30  # other formats keep the motion's 30 fps
    assert main(["convert", speech, "-o", str(tmp_path / "f.fap"), "-q"]) == 0
    from prosody.fap.fapfile import read_fap

    assert read_fap(tmp_path / "f.fap").stream.fps == 30


@pytest.mark.parametrize("ending", [".rhubarb.json", ".dat"])
def test_convert_can_write_cues_to_standard_output(ending, capsys) -> None:
    from conftest import REPO

    name = {".rhubarb.json": "rhubarb-json", ".dat": "moho-dat"}[ending]
    assert main(["convert", str(REPO / "samples" / "arctic_a0009.wav"), "-o", "-", "--format", name, "-q"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("{") if ending == ".rhubarb.json" else text.startswith("MohoSwitch1")


@pytest.mark.parametrize("ending", [".rhubarb.json", ".rhubarb.xml", ".dat"])
def test_cue_files_name_the_recording_and_end_where_it_ends(tmp_path: Path, ending) -> None:
    """As Rhubarb's own files: ``soundFile`` is the recording's absolute path (Rhubarb's Vegas importer opens
    it), and the duration and the last cue end at the recording's length truncated to 0.01 s, not on the
    frame grid past it (1.234 s of sound at 30 fps is 38 frames, 1.2667 s)."""
    import soundfile
    from conftest import REPO

    clip = tmp_path / "short clip.wav"
    samples, rate = soundfile.read(REPO / "samples" / "arctic_a0009.wav")
    soundfile.write(clip, samples[: int(1.234 * rate)], rate)
    out = tmp_path / f"cues{ending}"
    assert main(["convert", str(clip), "-o", str(out), "-q", *(["--dat-frame-rate", "100"] if ending == ".dat"
                                                               else [])]) == 0
    if ending == ".rhubarb.json":
        document = json.loads(out.read_text())
        assert document["metadata"] == {"soundFile": str(clip.absolute()), "duration": 1.23}
        assert document["mouthCues"][-1]["end"] == 1.23 and document["mouthCues"][-1]["value"] == "X"
    elif ending == ".rhubarb.xml":
        root = ElementTree.parse(out).getroot()
        assert root.findtext("metadata/soundFile") == str(clip.absolute())
        assert root.findtext("metadata/duration") == "1.23"
        assert root.findall("mouthCues/mouthCue")[-1].get("end") == "1.23"
    else:  # at 100 frames a second the closing X is at frame 1 + 123
        assert out.read_text().splitlines()[-1] == "124 X"


@pytest.mark.parametrize("name", ["bad\x01name", "tab\tand\x7fdel", "undecodable\udcff"])
def test_cue_files_stay_well_formed_whatever_the_name(tmp_path: Path, name) -> None:
    """A stream named with control characters or bytes that are not UTF-8 (a file name's) is written as
    \\xNN in the metadata: the XML parses and the JSON holds no lone surrogate."""
    from prosody.fap.mouth_cues import write_rhubarb_json, write_rhubarb_xml

    stream = dataclasses.replace(_stream(), name=name)
    write_rhubarb_xml(stream, tmp_path / "a.rhubarb.xml")
    sound_file = ElementTree.parse(tmp_path / "a.rhubarb.xml").getroot().findtext("metadata/soundFile")
    assert sound_file is not None and "\\x" in sound_file
    write_rhubarb_json(stream, tmp_path / "a.rhubarb.json")
    text = (tmp_path / "a.rhubarb.json").read_text(encoding="utf-8")
    assert "\\ud" not in text.lower() and "\\x" in json.loads(text)["metadata"]["soundFile"]


def test_extended_shapes_left_out_become_their_basic_shapes(tmp_path: Path, capsys) -> None:
    """Rhubarb's --extendedShapes: G, H and X are optional; left out, G becomes A, H C and X A. The cues of the
    sample recording (it has an /f/: G, and pauses: X) with none of them hold only A-F and end closed (A);
    with GX they are the default's."""
    from conftest import REPO

    speech = str(REPO / "samples" / "arctic_a0009.wav")
    every = tmp_path / "every.rhubarb.tsv"
    basic = tmp_path / "basic.rhubarb.tsv"
    assert main(["convert", speech, "-o", str(every), "-q"]) == 0
    assert main(["convert", speech, "-o", str(basic), "-q", "--extended-shapes", ""]) == 0
    every_rows, basic_rows = _read_tsv(every), _read_tsv(basic)
    assert {"G", "X"} <= {shape for _, shape in every_rows}
    assert {shape for _, shape in basic_rows} <= set("ABCDEF") and basic_rows[-1][1] == "A"
    # played at any time, the basic cue is the full one with G and X as A
    def at(rows, t):
        return next(shape for start, shape in reversed(rows) if start <= t + 1e-9)
    for t in np.arange(0, every_rows[-1][0], 0.01):
        assert at(basic_rows, t) == {"G": "A", "X": "A"}.get(at(every_rows, t), at(every_rows, t))
    gx = tmp_path / "gx.rhubarb.tsv"
    assert main(["convert", speech, "-o", str(gx), "-q", "--extended-shapes", "xg"]) == 0
    assert _read_tsv(gx) == every_rows
    # refused before the audio: letters that are not extended shapes, or an output that is not cues
    assert main(["convert", speech, "-o", str(tmp_path / "x.rhubarb.tsv"), "--extended-shapes", "GA"]) == 2
    assert main(["convert", speech, "-o", str(tmp_path / "x.fap"), "--extended-shapes", "GX"]) == 2
    assert "extended" in capsys.readouterr().err
