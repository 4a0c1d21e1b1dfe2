"""The drawn-face preview (``face="drawn"``; the 3D head is in test_head3d.py): brow height follows FAP
31-36, head angles move the face with the FAP signs, and the GIF and MP4 writers produce complete files (or
none)."""

from __future__ import annotations

import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import soundfile

from prosody.cli import main
from prosody.errors import ConfigError
from prosody.evaluation.preview import (
    BROW_COLOR,
    MAX_GIF_FRAMES,
    FaceRenderer,
    PreviewError,
    find_ffmpeg,
    render_frames,
    write_preview,
)
from prosody.fap.fapfile import write_fap
from prosody.fap.stream import FapStream
from prosody.outputs import write_stream

WIDTH = 320


def _color_mask(frame: np.ndarray, color: tuple[int, int, int], *, tolerance: int = 30) -> np.ndarray:
    return np.abs(frame.astype(int) - np.array(color)).max(axis=2) <= tolerance


def _centroid(mask: np.ndarray) -> tuple[float, float]:
    rows, columns = np.nonzero(mask)
    assert rows.size > 0, "nothing of that colour was drawn"
    return float(columns.mean()), float(rows.mean())


def _brows(frame: np.ndarray, renderer: FaceRenderer) -> tuple[np.ndarray, np.ndarray]:
    """Brow pixels of the character's left brow (viewer's right half) and right brow, in the face area."""
    mask = _color_mask(frame[: renderer.face_height], BROW_COLOR)
    half = renderer.width // 2
    left, right = mask.copy(), mask.copy()
    left[:, :half] = False
    right[:, half:] = False
    return left, right


def _frames(curves: dict[int, np.ndarray], *, brow_scale: float = 1.0) -> list[np.ndarray]:
    return list(render_frames(FapStream.from_curves(curves, fps=30), width=WIDTH, strip=False, brow_scale=brow_scale,
                              face="drawn"))


def test_brow_height_follows_fap_31_to_36_at_true_scale() -> None:
    raises = np.array([0.0, 100.0, 250.0, 500.0, 1000.0])
    frames = _frames({fap: raises for fap in (31, 32, 33, 34, 35, 36)})
    renderer = FaceRenderer(WIDTH)
    expected_px = raises / 1024 * renderer.ens_pixels  # FAPU: ENS = ENS0 / 1024
    for side in (0, 1):
        heights = np.array([_centroid(_brows(frame, renderer)[side])[1] for frame in frames])
        np.testing.assert_allclose(heights[0] - heights, expected_px, atol=0.5)
    assert expected_px[-1] > 10  # the test moves the brows far enough to mean something


def test_fap_31_raises_the_inner_end_of_the_characters_left_brow_only() -> None:
    from prosody.evaluation.preview import FacePose

    width = 640
    renderer = FaceRenderer(width)
    frames = list(render_frames(FapStream.from_curves({31: np.array([0.0, 800.0]), 32: np.zeros(2)}, fps=30),
                                width=width, strip=False, brow_scale=1, face="drawn"))
    rise_px = 800 / 1024 * renderer.ens_pixels
    inner_x, middle_x, outer_x = renderer.brow_points(FacePose())["left"][:, 0]
    neutral_left, neutral_right = _brows(frames[0], renderer)
    raised_left, raised_right = _brows(frames[1], renderer)

    def top_row(mask: np.ndarray, x: float) -> int:
        return int(np.nonzero(mask[:, round(x)])[0].min())

    # the inner end moves by the whole raise; along the brow the raise fades linearly to the middle point
    near_inner = inner_x + 2
    expected = rise_px * (1 - (near_inner - inner_x) / (middle_x - inner_x))
    assert top_row(neutral_left, near_inner) - top_row(raised_left, near_inner) == pytest.approx(expected, abs=1.5)
    assert top_row(neutral_left, outer_x - 2) == top_row(raised_left, outer_x - 2)
    assert np.array_equal(neutral_right, raised_right)
    assert rise_px > 20


