"""Hard inputs handled as documented, and a bounded fuzz pass over the .fap, ballot and model parsers."""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest
import soundfile
from conftest import harmonic_tone
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from audio_features import NoVoicedFramesWarning, extract_features
from prosody.cli import main
from prosody.errors import BallotError, FapFormatError, ModelError
from prosody.fap.fapfile import read_fap
from prosody.motion.heads.arx import DEFAULT_MODEL_PATH, ArxHeadModel
from prosody.study.ballots import parse_ballots

# irregular files are read with a warning each (asserted where it matters): not errors in these tests
pytestmark = pytest.mark.filterwarnings("ignore::prosody.errors.FapIrregularityWarning")



@pytest.mark.parametrize("sample_rate_hz", [8000, 192000])
def test_extreme_sample_rates(tmp_path, sample_rate_hz) -> None:
    path = tmp_path / "tone.wav"
    soundfile.write(path, harmonic_tone(220, 1.0, sample_rate_hz), sample_rate_hz)
    features = extract_features(path)
    voiced = features.f0.values[features.f0.voiced]
    assert features.n_frames == 30 and np.all(np.abs(1200 * np.log2(voiced / 220)) < 17)  # within 1%


def test_one_sample_dc_and_long_silence_convert_without_crashing(tmp_path, capsys) -> None:
    cases = {"one_sample.wav": np.array([0.1]), "dc.wav": np.full(16000, 0.5),
             "silence.wav": np.zeros(16000 * 30)}
    for name, samples in cases.items():
        soundfile.write(tmp_path / name, samples, 16000)
        out = tmp_path / f"{name}.fap"
        assert main(["convert", str(tmp_path / name), "-o", str(out)]) == 0, capsys.readouterr().err
        err = capsys.readouterr().err
        assert "warning: no voiced frame" in err  # no F0 anywhere: brows still, said once
        stream = read_fap(out).stream
        assert np.all(stream.curve(31) == 0)


def test_clipped_speech_like_tone_still_tracks(tmp_path) -> None:
    loud = np.clip(4.0 * harmonic_tone(180, 1.0, 16000), -1, 1)  # hard clipped at full scale
    path = tmp_path / "clipped.wav"
    soundfile.write(path, loud, 16000)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoVoicedFramesWarning)
        features = extract_features(path)
    assert abs(np.nanmedian(features.f0.values) - 180) < 1.8


