"""The default speech-driven head and brows, and the measures that judge them against recorded motion."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import soundfile
from conftest import make_features, segments

from audio_features import Audio, F0Track, Features, Track, extract_features, read_features_csv
from prosody.cli import main
from prosody.errors import ConfigError, GroundTruthError, ModelError
from prosody.fap.recorded import ENS_PER_EYE_WIDTH, read_brows_csv, read_motion
from prosody.fap.stream import FapStream
from prosody.jobs.pipeline import apply_controls, convert
from prosody.measures import (
    brow_events,
    brow_metrics,
    head_metrics,
    head_speed,
    lowpass_head,
    speed_envelope,
    velocity_spectrum_distance_db,
)
from prosody.motion.conditions import Condition
from prosody.motion.controls import fitted_features, shift_offsets, shifted_features
from prosody.motion.eyebrows import BROW_SCALE, AccentRule, EyebrowRule, NoRaiseWarning, accent_raises, brow_raises
from prosody.motion.heads.models import SHIPPED_MODELS, default_head_model, load_head_model, rest_pose
from prosody.motion.heads.prosodic import ProsodicHeadModel, follow, speech_presence

SR = 16000
FPS = 30.0


def _features(voiced: np.ndarray, f0_hz: np.ndarray, energy_db: np.ndarray) -> Features:
    """Features with a given voicing (F0 NaN where unvoiced, conditioned F0 held)."""
    f0 = np.where(voiced, f0_hz, np.nan)
    return Features(F0Track(f0, FPS, "Hz", "f0", voiced.astype(bool)), Track(np.asarray(f0_hz, float), FPS, "Hz",
                    "f0_conditioned"), Track(np.asarray(energy_db, float), FPS, "dB", "energy"), f0.size / FPS, "<t>")


# head measures: known answers --------------------------------------------------------------------------
def _wandering(rng, n: int = 900) -> np.ndarray:
    return np.cumsum(rng.standard_normal((n, 3)), axis=0) * 200.0


def test_head_metrics_of_the_recording_itself_are_perfect(rng) -> None:
    recorded = _wandering(rng)
    result = head_metrics(recorded, recorded, fps=FPS)
    assert result["speed_envelope_r"] == pytest.approx(1.0) and result["pitch_r"] == pytest.approx(1.0)
    assert result["std_ratio"] == pytest.approx({"48": 1.0, "49": 1.0, "50": 1.0})
    assert result["velocity_spectrum_distance_db"] == pytest.approx(0.0, abs=1e-9)


def test_twice_the_motion_is_six_decibels_and_a_ratio_of_two(rng) -> None:
    recorded = _wandering(rng)
    result = head_metrics(2 * recorded, recorded, fps=FPS)
    assert result["std_ratio"] == pytest.approx({"48": 2.0, "49": 2.0, "50": 2.0})
    assert result["velocity_spectrum_distance_db"] == pytest.approx(10 * np.log10(4.0))  # power x 4
    assert result["speed_envelope_r"] == pytest.approx(1.0)


def test_speed_ignores_direction_and_pitch_does_not(rng) -> None:
    recorded = _wandering(rng)
    mirrored = -recorded
    result = head_metrics(mirrored, recorded, fps=FPS)
    assert result["speed_envelope_r"] == pytest.approx(1.0)  # which way the head turns does not matter
    assert result["pitch_r"] == pytest.approx(-1.0)


def test_still_head_has_no_correlation_and_zero_spread(rng) -> None:
    recorded = _wandering(rng)
    result = head_metrics(np.zeros_like(recorded), recorded, fps=FPS)
    assert result["speed_envelope_r"] is None and result["pitch_r"] is None
    assert result["std_ratio"] == {"48": 0.0, "49": 0.0, "50": 0.0}
    assert result["velocity_spectrum_distance_db"] is None


def test_lowpass_keeps_nods_and_removes_tracker_jitter() -> None:
    t = np.arange(900) / FPS
    slow, fast = np.sin(2 * np.pi * 1.0 * t), np.sin(2 * np.pi * 10.0 * t)
    middle = slice(100, 800)  # away from the edges
    assert np.abs(lowpass_head(slow, fps=FPS)[middle] - slow[middle]).max() < 0.02
    assert np.abs(lowpass_head(fast, fps=FPS)[middle]).max() < 0.01


def test_speed_envelope_of_a_known_rotation() -> None:
    # yaw turning at a constant 0.2 rad/s: the speed envelope is 0.2 rad/s away from the ends
    t = np.arange(300) / FPS
    angles = np.column_stack([np.zeros_like(t), 0.2 * t, np.zeros_like(t)])
    envelope = speed_envelope(angles, fps=FPS)
    np.testing.assert_allclose(envelope[60:240], 0.2, rtol=1e-3)


def test_velocity_spectrum_distance_needs_one_segment() -> None:
    assert velocity_spectrum_distance_db(np.ones((40, 3)), np.ones((40, 3)), fps=FPS) is None


def test_head_metrics_refuse_mismatched_shapes() -> None:
    with pytest.raises(ConfigError, match="n_frames, 3"):
        head_metrics(np.zeros((10, 3)), np.zeros((11, 3)), fps=FPS)


# controls -------------------------------------------------------------------------------------------------
def test_shifted_features_move_every_track_by_the_offset() -> None:
    voiced = np.arange(20) % 3 == 0
    features = _features(voiced, 100.0 + np.arange(20), 40.0 + np.arange(20))
    moved = shifted_features(features, 5)
    np.testing.assert_array_equal(moved.energy.values, np.roll(features.energy.values, 5))
    np.testing.assert_array_equal(moved.f0.voiced, np.roll(voiced, 5))
    np.testing.assert_array_equal(moved.f0_conditioned.values, np.roll(features.f0_conditioned.values, 5))
    assert moved.n_frames == features.n_frames and moved.fps == features.fps


def test_other_recordings_are_tiled_or_trimmed() -> None:
    features = _features(np.ones(4, bool), np.array([100.0, 110, 120, 130]), np.array([50.0, 51, 52, 53]))
    assert fitted_features(features, 10).energy.values.tolist() == [50, 51, 52, 53, 50, 51, 52, 53, 50, 51]
    assert fitted_features(features, 2).f0.values.tolist() == [100, 110]


def test_shift_offsets_are_at_least_five_seconds_each_way() -> None:
    for n in (450, 900, 5000):
        offsets = shift_offsets(n, fps=FPS)
        assert len(offsets) == 4
        assert all(150 <= k <= n - 150 for k in offsets)
    assert shift_offsets(2, fps=FPS) == []


# the prosodic generator: a simulated system with a known answer --------------------------------------------
def _talk_and_pause(rng, n: int, *, seed_motion: int) -> tuple[Features, np.ndarray]:
    """Synthetic speech that alternates 2 s of talk and 2 s of pause, and head motion that moves fast while
    talking (and nods down, +pitch) and barely in the pauses."""
    talking = (np.arange(n) // 60) % 2 == 0
    f0 = 150.0 * 2 ** (rng.standard_normal(n) / 12)
    energy = np.where(talking, 65.0 + rng.standard_normal(n), 25.0)
    features = _features(talking, f0, energy)
    motion_rng = np.random.default_rng(seed_motion)
    smooth = np.hanning(9) / np.hanning(9).sum()  # nods of about 3 Hz and slower
    velocity = np.column_stack([np.convolve(motion_rng.standard_normal(n), smooth, mode="same") for _ in range(3)])
    motion = np.cumsum(velocity * np.where(talking, 1.0, 0.1)[:, None], axis=0) * 1500.0
    motion -= np.column_stack([np.convolve(motion[:, axis], np.ones(61) / 61, mode="same") for axis in range(3)])
    nod = np.convolve(np.where(talking, 3000.0, -3000.0), np.hanning(31) / np.hanning(31).sum(), mode="same")
    motion[:, 0] += nod
    return features, motion - np.median(motion, axis=0)


@pytest.fixture(scope="module")
def simulated():
    rng = np.random.default_rng(7)
    train = [_talk_and_pause(rng, 900, seed_motion=k) for k in range(4)]
    model = ProsodicHeadModel().fit([f for f, _ in train], [m for _, m in train])
    return model, _talk_and_pause(rng, 900, seed_motion=99)


def test_generated_speed_follows_the_talking(simulated) -> None:
    model, (features, recorded) = simulated
    talking = features.f0.voiced.astype(float)
    motion = np.column_stack(list(model.generate(features, seed=3).values()))
    envelope = speed_envelope(motion * 1e-5, fps=FPS)
    recorded_envelope = speed_envelope(recorded * 1e-5, fps=FPS)
    assert np.corrcoef(recorded_envelope, talking)[0, 1] > 0.6  # the system: fast while talking
    assert np.corrcoef(envelope, talking)[0, 1] > 0.6  # learnt from other recordings of it
    result = head_metrics(motion, recorded, fps=FPS)
    # pitch: the nod is predictable, the random part of that axis (about as large) is not
    assert result["speed_envelope_r"] > 0.6 and result["pitch_r"] > 0.4
    for ratio in result["std_ratio"].values():
        assert 0.5 < ratio < 2.0
    # the same generator with the audio shifted by half a cycle moves out of step
    shifted = np.column_stack(list(model.generate(shifted_features(features, 60), seed=3).values()))
    assert head_metrics(shifted, recorded, fps=FPS)["speed_envelope_r"] < 0


def test_burst_power_makes_the_head_move_in_bursts_and_hold(simulated, tmp_path) -> None:
    # the same fitted generator with the reshaping off (as files written before it read): the bursts make the
    # quick moments quicker and the slow ones slower, at about the same average speed
    import copy

    model, (features, _) = simulated
    assert model.burst_power == 0.5
    plain = copy.copy(model)
    plain.burst_power = 0.0

    def speeds(m) -> np.ndarray:
        motion = np.column_stack(list(m.generate(features, seed=3).values()))
        return np.degrees(head_speed(motion * 1e-5, fps=FPS))

    bursty, even = speeds(model), speeds(plain)

    def contrast(speed: np.ndarray) -> float:
        return float(np.percentile(speed, 90) / np.percentile(speed, 10))

    assert contrast(bursty) > 1.3 * contrast(even)
    assert 0.75 < bursty.mean() / even.mean() < 1.25
    payload = model.to_dict()
    del payload["settings"]["burst_power"]
    (tmp_path / "old.json").write_text(json.dumps(payload))
    old = load_head_model(tmp_path / "old.json")
    assert old.burst_power == 0.0
    np.testing.assert_array_equal(speeds(old), even)


def test_pitch_follows_the_prediction_quickly_when_talking_and_holds_in_pauses(simulated, tmp_path) -> None:
    model, (features, _) = simulated
    assert model.pitch_follow_s == 0.2
    raw, speed = model.predicted_pitch(features), model.predicted_envelope(features)
    followed = model._followed_pitch(features, speed)
    # the lag's time constant is 0.2 s (6 frames) at the average predicted speed, shorter when faster
    np.testing.assert_allclose(followed, follow(raw, speed / speed.mean(), frames=6.0), rtol=1e-12)
    # where the speech says the head is quiet it keeps much less of the prediction's changes than where it
    # says the head moves
    quiet, busy = speed[1:] <= np.percentile(speed, 25), speed[1:] >= np.percentile(speed, 75)

    def kept(where: np.ndarray) -> float:
        return float(np.abs(np.diff(followed))[where].mean() / np.abs(np.diff(raw))[where].mean())

    assert kept(quiet) < 0.5 * kept(busy)
    # files written before the setting read as 0: the prediction taken as it is
    payload = model.to_dict()
    del payload["settings"]["pitch_follow_s"]
    (tmp_path / "old.json").write_text(json.dumps(payload))
    old = load_head_model(tmp_path / "old.json")
    assert old.pitch_follow_s == 0.0
    np.testing.assert_array_equal(old._followed_pitch(features, speed), raw)


def test_same_seed_same_motion_other_seed_other_motion(simulated) -> None:
    model, (features, _) = simulated
    first, again, other = (model.generate(features, seed=s) for s in (5, 5, 6))
    for fap in (48, 49, 50):
        assert first[fap].tobytes() == again[fap].tobytes()
        assert not np.array_equal(first[fap], other[fap])


def test_model_file_round_trip_gives_the_same_motion(simulated, tmp_path) -> None:
    model, (features, _) = simulated
    path = tmp_path / "model.json"
    model.save(path, extra={"note": "simulated"})
    loaded = load_head_model(path)
    assert isinstance(loaded, ProsodicHeadModel)
    for fap, curve in model.generate(features, seed=1).items():
        np.testing.assert_array_equal(loaded.generate(features, seed=1)[fap], curve)
    payload = json.loads(path.read_text())
    assert payload["format"] == "visual-prosody-head" and payload["kind"] == "prosodic" and payload["version"] == 1


@pytest.mark.parametrize("change, message", [
    (lambda p: p.update(kind="arx"), "kind"),
    (lambda p: p.update(version=2), "version"),
    (lambda p: p.pop("filters"), "missing or malformed"),
    (lambda p: p.update(filters=[[1.0, 2.0]]), "shape"),
    (lambda p: p["settings"].update(ridge=float("nan")), "finite"),
    (lambda p: p["settings"].update(pitch_share=True), "finite number"),
    (lambda p: p["settings"].update(speed_iterations=2.5), "whole number"),
    (lambda p: p["settings"].update(pitch_share=3.0), r"pitch_share must be a number in \[0, 1\]"),
    (lambda p: p.update(fps=float("inf")), "fps"),
    (lambda p: p.update(spread_au=[1.0, -1.0, 1.0]), "positive"),
    (lambda p: p["settings"].pop("ridge"), "settings"),
    (lambda p: p.update(features=["voiced"]), "features"),
])
def test_model_files_are_validated(simulated, tmp_path, change, message) -> None:
    model, _ = simulated
    payload = model.to_dict()
    change(payload)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(payload))
    with pytest.raises(ModelError, match=message):
        load_head_model(path)


def test_model_loader_refuses_what_is_not_a_model(tmp_path) -> None:
    (tmp_path / "x.json").write_text('{"format": "something-else"}')
    with pytest.raises(ModelError, match="not a head model"):
        load_head_model(tmp_path / "x.json")
    (tmp_path / "deep.json").write_text("[" * 100000 + "]" * 100000)
    with pytest.raises(ModelError, match="nested|not a head model"):
        load_head_model(tmp_path / "deep.json")
    with pytest.raises(ModelError, match="no such model file.*prosodic, arx"):
        load_head_model(tmp_path / "none.json")


def test_unfitted_and_bad_settings() -> None:
    with pytest.raises(ConfigError, match="not fitted"):
        ProsodicHeadModel().generate(make_features(np.full(10, 100.0), np.full(10, 60.0)))
    with pytest.raises(ConfigError, match="lookahead_s"):
        ProsodicHeadModel(lookahead_s=-1).fit([make_features(np.full(200, 100.0), np.full(200, 60.0))],
                                              [np.zeros((200, 3))])


def test_seed_must_be_a_whole_number_at_least_zero() -> None:
    model = default_head_model()
    features = make_features(np.full(30, 150.0), np.full(30, 60.0))
    with pytest.raises(ConfigError, match="seed"):
        model.generate(features, seed=-1)


# the shipped models ----------------------------------------------------------------------------------------
def test_shipped_models_by_name() -> None:
    assert set(SHIPPED_MODELS) == {"prosodic", "arx"}
    assert load_head_model("prosodic").kind == "prosodic"
    assert load_head_model("arx").kind == "arx"
    assert default_head_model().fps_ == 30.0


def test_silence_and_noise_settle_to_an_idle_sway_and_speech_moves_the_head(rng) -> None:
    model = default_head_model()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no voiced frame: a warning of the analysis
        silence = extract_features(Audio(np.zeros(SR * 10), SR))
        noise = extract_features(Audio(0.1 * rng.standard_normal(SR * 10), SR))
    assert speech_presence(silence).max() == 0 and speech_presence(noise).max() == 0
    # a voice: a chirp-like intonation over a 6 s phrase
    t = np.arange(SR * 10) / SR
    f0 = np.where((t % 5) < 3.5, 140 + 40 * np.sin(2 * np.pi * 1.3 * t), 0.0)
    speech = extract_features(Audio(segments_from(f0), SR))

    def spread(features: Features) -> float:
        curves = [model.generate(features, seed=s) for s in range(3)]
        return float(np.mean([np.std(c[fap]) for c in curves for fap in (48, 49, 50)]))

    at_rest, on_noise, talking = spread(silence), spread(noise), spread(speech)
    assert talking > 2000  # a person's size: thousands of AU (a few degrees)
    assert at_rest < 0.25 * talking and on_noise < 0.25 * talking
    assert at_rest == pytest.approx(on_noise)  # noise without a voice is treated as silence


def segments_from(f0_hz: np.ndarray) -> np.ndarray:
    from conftest import gliding_tone

    return gliding_tone(f0_hz, SR, amplitude=0.5)


def test_gains_scale_motion_about_the_rest_pose() -> None:
    arx = load_head_model("arx")
    rest = rest_pose(arx)
    assert any(abs(value) > 1 for value in rest.values())  # the thesis model rests off zero
    features = make_features(150 + 20 * np.sin(np.arange(300) / 7), 60 + 5 * np.cos(np.arange(300) / 5))
    curves = arx.generate(features)
    stream = FapStream.from_curves(curves, fps=FPS)
    still = apply_controls(stream, gains={"pitch": 0.0, "yaw": 0.0, "roll": 0.0}, rest=rest)
    for fap in (48, 49, 50):
        np.testing.assert_allclose(still.curve(fap), rest[fap])
    doubled = apply_controls(stream, gains={"yaw": 2.0}, rest=rest)
    np.testing.assert_allclose(doubled.curve(49) - rest[49], 2 * (curves[49] - rest[49]))
    assert rest_pose(default_head_model()) == {48: 0.0, 49: 0.0, 50: 0.0}


def test_convert_uses_the_seed_for_the_speech_driven_head(tmp_path) -> None:
    audio = tmp_path / "v.wav"
    soundfile.write(audio, segments(SR, (0.6, 140, 0.5), (0.5, 230, 0.5), (0.8, 150, 0.5), (0.4, 0, 0)), SR)
    a = convert(audio, seed=1)
    b = convert(audio, seed=1)
    c = convert(audio, seed=2)
    assert a.values.tobytes() == b.values.tobytes()
    assert not np.array_equal(a.curve(49), c.curve(49))
    arx = convert(audio, model="arx")
    thesis = convert(audio, model=SHIPPED_MODELS["arx"])
    np.testing.assert_array_equal(arx.values, thesis.values)


# eyebrows: the accent rule ---------------------------------------------------------------------------------
def _voice(f0: np.ndarray, energy: float = 60.0) -> Features:
    return _features(f0 > 0, np.where(f0 > 0, f0, 1.0), np.where(f0 > 0, energy, 20.0))


def test_accent_rule_raises_on_any_voice_and_any_level() -> None:
    for median_hz in (95.0, 150.0, 260.0):
        f0 = np.full(120, median_hz)
        f0[40:55] = median_hz * 2 ** (6 / 12)  # a 6-semitone accent for 0.5 s
        for level in (40.0, 60.0, 85.0):
            raises = accent_raises(_voice(f0, level))
            assert raises.events == ((40, 55),)
            # 12 ENS at the threshold plus 3 per semitone above it, at people's size (BROW_SCALE times that)
            assert raises.displacement_ens[45] == pytest.approx((12 + 3 * 2) * BROW_SCALE)


def test_accent_rule_ignores_octave_errors_and_pauses() -> None:
    f0 = np.full(120, 120.0)
    f0[50] = 240.0  # a one-frame octave error
    f0[70:90] = 0.0  # a pause: no voice, whatever a spline would bridge
    assert accent_raises(_voice(f0)).events == ()


def test_accent_rule_holds_at_least_300_ms_and_at_most_1_2_s() -> None:
    f0 = np.full(200, 120.0)
    f0[20:23] = 200.0  # a 100 ms peak: held for the minimum 9 frames
    f0[100:190] = 200.0  # a 3 s high stretch: released after 36 frames
    events = accent_raises(_voice(f0)).events
    assert events == ((20, 29), (100, 136))  # no new raise until the pitch has come down
    assert accent_raises(_voice(f0), AccentRule(max_hold_s=0.6)).events[1] == (100, 118)


def test_quiet_frames_do_not_raise() -> None:
    f0 = np.full(120, 120.0)
    f0[40:55] = 200.0
    features = _features(f0 > 0, f0, np.where((np.arange(120) >= 40) & (np.arange(120) < 55), 30.0, 60.0))
    assert accent_raises(features).events == ()


def test_no_voice_gives_no_raise_and_says_so() -> None:
    raises = brow_raises(_voice(np.zeros(60)))
    assert raises.events == () and not np.isfinite(raises.f0_threshold_hz)
    with pytest.warns(NoRaiseWarning, match="no voiced speech"):
        from prosody.motion.conditions import condition_stream

        condition_stream(Condition.SPEECH_DRIVEN, _voice(np.zeros(60)))


def test_thesis_rule_stays_available_by_name() -> None:
    f0 = np.full(90, 150.0)
    f0[30:] = 250.0
    raises = brow_raises(make_features(f0, np.full(90, 60.0)), EyebrowRule())
    assert raises.rule == "thesis" and raises.events == ((30, 90),)


@pytest.mark.parametrize("kwargs", [dict(threshold_semitones=-1), dict(loudness_db=float("nan")),
                                    dict(min_hold_s=1.0, max_hold_s=0.5), dict(ramp_s=0.0), dict(median_s=2.0),
                                    dict(max_ens=0.0), dict(base_ens=True)])
def test_accent_rule_refuses_bad_settings(kwargs) -> None:
    with pytest.raises(ConfigError):
        AccentRule(**kwargs)


def test_cli_refuses_thesis_options_with_the_accent_rule(tmp_path, capsys) -> None:
    audio = tmp_path / "v.wav"
    soundfile.write(audio, segments(SR, (0.6, 140, 0.5), (0.5, 230, 0.5)), SR)
    out = tmp_path / "x.fap"
    assert main(["convert", str(audio), "-o", str(out), "--eyebrow-semitones", "3"]) == 2
    assert "--brows thesis" in capsys.readouterr().err and not out.exists()
    assert main(["convert", str(audio), "-o", str(out), "--brows", "thesis", "--eyebrow-semitones", "3",
                 "--eyebrow-threshold", "200"]) == 2
    for bad in (["--brows", "thesis", "--energy-relative", "nan"], ["--seed", "-1"]):
        with pytest.raises(SystemExit) as exit_info:
            main(["convert", str(audio), "-o", str(out), *bad])
        assert exit_info.value.code == 2
    assert main(["convert", str(audio), "-o", str(out), "--brows", "thesis", "--eyebrow-semitones", "3"]) == 0


# recorded brows ---------------------------------------------------------------------------------------------
def _brows_csv(path, inner_l, inner_r, outer_l, outer_r) -> None:
    lines = ["frame,time_s,brow_inner_up,brow_outer_up_l,brow_outer_up_r,inner_height_l,inner_height_r,"
             "outer_height_l,outer_height_r"]
    for k, values in enumerate(zip(inner_l, inner_r, outer_l, outer_r, strict=True)):
        cells = ["" if v is None else f"{v}" for v in values]
        lines.append(f"{k},{k / 30:.4f},0.1,0.1,0.1," + ",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def test_brows_csv_maps_heights_to_fap_31_to_34(tmp_path) -> None:
    path = tmp_path / "c.brows.csv"
    _brows_csv(path, [0.40, 0.41, None, 0.43], [0.30, 0.30, 0.30, 0.32], [0.35] * 4, [0.33] * 4)
    stream = read_brows_csv(path)
    inner_l = np.array([0.40, 0.41, 0.42, 0.43])  # the missing frame interpolated
    np.testing.assert_allclose(stream.curve(31), (inner_l - np.median(inner_l)) * ENS_PER_EYE_WIDTH)
    np.testing.assert_allclose(stream.curve(32), (np.array([0.30, 0.30, 0.30, 0.32]) - 0.30) * ENS_PER_EYE_WIDTH)
    np.testing.assert_allclose(stream.curve(33), (stream.curve(31) + 0.0) / 2)  # outer heights constant
    assert stream.active_faps == (31, 32, 33, 34)


def test_brows_csv_errors_name_the_line(tmp_path) -> None:
    path = tmp_path / "c.brows.csv"
    _brows_csv(path, [0.4, 0.4], [0.3, 0.3], [0.3, 0.3], [0.3, 0.3])
    path.write_text(path.read_text().replace("1,0.0333", "5,0.0333"))
    with pytest.raises(GroundTruthError, match="line 3"):
        read_brows_csv(path)
    _brows_csv(path, [None, None], [None, None], [None, None], [None, None])
    with pytest.raises(GroundTruthError, match="no frame with a tracked face"):
        read_brows_csv(path)


def test_head_csv_with_brows_beside_it_carries_both(tmp_path) -> None:
    head = tmp_path / "c.head.csv"
    head.write_text("frame,time_s,rx_rad,ry_rad,rz_rad\n" + "".join(
        f"{k},{k / 30:.6f},{0.01 * k},0,0\n" for k in range(5)))
    _brows_csv(tmp_path / "c.brows.csv", [0.40, 0.41, 0.42, 0.43, 0.44], [0.3] * 5, [0.3] * 5, [0.3] * 5)
    stream = read_motion(head)
    assert stream.active_faps == (31, 32, 33, 34, 48, 49, 50)
    np.testing.assert_allclose(stream.curve(31), (np.arange(5) - 2) * 0.01 * ENS_PER_EYE_WIDTH)


def test_brow_events_and_onset_agreement_on_known_bumps() -> None:
    n = 300
    recorded = np.zeros(n)
    for start in (40, 150, 240):
        recorded[start:start + 12] = 20.0  # three 0.4 s raises of 20 ENS
    events = brow_events(recorded, fps=FPS)
    assert [a for a, _ in events] == pytest.approx([40, 150, 240], abs=3)
    matching = np.zeros(n)
    matching[42:54] = 10.0
    matching[152:164] = 10.0
    result = brow_metrics(matching, recorded, fps=FPS)
    assert result["onsets"] == {"precision": 1.0, "recall": pytest.approx(2 / 3), "f1": pytest.approx(0.8)}
    assert result["raises"] == 2 and result["recorded_raises"] == 3
    late = np.roll(matching, 60)
    assert brow_metrics(late, recorded, fps=FPS)["onsets"]["precision"] == 0.0


# the real clips -------------------------------------------------------------------------------------------
@pytest.mark.shared_data
def test_shipped_default_is_speech_driven_on_a_real_clip(shared_data) -> None:
    """In-sample (the default was trained on these clips): the timing must beat the control by far."""
    from prosody.evaluation.compare import compare

    clip = shared_data / "talking-heads" / "Obama_clip1"
    result = compare(clip.with_suffix(".wav"), ground_truth=clip.with_suffix(".head.csv"), seeds=3,
                     conditions=["speech", "random", "truth"])
    speech = result.metrics["conditions"]["SPEECH_DRIVEN"]["head"]
    control = result.metrics["controls"]["mismatched_audio"]
    assert speech["speed_envelope_r"] - control["speed_envelope_r"] > 0.3
    assert speech["pitch_r"] - control["pitch_r"] > 0.3
    for ratio in speech["std_ratio"].values():
        assert 0.33 < ratio < 3.0  # this clip nods more than most: its pitch spread is 1.8 times the average
    assert result.metrics["conditions"]["GROUND_TRUTH"]["brows"]["raise_r"] > 0.95


@pytest.mark.shared_data
def test_features_csv_round_trip(shared_data, tmp_path) -> None:
    features = extract_features(shared_data / "talking-heads" / "feifeili_clip3.wav")
    features.write_csv(tmp_path / "f.csv")
    back = read_features_csv(tmp_path / "f.csv", fps=30.0)
    np.testing.assert_array_equal(back.f0.voiced, features.f0.voiced)
    np.testing.assert_allclose(back.energy.values, features.energy.values, atol=5e-4)


def test_the_generators_numpy_lowpass_matches_scipys_butterworth(rng) -> None:
    """The generator filters with numpy (convert must not pay for importing scipy.signal); it must agree
    with the 4th-order zero-phase Butterworth that the measures use."""
    from scipy.signal import butter, sosfiltfilt

    from prosody.motion.heads.prosodic import smooth_speed_envelope, zero_phase_lowpass

    walk = np.cumsum(rng.standard_normal((900, 3)), axis=0) * 1e-3
    reference = sosfiltfilt(butter(4, 4.0, fs=FPS, output="sos"), walk, axis=0)
    assert np.abs(zero_phase_lowpass(walk, fps=FPS) - reference).max() < 0.005 * walk.std()
    envelope = speed_envelope(walk, fps=FPS)
    np.testing.assert_allclose(smooth_speed_envelope(walk, fps=FPS), envelope, rtol=0.05, atol=0.02 * envelope.mean())


def test_compare_measures_the_thesis_model_beside_the_default(tmp_path, rng) -> None:
    from prosody.evaluation.compare import compare

    audio = tmp_path / "v.wav"
    soundfile.write(audio, segments(SR, (2.0, 140, 0.5), (1.0, 230, 0.5), (3.0, 150, 0.5), (2.0, 0, 0),
                                    (4.0, 170, 0.5)), SR)
    n = 360
    walk = np.cumsum(0.002 * rng.standard_normal((n, 3)), axis=0)
    truth = tmp_path / "v.head.csv"
    truth.write_text("frame,time_s,rx_rad,ry_rad,rz_rad\n" + "".join(
        f"{k},{k / 30:.6f},{a!r},{b!r},{c!r}\n" for k, (a, b, c) in enumerate(walk.tolist())))
    result = compare(audio, ground_truth=truth, seeds=2, other_head_models={"thesis": "arx"},
                     conditions=["speech", "truth"])
    other = result.metrics["other_head_models"]["thesis"]
    assert other["kind"] == "arx"
    # the ARX model is deterministic: its own figure is one run, and it is what the model generates
    arx = load_head_model("arx")
    generated = np.column_stack([arx.generate(result.features)[fap] for fap in (48, 49, 50)])
    recorded = result.streams[Condition.GROUND_TRUTH].curves((48, 49, 50))
    assert other["head"]["pitch_r"] == pytest.approx(head_metrics(generated, recorded, fps=FPS)["pitch_r"])
    assert other["mismatched_audio"]["speed_envelope_r"] is not None
    # its stream: the speech-driven face with the ARX head, written beside the conditions' files
    from prosody.evaluation.compare import write_comparison
    from prosody.fap.fapfile import read_fap

    speech = result.streams[Condition.SPEECH_DRIVEN]
    np.testing.assert_allclose(result.other_models["thesis"].curves((48, 49, 50)), generated)
    np.testing.assert_array_equal(result.other_models["thesis"].curves((31, 33)), speech.curves((31, 33)))
    folder = tmp_path / "out"
    write_comparison(result, folder, plots=False)
    written = read_fap(folder / "speech_driven.thesis.fap").stream
    np.testing.assert_allclose(written.curves((48, 49, 50)), generated, atol=0.5)  # .fap holds whole numbers
    result.other_models.clear()
    write_comparison(result, folder, plots=False)  # written again without it: no stale file is left
    assert not (folder / "speech_driven.thesis.fap").exists() and (folder / "speech_driven.fap").exists()


@pytest.mark.parametrize("fps", [25.0, 29.97, 60.0])
def test_speech_driven_head_at_other_frame_rates(tmp_path, fps) -> None:
    audio = tmp_path / "v.wav"
    soundfile.write(audio, segments(SR, (1.0, 140, 0.5), (0.5, 230, 0.5), (1.5, 150, 0.5)), SR)
    for model in ("prosodic", "arx"):
        stream = convert(audio, model=model, fps=fps)
        assert stream.fps == fps and stream.n_frames == int(np.ceil(3.0 * fps - 1e-9))
        assert np.all(np.isfinite(stream.curves((48, 49, 50))))
    at_30 = convert(audio, fps=30.0)
    other = convert(audio, fps=fps)
    # the same motion, sampled on another grid
    times = np.arange(other.n_frames) / fps
    expected = np.interp(times, np.arange(at_30.n_frames) / 30.0, at_30.curve(49))
    assert np.corrcoef(other.curve(49), expected)[0, 1] > 0.95


def test_every_shipped_model_file_is_read_and_written_the_one_way(tmp_path) -> None:
    """Every model class is a JsonModel: each shipped file loads by its kind's class, and what it saves loads
    back to the same data; a file of one kind is refused by another kind's reader, naming the file."""
    import json

    from prosody.errors import ModelError
    from prosody.motion.face.mouth_model import AcousticMouthModel, LiveMouthModel
    from prosody.motion.heads.arx import ArxHeadModel
    from prosody.motion.heads.live import LiveHeadModel
    from prosody.motion.heads.models import NAMED_MODELS
    from prosody.motion.heads.pad import PadHeadModel
    from prosody.motion.heads.prosodic import ProsodicHeadModel
    from prosody.motion.model_files import MODELS_DIR, JsonModel

    readers = {"arx": ArxHeadModel, "prosodic": ProsodicHeadModel, "prosodic-live": LiveHeadModel,
               "mouth-acoustic": AcousticMouthModel, "mouth-live": LiveMouthModel, "pad": PadHeadModel}
    assert all(issubclass(reader, JsonModel) for reader in readers.values())
    files = sorted(MODELS_DIR.glob("*.json"))
    assert {json.loads(path.read_text())["kind"] for path in files} == set(readers) - {"pad"}
    for path in files:
        reader = readers[json.loads(path.read_text())["kind"]]
        model = reader.load(path)
        model.save(tmp_path / path.name)
        assert reader.load(tmp_path / path.name).to_dict() == model.to_dict(), path.name
        for other in set(readers.values()) - {reader}:
            with pytest.raises(ModelError, match=path.name):
                other.load(path)
    pad = NAMED_MODELS["pad"]()
    pad.save(tmp_path / "pad.json")
    assert PadHeadModel.load(tmp_path / "pad.json").to_dict() == pad.to_dict()
