"""Greta's expressivity controls: known answers on synthetic motion, and each control's measure on real speech."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from audio_features import extract_features
from prosody.cli import main
from prosody.dsp import head_speed, speed_envelope
from prosody.errors import ConfigError
from prosody.measures import speed_distribution
from prosody.motion.conditions import Condition, condition_stream, head_motion
from prosody.motion.expressivity import (
    NOD_CYCLES,
    NOD_HZ,
    BrowShaper,
    Expressivity,
    HeadShaper,
    shape_brows,
    shape_head,
)
from prosody.motion.heads.models import load_head_model, rest_pose

FPS = 30.0
HEAD = (48, 49, 50)


def _axes(stream_or_curves) -> np.ndarray:
    curves = stream_or_curves
    return np.column_stack([curves[fap] for fap in (48, 49, 50)])


def _speeds(motion_au: np.ndarray) -> np.ndarray:
    return np.degrees(head_speed(motion_au * 1e-5, fps=FPS))


def _high_share(motion_au: np.ndarray, *, above_hz: float = 4.0) -> float:
    """Share of the velocity's power above ``above_hz`` (all axes)."""
    velocity = np.diff(motion_au, axis=0)
    power = np.abs(np.fft.rfft(velocity - velocity.mean(axis=0), axis=0)) ** 2
    frequencies = np.fft.rfftfreq(velocity.shape[0], d=1 / FPS)
    return float(power[frequencies >= above_hz].sum() / power.sum())


@pytest.fixture(scope="module")
def real_head():
    """The default generator's head on a real recording, three seeds: (n_frames, 3) AU each."""
    from conftest import SHARED_DATA

    path = SHARED_DATA / "talking-heads" / "KristiNoem.wav"
    if not path.exists():
        pytest.skip(f"real data not found at {SHARED_DATA}")
    features = extract_features(path)
    model = load_head_model("prosodic")
    return features, [_axes(head_motion(model, features, seed=seed)) for seed in range(3)]


def _mean_over_seeds(motions, expressivity, measure):
    return float(np.mean([measure(shape_head(m, fps=FPS, expressivity=expressivity)) for m in motions])), \
        float(np.mean([measure(m) for m in motions]))


# the controls themselves ----------------------------------------------------------------------------------
def test_controls_are_checked_and_neutral_by_default():
    assert Expressivity().is_neutral and not Expressivity(power=0.1).is_neutral
    for name, value in (("activation", -0.1), ("activation", 1.5), ("spatial", 1.01), ("temporal", -2),
                        ("fluidity", math.nan), ("power", math.inf), ("repetition", -0.5), ("spatial", True)):
        with pytest.raises(ConfigError, match=name):
            Expressivity(**{name: value})
    with pytest.raises(ConfigError, match="unknown"):
        Expressivity().with_changes(speed=1)
    assert Expressivity.still() == Expressivity(activation=0)


def test_neutral_controls_leave_every_frame_as_generated(rng):
    motion = np.cumsum(rng.standard_normal((600, 3)), axis=0) * 300
    assert np.array_equal(shape_head(motion, fps=FPS, expressivity=Expressivity()), motion)
    shaper = HeadShaper(Expressivity(), fps=FPS)
    assert np.array_equal(np.array([shaper.step(row) for row in motion]), motion)
    brows = np.maximum(rng.standard_normal(600), 0) * 5
    brow_shaper = BrowShaper(Expressivity(), fps=FPS)
    assert np.array_equal([brow_shaper.step(v) for v in brows], brows)


def test_spatial_scales_the_motion_about_rest_exactly(rng):
    motion = np.cumsum(rng.standard_normal((300, 3)), axis=0) * 100
    for spatial, factor in ((1, 2.0), (-1, 0.5), (0.5, math.sqrt(2))):
        shaped = shape_head(motion, fps=FPS, expressivity=Expressivity(spatial=spatial))
        np.testing.assert_allclose(shaped, motion * factor, rtol=1e-12)
    brows = np.zeros(60)
    brows[10:30] = 8.0
    np.testing.assert_allclose(shape_brows(brows, fps=FPS, expressivity=Expressivity(spatial=1)), 2 * brows)


