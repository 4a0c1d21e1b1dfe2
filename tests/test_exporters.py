"""Exports parsed back by independent readers (csv, json, the bvh package), values checked against the stream;
and the per-channel intensity controls."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from bvh import Bvh

from prosody.cli import main
from prosody.errors import ConfigError, FapWriteError
from prosody.fap.exporters import ARKIT_BLENDSHAPES, BROW_FULL_SCALE_ENS, livelink_timecode
from prosody.fap.stream import FapStream
from prosody.jobs.pipeline import apply_controls
from prosody.outputs import format_for, write_stream


@pytest.fixture
def stream(rng) -> FapStream:
    n = 45
    curves = {31: np.linspace(0, 60, n), 32: np.linspace(0, 60, n), 33: np.full(n, 10.0), 34: np.full(n, 10.0),
              48: 3000 * np.sin(np.arange(n) / 7), 49: -2000 * np.cos(np.arange(n) / 5), 50: rng.normal(0, 800, n)}
    base = FapStream.from_curves(curves, fps=30, name="test stream")
    mask = base.mask.copy()
    mask[5, 49] = False  # FAP 50 masked off in frame 5
    return FapStream(base.values, mask, 30, "test stream")


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_format_from_extension_and_name() -> None:
    assert format_for("a.fap") == "fap" and format_for("a.CSV") == "csv" and format_for("a.livelink.csv") == "livelink"
    assert format_for("a.bvh") == "bvh" and format_for("a.json") == "json" and format_for("a.txt", "csv") == "csv"
    with pytest.raises(ConfigError, match="give output_format=NAME"):
        format_for("a.txt")


def test_csv_in_fap_units_and_physical(tmp_path, stream) -> None:
    write_stream(stream, tmp_path / "s.csv")
    rows = _rows(tmp_path / "s.csv")
    assert list(rows[0]) == ["frame", "time_s", "fap31_raise_l_i_eyebrow_ens", "fap32_raise_r_i_eyebrow_ens",
                             "fap33_raise_l_m_eyebrow_ens", "fap34_raise_r_m_eyebrow_ens", "fap48_head_pitch_au",
                             "fap49_head_yaw_au", "fap50_head_roll_au"]
    assert len(rows) == 45 and float(rows[30]["time_s"]) == pytest.approx(1.0)
    np.testing.assert_allclose([float(r["fap48_head_pitch_au"]) for r in rows], stream.curve(48), rtol=1e-5)
    assert rows[5]["fap50_head_roll_au"] == ""  # masked off in that frame
    write_stream(stream, tmp_path / "p.csv", "csv-physical")
    physical = _rows(tmp_path / "p.csv")
    np.testing.assert_allclose([float(r["fap48_head_pitch_rad"]) for r in physical], stream.curve(48) * 1e-5,
                               rtol=1e-5)
    np.testing.assert_allclose([float(r["fap31_raise_l_i_eyebrow_ens0"]) for r in physical],
                               stream.curve(31) / 1024, rtol=1e-5, atol=1e-9)


def test_json(tmp_path, stream) -> None:
    write_stream(stream, tmp_path / "s.json")
    payload = json.loads((tmp_path / "s.json").read_text())
    assert (payload["fps"], payload["frames"], payload["name"]) == (30, 45, "test stream")
    by_fap = {entry["fap"]: entry for entry in payload["faps"]}
    assert by_fap[49]["name"] == "head_yaw" and by_fap[49]["unit"] == "AU"
    np.testing.assert_allclose(by_fap[49]["values"], stream.curve(49))
    assert by_fap[50]["values"][5] is None


def test_bvh_read_by_an_independent_parser(tmp_path, stream) -> None:
    write_stream(stream, tmp_path / "s.bvh")
    with open(tmp_path / "s.bvh") as handle:
        parsed = Bvh(handle.read())
    assert parsed.get_joints_names() == ["Head"]
    assert parsed.nframes == 45 and parsed.frame_time == pytest.approx(1 / 30)
    channels = np.array(parsed.frames_joint_channels("Head", ["Xrotation", "Yrotation", "Zrotation"]))
    degrees = np.degrees(stream.curves((48, 49, 50)) * 1e-5)  # 1 AU = 1e-5 rad
    np.testing.assert_allclose(channels, degrees, atol=1e-5)
    assert channels[0, 0] == 0 and channels[10, 0] == pytest.approx(np.degrees(3000 * np.sin(10 / 7) * 1e-5), abs=1e-5)


def test_bvh_needs_head_motion(tmp_path) -> None:
    with pytest.raises(FapWriteError, match="no head rotation"):
        write_stream(FapStream.from_curves({31: np.zeros(3)}, fps=30), tmp_path / "x.bvh")
    assert not (tmp_path / "x.bvh").exists()


def test_livelink_csv(tmp_path, stream) -> None:
    write_stream(stream, tmp_path / "s.livelink.csv")
    rows = _rows(tmp_path / "s.livelink.csv")
    columns = list(rows[0])
    assert columns[:2] == ["Timecode", "BlendShapeCount"] and len(columns) == 2 + 52 + 9
    assert columns[2:54] == list(ARKIT_BLENDSHAPES)
    assert columns[54:57] == ["HeadYaw", "HeadPitch", "HeadRoll"]
    assert rows[0]["BlendShapeCount"] == "61" and rows[31]["Timecode"] == "00:00:01:01.000"
    np.testing.assert_allclose([float(r["HeadPitch"]) for r in rows], stream.curve(48) * 1e-5, rtol=1e-5)
    np.testing.assert_allclose([float(r["HeadYaw"]) for r in rows], stream.curve(49) * 1e-5, rtol=1e-5)
    inner = np.array([float(r["BrowInnerUp"]) for r in rows])
    np.testing.assert_allclose(inner, np.clip(stream.curve(31) / BROW_FULL_SCALE_ENS, 0, 1), rtol=1e-5)
    assert inner.max() == 1.0  # 60 ENS is beyond full scale: clipped
    assert float(rows[0]["BrowOuterUpLeft"]) == pytest.approx(10 / BROW_FULL_SCALE_ENS)
    assert all(float(r["JawOpen"]) == 0 for r in rows)


def test_livelink_timecode() -> None:
    assert livelink_timecode(0, 30) == "00:00:00:00.000"
    assert livelink_timecode(30 * 3661 + 7, 30) == "01:01:01:07.000"
    assert livelink_timecode(1, 29.97) == "00:00:00:01.000"


def test_intensity_controls(stream) -> None:
    controlled = apply_controls(stream, gains={"pitch": 0.5, "brows": 2.0}, disabled=["roll"])
    np.testing.assert_allclose(controlled.curve(48), 0.5 * stream.curve(48))
    np.testing.assert_allclose(controlled.curve(33), 2.0 * stream.curve(33))
    np.testing.assert_allclose(controlled.curve(49), stream.curve(49))
    assert 50 not in controlled.active_faps
    with pytest.raises(ConfigError, match="unknown channel"):
        apply_controls(stream, disabled=["nose"])


def test_convert_cli_formats_and_controls(tmp_path) -> None:
    import soundfile
    from conftest import segments

    audio = tmp_path / "tone.wav"
    soundfile.write(audio, segments(16000, (0.5, 150, 0.5), (0.5, 250, 0.5)), 16000)
    assert main(["convert", str(audio), "-o", str(tmp_path / "full.csv")]) == 0
    assert main(["convert", str(audio), "-o", str(tmp_path / "half.csv"), "--yaw-gain", "0.5", "--off",
                 "brows,roll"]) == 0
    full, half = _rows(tmp_path / "full.csv"), _rows(tmp_path / "half.csv")
    assert "fap31_raise_l_i_eyebrow_ens" not in half[0] and "fap50_head_roll_au" not in half[0]
    np.testing.assert_allclose([float(r["fap49_head_yaw_au"]) for r in half],
                               [0.5 * float(r["fap49_head_yaw_au"]) for r in full], rtol=1e-5, atol=1e-3)
    assert main(["convert", str(audio), "-o", str(tmp_path / "x.txt"), "--format", "bvh"]) == 0
    assert (tmp_path / "x.txt").read_text().startswith("HIERARCHY")


def test_livelink_mouth_and_face_blendshapes(tmp_path) -> None:
    n = 3
    stream = FapStream.from_curves({3: np.array([0.0, 300.0, 0.0]), 4: np.array([0.0, -75.0, 0.0]),
                                    5: np.array([0.0, -125.0, 0.0]), 12: np.array([150.0, 0.0, -75.0]),
                                    16: np.array([300.0, 300.0, 0.0]), 17: np.array([300.0, 300.0, 0.0]),
                                    19: np.array([0.0, 0.0, 300.0])}, fps=30)
    path = tmp_path / "x.livelink.csv"
    write_stream(stream, path)
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == n
    value = [{k: float(v) for k, v in row.items() if k != "Timecode"} for row in rows]
    assert value[1]["JawOpen"] == pytest.approx(0.5) and value[0]["JawOpen"] == 0
    assert value[0]["MouthSmileLeft"] == 1 and value[2]["MouthFrownLeft"] == pytest.approx(0.5)
    assert value[0]["MouthSmileRight"] == 0  # FAP 13 is not in the stream
    assert value[0]["MouthPucker"] == 1 and value[0]["MouthFunnel"] == 0  # rounded, lips closed
    assert value[1]["MouthFunnel"] == pytest.approx(1) and value[1]["MouthPucker"] == pytest.approx(0)
    assert value[2]["EyeBlinkLeft"] == 1 and value[1]["MouthClose"] == 0


def test_json_and_json_lines_are_read_back_for_preview(tmp_path, stream) -> None:
    from prosody.errors import FapFormatError
    from prosody.fap.exporters import read_stream_json

    write_stream(stream, tmp_path / "x.json")
    back = read_stream_json(tmp_path / "x.json")
    assert back.fps == stream.fps and back.n_frames == stream.n_frames
    for fap in stream.active_faps:
        np.testing.assert_allclose(back.curve(fap), stream.curve(fap))
    lines = [json.dumps({"frame": k, "time_s": k / 30, "faps": {"48": 10.0 * k, "3": 5.0}}) for k in range(6)]
    (tmp_path / "x.jsonl").write_text("\n".join(lines) + "\n")
    live = read_stream_json(tmp_path / "x.jsonl")
    assert live.fps == 30 and live.n_frames == 6 and live.curve(48).tolist() == [0, 10, 20, 30, 40, 50]
    (tmp_path / "bad.jsonl").write_text('{"frame": 0}\n')
    with pytest.raises(FapFormatError, match="not a stream this package wrote"):
        read_stream_json(tmp_path / "bad.jsonl")


def test_read_stream_reads_back_every_stream_this_package_writes(stream, tmp_path) -> None:
    """One reader for the streams the package writes and reads back, by ending: .fap, the json export and the
    JSON lines of a live stream (the preview draws them all); a .csv export is refused in one line."""
    from prosody.fap.exporters import is_stream_file, read_stream

    for ending in (".fap", ".json"):
        path = tmp_path / f"s{ending}"
        write_stream(stream, path)
        back = read_stream(path)
        assert is_stream_file(path) and back.n_frames == stream.n_frames and back.fps == stream.fps
        np.testing.assert_allclose(back.curve(48), stream.curve(48), atol=0.5)  # the .fap keeps integers
    lines = tmp_path / "live.jsonl"
    lines.write_text("".join(json.dumps({"frame": k, "time_s": k / 30, "faps": {"48": 10.0 * k}}) + "\n"
                             for k in range(5)))
    live = read_stream(lines)
    assert live.n_frames == 5 and live.fps == pytest.approx(30) and live.curve(48)[4] == 40.0
    assert not is_stream_file(tmp_path / "talk.wav")
    with pytest.raises(ConfigError, match="not read back"):
        read_stream(tmp_path / "s.csv")
