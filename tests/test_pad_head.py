"""Jia et al.'s PAD-driven head gestures: Eq. 1, 2 and 13 and the peak rule (doctests), and on real speech."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_features

from prosody.errors import ConfigError
from prosody.motion.heads.models import load_head_model
from prosody.motion.heads.pad import (
    AU_PER_DEGREE,
    TABLE3_AMPLITUDE_DEG,
    TABLE3_AVERAGE_DEG,
    PadHeadModel,
    amplitude,
    pad_from_questionnaire,
    prosodic_words,
    smooth_boundaries,
)


def test_eq2_with_the_default_coefficients_gives_table3_at_neutral_settings():
    for axis, mean in enumerate(TABLE3_AMPLITUDE_DEG):
        coefficients = PadHeadModel().coefficients_[axis]
        assert amplitude(0, 0.5, coefficients) == pytest.approx(mean)
        assert amplitude(0, -0.5, coefficients) == 0  # silence: no gesture
        assert amplitude(0, 0, coefficients) < amplitude(0, 0.5, coefficients) < amplitude(0, 1, coefficients)


def test_boundary_smoothing_keeps_a_constant_and_ramps_a_step_over_five_frames():
    np.testing.assert_array_equal(smooth_boundaries(np.full(40, 3.0), [10, 25], window=6), 3.0)
    ramp = smooth_boundaries(np.r_[np.zeros(20), np.ones(20)], [20], window=6)
    between = np.flatnonzero((ramp > 1e-9) & (ramp < 1 - 1e-9))
    assert between.size == 5 and np.all(np.diff(ramp[between]) > 0)


def test_the_questionnaire_is_checked():
    assert pad_from_questionnaire([0] * 12) == (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match="twelve answers"):
        pad_from_questionnaire([5] * 12)


def _accent_features():
    """1 s of silence, 1.2 s of speech-like syllables (energy peaks) with an accent at 1.5 s, then silence."""
    fps, n = 30.0, 120
    energy = np.full(n, 30.0)
    f0 = np.full(n, np.nan)
    for k in range(30, 66):
        energy[k] = 70 + 8 * np.cos(2 * np.pi * (k - 30) / 9)
        f0[k] = 130.0
    f0[45:50] = 200.0
    features = make_features(np.nan_to_num(f0, nan=0.0), energy, fps=fps)
    voiced = ~np.isnan(f0)
    return type(features)(f0=type(features.f0)(np.where(voiced, f0, np.nan), fps, "Hz", "f0", voiced),
                          f0_conditioned=features.f0_conditioned, energy=features.energy,
                          duration_s=features.duration_s, source="<synthetic>")


def test_prosodic_words_a_peak_on_the_accent_and_a_still_head_in_silence():
    # 1 s of silence, then 1.2 s of speech-like syllables (energy peaks) with an accent, then silence
    fps, n = 30.0, 120
    energy = np.full(n, 30.0)
    f0 = np.full(n, np.nan)
    for k in range(30, 66):
        energy[k] = 70 + 8 * np.cos(2 * np.pi * (k - 30) / 9)  # a syllable every 0.3 s
        f0[k] = 130.0
    f0[45:50] = 200.0  # the accent
    features = make_features(np.nan_to_num(f0, nan=0.0), energy, fps=fps)
    voiced = ~np.isnan(f0)
    features = type(features)(f0=type(features.f0)(np.where(voiced, f0, np.nan), fps, "Hz", "f0", voiced),
                              f0_conditioned=features.f0_conditioned, energy=features.energy,
                              duration_s=features.duration_s, source="<synthetic>")
    words = prosodic_words(features)
    assert words and all(30 <= w.start and w.end <= 66 for w in words)
    accented = [w for w in words if w.start <= 47 < w.end]
    assert accented and abs(accented[0].peak - 48) <= 3 and accented[0].arousal == 1.0
    head = PadHeadModel().generate(features, seed=0)
    pitch = head[48] / AU_PER_DEGREE
    assert np.all(pitch[:24] == 0) and np.all(pitch[75:] == 0)  # silence: still
    assert pitch[30:66].max() > 3  # a nod of Table 3's size on the accent


@pytest.mark.shared_data
def test_on_real_speech_amplitude_rises_with_arousal_and_is_of_table3_size(shared_data):
    from audio_features import extract_features

    features = extract_features(shared_data / "talking-heads" / "Obama_clip1.wav")
    words = prosodic_words(features)
    assert len(words) > 10 and {w.arousal for w in words} == {0.0, 0.5, 1.0}
    head = PadHeadModel().generate(features, seed=3)
    pitch = head[48] / AU_PER_DEGREE
    by_arousal = {a: np.mean([np.ptp(pitch[w.start + 3:w.end - 3]) for w in words if w.arousal == a
                              and w.end - w.start > 12]) for a in (0.0, 0.5, 1.0)}
    assert by_arousal[0.0] < by_arousal[0.5] < by_arousal[1.0]
    # every axis, over three seeds: the peak-to-peak of a PW at A = 0.5 and the spread of the PWs' mean pose
    # are Table 3's amplitude mean and pose std within 25 % (measured: 9.2 / 3.2 / 3.1 deg, 2.8 / 1.5 / 1.7 deg)
    long_words = [w for w in words if w.end - w.start > 12]
    for axis, fap in enumerate((48, 49, 50)):
        sizes, spreads = [], []
        for seed in range(3):
            curve = PadHeadModel().generate(features, seed=seed)[fap] / AU_PER_DEGREE
            sizes += [np.ptp(curve[w.start + 3:w.end - 3]) for w in long_words if w.arousal == 0.5]
            spreads.append(np.std([curve[w.start:w.end].mean() for w in long_words]))
        assert np.mean(sizes) == pytest.approx(TABLE3_AMPLITUDE_DEG[axis], rel=0.25), axis
        assert np.mean(spreads) == pytest.approx(TABLE3_AVERAGE_DEG[axis][1], rel=0.25), axis
    again = PadHeadModel().generate(features, seed=3)
    np.testing.assert_array_equal(head[48], again[48])  # seeded
    assert not np.array_equal(head[48], PadHeadModel(randomized=True).generate(features, seed=3)[48])


def test_pad_is_a_named_head_model():
    assert load_head_model("pad").kind == "pad" and load_head_model("pad-random").randomized
    with pytest.raises(ConfigError):
        PadHeadModel(pleasure=2)


# PAD in: the state over time, the face's partial expressions, and the gestures ------------------------------
def test_pad_states_parse_from_text_and_files(tmp_path):
    from prosody.motion.face.pad import PadSegment, pad_at, parse_pad

    assert parse_pad("0.5,-0.25,1") == [PadSegment(0.5, -0.25, 1.0)]
    for bad in ("0.5,0.2", "a,b,c", "2,0,0", "nan,0,0"):
        with pytest.raises(ConfigError):
            parse_pad(bad)
    timed = tmp_path / "states.csv"
    timed.write_text("start_s,end_s,pleasure,arousal,dominance\n0,1.5,1,0,0\n1.5,3,-1,1,0.5\n", encoding="utf-8")
    states = parse_pad(str(timed))
    assert pad_at(states, 1.0) == (1.0, 0.0, 0.0) and pad_at(states, 2.0) == (-1.0, 1.0, 0.5)
    assert pad_at(states, 5.0) == (0.0, 0.0, 0.0)  # past every state: neutral
    (tmp_path / "bad.csv").write_text("start_s,end_s,pleasure,arousal,dominance\n0,1,0,0,3\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="line 2"):
        parse_pad(str(tmp_path / "bad.csv"))


def test_pad_face_map_is_linear_and_replaceable(tmp_path):
    import json

    from prosody.motion.face.pad import DEFAULT_FACE_MAP, face_targets, read_face_map

    assert face_targets(0, 0, 0) == {fap: 0.0 for entry in DEFAULT_FACE_MAP.values() for fap in entry["faps"]}
    one, two = face_targets(0.2, 0.4, -0.2), face_targets(0.4, 0.8, -0.4)
    assert all(two[fap] == pytest.approx(2 * one[fap]) for fap in one)  # linear in PAD
    fearful, angry = face_targets(-0.6, 0.8, -0.6), face_targets(-0.6, 0.8, 0.6)
    assert fearful[35] > 0 and fearful[19] < 0  # brows up, eyes wide
    assert angry[37] > fearful[37] > 0  # dominance squeezes the brows
    mine = tmp_path / "map.json"
    mine.write_text(json.dumps({"format": "visual-prosody-pad-face", "parameters": {
        "smile": {"weights": [1, 0, 0], "faps": {"12": 100, "13": 100}}}}), encoding="utf-8")
    assert face_targets(0.5, 0, 0, read_face_map(mine)) == {12: 50.0, 13: 50.0}
    mine.write_text(json.dumps({"format": "visual-prosody-pad-face", "parameters": {
        "smile": {"weights": [1, 0], "faps": {"12": 100}}}}), encoding="utf-8")
    with pytest.raises(ConfigError, match="three numbers"):
        read_face_map(mine)


def test_timed_pad_shows_on_the_face_in_its_stretch_only():
    from prosody.motion.face.layer import face_layer
    from prosody.motion.face.pad import PadSegment, face_targets

    layer = face_layer(None, 150, fps=30, lips=None, pad=[PadSegment(0, 1, 0, 2.0, 3.0)])
    raise_ = layer.curves[31]
    assert raise_[75] == pytest.approx(face_targets(0, 1, 0)[31], rel=0.03)
    assert raise_[:30].max() < 0.05 * raise_[75] and raise_[130:].max() < 0.05 * raise_[75]


def test_pad_state_drives_the_gestures():
    from prosody.motion.face.pad import PadSegment

    features = _accent_features()
    calm = PadHeadModel().with_states([PadSegment(0, -1, 0)]).generate(features, seed=0)[48]
    aroused = PadHeadModel().with_states([PadSegment(0, 1, 0)]).generate(features, seed=0)[48]
    assert np.ptp(aroused) > np.ptp(calm)
    # pleasure reaches Eq. 2 through the coefficients: C1..C3 apply at P = 1, C4..C6 at P = 0
    pleased = PadHeadModel(coefficients=[(0, 0, 1, 0, 0, 0)] * 3).with_states([PadSegment(1, 0, 0)])
    neutral = PadHeadModel(coefficients=[(0, 0, 1, 0, 0, 0)] * 3).with_states([PadSegment(0, 0, 0)])
    # the same seed draws the same poses: the difference is the accent's sinusoid, Amp(1, A) = C3 = 1 degree
    nod = (pleased.generate(features, seed=0)[48] - neutral.generate(features, seed=0)[48]) / AU_PER_DEGREE
    assert 0.8 < np.ptp(nod) <= 1.0 + 1e-9


@pytest.mark.shared_data
def test_eq2_arousal_coefficients_are_recovered_from_motion_made_with_them(shared_data):
    # a simulated system with known coefficients: motion generated with C4-C6 = (2, 3, 4) on real speech, where
    # the pose drawn per PW and the boundary smoothing blur each stretch's peak-to-peak
    from audio_features import extract_features
    from prosody.motion.heads.pad import arousal_amplitudes, fit_arousal

    features = extract_features(shared_data / "talking-heads" / "Obama_clip1.wav")
    true = [(2.0, 3.0, 4.0, 2.0, 3.0, 4.0)] * 3
    levels = (-0.5, 0.0, 0.5, 1.0)
    found = []
    for seed in range(3):
        head = PadHeadModel(coefficients=true).generate(features, seed=seed)
        arousal, sizes = arousal_amplitudes(features, np.column_stack([head[fap] for fap in (48, 49, 50)]))
        assert set(arousal.tolist()) == set(levels) and sizes.shape == (arousal.size, 3)
        fitted = fit_arousal(arousal, sizes)
        assert all(axis[:3] == axis[3:] for axis in fitted)  # no pleasure in the data: C1-C3 = C4-C6
        found.append([[amplitude(0, a, axis) for a in levels] for axis in fitted])
    expected = [amplitude(0, a, true[0]) for a in levels]  # 3, 4, 6, 9 degrees
    for axis in np.mean(found, axis=0):
        np.testing.assert_allclose(axis, expected, rtol=0.2)
        assert np.all(np.diff(axis) > 0)
    with pytest.raises(ConfigError, match="at least three arousal levels"):
        fit_arousal(np.array([0.0, 1.0, 1.0]), np.ones((3, 3)))


@pytest.mark.shared_data
@pytest.mark.slow
def test_train_kind_pad_writes_a_model_that_model_file_reads(shared_data, tmp_path, capsys):
    import json

    from prosody.cli import main
    from prosody.motion.heads.pad import arousal_amplitudes, fit_arousal
    from prosody.motion.heads.training import find_pairs, load_training_set

    out = tmp_path / "pad.json"
    folder = shared_data / "talking-heads"
    assert main(["train", "--data", str(folder), "--kind", "pad", "--cv", "-o", str(out)]) == 0
    assert "PAD gesture model fitted on 7 recordings" in capsys.readouterr().err
    payload = json.loads(out.read_text())
    assert payload["format"] == "visual-prosody-pad" and len(payload["training"]) == 7
    held = payload["cross_validation"]  # no speakers.csv there: each recording is held out alone
    assert held["folds"] == 7 and {"r", "chance_r", "chance_spread", "mae_fitted"} <= set(held["pitch"])
    # the file's coefficients are the fit of every recording's stretches
    data = load_training_set(find_pairs(folder), report=lambda line: None)
    pieces = [arousal_amplitudes(f, m) for f, m in zip(data.features, data.motion_au, strict=True)]
    expected = fit_arousal(np.concatenate([a for a, _ in pieces]), np.vstack([y for _, y in pieces]))
    np.testing.assert_allclose(payload["coefficients"], expected, rtol=1e-12)
    model = load_head_model(out)
    assert isinstance(model, PadHeadModel) and model.coefficients_ == expected and len(model.training_) == 7
    assert main(["convert", str(folder / "reagan_clip1.wav"), "--model", str(out), "-o", str(tmp_path / "r.fap")]) == 0


@pytest.mark.parametrize("fap", [1, 2, 69])
def test_a_pad_map_may_name_only_faps_3_to_68(tmp_path, fap):
    import json

    from prosody.motion.face.pad import read_face_map

    path = tmp_path / "map.json"
    from prosody.motion.face.pad import FACE_MAP_FORMAT

    path.write_text(json.dumps({"format": FACE_MAP_FORMAT,
                                "parameters": {"smile": {"weights": [1, 0, 0], "faps": {str(fap): 10}}}}))
    with pytest.raises(ConfigError, match="FAPs must be numbered 3-68"):
        read_face_map(path)
