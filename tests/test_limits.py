"""A human head: generated motion is bent back within the angles a neck reaches and the height a brow rises,
whatever the gains and expressivity controls ask; recorded motion is left as it is."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import REPO

from prosody.cli import main
from prosody.fap.fapfile import read_fap
from prosody.motion.limits import (
    HEAD_LIMITS_DEG,
    KNEE,
    LIMITS,
    limit_frame,
    soft_limit,
    within_human_limits,
)

SAMPLE = REPO / "samples" / "arctic_a0009.wav"
EXTREME = ["--spatial", "1", "--power", "1", "--repetition", "1", "--temporal", "-1", "--fluidity", "-1"]


def test_the_bend_keeps_values_below_the_knee_and_is_smooth_and_bounded_above_it():
    limit = 1000.0
    x = np.linspace(-1e6, 1e6, 400_001)
    y = soft_limit(x, limit)
    inside = np.abs(x) <= KNEE * limit
    assert np.array_equal(y[inside], x[inside])
    assert np.all(np.abs(y) <= limit) and np.all(np.diff(y) >= 0)  # bounded, never reversing
    h = 1e-3  # the slope is 1 on both sides of the knee: no kink
    knee = KNEE * limit
    assert (soft_limit(np.array([knee + h]), limit)[0] - knee) / h == pytest.approx(1.0, abs=1e-5)
    # tanh's own values past the knee: 0.25 L * tanh(1) above the knee at one quarter-limit beyond it
    assert soft_limit(np.array([limit]), limit)[0] == pytest.approx(knee + 0.25 * limit * math.tanh(1.0))


def test_the_limits_are_the_necks_ranges_in_fap_units():
    assert LIMITS[48] == pytest.approx(math.radians(45) * 1e5) and LIMITS[49] == pytest.approx(math.radians(60) * 1e5)
    assert LIMITS[50] == pytest.approx(math.radians(45) * 1e5) and HEAD_LIMITS_DEG == {48: 45.0, 49: 60.0, 50: 45.0}
    frame = limit_frame({48: 2e6, 49: -10.0, 31: 5000.0, 3: 2e6})
    assert abs(frame[48]) <= LIMITS[48] and frame[49] == -10.0 and frame[31] <= LIMITS[31] and frame[3] == 2e6


def test_every_control_at_its_extreme_keeps_a_human_head(tmp_path, capsys):
    out = tmp_path / "extreme.fap"
    argv = ["convert", str(SAMPLE), "-o", str(out), "--lips", "none", *EXTREME]
    assert main([*argv, "--pitch-gain", "4", "--yaw-gain", "4", "--roll-gain", "4", "--brow-gain", "4"]) == 0
    err = capsys.readouterr().err
    assert "went past what a human head or brow can do" in err and "lower the gains" in err
    stream = read_fap(out).stream
    for fap, degrees in HEAD_LIMITS_DEG.items():
        assert np.abs(stream.values[:, fap - 1]).max() * 1e-5 < math.radians(degrees) + 1e-5
    assert np.abs(stream.values[:, 30:36]).max() <= LIMITS[31]
    # the default controls stay well inside: nothing bent, nothing said
    assert main(["convert", str(SAMPLE), "-o", str(tmp_path / "plain.fap"), "--lips", "none"]) == 0
    assert "human head" not in capsys.readouterr().err


def test_a_gain_without_bound_is_refused(tmp_path, capsys):
    for gain in ("1e300", "101", "-1", "nan"):
        with pytest.raises(SystemExit) as stop:
            main(["convert", str(SAMPLE), "-o", str(tmp_path / "x.bvh"), "--pitch-gain", gain])
        assert stop.value.code == 2
        assert "expected a number in [0, 100]" in capsys.readouterr().err or gain == "nan"


def test_recorded_motion_is_never_bent(tmp_path):
    from prosody.fap.fapfile import write_fap
    from prosody.fap.stream import FapStream

    truth = tmp_path / "truth.fap"
    n = 93  # the sample's 3.1 s at 30 fps
    write_fap(FapStream.from_curves({49: np.linspace(0, 2e5, n), 48: np.zeros(n), 50: np.zeros(n)}, fps=30), truth)

    far = FapStream.from_curves({49: np.array([0.0, 3e5, -3e5]), 31: np.array([0.0, 900.0, 0.0])}, fps=30)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bent_stream, bent = within_human_limits(far)
    assert set(bent) == {49, 31} and bent[49] == pytest.approx(2 / 3)
    assert np.abs(bent_stream.values[:, 48]).max() < LIMITS[49]
    # convert's truth condition writes a recording's motion as it is, however far it goes
    from prosody.jobs.pipeline import convert

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stream = convert(SAMPLE, None, condition="truth", ground_truth=truth, lips=None)
    assert np.abs(stream.values[:, 48]).max() > LIMITS[49]


def test_the_live_stream_keeps_a_human_head_at_every_extreme():
    import soundfile

    from prosody.live.converter import LiveConverter
    from prosody.motion.expressivity import Expressivity

    samples, rate = soundfile.read(SAMPLE)
    converter = LiveConverter(rate, gains={"pitch": 4, "yaw": 4, "roll": 4, "brows": 4},
                              expressivity=Expressivity(spatial=1, power=1, repetition=1, temporal=-1, fluidity=-1))
    frames = converter.push(samples) + converter.finish()
    for fap, limit in LIMITS.items():
        if fap in frames[0].faps:
            assert max(abs(frame.faps[fap]) for frame in frames) <= limit
