"""Malformed input: one-line errors naming the file, the right exit code, and no output left behind."""

from __future__ import annotations

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
    assert "f0_floor_hz" in capsys.readouterr().err


def test_unwritable_output_is_exit_1(tmp_path, capsys) -> None:
    wav = _wav(tmp_path / "tone.wav", harmonic_tone(200, 0.5, 16000))
    code = main(["features", str(wav), "-o", str(tmp_path / "no" / "such" / "dir" / "f.csv")])
    assert code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No such file or directory" in err
