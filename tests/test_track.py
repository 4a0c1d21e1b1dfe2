"""prosody track: video reading, the face's curves, gaps, sync, and the files it writes.

Known answers: rotations composed from known angles; ramps resampled onto the grid; the talking-heads
README's audio-video lags (computed there independently); and real clips transformed in ways whose effect
on the curves is known (a mirror negates yaw and roll, a rotation flag shown upright changes nothing, a
sound that starts half a second late moves every curve 15 frames).
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import warnings

import numpy as np
import pytest
import soundfile
from conftest import SHARED_DATA

from prosody.cli import main
from prosody.errors import ConfigError, TrackingError
from prosody.fap.recorded import RecordedGapWarning, read_head_csv, read_mouth_csv
from prosody.measures import opening_agreement
from prosody.tracking.curves import EnvelopeAccumulator, estimate_sync, on_grid
from prosody.tracking.face import head_angles

av = pytest.importorskip("av", reason="the 'track' extra (PyAV) is not installed")
pytest.importorskip("mediapipe", reason="the 'track' extra (MediaPipe) is not installed")

VIDEOS = SHARED_DATA / "talking-videos"
HEADS = SHARED_DATA / "talking-heads"
CLIP = VIDEOS / "LipNet_GRID_bbaf2n.mpg"  # 3 s, 25 fps, 360x288, MPEG-1 video and MP2 sound at 44.1 kHz


def needs_clip(test):
    """Reads the shared talking-videos clip: skipped where it is absent."""
    return pytest.mark.shared_data(pytest.mark.skipif(not CLIP.is_file(),
                                                      reason="shared talking-videos not available")(test))


def _rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return z @ y @ x


@pytest.mark.parametrize("angles", [(0.1, -0.3, 0.2), (-0.4, 0.5, -0.6), (0.0, 0.0, 0.0), (0.7, -1.2, 1.0)])
def test_head_angles_recover_composed_rotations(angles):
    assert head_angles(_rotation(*angles)) == pytest.approx(angles, abs=1e-9)


def test_on_grid_resamples_a_ramp_at_25_fps_onto_30_fps():
    times = np.arange(75) / 25.0  # 3 s
    values = np.column_stack([times * 2.0, -times])
    out, bridged, missing = on_grid(times, values, n_frames=90)
    grid = np.arange(90) / 30.0
    assert np.allclose(out[:89, 0], grid[:89] * 2.0) and np.allclose(out[:89, 1], -grid[:89])
    assert out[89].tolist() == values[-1].tolist()  # past the last picture (2.96 s) it is held, not extrapolated
    assert bridged == 0 and missing == 0


def test_on_grid_bridges_short_gaps_and_leaves_long_ones_empty():
    times = np.arange(150) / 25.0
    values = np.column_stack([times])
    values[20:24] = np.nan  # 4 frames, 0.16 s: bridged
    values[60:100] = np.nan  # 1.6 s: left empty
    out, bridged, missing = on_grid(times, values, n_frames=180, max_gap_s=0.25)
    grid = np.arange(180) / 30.0
    short = (grid > 19 / 25) & (grid < 24 / 25)
    assert np.allclose(out[short, 0], grid[short])  # a ramp interpolates exactly
    long = (grid > 59 / 25) & (grid < 100 / 25)
    assert np.isnan(out[long, 0]).all()
    assert missing == int(long.sum()) and bridged == int(short.sum())
    known = ~np.isnan(out[:179, 0])
    assert np.allclose(out[:179][known, 0], grid[:179][known])


def test_on_grid_holds_the_last_frame_only_one_video_frame_past_the_picture():
    times = np.arange(25) / 25.0  # the picture ends at 0.96 s
    out, _, missing = on_grid(times, np.ones((25, 1)), n_frames=33)  # the sound lasts 1.1 s
    assert np.isfinite(out[:30, 0]).all()  # up to 1.0 s: within a video frame of the last one
    assert np.isnan(out[31:, 0]).all() and missing == 33 - 30 - int(np.isfinite(out[30, 0]))


def test_envelope_is_the_rms_of_a_tone_whatever_the_blocks():
    rate = 16000
    t = np.arange(rate * 2) / rate
    tone = 0.5 * np.sin(2 * np.pi * 220 * t)
    whole = EnvelopeAccumulator(sample_rate_hz=rate)
    whole.add(tone)
    pieces = EnvelopeAccumulator(sample_rate_hz=rate)
    for start in range(0, tone.size, 777):
        pieces.add(tone[start:start + 777])
    assert np.allclose(whole.envelope(60), pieces.envelope(60))
    assert np.allclose(whole.envelope(60)[1:-1], 0.5 / math.sqrt(2), rtol=0.01)
    assert whole.envelope(70)[60:].tolist() == [0.0] * 10  # past the sound


#: The talking-heads README's lags (video taken this many 30 fps frames earlier than the audio), computed
#: there by its own code; the sync estimate finds them within a frame on the clips where it is reliable.
README_LAGS = {"KristiNoem": 5, "Obama_clip1": 8, "Obama_clip2": 6, "andrew_clip_1": 3, "reagan_clip1": 2}


@pytest.mark.shared_data
@pytest.mark.skipif(not HEADS.is_dir(), reason="shared talking-heads not available")
@pytest.mark.parametrize("clip", sorted(README_LAGS))
def test_sync_estimate_finds_the_readme_lags(clip):
    mouth = read_mouth_csv(HEADS / f"{clip}.mouth.csv")
    samples, rate = soundfile.read(HEADS / f"{clip}.wav")
    envelope = EnvelopeAccumulator(sample_rate_hz=rate)
    envelope.add(samples)
    estimate = estimate_sync(mouth.lip_opening, envelope.envelope(mouth.n_frames))
    assert estimate.reliable, estimate.describe()
    assert abs(estimate.lead_ms * 30 / 1000 - README_LAGS[clip]) <= 1 + 1e-6


def test_sync_estimate_says_when_it_cannot_tell():
    short = estimate_sync(np.random.default_rng(0).random(60), np.ones(60))
    assert short.lead_ms is None and "under" in short.reason
    rng = np.random.default_rng(1)
    noise = estimate_sync(rng.random(300), rng.random(300))  # unrelated: no reliable peak
    assert not noise.reliable


# Real clips -------------------------------------------------------------------------------------------
def _ffmpeg() -> str:
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    return imageio_ffmpeg.get_ffmpeg_exe()


def _run_ffmpeg(*arguments: str) -> None:
    subprocess.run([_ffmpeg(), "-v", "error", "-y", *arguments], check=True)


def _read_columns(path) -> dict[str, np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) if row[key] else np.nan for row in rows]) for key in rows[0]}


@pytest.fixture(scope="module")
def tracked(tmp_path_factory):
    """The clip tracked once by the command, for the tests that read its outputs."""
    if not CLIP.is_file():
        pytest.skip("shared talking-videos not available")
    out = tmp_path_factory.mktemp("tracked")
    assert main(["track", str(CLIP), "-o", str(out), "--quiet"]) == 0
    return out


@needs_clip
def test_track_writes_the_talking_heads_files(tracked):
    stem = tracked / CLIP.stem
    samples, rate = soundfile.read(f"{stem}.wav")
    assert rate == 16000 and samples.ndim == 1 and samples.size / rate == pytest.approx(3.0, abs=0.03)
    head = read_head_csv(f"{stem}.head.csv")
    assert head.n_frames == 90 and head.fps == 30  # 3 s of sound at 30 fps, from a 25 fps video
    mouth = read_mouth_csv(f"{stem}.mouth.csv")
    assert mouth.n_frames == 90
    # the frontal GRID speaker's opening, measured by the inner-lip landmarks and by the jawOpen blendshape,
    # is one curve: the two agree (r 0.97 here; the talking videos' median is 0.80)
    assert opening_agreement(mouth.lip_opening, mouth.jaw_open, fps=30.0) > 0.9
    columns = _read_columns(f"{stem}.brows.csv")
    assert list(columns)[:5] == ["frame", "time_s", "brow_inner_up", "brow_outer_up_l", "brow_outer_up_r"]
    assert np.isfinite(columns["inner_height_l"]).all()
    record = json.loads((tracked / f"{CLIP.stem}.track.json").read_text())
    assert record["video"]["fps"] == 25 and record["video_frames"] == 75 and record["faces_seen"] == 1
    assert record["missing_frames"] == 0
    assert record["mouth_agreement"] == pytest.approx(opening_agreement(mouth.lip_opening, mouth.jaw_open,
                                                                         fps=30.0), abs=1e-3)
    # the sound was not silent: the GRID speaker says a sentence
    assert np.sqrt(np.mean(samples**2)) > 0.01


@needs_clip
def test_a_complete_output_is_skipped_and_force_redoes_it(tracked, capsys):
    record = tracked / f"{CLIP.stem}.track.json"
    before = record.stat().st_mtime_ns
    assert main(["track", str(CLIP), "-o", str(tracked)]) == 0
    assert "1 already complete" in capsys.readouterr().err and record.stat().st_mtime_ns == before
    assert main(["track", str(CLIP), "-o", str(tracked), "--force", "--quiet"]) == 0
    assert record.stat().st_mtime_ns != before


@pytest.mark.slow
@needs_clip
def test_a_mirrored_video_negates_yaw_and_roll(tracked, tmp_path):
    mirrored = tmp_path / "mirrored.mp4"
    _run_ffmpeg("-i", str(CLIP), "-vf", "hflip", "-c:v", "libx264", "-crf", "12", "-c:a", "aac", str(mirrored))
    assert main(["track", str(mirrored), "-o", str(tmp_path), "--quiet"]) == 0
    original = _read_columns(tracked / f"{CLIP.stem}.head.csv")
    flipped = _read_columns(tmp_path / "mirrored.head.csv")
    n = min(original["rx_rad"].size, flipped["rx_rad"].size)
    assert np.corrcoef(original["rx_rad"][:n], flipped["rx_rad"][:n])[0, 1] > 0.9  # pitch unchanged
    for axis in ("ry_rad", "rz_rad"):
        assert np.median(np.abs(original[axis][:n] + flipped[axis][:n])) < 0.02  # yaw and roll negated (rad)


@pytest.mark.slow
@needs_clip
def test_a_rotation_flag_is_applied(tracked, tmp_path):
    turned = tmp_path / "turned.mp4"
    flagged = tmp_path / "flagged.mp4"
    # pixels turned 90 degrees clockwise, then flagged to be shown turned back: players show it upright
    _run_ffmpeg("-i", str(CLIP), "-vf", "transpose=1", "-c:v", "libx264", "-crf", "12", "-c:a", "aac", str(turned))
    _run_ffmpeg("-display_rotation", "90", "-i", str(turned), "-c", "copy", str(flagged))
    with av.open(str(flagged)) as container:
        assert round(next(container.decode(video=0)).rotation) % 360 == 90
    assert main(["track", str(flagged), "-o", str(tmp_path), "--quiet"]) == 0
    original = _read_columns(tracked / f"{CLIP.stem}.head.csv")
    upright = _read_columns(tmp_path / "flagged.head.csv")
    n = min(original["rz_rad"].size, upright["rz_rad"].size)
    assert np.median(np.abs(original["rz_rad"][:n] - upright["rz_rad"][:n])) < 0.02  # not 90 degrees of roll
    assert record_of(tmp_path, "flagged")["video"]["rotation_deg"] == 90


def record_of(folder, stem) -> dict:
    return json.loads((folder / f"{stem}.track.json").read_text())


@needs_clip
def test_a_sound_that_starts_late_moves_the_curves(tracked, tmp_path):
    late = tmp_path / "late.mkv"
    # the picture as it is, its own sound 0.5 s later: motion at video time t is at sound time t - 0.5
    _run_ffmpeg("-i", str(CLIP), "-itsoffset", "0.5", "-i", str(CLIP), "-map", "0:v", "-map", "1:a",
                "-c", "copy", str(late))
    assert main(["track", str(late), "-o", str(tmp_path), "--quiet"]) == 0
    assert record_of(tmp_path, "late")["video"]["video_start_s"] == pytest.approx(-0.5, abs=0.03)
    original = _read_columns(tracked / f"{CLIP.stem}.head.csv")
    shifted = _read_columns(tmp_path / "late.head.csv")
    n = min(original["ry_rad"].size - 15, shifted["ry_rad"].size)
    for axis in ("rx_rad", "ry_rad", "rz_rad"):
        assert np.nanmax(np.abs(shifted[axis][:n] - original[axis][15:15 + n])) < 0.01


@pytest.mark.slow
@needs_clip
def test_frames_without_a_face_become_empty_cells_and_the_reader_bridges_them(tmp_path):
    blanked = tmp_path / "blanked.mp4"
    # one second (frames 25-49 of 75) painted black: no face there
    _run_ffmpeg("-i", str(CLIP), "-vf", "drawbox=enable='between(n,25,49)':x=0:y=0:w=iw:h=ih:color=black:t=fill",
                "-c:v", "libx264", "-crf", "12", "-c:a", "aac", str(blanked))
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        assert main(["track", str(blanked), "-o", str(tmp_path), "--quiet"]) == 0
    head = _read_columns(tmp_path / "blanked.head.csv")
    empty = np.isnan(head["rx_rad"])
    assert 25 <= empty.sum() <= 32 and empty[32:58].all() and not empty[:29].any() and not empty[62:].any()
    with pytest.warns(RecordedGapWarning, match="left out of the measures"):
        stream = read_head_csv(tmp_path / "blanked.head.csv")
    assert not stream.mask[35:55, 47].any() and stream.mask[:25, 47].all()


def test_a_video_without_a_face_is_a_clear_error(tmp_path):
    noise = tmp_path / "noise.mp4"
    _run_ffmpeg("-f", "lavfi", "-i", "testsrc2=size=160x120:rate=25:duration=1", "-c:v", "libx264", str(noise))
    from prosody.jobs.track import TrackWarning, track_video

    with pytest.raises(TrackingError, match="no face found in any of its 25 frames"), \
            pytest.warns(TrackWarning, match="no sound in the video"):
        track_video(noise, tmp_path / "out")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())  # nothing half-written


@pytest.mark.parametrize("content, message", [
    (b"not a video at all", "not a video that FFmpeg can read"),
    (b"", "not a video that FFmpeg can read"),
])
def test_unreadable_videos_fail_in_one_line(tmp_path, capsys, content, message):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(content)
    assert main(["track", str(bad), "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").glob("bad.*"))


def test_track_refuses_clashing_stems_and_a_shared_audio(tmp_path):
    from prosody.jobs.track import track_videos

    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "take.mp4").write_bytes(b"x")
    with pytest.raises(ConfigError, match="would both write take"):
        track_videos([tmp_path / "a", tmp_path / "b"], tmp_path / "out")
    with pytest.raises(ConfigError, match="no such file or folder"):
        track_videos([tmp_path / "missing.mp4"], tmp_path / "out")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="no video found"):
        track_videos([tmp_path / "empty"], tmp_path / "out")
    (tmp_path / "a" / "other.mp4").write_bytes(b"y")
    with pytest.raises(ConfigError, match="--audio goes with one video only"):
        track_videos([tmp_path / "a"], tmp_path / "out", audio=tmp_path / "x.wav")


def test_the_face_model_is_the_pinned_file():
    import hashlib

    from prosody.tracking.face import MODEL_SHA256, model_path

    with open(model_path(), "rb") as handle:
        assert hashlib.sha256(handle.read()).hexdigest() == MODEL_SHA256


def test_the_users_own_wav_beside_the_video_is_never_replaced(tmp_path, capsys):
    # clip.mp4 has its own sound; clip.wav beside it is the user's (48 kHz stereo): tracking into that folder
    # would write clip.wav: refused in one line, the user's file untouched
    video = tmp_path / "clip.mp4"
    _run_ffmpeg("-f", "lavfi", "-i", "testsrc2=size=160x120:rate=25:duration=1", "-f", "lavfi", "-i",
                "sine=frequency=220:sample_rate=44100:duration=1", "-c:v", "libx264", "-c:a", "aac", "-shortest",
                str(video))
    theirs = tmp_path / "clip.wav"
    soundfile.write(theirs, np.zeros((4800, 2)), 48000)
    before = theirs.read_bytes()
    assert main(["track", str(video), "-o", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "clip.wav already exist(s) and was not written by 'prosody track'" in err and "Traceback" not in err
    assert theirs.read_bytes() == before
    assert sorted(path.name for path in tmp_path.iterdir()) == ["clip.mp4", "clip.wav"]
    # so are curve files of the same names; a record of an earlier tracking that lists them makes them ours
    theirs.unlink()
    (tmp_path / "clip.head.csv").write_text("mine\n")
    from prosody.jobs.track import _refuse_files_of_others

    with pytest.raises(ConfigError, match="clip.head.csv already exist"):
        _refuse_files_of_others(video, tmp_path / "clip", tmp_path / "clip.track.json", writes_wav=True)
    (tmp_path / "clip.track.json").write_text(json.dumps({"files": ["clip.head.csv"]}))
    _refuse_files_of_others(video, tmp_path / "clip", tmp_path / "clip.track.json", writes_wav=True)


@pytest.mark.slow
@needs_clip
@pytest.mark.parametrize("container", ["webm", "matroska"])
def test_a_silent_recording_without_a_length_in_its_header_is_timed_by_its_frames(tmp_path, container):
    # a browser recorder's file: written to a pipe, its header holds no duration
    silent = tmp_path / f"take.{'webm' if container == 'webm' else 'mkv'}"
    with open(silent, "wb") as out:
        subprocess.run([_ffmpeg(), "-v", "error", "-i", str(CLIP), "-an", "-c:v", "libvpx", "-b:v", "1M",
                        "-f", container, "pipe:1"], stdout=out, check=True)
    from prosody.tracking.video import probe_video

    assert not math.isfinite(probe_video(silent).duration_s) or probe_video(silent).duration_s == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["track", str(silent), "-o", str(tmp_path / "out"), "--quiet"]) == 0
    head = read_head_csv(tmp_path / "out" / "take.head.csv")
    assert head.n_frames == 90  # 75 pictures at 25 fps: 3 s at 30 fps
    assert json.loads((tmp_path / "out" / "take.track.json").read_text())["video_frames"] == 75


def test_an_unreliable_sync_estimate_states_no_lead() -> None:
    """A perfectly synced render read 'the mouth moves 433 ms ahead of the sound (r 0.10 ... unreliable)'."""
    from prosody.tracking.curves import SyncEstimate

    weak = SyncEstimate(433.0, 0.10, 120.0).describe()
    assert "433" not in weak and "ahead" not in weak and "no lead is stated" in weak and "r 0.10" in weak
    strong = SyncEstimate(-40.0, 0.6, 10.0).describe()
    assert strong == "the mouth moves 40 ms behind the sound (r 0.60, +-10 ms: reliable)"
    assert "not estimated" in SyncEstimate(None, None, None, "a still mouth").describe()