@pytest.mark.parametrize(("fap", "axis", "sign"), [
    (48, 1, +1),   # + pitch bows the head: the nose goes down (image rows grow downward)
    (49, 0, +1),   # + yaw turns to the character's left, the viewer's right
])
def test_head_angles_move_the_nose_with_the_fap_signs(fap: int, axis: int, sign: int) -> None:
    nose_color = (185, 135, 105)
    frames = _frames({fap: np.array([0.0, 10000.0])})  # 0.1 rad
    before = _centroid(_color_mask(frames[0], nose_color, tolerance=12))
    after = _centroid(_color_mask(frames[1], nose_color, tolerance=12))
    assert sign * (after[axis] - before[axis]) > 3


def test_positive_roll_tilts_the_head_to_the_characters_right() -> None:
    renderer = FaceRenderer(WIDTH)
    frames = _frames({50: np.array([0.0, 10000.0])})
    heights = []
    for frame in frames:
        left, right = _brows(frame, renderer)
        heights.append(_centroid(left)[1] - _centroid(right)[1])
    # the character's left brow (viewer's right) rises above the right one as the head tips to its right
    assert heights[1] - heights[0] < -3


def test_head_outline_is_the_ellipse_of_the_rotated_head() -> None:
    renderer = FaceRenderer(WIDTH)
    from prosody.evaluation.preview import FacePose

    still = renderer.head_outline(FacePose())
    a, b, _ = renderer.model.head_radii
    width_px, height_px = np.ptp(still[:, 0]), np.ptp(still[:, 1])
    assert width_px == pytest.approx(2 * a * renderer.scale, rel=1e-3)
    assert height_px == pytest.approx(2 * b * renderer.scale, rel=1e-3)
    turned = renderer.head_outline(FacePose(roll_rad=np.pi / 2))  # on its side: width and height swap
    assert np.ptp(turned[:, 0]) == pytest.approx(height_px, rel=1e-3)


def test_gif_has_one_frame_per_stream_frame_and_keeps_time(tmp_path: Path) -> None:
    from PIL import Image

    n_frames = 20
    stream = FapStream.from_curves({31: np.linspace(0, 300, n_frames), 48: np.linspace(0, 3000, n_frames)}, fps=30)
    reported: list[tuple[int, int]] = []
    path = write_preview(stream, tmp_path / "face.gif", width=96, progress=lambda *done: reported.append(done))
    assert reported == [(k, n_frames) for k in range(1, n_frames + 1)]
    with Image.open(path) as image:
        durations = []
        for index in range(image.n_frames):
            image.seek(index)
            durations.append(image.info["duration"])
        assert image.n_frames == n_frames
        assert image.size == (96, 120)
    # GIF delays are whole centiseconds: 30 fps alternates 30 and 40 ms and ends on time
    assert set(durations) <= {30, 40}
    assert sum(durations) == pytest.approx(n_frames / 30 * 1000, abs=10)


def test_excerpt_and_bad_requests(tmp_path: Path) -> None:
    from PIL import Image

    stream = FapStream.from_curves({31: np.linspace(0.0, 900.0, 90)}, fps=30)
    path = write_preview(stream, tmp_path / "part.gif", width=64, start_s=1.0, duration_s=0.5)
    with Image.open(path) as image:
        total_ms = 0
        for index in range(image.n_frames):
            image.seek(index)
            total_ms += image.info["duration"]
    assert total_ms == 500
    with pytest.raises(ConfigError, match="mp4 or .gif"):
        write_preview(stream, tmp_path / "face.avi")
    with pytest.raises(ConfigError, match="past the end"):
        write_preview(stream, tmp_path / "late.gif", start_s=5.0)
    long_stream = FapStream.from_curves({31: np.zeros(MAX_GIF_FRAMES + 1)}, fps=30)
    with pytest.raises(PreviewError, match="too long"):
        write_preview(long_stream, tmp_path / "long.gif", width=64)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["part.gif"]


def test_mp4_without_ffmpeg_says_so_and_writes_nothing(tmp_path: Path) -> None:
    stream = FapStream.from_curves({31: np.zeros(5)}, fps=30)
    with pytest.raises(PreviewError, match="needs ffmpeg"):
        write_preview(stream, tmp_path / "face.mp4", ffmpeg=None)
    with pytest.raises(PreviewError, match="ffmpeg failed"):
        write_preview(stream, tmp_path / "face.mp4", width=64, ffmpeg="false")
    assert list(tmp_path.iterdir()) == []