def test_unsupported_format_is_one_line(tmp_path, capsys) -> None:
    path = tmp_path / "movie.mp4"
    path.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(200))
    assert main(["convert", str(path), "-o", str(tmp_path / "x.fap")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "movie.mp4" in err and not (tmp_path / "x.fap").exists()


def test_interrupted_write_leaves_nothing(tmp_path, monkeypatch) -> None:
    from prosody.fap import fapfile
    from prosody.fap.stream import FapStream

    stream = FapStream.from_curves({48: np.arange(100.0)}, fps=30)

    def interrupted(*args, **kwargs):
        yield "2.1 x 30 100\n"
        yield "0 " * 68 + "\n"
        raise KeyboardInterrupt  # Ctrl-C half-way through the frames

    monkeypatch.setattr(fapfile, "_fap_lines", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fapfile.write_fap(stream, tmp_path / "x.fap")
    assert list(tmp_path.iterdir()) == []


def test_written_files_get_the_usual_permissions(tmp_path) -> None:
    import os

    from prosody.fap.fapfile import write_fap
    from prosody.fap.stream import FapStream

    old_umask = os.umask(0o022)
    try:
        write_fap(FapStream.from_curves({48: np.zeros(3)}, fps=30), tmp_path / "x.fap")
        os.umask(0o077)
        write_fap(FapStream.from_curves({48: np.zeros(3)}, fps=30), tmp_path / "private.fap")
    finally:
        os.umask(old_umask)
    # what open() would have made, not the temporary file's 0600
    assert (tmp_path / "x.fap").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "private.fap").stat().st_mode & 0o777 == 0o600
    # a file replaced keeps its own permissions (a private 0600 never becomes readable by all)
    (tmp_path / "x.fap").chmod(0o600)
    write_fap(FapStream.from_curves({48: np.ones(3)}, fps=30), tmp_path / "x.fap")
    assert (tmp_path / "x.fap").stat().st_mode & 0o777 == 0o600
    assert os.umask(0o022) == 0o022 and os.umask(0o022) == 0o022  # left as it was


# fuzzing: any text gives a result or the package's own error, never another exception or a hang ----------
FUZZ = settings(max_examples=int(os.environ.get("PROSODY_FUZZ_EXAMPLES", "150")), deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
_fap_tokens = st.sampled_from(["2.1", "2.0", "name", "25", "3", "0", "1", "-7", "1.5", "#", "x", "\t", " "])
_fap_lines = st.lists(st.lists(_fap_tokens, max_size=70).map(" ".join), max_size=8).map("\n".join)


@FUZZ
@given(text=st.one_of(_fap_lines, st.text(max_size=400)))
def test_fuzz_fap_reader(tmp_path, text) -> None:
    path = tmp_path / "fuzz.fap"
    path.write_text(text, encoding="latin-1", errors="replace")
    try:
        fap = read_fap(path)
    except FapFormatError as error:
        assert str(path) in str(error)
    else:
        assert fap.stream.values.shape[1] == 68


@FUZZ
@given(text=st.text(alphabet=st.sampled_from(list("stimulus,subjectleftrightchoiceNO_PROSODYRANDOM\n\"")),
                    max_size=300))
def test_fuzz_ballot_parser(text) -> None:
    try:
        ballots = parse_ballots("stimulus,subject,left,right,choice\n" + text)
    except BallotError:
        return
    assert all(b.choice in ("left", "right") for b in ballots)


@FUZZ
@given(data=st.data())
def test_fuzz_model_loader(tmp_path, data) -> None:
    payload = json.loads(DEFAULT_MODEL_PATH.read_text())
    key = data.draw(st.sampled_from(sorted(payload)))
    payload[key] = data.draw(st.one_of(st.none(), st.integers(), st.floats(allow_nan=True), st.text(max_size=5),
                                       st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=4)))
    path = tmp_path / "model.json"
    path.write_text(json.dumps(payload))
    try:
        model = ArxHeadModel.load(path)
    except ModelError as error:
        assert str(path) in str(error)
    else:
        assert model.spectral_radius_ < 1


# past the header: values and their extremes, nested model fields, generation after loading, ballots that are
# valid enough to be analysed
_extreme_numbers = st.sampled_from(["0", "-0", "1e308", "-1e308", "1e400", "nan", "inf", "99999999999999999999",
                                    "1.5e-320", "+3", ".5", "7."])


@FUZZ
@given(values=st.lists(_extreme_numbers, min_size=2, max_size=2), fps=_extreme_numbers)
def test_fuzz_fap_values_and_rates(tmp_path, values, fps) -> None:
    mask = " ".join("1" if fap in (48, 49) else "0" for fap in range(1, 69))
    path = tmp_path / "v.fap"
    path.write_text(f"2.1 v {fps} 1\n{mask}\n0 {values[0]} {values[1]}\n")
    try:
        fap = read_fap(path)
    except FapFormatError as error:
        assert str(path) in str(error)
        return
    assert np.all(np.isfinite(fap.stream.values)) and 1 <= fap.stream.fps <= 1000


def _nested_paths(payload, prefix=()):
    if isinstance(payload, dict):
        for key, value in payload.items():
            yield prefix + (key,)
            yield from _nested_paths(value, prefix + (key,))
    elif isinstance(payload, list) and payload and not isinstance(payload[0], (int, float)):
        for index, value in enumerate(payload[:2]):
            yield prefix + (index,)
            yield from _nested_paths(value, prefix + (index,))


@FUZZ
@given(data=st.data())
def test_fuzz_nested_fields_of_both_model_kinds(tmp_path, data) -> None:
    from prosody.motion.heads.models import PROSODIC_MODEL_PATH, load_head_model

    source = data.draw(st.sampled_from([PROSODIC_MODEL_PATH, DEFAULT_MODEL_PATH]))
    payload = json.loads(source.read_text())
    route = data.draw(st.sampled_from(sorted(_nested_paths(payload), key=str)))
    holder = payload
    for step in route[:-1]:
        holder = holder[step]
    holder[route[-1]] = data.draw(st.one_of(
        st.none(), st.booleans(), st.integers(min_value=-10**30, max_value=10**30),
        st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3),
        st.lists(st.floats(allow_nan=True), max_size=3), st.dictionaries(st.text(max_size=2), st.integers(),
                                                                          max_size=2)))
    path = tmp_path / "model.json"
    path.write_text(json.dumps(payload))  # NaN and Infinity as JSON writes them
    try:
        model = load_head_model(path)
    except ModelError as error:
        assert str(path) in str(error)
        return
    # whatever loads must generate finite motion (at the model's rate or, resampled, at another)
    from conftest import make_features

    from prosody.motion.conditions import head_motion

    features = make_features(150 + 30 * np.sin(np.arange(120) / 9), 60 + 5 * np.cos(np.arange(120) / 4))
    curves = head_motion(model, features, seed=1)
    assert all(np.all(np.isfinite(curve)) for curve in curves.values())


@settings(FUZZ, max_examples=max(1, FUZZ.max_examples // 4))  # each example runs 12 t-tests: fewer examples
@given(rows=st.lists(st.tuples(st.sampled_from(["s1", "s2"]), st.sampled_from(["p1", "p2", "p3"]),
                               st.sampled_from(["none", "RANDOM", "speech", "GROUND_TRUTH"]),
                               st.sampled_from(["NO_PROSODY", "random", "SPEECH_DRIVEN", "truth"]),
                               st.sampled_from(["left", "right", "LEFT"])), min_size=1, max_size=40))
def test_fuzz_ballots_that_are_analysed(rows) -> None:
    from prosody.study.ballots import analyze_ballots

    text = "stimulus,subject,left,right,choice\n" + "\n".join(",".join(row) for row in rows)
    try:
        ballots = parse_ballots(text)
    except BallotError as error:
        assert "duplicates" in str(error)
        return
    results = analyze_ballots(ballots)
    for stimulus, scores in results["scores"].items():
        assert sum(scores.values()) == sum(b.stimulus == stimulus for b in ballots)
    for test in results["ttests"]:
        assert test["p"] is None or 0 <= test["p"] <= 1