def test_spatial_scales_the_arx_model_about_its_own_rest_pose():
    features = extract_features(_tone_speech())
    model = load_head_model("arx")
    rest = np.array([rest_pose(model)[fap] for fap in (48, 49, 50)])
    plain = condition_stream(Condition.SPEECH_DRIVEN, features, model=model).curves(HEAD)
    bigger = condition_stream(Condition.SPEECH_DRIVEN, features, model=model,
                              expressivity=Expressivity(spatial=1)).curves(HEAD)
    np.testing.assert_allclose(bigger - rest, 2 * (plain - rest), atol=1e-6)


def _tone_speech():
    from conftest import harmonic_tone

    from audio_features import Audio

    rate = 16000
    parts = [harmonic_tone(f0, 0.6, rate) for f0 in (140, 190, 150, 230, 160)]
    gaps = np.zeros(int(0.3 * rate))
    return Audio(np.concatenate([np.concatenate([p, gaps]) for p in parts]), rate)


# brows: raises with known answers ----------------------------------------------------------------------------
def _raises(n=300, spans=((20, 50), (90, 120), (160, 190), (230, 260)), height=8.0):
    curve = np.zeros(n)
    for start, end in spans:
        curve[start:end] = height
    return curve


def test_brow_activation_keeps_an_even_share_of_the_raises():
    curve = _raises()
    for activation, kept in ((1.0, [1, 1, 1, 1]), (0.5, [0, 1, 0, 1]), (0.25, [0, 0, 0, 1]), (0.0, [0, 0, 0, 0])):
        shaped = shape_brows(curve, fps=FPS, expressivity=Expressivity(activation=activation))
        assert [int(shaped[start + 5] > 0) for start in (20, 90, 160, 230)] == kept


def test_brow_temporal_holds_longer_or_cuts_short():
    curve = _raises(spans=((20, 110),))  # a 3 s raise
    longer = shape_brows(curve, fps=FPS, expressivity=Expressivity(temporal=1))
    # held 0.5 s (15 frames) past its end, then down over 0.1 s (3 frames)
    assert longer[110 + 14] == 8.0 and 0 < longer[110 + 16] < 8.0 and longer[110 + 18] == 0.0
    shorter = shape_brows(curve, fps=FPS, expressivity=Expressivity(temporal=-1))
    # at most 1.2 s * 4^-1 = 0.3 s (9 frames), then down over 3 frames
    assert shorter[20 + 9] == 8.0 and shorter[20 + 12] == 0.0 and not shorter[40:].any()


def test_brow_power_flicks_the_onset_and_repetition_echoes_the_raise():
    curve = _raises(spans=((20, 50),))
    flick = shape_brows(curve, fps=FPS, expressivity=Expressivity(power=1))
    assert flick[20] == pytest.approx(8.0 * 1.5)  # +power/2 of the height at the onset
    assert flick[45] == pytest.approx(8.0, rel=0.01)  # settled after 0.15 s time constants
    echo = shape_brows(curve, fps=FPS, expressivity=Expressivity(repetition=1))
    # 0.15 s (5 frames) after the end, a raise of 0.7 of the height that lasts 0.35 s
    assert not echo[50:54].any() and echo[55:66].max() == pytest.approx(0.7 * 8.0) and not echo[70:].any()


def test_brow_fluidity_softens_or_sharpens_the_ramps():
    curve = np.zeros(120)
    curve[20:60] = np.minimum(1.0, (np.arange(40) + 1) / 10) * 8  # a 10-frame ramp up
    smooth = shape_brows(curve, fps=FPS, expressivity=Expressivity(fluidity=1))
    abrupt = shape_brows(curve, fps=FPS, expressivity=Expressivity(fluidity=-1))
    assert np.abs(np.diff(smooth)).max() < 0.6 * np.abs(np.diff(curve)).max()
    assert abrupt[20] == pytest.approx(curve[20]) and np.all(abrupt[20:60] >= curve[20:60] - 1e-12)