def _probe(ffmpeg: str, path: Path) -> str:
    result = subprocess.run([ffmpeg, "-hide_banner", "-i", str(path), "-map", "0", "-f", "null", "-"],
                            capture_output=True, text=True, check=True)
    return result.stderr


@pytest.mark.skipif(find_ffmpeg() is None, reason="no ffmpeg on PATH and imageio-ffmpeg not installed")
def test_mp4_has_every_frame_and_the_audio(tmp_path: Path) -> None:
    ffmpeg = find_ffmpeg()
    assert ffmpeg is not None
    rate = 16000
    t = np.arange(int(rate * 1.0)) / rate
    soundfile.write(tmp_path / "tone.wav", 0.3 * np.sin(2 * np.pi * 220 * t), rate)
    stream = FapStream.from_curves({31: np.linspace(0, 300, 30), 49: np.linspace(0, 5000, 30)}, fps=30)
    path = write_preview(stream, tmp_path / "face.mp4", audio=tmp_path / "tone.wav", width=96)
    report = _probe(ffmpeg, path)
    assert "Video: h264" in report and "96x120" in report
    assert "Audio: aac" in report
    frames = [line for line in report.replace("\r", "\n").splitlines() if line.startswith("frame=")]
    assert frames and int(frames[-1].split("=")[1].split()[0]) == 30


