"""The eyebrow rule: events at the frames the rule implies, on synthetic tones and on exact tracks."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_features, segments

from audio_features import Audio, extract_features
from prosody.errors import ConfigError
from prosody.motion.eyebrows import EyebrowRule, eyebrow_raises

SR = 16000


def _raises(signal: np.ndarray, rule: EyebrowRule | None = None):
    return eyebrow_raises(extract_features(Audio(signal, SR)), rule)


def test_jump_through_207_raises_at_the_crossing_frame() -> None:
    result = _raises(segments(SR, (0.5, 150, 0.5), (1.0, 250, 0.5)))
    assert len(result.events) == 1
    onset, _ = result.events[0]
    assert onset == 16  # the jump is at 0.5 s = frame 15, whose 40 ms pitch window straddles it
    assert np.all(result.displacement_ens[:onset] == 0)
    assert np.all(result.displacement_ens[onset:] > 0)  # stays raised: still loud at the end


def test_blip_then_silence_holds_nine_frames_then_ramps_over_three() -> None:
    result = _raises(segments(SR, (0.5, 150, 0.5), (0.1, 250, 0.5), (1.0, 0, 0)))
    (onset, release), = result.events
    assert abs(onset - 15) <= 1
    assert release == onset + 9  # silence well before the 300 ms minimum is over
    brows = result.displacement_ens
    assert np.all(brows[onset:release] > 0)
    last = brows[release - 1]
    np.testing.assert_allclose(brows[release : release + 3], [last * 2 / 3, last / 3, 0.0])
    assert np.all(brows[release + 2 :] == 0)


def test_loud_low_stretch_after_the_blip_keeps_the_raise() -> None:
    signal = segments(SR, (0.5, 150, 0.5), (0.1, 250, 0.5), (1.0, 150, 0.5), (0.5, 0, 0))
    result = _raises(signal)
    (onset, release), = result.events
    loud_end = int((0.5 + 0.1 + 1.0) * 30)  # frame 48: silence begins
    assert abs(onset - 15) <= 1
    # energy stays far above 45 dB through the 150 Hz stretch; the Praat window smears the edge by < 2 frames
    assert loud_end - 1 <= release <= loud_end + 2
    assert np.all(result.displacement_ens[onset:release] > 0)


def test_tone_below_threshold_never_raises() -> None:
    result = _raises(segments(SR, (0.5, 150, 0.5), (0.5, 200, 0.5), (0.5, 180, 0.5)))
    assert result.events == ()
    assert np.all(result.displacement_ens == 0)


def test_falling_crossing_never_triggers() -> None:
    result = _raises(segments(SR, (0.6, 250, 0.5), (0.6, 150, 0.5)))
    assert result.events == ()
    assert np.all(result.displacement_ens == 0)


def test_rule_on_exact_tracks() -> None:
    f0 = np.full(40, 150.0)
    f0[5:8] = 250.0  # crossing at frame 5
    f0[20:] = 230.0  # second crossing at frame 20
    energy = np.full(40, 60.0)
    energy[10:18] = 30.0  # quiet from frame 10 to 17
    rule = EyebrowRule(gain_ens_per_hz=0.1, offset_ens=-5.0)
    result = eyebrow_raises(make_features(f0, energy), rule)
    assert result.events == ((5, 14), (20, 40))
    brows = result.displacement_ens
    expected = np.maximum(0.1 * f0 - 5, 0)
    np.testing.assert_allclose(brows[5:14], expected[5:14])  # hold covers the quiet frames 10-13
    np.testing.assert_allclose(brows[14:17], [expected[13] * 2 / 3, expected[13] / 3, 0])
    assert np.all(brows[17:20] == 0)
    curves = result.curves()
    assert set(curves) == {31, 32, 33, 34}
    np.testing.assert_array_equal(curves[31], curves[32])
    np.testing.assert_array_equal(curves[33], curves[34])


def test_new_crossing_while_raised_restarts_the_hold() -> None:
    f0 = np.full(30, 150.0)
    f0[2] = 250.0
    f0[8] = 250.0  # rises again at frame 8 while still in the first hold
    energy = np.full(30, 20.0)  # quiet throughout: only the minimum hold keeps the brows up
    result = eyebrow_raises(make_features(f0, energy))
    assert result.events == ((2, 17),)


def test_never_negative_even_with_negative_offset() -> None:
    f0 = np.array([100.0, 210.0, 20.0, 20.0, 20.0])
    result = eyebrow_raises(make_features(f0, np.full(5, 60.0)), EyebrowRule(offset_ens=-50.0))
    assert np.all(result.displacement_ens >= 0)


def test_speaker_relative_threshold_for_a_low_voice() -> None:
    # a low voice rising from 100 Hz to 130 Hz: 4.5 semitones, never near 207 Hz
    signal = segments(SR, (0.6, 100, 0.5), (0.6, 130, 0.5))
    features = extract_features(Audio(signal, SR))
    assert eyebrow_raises(features).events == ()
    relative = EyebrowRule(threshold_semitones=2.0)
    median = np.median(features.f0.values[features.f0.voiced])
    result = eyebrow_raises(features, relative)
    assert result.f0_threshold_hz == pytest.approx(median * 2 ** (2 / 12))
    assert len(result.events) == 1 and abs(result.events[0][0] - 18) <= 1


def test_energy_threshold_relative_to_the_speech_level() -> None:
    f0 = np.full(30, 150.0)
    f0[2] = 250.0
    energy = np.full(30, 30.0)
    energy[:20] = 40.0  # a quietly recorded voice: below the absolute 45 dB everywhere
    features = make_features(f0, energy)
    assert eyebrow_raises(features).events == ((2, 11),)  # released as soon as the hold ends
    result = eyebrow_raises(features, EyebrowRule(energy_relative_db=-5.0))
    assert result.energy_threshold_db == pytest.approx(35.0)  # median level 40 dB, minus 5
    assert result.events == ((2, 20),)


def test_rule_parameters_are_checked() -> None:
    with pytest.raises(ConfigError):
        EyebrowRule(ramp_frames=0)
    with pytest.raises(ConfigError):
        EyebrowRule(threshold_hz=-1)


def test_an_octave_jump_of_a_few_frames_raises_no_brow_offline_or_live():
    # Praat's octave errors on a low voice last up to three frames, 17-20 semitones above the speaker's median
    # (reagan_clip1 at 21.77 s: 380, 353, 317 Hz on a voice near 118 Hz); a 5-frame median keeps three
    from prosody.motion.eyebrows import AccentRule, accent_raises
    from prosody.motion.heads.live import live_brows

    f0 = np.full(90, 118.0)
    f0[40:43] = (380.0, 353.0, 317.0)
    features = make_features(f0, np.full(90, 70.0))
    assert accent_raises(features).events == ()
    assert accent_raises(features, AccentRule(octave_error_semitones=24)).events != ()  # what it guards against
    for rule in (AccentRule(), AccentRule(octave_error_semitones=24)):
        live = live_brows(rule, fps=30.0, lookahead=3)
        values = [live.push(float(f), 70.0) for f in f0] + live.finish()
        raised = max(value for value in values if value is not None) > 0
        assert raised == (rule.octave_error_semitones == 24)


def test_the_accent_rule_counts_seconds_not_frames():
    # one accent, at 25, 30 and 60 fps: the same raise in seconds (it once raised 2.8, 3.1 and 3.9 times a file)
    from prosody.motion.eyebrows import AccentRule, accent_raises

    rule = AccentRule()
    assert [rule.median_frames_at(fps) for fps in (25, 30, 60)] == [5, 5, 11]
    assert [rule.ramp_frames_at(fps) for fps in (25, 30, 60)] == [2, 3, 6]
    spans = []
    for fps in (25.0, 30.0, 60.0):
        t = np.arange(int(3 * fps)) / fps
        f0 = np.where((t >= 1.0) & (t < 1.6), 200.0, 140.0)
        f0[int(2.2 * fps)] = 200.0  # a one-frame jitter after it: no second raise at any rate
        raises = accent_raises(make_features(f0, np.full(t.size, 70.0), fps=fps), rule)
        assert len(raises.events) == 1
        start, end = raises.events[0]
        spans.append((start / fps, end / fps))
    for start_s, end_s in spans:
        assert start_s == pytest.approx(1.0, abs=0.05) and end_s == pytest.approx(1.6, abs=0.05)


def test_a_raise_that_starts_during_the_ramp_down_continues_the_one_before() -> None:
    # 207 Hz crossed at frame 15, silence from frame 18: held 9 frames, ramp down from frame 24; a second
    # crossing at frame 25, while the brows are still up, is the same raise to a viewer and to the measures
    from prosody.measures import generated_brow_events

    f0 = np.full(60, 150.0)
    f0[15:18] = 250.0
    f0[25:28] = 250.0
    energy = np.full(60, 30.0)
    energy[:18] = 60.0
    result = eyebrow_raises(make_features(f0, energy), EyebrowRule())
    assert result.displacement_ens[24] > 0 and result.displacement_ens[25] > 0
    assert result.events == ((15, 34),)  # the second raise's own 9-frame hold ends at 34
    assert len(generated_brow_events(result.displacement_ens)) == len(result.events)
    f0[25:28] = 150.0
    f0[30:33] = 250.0  # after the brows are back at rest: two raises
    apart = eyebrow_raises(make_features(f0, energy), EyebrowRule())
    assert apart.events == ((15, 24), (30, 39))
    assert len(generated_brow_events(apart.displacement_ens)) == 2