# head: synthetic motion ----------------------------------------------------------------------------------
def test_repetition_nods_once_per_strong_accent():
    n = int(12 * FPS)
    t = np.arange(n) / FPS
    motion = np.zeros((n, 3))
    # a slow sway with three quick turns of the head (yaw) 4 s apart
    motion[:, 0] = 2000 * np.sin(2 * np.pi * 0.2 * t)
    for start in (2.0, 6.0, 10.0):
        motion[:, 1] += 8000 * np.clip((t - start) / 0.3, 0, 1) * (1 if start != 6.0 else -1)
    shaper = HeadShaper(Expressivity(repetition=1), fps=FPS)
    shaped = np.array([shaper.step(row) for row in motion])
    nod = shaped[:, 0] - motion[:, 0]
    active = np.flatnonzero(np.abs(nod) > 1e-9)
    starts = active[np.concatenate([[True], np.diff(active) > 10])]  # a nod crosses zero within itself
    assert len(starts) == 3
    assert np.all(np.abs(starts / FPS - np.array([2.0, 6.0, 10.0])) < 0.3)
    length = int(round(NOD_CYCLES / NOD_HZ * FPS))
    assert np.all(np.diff(starts) > length) and active.size <= 3 * length
    np.testing.assert_array_equal(shaped[:, 1:], motion[:, 1:])  # only the pitch nods


def test_activation_zero_on_a_moving_head_leaves_a_slow_sway(rng):
    velocity = rng.standard_normal((1800, 3)) * 400
    motion = np.cumsum(velocity, axis=0)
    motion -= np.linspace(motion[0], motion[-1], motion.shape[0])
    still = shape_head(motion, fps=FPS, expressivity=Expressivity.still())
    # a tenth of the velocity is kept, and the 4 s pull towards the generator's pose adds a slow drift
    assert np.mean(_speeds(still)) < 0.2 * np.mean(_speeds(motion))


@pytest.mark.parametrize("controls", [Expressivity(power=1), Expressivity(power=0.5),
                                      Expressivity(activation=0.5), Expressivity(power=-1)])