@pytest.mark.skipif(find_ffmpeg() is None, reason="no ffmpeg on PATH and imageio-ffmpeg not installed")
def test_cli_preview_of_a_recording_and_of_a_fap_file(tmp_path: Path) -> None:
    from conftest import harmonic_tone

    tone_wav = tmp_path / "tone.wav"
    soundfile.write(tone_wav, harmonic_tone(240.0, 1.5, 16000), 16000)
    assert main(["preview", str(tone_wav), "-o", str(tmp_path / "tone.mp4"), "--width", "96"]) == 0
    assert main(["convert", str(tone_wav), "-o", str(tmp_path / "tone.fap")]) == 0
    assert main(["preview", str(tmp_path / "tone.fap"), "-o", str(tmp_path / "fap.gif"), "--width", "64",
                 "--exaggerate", "5"]) == 0
    assert main(["preview", str(tone_wav), "-o", str(tmp_path / "tone.webm")]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fap.gif", "tone.fap", "tone.mp4", "tone.wav"]


def test_side_by_side_panels_share_one_strip_scale_and_keep_their_own_motion(tmp_path: Path) -> None:
    from PIL import Image

    from prosody.evaluation.preview import render_frames, strip_scales, write_side_by_side

    still = FapStream.from_curves({48: np.zeros(6), 31: np.zeros(6)}, fps=30)
    moving = FapStream.from_curves({48: np.full(6, 8000.0), 31: np.full(6, 20.0)}, fps=30)
    assert strip_scales([still, moving]) == (20.0, 8000.0)
    path = write_side_by_side({"STILL": still, "MOVING": moving}, tmp_path / "pair.gif", panel_width=64)
    with Image.open(path) as image:
        assert image.n_frames == 6 and image.size == (128, 80)
        first = np.asarray(image.convert("RGB"))
    # each half is that stream's own face, drawn as the single preview draws it
    alone = next(render_frames(moving, width=64, label="MOVING", scales=(20.0, 8000.0)))
    assert np.abs(first[:, 64:].astype(int) - alone.astype(int)).mean() < 8  # GIF palette only
    assert np.abs(first[:, :64].astype(int) - first[:, 64:].astype(int)).mean() > 1  # the faces differ
    with pytest.raises(ConfigError, match="one length"):
        write_side_by_side({"a": still, "b": FapStream.from_curves({48: np.zeros(7)}, fps=30)}, tmp_path / "x.gif")
    assert not (tmp_path / "x.gif").exists()


@pytest.mark.slow
@pytest.mark.skipif(find_ffmpeg() is None, reason="no ffmpeg on PATH and imageio-ffmpeg not installed")
def test_compare_video_has_the_conditions_side_by_side_with_the_audio(tmp_path: Path) -> None:
    from conftest import segments

    ffmpeg = find_ffmpeg()
    assert ffmpeg is not None
    audio = tmp_path / "v.wav"
    soundfile.write(audio, segments(16000, (0.5, 140, 0.5), (0.4, 230, 0.5), (0.4, 150, 0.5)), 16000)
    assert main(["compare", str(audio), "-o", str(tmp_path / "out"), "--no-plots", "--video", "--seeds", "2"]) == 0
    report = _probe(ffmpeg, tmp_path / "out" / "conditions.mp4")
    assert "Video: h264" in report and "960x400" in report and "Audio: aac" in report  # 3 panels of 320 x 400


def test_previews_to_be_compared_can_share_the_strip_scale(tmp_path: Path) -> None:
    from prosody.evaluation.preview import CurveStrip

    small = FapStream.from_curves({48: np.linspace(0, 1000, 30), 31: np.full(30, 5.0)}, fps=30)
    large = FapStream.from_curves({48: np.linspace(0, 8000, 30), 31: np.full(30, 20.0)}, fps=30)
    own = CurveStrip(small, width=200, height=60)
    shared = CurveStrip(small, width=200, height=60, scales=(20.0, 8000.0))
    assert own.curves["pitch"].max() == pytest.approx(1.0)  # its own scale fills the strip
    assert shared.curves["pitch"].max() == pytest.approx(1000 / 8000)  # the shared one shows it smaller
    assert CurveStrip(large, width=200, height=60, scales=(20.0, 8000.0)).curves["pitch"].max() == pytest.approx(1)
    from prosody.fap.fapfile import write_fap

    write_fap(small, tmp_path / "small.fap")
    assert main(["preview", str(tmp_path / "small.fap"), "-o", str(tmp_path / "x.gif"), "--width", "64",
                 "--strip-scale", "20,4.6"]) == 0
    assert main(["preview", str(tmp_path / "small.fap"), "-o", str(tmp_path / "y.gif"), "--strip-scale", "a"]) == 2
    assert main(["preview", str(tmp_path / "small.fap"), "-o", str(tmp_path / "y.gif"), "--strip-scale", "0,5"]) == 2
    assert not (tmp_path / "y.gif").exists()


def test_brows_are_drawn_at_true_size_by_default_and_larger_when_asked() -> None:
    raises = np.array([0.0, 100.0])
    renderer = FaceRenderer(WIDTH)
    true_size = _frames({fap: raises for fap in (31, 32, 33, 34)})
    default = list(render_frames(FapStream.from_curves({fap: raises for fap in (31, 32, 33, 34)}, fps=30),
                                 width=WIDTH, strip=False, face="drawn"))
    larger = _frames({fap: raises for fap in (31, 32, 33, 34)}, brow_scale=4.0)
    rise = [_centroid(_brows(f[0], renderer)[0])[1] - _centroid(_brows(f[1], renderer)[0])[1]
            for f in (true_size, default, larger)]
    assert rise[1] == pytest.approx(rise[0], rel=0.05)
    assert rise[2] == pytest.approx(4 * rise[0], rel=0.1)
    from prosody.evaluation.preview import BROW_VIEW_SCALE, poses

    assert BROW_VIEW_SCALE == 1 and poses(FapStream.from_curves({31: raises}, fps=30))[1].left_brow_ens[0] == 100
    assert poses(FapStream.from_curves({31: raises}, fps=30), brow_scale=4)[1].left_brow_ens[0] == 400


@pytest.mark.parametrize("closing", [0.0, 200.0, 400.0, -150.0, 1024.0])
def test_eyelids_open_and_close_the_characters_left_eye_by_fap_19_and_21(closing: float) -> None:
    # at rest the lids rest on the iris (the opening is IRISD0); FAP 19 lowers the top lid and FAP 21 raises the
    # bottom one by closing * IRISD0 / 1024, within the eye and never past each other
    from prosody.evaluation.preview import _EYE_WHITE, _SKIN, _SKIN_EDGE

    renderer = FaceRenderer(WIDTH)
    m = renderer.model
    frame = _frames({19: np.array([closing]), 21: np.array([closing / 2])})[0][: renderer.face_height]
    rest = _frames({19: np.array([0.0])})[0][: renderer.face_height]
    top, bottom = m.eyelids(closing, closing / 2)
    expected = float(np.ptp(renderer.to_pixels(np.array([[m.eye_x, top, 0.0], [m.eye_x, bottom, 0.0]]))[:, 1]))
    centre = renderer.to_pixels(np.array([[m.eye_x, m.eye_y, 0.0], [-m.eye_x, m.eye_y, 0.0]]))
    for (column, row), moved in zip(centre, (True, False), strict=True):
        line = frame[:, int(column)][:, None, :]
        # the eye shows where the pixel is neither skin (a lid) nor a lid's edge: the run through the eye's centre
        shows = ~(_color_mask(line, _SKIN, tolerance=20) | _color_mask(line, _SKIN_EDGE, tolerance=20))[:, 0]
        run, k = 0, int(round(row))
        if shows[k]:
            lo, hi = k, k
            while shows[lo - 1]:
                lo -= 1
            while shows[hi + 1]:
                hi += 1
            run = hi - lo + 1
        if moved:  # the lids' edges are lines 2 px wide, centred on the lids
            assert run == pytest.approx(max(0.0, expected - 2), abs=2.0)
        else:  # the right eye keeps its neutral opening
            band = slice(int(row) - 20, int(row) + 20), slice(int(column) - 20, int(column) + 20)
            assert np.array_equal(frame[band], rest[band])
    assert _color_mask(frame, _EYE_WHITE, tolerance=10).any()  # the other eye is open
    assert m.irisd0 == pytest.approx(0.15) and m.eyelids(0.0, 0.0) == pytest.approx((0.175, 0.025))
    assert m.eyelids(2000.0, 2000.0)[0] == m.eyelids(2000.0, 2000.0)[1]  # shut, not crossed


def test_the_mouth_at_rest_is_straight_and_joy_and_sadness_bend_it_their_ways():
    from prosody.evaluation.preview import FacePose, FaceRenderer
    from prosody.motion.face.expressions import EXPRESSIONS

    renderer = FaceRenderer(WIDTH)

    def bend(lips: dict[int, float]) -> float:
        """Height of the lips' corners above their middle (face units; up is +y)."""
        upper, lower = renderer.mouth_points(FacePose(lip_faps=tuple(lips.items())))
        middle = (upper[6, 1] + lower[6, 1]) / 2
        return float((upper[0, 1] + upper[-1, 1]) / 2 - middle)

    assert bend({}) == pytest.approx(0.0, abs=1e-12)
    mns = (renderer.model.nose_bottom_y - renderer.model.mouth_y) / 1024
    joy = {fap: value for fap, value in EXPRESSIONS["joy"].items() if fap in (4, 5, 6, 7, 12, 13)}
    assert bend(joy) == pytest.approx(240 * mns)  # the corners rise by FAP 12/13, the middle stays
    sad = {fap: value for fap, value in EXPRESSIONS["sadness"].items() if fap in (4, 5, 6, 7, 12, 13)}
    # the corners fall by FAP 12/13; the middle moves by half of the upper lip's fall (4) and the lower's rise (5)
    middle = (-sad.get(4, 0.0) + sad.get(5, 0.0)) / 2
    assert sad[12] < 0 and bend(sad) == pytest.approx((sad[12] - middle) * mns)


def test_a_csv_export_is_refused_with_what_preview_reads(tmp_path: Path, capsys) -> None:
    exported = tmp_path / "talk.csv"
    exported.write_text("frame,time_s,fap3_open_jaw_mns\n0,0.000000,12\n")
    assert main(["preview", str(exported), "-o", str(tmp_path / "talk.gif")]) == 2
    said = capsys.readouterr().err
    assert "a .csv export is not read back" in said and ".json" in said
    assert not (tmp_path / "talk.gif").exists()


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "missing"])
def test_preview_audio_that_is_no_file_is_refused_before_anything(kind: str, tmp_path) -> None:
    """--audio FIFO hung the preview and /dev/zero reached ffmpeg: refused in one line, exit 2."""
    import os
    import subprocess
    import sys

    from prosody.fap.fapfile import write_fap

    write_fap(FapStream.from_curves({3: np.linspace(0, 300, 5)}, fps=25), tmp_path / "x.fap")
    audio = {"fifo": tmp_path / "pipe", "device": Path("/dev/zero"), "folder": tmp_path,
             "missing": tmp_path / "none.wav"}[kind]
    if kind == "fifo":
        os.mkfifo(audio)
    done = subprocess.run([sys.executable, "-m", "prosody", "preview", str(tmp_path / "x.fap"), "-o",
                           str(tmp_path / "x.mp4"), "--audio", str(audio)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "--audio" in done.stderr, done.stderr
    assert not (tmp_path / "x.mp4").exists()


def test_a_streams_name_cannot_drive_the_terminal(tmp_path) -> None:
    """Terminal escapes in a stream's name (a .json name, a .fap header) were printed raw by preview."""
    import subprocess
    import sys


    write_stream(FapStream.from_curves({3: np.linspace(0, 300, 5)}, fps=25, name="evil\x1b[2J\x1b]0;title\x07"),
                 tmp_path / "x.json")
    done = subprocess.run([sys.executable, "-m", "prosody", "preview", str(tmp_path / "x.json"), "-o",
                           str(tmp_path / "x.gif"), "--width", "64"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "\x1b" not in done.stderr and "\x07" not in done.stderr and "evil\\x1b[2J" in done.stderr


@pytest.mark.parametrize("options", [["--off", "brows"], ["--pitch-gain", "5"], ["--expression", "happy"],
                                     ["--condition", "none"], ["--seed", "3"], ["--lips", "acoustic"],
                                     ["--fps", "25"], ["--f0-floor", "60", "--brows", "thesis"]])
def test_options_that_make_a_stream_are_refused_for_a_stream_shown_as_it_is(tmp_path: Path, capsys,
                                                                            options) -> None:
    """preview X.fap (or .json) shows the stream as it is: the options that make a stream from a recording
    were silently ignored; now they are named, in one line, before anything is drawn."""
    write_fap(FapStream.from_curves({3: np.linspace(0, 300, 5)}, fps=25), tmp_path / "x.fap")
    write_stream(FapStream.from_curves({3: np.linspace(0, 300, 5)}, fps=25), tmp_path / "x.json")
    for stream in ("x.fap", "x.json"):
        assert main(["preview", str(tmp_path / stream), "-o", str(tmp_path / "x.gif"), *options]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and options[0] in err and "is a stream" in err, err
        if len(options) > 2:
            assert options[2] in err
        assert (" makes a stream" in err) == (len(options) == 2)  # one option makes, two make
    assert not (tmp_path / "x.gif").exists()
    # the drawing options stay
    assert main(["preview", str(tmp_path / "x.fap"), "-o", str(tmp_path / "x.gif"), "--width", "64",
                 "--exaggerate", "2", "--no-strip"]) == 0


@pytest.mark.parametrize("change, words", [
    ({"fps": 1e-300}, "frame rate"), ({"fps": 1e9}, "frame rate"), ({"fps": float("nan")}, "frame rate"),
    ({"name": "x" * 1_000_000}, "characters")])
def test_json_streams_out_of_bounds_are_refused_in_one_line(tmp_path: Path, capsys, change, words) -> None:
    """A JSON stream's frame rate is bounded to 1-1000 fps as a .fap file's (1e-300 overflowed Pillow, 1e9
    was accepted) and its name's length; the refusal is one line, exit 1 (a bad input file), no traceback."""
    import json

    write_stream(FapStream.from_curves({3: np.linspace(0, 300, 5)}, fps=25), tmp_path / "x.json")
    document = json.loads((tmp_path / "x.json").read_text())
    document.update(change)
    (tmp_path / "x.json").write_text(json.dumps(document))
    assert main(["preview", str(tmp_path / "x.json"), "-o", str(tmp_path / "x.gif"), "--width", "64"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err


@pytest.mark.parametrize("times", [[0.0, 0.0, 0.0], [0.0, 1e-9, 2e-9], [0.3, 0.2, 0.1]])
def test_jsonl_streams_whose_times_do_not_step_are_refused(tmp_path: Path, capsys, times) -> None:
    """Equal time_s divided by zero; steps of 1 ns made 1e9 fps; times that go back are not a stream."""
    import json

    lines = [json.dumps({"frame": k, "time_s": t, "faps": {"3": 100.0 * k}}) for k, t in enumerate(times)]
    (tmp_path / "x.jsonl").write_text("\n".join(lines) + "\n")
    assert main(["preview", str(tmp_path / "x.jsonl"), "-o", str(tmp_path / "x.gif"), "--width", "64"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.slow
def test_gifs_whose_frames_would_not_fit_in_memory_or_play_are_refused_before_drawing(tmp_path: Path) -> None:
    """A GIF at --width 3840 held about 36 MB a frame (66 GB at the 1,800 frames allowed); a 1000 fps GIF had
    delays of 0 ms, which players slow to 100 ms. Both are refused in one line, with what to do instead, and
    nothing is written; the default width's longest GIF stays within the bound."""
    from prosody.evaluation.preview import MAX_GIF_PIXELS, check_gif

    stream = FapStream.from_curves({3: np.zeros(300)}, fps=30)
    with pytest.raises(PreviewError, match="GB while it is written.*smaller width"):
        write_preview(stream, tmp_path / "big.gif", width=3840, strip=False)
    with pytest.raises(PreviewError, match="too fast for a GIF"):
        write_preview(FapStream.from_curves({3: np.zeros(100)}, fps=1000), tmp_path / "fast.gif", width=64)
    assert not list(tmp_path.iterdir())
    check_gif(tmp_path / "x.gif", fps=30, n_frames=MAX_GIF_FRAMES, width=480, height=600)  # the default: allowed
    assert MAX_GIF_FRAMES * 480 * 600 <= MAX_GIF_PIXELS
    write_preview(FapStream.from_curves({3: np.zeros(10)}, fps=50), tmp_path / "ok.gif", width=64)
    assert (tmp_path / "ok.gif").is_file()


def test_excerpts_at_the_edges_and_bounds_of_what_preview_reads(tmp_path: Path, capsys) -> None:
    """The probe's low items: a zero-frame .fap was 'start 0 s past the end' (exit 2), now 'no frames' (1);
    --start 0.099 on a 0.10 s stream was refused by rounding; --duration 1e-9 was reported as 0.00 s; a
    --strip-scale of 1e-320 leaked numpy's overflow warnings; .fap values to 1.7e308 and a frame number of
    1e300 were read."""
    (tmp_path / "empty.fap").write_text("2.1 empty 30 0\n")
    assert main(["preview", str(tmp_path / "empty.fap"), "-o", str(tmp_path / "e.gif")]) == 1
    assert "no frames" in capsys.readouterr().err
    write_fap(FapStream.from_curves({3: np.array([0.0, 100.0, 200.0])}, fps=30), tmp_path / "short.fap")
    assert main(["preview", str(tmp_path / "short.fap"), "-o", str(tmp_path / "s.gif"), "--width", "64",
                 "--start", "0.099"]) == 0
    assert "1 frame, 0.03 s from 0.07 s" in capsys.readouterr().err
    assert main(["preview", str(tmp_path / "short.fap"), "-o", str(tmp_path / "d.gif"), "--width", "64",
                 "--duration", "1e-9"]) == 0
    assert "1 frame, 0.03 s from 0.00 s" in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["preview", str(tmp_path / "short.fap"), "-o", str(tmp_path / "x.gif"),
                     "--strip-scale", "1e-320,5"]) == 2
    assert "0.001 to 1000000" in capsys.readouterr().err
    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    for line, said in (("0 1.7e308", "beyond +-16777216"), ("1e300 5", "frame number")):
        (tmp_path / "huge.fap").write_text(f"2.1 huge 30 1\n{mask}\n{line}\n")
        assert main(["preview", str(tmp_path / "huge.fap"), "-o", str(tmp_path / "h.gif")]) == 1
        assert said in capsys.readouterr().err
    assert not any(p.name in ("e.gif", "x.gif", "h.gif") for p in tmp_path.iterdir())
