"""Malformed input: one-line errors naming the file, the right exit code, and no output left behind."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
import soundfile
from conftest import harmonic_tone

from audio_features import AudioLoadError, extract_features, load_audio
from prosody.cli import main


def _wav(path, samples, sr=16000, subtype="PCM_16"):
    soundfile.write(path, samples, sr, subtype=subtype)
    return path


def _bad_inputs(tmp_path):
    good = _wav(tmp_path / "good.wav", harmonic_tone(200, 1.0, 16000))
    data = good.read_bytes()
    (tmp_path / "text.wav").write_text("this is not audio\n")
    (tmp_path / "truncated.wav").write_bytes(data[: len(data) // 2])
    (tmp_path / "header_only.wav").write_bytes(data[:30])
    (tmp_path / "empty.wav").write_bytes(b"")
    _wav(tmp_path / "zero_length.wav", np.zeros(0))
    nan = harmonic_tone(200, 0.5, 16000)
    nan[100] = np.nan
    _wav(tmp_path / "nan.wav", nan, subtype="FLOAT")
    inf = harmonic_tone(200, 0.5, 16000)
    inf[200] = np.inf
    _wav(tmp_path / "inf.wav", inf, subtype="DOUBLE")
    _wav(tmp_path / "low_rate.wav", harmonic_tone(100, 0.5, 4000), sr=4000)
    (tmp_path / "folder.wav").mkdir()
    return {
        "missing.wav": "no such file",
        "text.wav": "not an audio file",
        "truncated.wav": "truncated",
        "header_only.wav": "not an audio file",
        "empty.wav": "empty",
        "zero_length.wav": "no samples",
        "nan.wav": "not finite",
        "inf.wav": "not finite",
        "low_rate.wav": "below the supported minimum",
        "folder.wav": "directory",
    }


def test_bad_audio_gives_one_line_exit_1_and_no_output(tmp_path, capsys) -> None:
    for name, reason in _bad_inputs(tmp_path).items():
        out = tmp_path / f"{name}.csv"
        code = main(["features", str(tmp_path / name), "-o", str(out)])
        err = capsys.readouterr().err
        assert code == 1, name
        assert err.count("\n") == 1 and name in err and reason in err, err
        assert "Traceback" not in err
        assert not out.exists()
        assert not list(tmp_path.glob(f".{out.name}*")), "a temporary file was left behind"


@pytest.mark.parametrize("reading", ["at once", "streamed"])
def test_bad_audio_raises_value_error_subclass_in_python(tmp_path, monkeypatch, reading) -> None:
    from audio_features import features as features_module

    if reading == "streamed":  # the path of long files: a peak scan, then chunked reads
        monkeypatch.setattr(features_module, "IN_MEMORY_SAMPLES", 0)
    for name in _bad_inputs(tmp_path):
        with pytest.raises(AudioLoadError) as caught:
            extract_features(tmp_path / name)
        assert isinstance(caught.value, ValueError)
        assert name in str(caught.value)


def test_load_audio_rejects_non_finite_in_memory(tmp_path) -> None:
    path = _wav(tmp_path / "nan.wav", np.array([0.0, np.nan, 0.0]), subtype="FLOAT")
    with pytest.raises(AudioLoadError, match="sample 1"):
        load_audio(path)


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["features"],
        ["features", "x.wav"],
        ["features", "x.wav", "-o", "y.csv", "--fps", "0"],
        ["features", "x.wav", "-o", "y.csv", "--fps", "abc"],
        ["no-such-command"],
    ],
)
def test_usage_errors_exit_2(argv, capsys) -> None:
    with pytest.raises(SystemExit) as caught:
        main(argv)
    assert caught.value.code == 2
    assert "Traceback" not in capsys.readouterr().err


def test_parameter_error_is_usage_exit_2(tmp_path, capsys) -> None:
    wav = _wav(tmp_path / "tone.wav", harmonic_tone(200, 0.5, 16000))
    code = main(["features", str(wav), "-o", str(tmp_path / "f.csv"), "--f0-floor", "600"])
    assert code == 2
    assert "--f0-floor" in capsys.readouterr().err


def test_unwritable_output_is_exit_1(tmp_path, capsys) -> None:
    wav = _wav(tmp_path / "tone.wav", harmonic_tone(200, 0.5, 16000))
    code = main(["features", str(wav), "-o", str(tmp_path / "no" / "such" / "dir" / "f.csv")])
    assert code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No such file or directory" in err


# containers: truncation everywhere, estimated lengths decoded, impossible rates refused -------------------
def test_truncated_flac_is_reported_as_such(tmp_path, capsys) -> None:
    path = tmp_path / "cut.flac"
    soundfile.write(tmp_path / "whole.flac", harmonic_tone(200, 3.0, 16000), 16000)
    data = (tmp_path / "whole.flac").read_bytes()
    path.write_bytes(data[: len(data) // 2])
    for call in (lambda: extract_features(path), lambda: load_audio(path)):
        with pytest.raises(AudioLoadError, match="truncated or damaged FLAC"):
            call()
    assert main(["convert", str(path), "-o", str(tmp_path / "x.fap")]) == 1
    assert capsys.readouterr().err.count("\n") == 1 and not (tmp_path / "x.fap").exists()


def test_an_mp3_whose_header_only_estimates_its_length_is_decoded_to_its_end(tmp_path) -> None:
    from prosody.evaluation.preview import find_ffmpeg

    ffmpeg = find_ffmpeg()
    if ffmpeg is None:
        pytest.skip("no ffmpeg to write an MP3 without its Xing frame count")
    import subprocess

    source = _wav(tmp_path / "tone.wav", harmonic_tone(200, 3.0, 16000))
    mp3 = tmp_path / "tone.mp3"
    subprocess.run([ffmpeg, "-loglevel", "error", "-y", "-i", str(source), "-write_xing", "0", str(mp3)], check=True)
    with soundfile.SoundFile(mp3) as sound:
        estimated = sound.frames
    decoded = load_audio(mp3).samples.shape[0]
    assert decoded != estimated  # the case at hand: the header's count is only an estimate
    features = extract_features(mp3)
    assert features.n_frames == int(np.ceil(decoded / 16000 * 30 - 1e-9))
    assert abs(features.duration_s - 3.0) < 0.1


def test_a_sample_rate_no_recording_uses_is_refused_before_analysis(tmp_path, capsys) -> None:
    import struct

    path = _wav(tmp_path / "tone.wav", harmonic_tone(200, 1.0, 16000))
    data = bytearray(path.read_bytes())
    data[24:28] = struct.pack("<I", 2**31 - 1)  # the fmt chunk's sample rate
    path.write_bytes(bytes(data))
    assert main(["convert", str(path), "-o", str(tmp_path / "x.fap")]) == 1
    err = capsys.readouterr().err
    assert "2147483647 Hz" in err and err.count("\n") == 1
    from audio_features import Audio

    with pytest.raises(AudioLoadError, match="above any recording"):
        Audio(np.zeros(10), 10_000_000)


# library entry points check what the command line checks --------------------------------------------------
def test_integer_pcm_is_scaled_from_its_full_range() -> None:
    from audio_features import Audio

    tone = harmonic_tone(200, 1.0, 16000)
    as_int16 = np.round(tone * 32767).astype(np.int16)
    floats = extract_features(Audio(tone, 16000))
    ints = extract_features(Audio(as_int16, 16000))
    np.testing.assert_allclose(ints.energy.values, floats.energy.values, atol=0.01)  # not 90 dB louder
    np.testing.assert_array_equal(ints.f0.voiced, floats.f0.voiced)


def test_channels_first_arrays_are_refused() -> None:
    from audio_features import Audio

    with pytest.raises(AudioLoadError, match="channels-first"):
        Audio(np.zeros((2, 16000)), 16000)
    assert Audio(np.zeros((16000, 2)), 16000).samples.shape == (16000,)


@pytest.mark.parametrize("kwargs", [dict(threshold_hz=float("nan")), dict(threshold_hz=0.0),
                                    dict(energy_threshold_db=float("nan")), dict(threshold_semitones=float("nan")),
                                    dict(energy_relative_db=float("inf"))])
def test_thesis_rule_refuses_meaningless_thresholds(kwargs) -> None:
    from prosody.errors import ConfigError
    from prosody.motion.eyebrows import EyebrowRule

    with pytest.raises(ConfigError):
        EyebrowRule(**kwargs)


def test_grids_and_frames_of_impossible_size_are_refused(tmp_path) -> None:
    from audio_features import Audio, ParameterError
    from prosody.errors import ConfigError
    from prosody.evaluation.preview import render_frames
    from prosody.fap.stream import FapStream

    with pytest.raises(ParameterError, match="fps"):
        extract_features(Audio(harmonic_tone(200, 0.5, 16000), 16000), fps=1e9)
    with pytest.raises(ConfigError, match="3840"):
        next(render_frames(FapStream.from_curves({48: np.zeros(2)}, fps=30), width=100_000))


def test_arx_fit_refuses_widths_its_files_cannot_hold(tmp_path) -> None:
    from prosody.errors import ConfigError, ModelError
    from prosody.motion.heads.arx import ArxHeadModel

    with pytest.raises(ConfigError, match="inputs must be"):
        ArxHeadModel().fit_arrays([np.zeros((50, 4))], [np.zeros((50, 3))])
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ModelError, match="nested"):
        ArxHeadModel.load(deep)
    model = ArxHeadModel().fit_arrays([np.random.default_rng(1).standard_normal((80, 5))],
                                      [np.random.default_rng(2).standard_normal((80, 3))])
    payload = model.to_dict()
    payload["orders"]["na"] = float("inf")
    bad = tmp_path / "inf.json"
    import json

    bad.write_text(json.dumps(payload))
    with pytest.raises(ModelError, match="malformed"):
        ArxHeadModel.load(bad)


def test_head_csv_rows_off_the_30_fps_grid_are_refused(tmp_path) -> None:
    from prosody.errors import GroundTruthError
    from prosody.fap.recorded import read_head_csv

    path = tmp_path / "c.head.csv"
    path.write_text("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0.0,0,0,0\n1,0.04,0,0,0\n")  # 25 fps timing
    with pytest.raises(GroundTruthError, match="line 3: time_s 0.04 is not frame 1 at 30 fps"):
        read_head_csv(path)


def test_huge_csv_cells_are_one_line_errors(tmp_path) -> None:
    from prosody.errors import BallotError, GroundTruthError
    from prosody.fap.recorded import read_head_csv
    from prosody.study.ballots import read_ballots

    big = "x" * 200_000
    head = tmp_path / "c.head.csv"
    head.write_text(f'frame,time_s,rx_rad,ry_rad,rz_rad\n0,0.0,"{big}",0,0\n')
    with pytest.raises(GroundTruthError, match="line 2: not a CSV row"):
        read_head_csv(head)
    ballots = tmp_path / "b.csv"
    ballots.write_text(f'stimulus,subject,left,right,choice\n"{big}",p,none,random,left\n')
    with pytest.raises(BallotError, match="line 2: not a CSV row"):
        read_ballots(ballots)


def test_ballots_take_the_short_condition_names(tmp_path) -> None:
    from prosody.study.ballots import parse_ballots

    ballots = parse_ballots("stimulus,subject,left,right,choice\ns,p,speech,truth,left\ns,p,none,random,right\n")
    assert [(b.left, b.right, b.chosen) for b in ballots] == [("SPEECH_DRIVEN", "GROUND_TRUTH", "SPEECH_DRIVEN"),
                                                              ("NO_PROSODY", "RANDOM", "RANDOM")]


def test_one_root_catches_what_either_package_raises(tmp_path) -> None:
    from audio_features import ParameterError, VisualProsodyError
    from prosody.errors import ConfigError, PreviewError, UnknownFapError
    from prosody.fap.table import fap_info

    with pytest.raises(VisualProsodyError):
        load_audio(tmp_path / "missing.wav")
    with pytest.raises(VisualProsodyError):
        from prosody.motion.eyebrows import AccentRule

        AccentRule(threshold_semitones=-1)
    assert issubclass(ConfigError, ParameterError) and issubclass(ConfigError, ValueError)
    assert issubclass(PreviewError, OSError) and issubclass(UnknownFapError, KeyError)
    with pytest.raises(UnknownFapError, match="unknown FAP 99"):
        fap_info(99)


def test_results_holding_arrays_compare_by_identity_and_hash() -> None:
    from audio_features import Audio
    from prosody.fap.stream import FapStream

    features = extract_features(Audio(harmonic_tone(200, 0.5, 16000), 16000))
    stream = FapStream.from_curves({48: np.zeros(3)}, fps=30)
    for value in (features, features.f0, features.energy, stream):
        assert value == value and hash(value) == hash(value)  # no "truth value of an array is ambiguous"
    assert {features, stream} == {features, stream}
    assert FapStream.from_curves({48: np.zeros(3)}, fps=30) != stream  # equal content, another object


@pytest.mark.parametrize("arguments", [
    ["inspect", "{pipe}"],
    ["convert", "{pipe}", "-o", "{dir}/x.fap"],
    ["convert", "{wav}", "-o", "{dir}/x.fap", "--base", "{pipe}"],
    ["convert", "{wav}", "-o", "{dir}/x.fap", "--model", "{pipe}"],
    ["compare", "{wav}", "-o", "{dir}/cmp", "--ground-truth", "{zero}"],
    ["study", "analyze", "{pipe}", "-o", "{dir}/r.json"],
    ["preview", "{pipe}", "-o", "{dir}/x.gif"],
    ["features", "{zero}", "-o", "{dir}/x.csv"],
])
def test_a_pipe_or_a_device_given_as_an_input_is_refused_at_once(tmp_path, arguments) -> None:
    # opening a pipe no one writes blocks for ever, /dev/zero reads without end: both must be one line
    import os
    import subprocess
    import sys

    pipe, zero, wav = tmp_path / "in.fap", tmp_path / "zero.head.csv", tmp_path / "speech.wav"
    os.mkfifo(pipe)
    zero.symlink_to("/dev/zero")
    soundfile.write(wav, harmonic_tone(150, 1.0, 16000), 16000)
    argv = [a.format(pipe=pipe, zero=zero, wav=wav, dir=tmp_path) for a in arguments]
    result = subprocess.run([sys.executable, "-m", "prosody", *argv], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1, result.stderr
    errors = [line for line in result.stderr.splitlines() if ": error: " in line]
    assert len(errors) == 1 and "not a regular file" in errors[0] and "Traceback" not in result.stderr


def test_batch_reports_a_pipe_named_like_audio_and_goes_on(tmp_path, capsys) -> None:
    import os

    indir = tmp_path / "in"
    indir.mkdir()
    soundfile.write(indir / "a.wav", harmonic_tone(150, 1.0, 16000), 16000)
    os.mkfifo(indir / "b.wav")
    (indir / "c.wav").symlink_to("/dev/zero")
    assert main(["batch", str(indir), "-o", str(tmp_path / "out"), "--condition", "none", "--seeds", "1"]) == 1
    err = capsys.readouterr().err
    assert "b.wav" in err and "c.wav" in err and err.count("not a regular file") == 2
    assert (tmp_path / "out" / "a" / "no_prosody.fap").exists()


def test_a_dask_scheduler_that_never_answers_is_given_up_on(monkeypatch) -> None:
    import threading

    from prosody.errors import ConfigError
    from prosody.jobs import runner

    release = threading.Event()

    class Silent:  # accepts and never answers, as a listener that is no scheduler does
        def __init__(self, address, timeout):
            release.wait(10)

    monkeypatch.setattr(runner, "SCHEDULER_TIMEOUT_S", 0.2)
    monkeypatch.setattr(runner, "_SCHEDULER_GRACE_S", 0.1)
    with pytest.raises(ConfigError, match="did not answer within 0.2 s"):
        runner._connect(Silent, "tcp://127.0.0.1:1")
    release.set()


@pytest.mark.parametrize("container, ending, subtype", [
    ("AIFF", "aiff", "PCM_16"), ("AU", "au", "PCM_16"), ("W64", "w64", "PCM_16"), ("RF64", "wav", "PCM_16"),
    ("WAV", "wav", "FLOAT"), ("OGG", "ogg", "VORBIS"),
])
def test_every_container_cut_off_is_reported_as_truncated(tmp_path, container, ending, subtype) -> None:
    # libsndfile reads most cut-off containers as if they were shorter: each header's promise is checked
    whole = tmp_path / f"whole.{ending}"
    soundfile.write(whole, harmonic_tone(150, 3.0, 16000), 16000, format=container, subtype=subtype)
    assert load_audio(whole).samples.size == 48000
    data = whole.read_bytes()
    for fraction in (0.5, 0.9):
        cut = tmp_path / f"cut.{ending}"
        cut.write_bytes(data[:int(len(data) * fraction)])
        with pytest.raises(AudioLoadError, match="truncated"):
            load_audio(cut)


@pytest.mark.parametrize("id3", [False, True])
def test_an_mp3_cut_off_is_reported_as_truncated_even_in_json_messages(tmp_path, id3) -> None:
    # libsndfile decodes a cut MP3 as a shorter one and its decoder only notes it on standard error; the
    # Xing/Info tag FFmpeg's LAME encoder writes says how many bytes the stream holds
    import json

    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    wav, whole = tmp_path / "tone.wav", tmp_path / "whole.mp3"
    soundfile.write(wav, harmonic_tone(150, 3.0, 16000), 16000)
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(wav), "-c:a", "libmp3lame",
                    *(["-id3v2_version", "3", "-metadata", "title=tone"] if id3 else ["-id3v2_version", "0"]),
                    str(whole)], check=True)
    assert abs(load_audio(whole).samples.size / 16000 - 3.0) < 0.1
    data = whole.read_bytes()
    for fraction in (0.5, 0.9):
        cut = tmp_path / "cut.mp3"
        cut.write_bytes(data[:int(len(data) * fraction)])
        with pytest.raises(AudioLoadError, match="truncated MP3 file"):
            load_audio(cut)
    result = subprocess.run([sys.executable, "-m", "prosody", "convert", str(cut), "-o", str(tmp_path / "x.fap"),
                             "--messages", "json", "--lips", "none"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and not (tmp_path / "x.fap").exists()
    events = [json.loads(line) for line in result.stderr.splitlines()]  # every line is JSON: no decoder note
    assert events[-1]["event"] == "error" and "truncated MP3 file" in events[-1]["message"]


def test_a_wav_header_whose_bits_do_not_fill_its_frames_is_refused(tmp_path) -> None:
    # a 7-bit header on 16-bit frames: libsndfile reads it from the bits, as 8-bit audio of double length
    import struct

    samples = (harmonic_tone(150, 1.0, 16000) * 10000).astype("<i2").tobytes()

    def wav(bits: int, block_align: int) -> bytes:
        fmt = struct.pack("<HHIIHH", 1, 1, 16000, 16000 * block_align, block_align, bits)
        body = b"WAVE" + b"fmt " + struct.pack("<I", 16) + fmt + b"data" + struct.pack("<I", len(samples)) + samples
        return b"RIFF" + struct.pack("<I", len(body)) + body

    damaged = tmp_path / "seven.wav"
    damaged.write_bytes(wav(7, 2))
    with pytest.raises(AudioLoadError, match="7-bit samples take 1 bytes per frame, but the header says 2"):
        load_audio(damaged)
    consistent = tmp_path / "sixteen.wav"
    consistent.write_bytes(wav(16, 2))
    assert load_audio(consistent).samples.size == 16000


@pytest.mark.parametrize("floor", ["0.01", "1e-9", "19.9"])
def test_a_pitch_floor_below_any_voice_is_refused_before_analysis(tmp_path, capsys, floor) -> None:
    # Praat's window is three periods of the floor: 0.01 Hz asked for 980 MB on a 3 s file, 1e-9 for 349 TiB
    wav = tmp_path / "a.wav"
    soundfile.write(wav, harmonic_tone(150, 1.0, 16000), 16000)
    assert main(["features", str(wav), "-o", str(tmp_path / "a.csv"), "--f0-floor", floor]) == 2
    err = capsys.readouterr().err
    assert "need 20 <= --f0-floor < --f0-ceiling" in err and not (tmp_path / "a.csv").exists()
    from audio_features.streaming import StreamingAnalyser

    with pytest.raises(ValueError, match="20 <= f0_floor_hz"):
        StreamingAnalyser(16000, f0_floor_hz=float(floor))


def test_gsm_wav_which_libsndfile_cannot_seek_in_is_read(tmp_path) -> None:
    import shutil
    import subprocess

    if shutil.which("sox") is None:
        pytest.skip("needs sox to write GSM 6.10 (apt-get install sox)")
    pcm, gsm = tmp_path / "pcm.wav", tmp_path / "gsm.wav"
    soundfile.write(pcm, harmonic_tone(150, 2.0, 8000), 8000)
    subprocess.run(["sox", str(pcm), "-e", "gsm-full-rate", str(gsm)], check=True)
    assert soundfile.info(str(gsm)).subtype == "GSM610"
    features = extract_features(gsm)
    assert features.n_frames == 60
    assert abs(1200 * np.log2(np.nanmedian(features.f0.values) / 150)) < 50
    assert load_audio(gsm).samples.size == 16000


@pytest.mark.parametrize("argv, message", [
    (["study", "plan", "--stimuli", "a,b", "-o", "{dir}/p.csv", "--seed", "-1"], "whole number from 0"),
    (["preview", "{wav}", "-o", "{dir}/p.gif", "--exaggerate", "1e308"], "(0, 100]"),
    (["preview", "{wav}", "-o", "{dir}/p.gif", "--start", "inf"], "[0, 1e+06]"),
    (["preview", "{wav}", "-o", "{dir}/p.gif", "--duration", "1e308"], "(0, 1e+06]"),
])
def test_numbers_out_of_range_are_usage_errors(tmp_path, capsys, argv, message) -> None:
    wav = tmp_path / "a.wav"
    soundfile.write(wav, harmonic_tone(150, 1.0, 16000), 16000)
    with pytest.raises(SystemExit) as stopped:
        main([a.format(dir=tmp_path, wav=wav) for a in argv])
    assert stopped.value.code == 2 and message in capsys.readouterr().err


def test_closed_standard_streams(tmp_path) -> None:
    import subprocess
    import sys

    wav = tmp_path / "a.wav"
    soundfile.write(wav, harmonic_tone(150, 1.0, 16000), 16000)
    closed_err = subprocess.run([sys.executable, "-m", "prosody", "convert", str(wav), "-o", str(tmp_path / "a.fap")],
                                stderr=subprocess.DEVNULL, pass_fds=(), close_fds=True,
                                preexec_fn=lambda: __import__("os").close(2), timeout=120)
    assert closed_err.returncode == 0 and (tmp_path / "a.fap").exists()
    closed_out = subprocess.run([sys.executable, "-m", "prosody", "features", str(wav), "-o", "-"],
                                stderr=subprocess.PIPE, text=True, preexec_fn=lambda: __import__("os").close(1),
                                timeout=120)
    assert closed_out.returncode == 2 and "standard output is closed" in closed_out.stderr


def test_model_numbers_beyond_any_fit_and_motion_beyond_a_turn_are_refused(tmp_path) -> None:
    import json

    from prosody.errors import GroundTruthError, ModelError
    from prosody.fap.recorded import read_head_csv
    from prosody.live.converter import live_head_model, shipped_live_model_path
    from prosody.motion.heads.arx import ArxHeadModel
    from prosody.motion.heads.models import ARX_MODEL_PATH, load_head_model

    live = json.loads(shipped_live_model_path(100).read_text())
    key = next(k for k, v in live.items() if isinstance(v, list) and v and isinstance(v[0], float))
    live[key][0] = 1e308
    (tmp_path / "live.json").write_text(json.dumps(live))
    with pytest.raises(ModelError, match="beyond 1e"):
        live_head_model(str(tmp_path / "live.json"), lookahead_ms=100)
    arx = json.loads(ARX_MODEL_PATH.read_text())
    arx["c"][0] = -1e300
    (tmp_path / "arx.json").write_text(json.dumps(arx))
    with pytest.raises(ModelError, match="beyond 1e"):
        load_head_model(str(tmp_path / "arx.json"))
    with pytest.raises(ValueError, match="ridge must be a number in"):
        ArxHeadModel(ridge=1e308)._check_orders()
    (tmp_path / "x.head.csv").write_text("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0.0,1e200,0,0\n")
    with pytest.raises(GroundTruthError, match="beyond pi rad"):
        read_head_csv(tmp_path / "x.head.csv")


def test_a_byte_order_mark_is_accepted_in_every_text_input(tmp_path) -> None:
    import json

    from prosody.fap.fapfile import read_fap
    from prosody.fap.recorded import read_head_csv
    from prosody.motion.heads.models import ARX_MODEL_PATH, load_head_model

    bom = b"\xef\xbb\xbf"
    (tmp_path / "x.head.csv").write_bytes(bom + b"frame,time_s,rx_rad,ry_rad,rz_rad\n0,0.0,0.01,0,0\n1,0.0333,0,0,0\n")
    assert read_head_csv(tmp_path / "x.head.csv").n_frames == 2
    (tmp_path / "x.fap").write_bytes(bom + b"2.1 x 30 1\n" + b"0 " * 47 + b"1 " + b"0 " * 19 + b"0\n0 500\n")
    assert read_fap(tmp_path / "x.fap").stream.curve(48)[0] == 500
    (tmp_path / "m.json").write_bytes(bom + json.dumps(json.loads(ARX_MODEL_PATH.read_text())).encode())
    assert load_head_model(tmp_path / "m.json").kind == "arx"


def test_asymmetries_between_what_is_written_and_what_is_read(tmp_path, capsys) -> None:
    import subprocess
    import sys

    from prosody.errors import FapWriteError
    from prosody.fap.fapfile import read_fap, write_fap
    from prosody.fap.stream import FapStream

    with pytest.raises(FapWriteError, match="outside 1-1000 fps"):
        write_fap(FapStream.from_curves({48: np.zeros(3)}, fps=5000), tmp_path / "fast.fap")
    # a 25 fps base with outer brows: resampled with a warning, and its outer brows left out beside ours
    wav = tmp_path / "speech.wav"
    soundfile.write(wav, harmonic_tone(150, 2.0, 16000), 16000)
    write_fap(FapStream.from_curves({35: np.full(50, 80.0), 36: np.full(50, 80.0), 3: np.full(50, 100.0)}, fps=25),
              tmp_path / "base.fap")
    assert main(["convert", str(wav), "-o", str(tmp_path / "out.fap"), "--base", str(tmp_path / "base.fap"),
                 "--lips", "none"]) == 0
    assert "resampled to 30 fps (give --fps 25" in capsys.readouterr().err
    out = read_fap(tmp_path / "out.fap").stream
    assert 3 in out.active_faps and not {35, 36} & set(out.active_faps)
    # a live model where an offline one is read, and the other way round
    from conftest import REPO

    models = REPO / "prosody" / "motion" / "models"
    live_model = str(models / "live_head_100ms.json")
    assert main(["convert", str(wav), "-o", str(tmp_path / "x.fap"), "--model", live_model]) == 1
    assert "is for 'prosody stream'" in capsys.readouterr().err
    # compressed audio piped to stream is told to give the file
    mp3 = b"ID3\x04\x00\x00\x00\x00\x00\x00" + bytes(200)
    result = subprocess.run([sys.executable, "-m", "prosody", "stream", "-", "-o", "-"], input=mp3,
                            capture_output=True, timeout=120)
    assert result.returncode == 1 and b"MP3 is read from a file" in result.stderr


@pytest.mark.parametrize(("forget", "code"), [(False, -2), (True, 0)])
def test_a_handled_interrupt_keeps_the_exit_code(forget, code) -> None:
    """CPython ends a process by SIGINT at exit when a KeyboardInterrupt once left a nested top-level
    evaluation (an interrupted import of scipy.sparse does that), whatever code it returns: after an interrupt
    it has handled, the command clears that record."""
    import subprocess
    import sys

    script = ("import ctypes, sys\n"
              "ctypes.pythonapi.PyRun_SimpleString(b'raise KeyboardInterrupt')  # leaves the record\n"
              f"if {forget}:\n"
              "    from prosody.cli.messages import forget_interrupt as _forget_interrupt\n"
              "    _forget_interrupt()\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=120)
    assert done.returncode == code


@pytest.mark.parametrize("ending", [".m4a", ".mp4", ".aac"])
def test_sound_in_an_mp4_without_ffmpeg_says_how_to_convert_it(ending: str, tmp_path, monkeypatch) -> None:
    """.m4a and .mp4 sound was refused as 'not an audio file libsndfile can read' with no hint; without an
    FFmpeg to read it through, the refusal says how to get one or convert it."""
    from audio_features import audio as audio_module
    from audio_features.audio import load_audio
    from audio_features.errors import AudioLoadError

    monkeypatch.setattr(audio_module, "find_ffmpeg", lambda: None)
    path = tmp_path / f"talk{ending}"
    path.write_bytes(b"\x00\x00\x00\x20ftypM4A \x00\x00\x02\x00" + bytes(64))  # an MP4 header, as iTunes writes
    with pytest.raises(AudioLoadError, match=f"imageio-ffmpeg.*ffmpeg -i talk{ending} -ac 1 talk.wav"):
        load_audio(path)


@pytest.mark.parametrize("ending, codec", [(".m4a", "aac"), (".mp4", "aac"), (".mkv", "libopus")])
def test_sound_in_an_mp4_is_read_through_ffmpeg(ending: str, codec: str, tmp_path) -> None:
    """With FFmpeg at hand (on PATH or imageio-ffmpeg), an M4A, an MP4 or a Matroska file's sound converts as
    its WAV does: the same frames, the head and lips following it (r >= 0.98 against the WAV's), and a broken one
    is refused in one line naming the file."""
    import subprocess

    from conftest import REPO

    from audio_features.audio import find_ffmpeg
    from audio_features.errors import AudioLoadError
    from prosody.jobs.pipeline import convert

    ffmpeg = find_ffmpeg()
    if ffmpeg is None:
        pytest.skip("needs FFmpeg (pip install imageio-ffmpeg)")
    wav = REPO / "samples" / "arctic_a0009.wav"
    packed = tmp_path / f"talk{ending}"
    subprocess.run([ffmpeg, "-v", "error", "-y", "-i", str(wav), "-c:a", codec, str(packed)], check=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ours, reference = convert(packed, None, lips="acoustic"), convert(wav, None, lips="acoustic")
    assert ours.n_frames == reference.n_frames
    for fap in (3, 48, 49, 50):
        assert np.corrcoef(ours.curve(fap), reference.curve(fap))[0, 1] >= 0.98, fap
    broken = tmp_path / f"broken{ending}"
    broken.write_bytes(packed.read_bytes()[:200])
    with pytest.raises(AudioLoadError, match=f"broken{ending}: FFmpeg could not decode its sound"):
        convert(broken, None)


def test_a_folder_given_as_a_recording_is_named_in_plain_english(tmp_path, capsys) -> None:
    from prosody.cli import main

    assert main(["convert", str(tmp_path), "-o", str(tmp_path / "x.fap")]) == 1
    assert f"{tmp_path}: is a directory, not an audio file" in capsys.readouterr().err