def test_reshaping_keeps_the_pose_where_the_generator_has_it(rng, controls):
    # nods that rise slowly (0.8 s) and fall quickly (0.2 s), of random heights: a gain that follows the speed
    # scales the falls more than the rises, and without balancing the two the pose drifts by about one spread
    pieces = []
    for height in rng.uniform(500, 4000, 60):
        pieces += [np.linspace(0, height, 24, endpoint=False), np.linspace(height, 0, 6, endpoint=False)]
    pitch = np.concatenate(pieces)
    motion = np.column_stack([pitch, 0.3 * pitch, np.zeros_like(pitch)])
    shaped = shape_head(motion, fps=FPS, expressivity=controls)
    offset = (shaped - motion)[len(pitch) // 4:, :2].mean(axis=0)
    assert np.all(np.abs(offset) < 0.15 * motion[:, :2].std(axis=0))
    # and the reshaping still happened: the fastest moments are faster or slower than generated
    assert not np.allclose(_speeds(shaped), _speeds(motion), rtol=0.05)


# head: each control's measure on real speech -------------------------------------------------------------------
@pytest.mark.shared_data
def test_activation_makes_the_head_hold_still(real_head):
    _, motions = real_head
    still, before = _mean_over_seeds(motions, Expressivity.still(),
                                     lambda m: speed_distribution(m * 1e-5, fps=FPS)["still_fraction"])
    assert before < 0.05 and still > 0.4
    p90_still, p90 = _mean_over_seeds(motions, Expressivity.still(), lambda m: np.percentile(_speeds(m), 90))
    assert p90_still < 0.25 * p90
    # at 0.5 the weakest half is held: the quiet moments slow down far more than the busy ones
    p10_half, p10 = _mean_over_seeds(motions, Expressivity(activation=0.5), lambda m: np.percentile(_speeds(m), 10))
    p90_half, _ = _mean_over_seeds(motions, Expressivity(activation=0.5), lambda m: np.percentile(_speeds(m), 90))
    assert p10_half < 0.5 * p10 and p90_half > 0.5 * p90


@pytest.mark.shared_data
def test_still_keeps_at_most_a_quarter_of_the_heads_spread(real_head):
    _, motions = real_head
    for motion in motions:
        still = shape_head(motion, fps=FPS, expressivity=Expressivity.still())
        assert (still.std(axis=0) / motion.std(axis=0)).mean() <= 0.25


def test_still_does_not_follow_a_generators_slow_drift():
    # a pose that drifts slowly (0.03 Hz, 4 degrees) under quick nods (1.5 Hz, 1 degree): the 4 s pull towards
    # the generator's pose would keep the drift; a held head rests at its mean pose instead
    t = np.arange(int(60 * FPS)) / FPS
    drift = 4.0 * np.sin(2 * np.pi * 0.03 * t)[:, None] * np.array([1.0, 0.7, 0.3])
    nods = 1.0 * np.sin(2 * np.pi * 1.5 * t)[:, None] * np.array([1.0, 0.2, 0.1])
    motion = (drift + nods) * 1745.33  # degrees in AU
    still = shape_head(motion, fps=FPS, expressivity=Expressivity.still())
    assert (still.std(axis=0) / motion.std(axis=0)).mean() < 0.25


@pytest.mark.shared_data
def test_temporal_makes_movements_slower_or_quicker_at_about_the_same_size(real_head):
    _, motions = real_head
    slow, speed = _mean_over_seeds(motions, Expressivity(temporal=1), lambda m: np.mean(_speeds(m)))
    quick, _ = _mean_over_seeds(motions, Expressivity(temporal=-1), lambda m: np.mean(_speeds(m)))
    assert slow < 0.65 * speed and quick > 1.5 * speed
    size, before = _mean_over_seeds(motions, Expressivity(temporal=1), lambda m: m.std(axis=0).mean())
    assert 0.75 < size / before < 1.25


@pytest.mark.shared_data
def test_fluidity_lowers_or_raises_the_velocity_spectrum_high_end(real_head):
    _, motions = real_head
    smooth, before = _mean_over_seeds(motions, Expressivity(fluidity=1), _high_share)
    jerky, _ = _mean_over_seeds(motions, Expressivity(fluidity=-1), _high_share)
    assert smooth < 0.25 * before and jerky > 1.2 * before


@pytest.mark.shared_data
def test_power_sharpens_or_evens_out_the_accents_at_about_the_same_speed(real_head):
    _, motions = real_head

    def contrast(m):
        speeds = _speeds(m)
        return np.percentile(speeds, 90) / np.percentile(speeds, 10)

    def variation(m):  # of the 0.5 s speed envelope: how unevenly the head moves over time
        envelope = speed_envelope(m * 1e-5, fps=FPS)
        return envelope.std() / envelope.mean()

    sharp, before = _mean_over_seeds(motions, Expressivity(power=1), contrast)
    assert sharp > 1.3 * before
    even, uneven = _mean_over_seeds(motions, Expressivity(power=-1), variation)
    assert even < 0.9 * uneven
    speed, plain = _mean_over_seeds(motions, Expressivity(power=1), lambda m: np.mean(_speeds(m)))
    assert 0.7 < speed / plain < 1.25


# every generator, live and the command line ------------------------------------------------------------------
def test_the_live_stream_shapes_its_frames_exactly_as_offline():
    from prosody.live.converter import LiveConverter

    audio = _tone_speech()
    controls = Expressivity(activation=0.6, power=0.5, temporal=0.3, fluidity=-0.4, repetition=1, spatial=0.2)

    def frames(expressivity):
        converter = LiveConverter(audio.sample_rate_hz, live_lips=False, expressivity=expressivity)
        out = converter.push(audio.samples) + converter.finish()
        return np.array([[f.faps[fap] for fap in (31, 48, 49, 50)] for f in out])

    plain, shaped = frames(None), frames(controls)
    np.testing.assert_allclose(shaped[:, 1:], shape_head(plain[:, 1:], fps=FPS, expressivity=controls), rtol=1e-12)
    np.testing.assert_allclose(shaped[:, 0], shape_brows(plain[:, 0], fps=FPS, expressivity=controls), rtol=1e-12)


def test_the_live_controls_can_change_while_streaming():
    from prosody.live.converter import LiveConverter

    audio = _tone_speech()
    half = audio.samples.size // 2
    converter = LiveConverter(audio.sample_rate_hz, live_lips=False)
    first = converter.push(audio.samples[:half])
    converter.set_expressivity(Expressivity(spatial=1))
    rest = converter.push(audio.samples[half:]) + converter.finish()
    plain = LiveConverter(audio.sample_rate_hz, live_lips=False)
    reference = plain.push(audio.samples) + plain.finish()
    assert [f.faps[48] for f in first] == [f.faps[48] for f in reference[:len(first)]]
    np.testing.assert_allclose([f.faps[48] for f in rest], [2 * f.faps[48] for f in reference[len(first):]])
    with pytest.raises(ConfigError):
        converter.set_expressivity({"spatial": 1})


@pytest.mark.parametrize("model", ["prosodic", "arx", "pad", "pad-random"])
def test_still_holds_every_head_model(model):
    features = extract_features(_tone_speech())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chosen = load_head_model(model)
        plain = condition_stream(Condition.SPEECH_DRIVEN, features, model=chosen)
        still = condition_stream(Condition.SPEECH_DRIVEN, features, model=chosen, expressivity=Expressivity.still())
    moving = np.abs(np.diff(plain.curves(HEAD), axis=0)).sum()
    held = np.abs(np.diff(still.curves(HEAD), axis=0)).sum()
    assert held < 0.2 * moving
    assert plain.curves((31,)).any() and not still.curves((31,)).any()  # no brow raise


def test_random_condition_takes_the_controls_too():
    features = extract_features(_tone_speech())
    plain = condition_stream(Condition.RANDOM, features, seed=3).curves(HEAD)
    smooth = condition_stream(Condition.RANDOM, features, seed=3, expressivity=Expressivity(fluidity=1)).curves(HEAD)
    assert _high_share(smooth) < 0.5 * _high_share(plain)


def test_command_line_controls(tmp_path, capsys):
    wav = tmp_path / "speech.wav"
    _write_wav(wav)
    out = tmp_path / "still.csv"
    assert main(["convert", str(wav), "-o", str(out), "--still", "--lips", "none"]) == 0
    assert main(["convert", str(wav), "-o", str(out), "--still", "--activation", "0.5"]) == 2
    assert "--still is --activation 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["convert", str(wav), "-o", str(out), "--spatial", "2"])
    assert exit_.value.code == 2 and "expected a number in [-1, 1]" in capsys.readouterr().err
    assert main(["convert", str(wav), "-o", str(out), "--condition", "none", "--power", "1"]) == 2
    assert "shape generated motion" in capsys.readouterr().err


def _write_wav(path):
    import soundfile

    audio = _tone_speech()
    soundfile.write(str(path), audio.samples, audio.sample_rate_hz)


def test_command_line_pad(tmp_path, capsys):
    wav = tmp_path / "speech.wav"
    _write_wav(wav)
    out = tmp_path / "pad.csv"
    assert main(["convert", str(wav), "-o", str(out), "--pad=-0.6,0.8,0.6", "--model", "pad", "--lips", "none"]) == 0
    header = out.read_text(encoding="utf-8").splitlines()[0]
    assert "fap37" in header and "fap19" in header  # squeezed brows and opened eyes
    assert main(["convert", str(wav), "-o", str(out), "--pad-map", "map.json"]) == 2
    assert "give --pad too" in capsys.readouterr().err
