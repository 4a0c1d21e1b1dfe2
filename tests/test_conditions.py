"""The four conditions, the Perlin baseline, recorded ground truth and ``prosody convert``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile
from conftest import harmonic_tone, make_features, segments

from prosody.cli import main
from prosody.errors import ConfigError, GroundTruthError
from prosody.fap.fapfile import read_fap, write_fap
from prosody.fap.recorded import fit_to_grid, read_head_csv
from prosody.fap.stream import FapStream
from prosody.motion.conditions import Condition, condition_stream
from prosody.motion.eyebrows import BROW_SCALE
from prosody.motion.perlin import HEAD_STD_AU, PerlinSettings, fractal_noise, perlin_curves

SR = 16000


def _write_head_csv(path: Path, rx, ry, rz) -> Path:
    lines = ["frame,time_s,rx_rad,ry_rad,rz_rad"]
    for k, (x, y, z) in enumerate(zip(rx, ry, rz, strict=False)):
        lines.append(f"{k},{k / 30:.6f},{float(x)!r},{float(y)!r},{float(z)!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


# Perlin ---------------------------------------------------------------------------------------------------
def test_perlin_same_seed_same_values_different_seed_different() -> None:
    a = perlin_curves(900, fps=30, seed=7)
    b = perlin_curves(900, fps=30, seed=7)
    c = perlin_curves(900, fps=30, seed=8)
    for fap in a:
        assert a[fap].tobytes() == b[fap].tobytes()
        assert not np.allclose(a[fap], c[fap])


def test_perlin_scales_signs_and_independent_axes() -> None:
    curves = perlin_curves(3000, fps=30, seed=3)
    for fap, std in HEAD_STD_AU.items():
        assert curves[fap].std() == pytest.approx(std)
        assert abs(curves[fap].mean()) < 1e-6 * std
    assert (curves[31] >= 0).all() and (curves[31] == 0).any()  # negatives dropped
    np.testing.assert_array_equal(curves[31], curves[32])
    np.testing.assert_array_equal(curves[33], curves[34])
    r = np.corrcoef([curves[48], curves[49], curves[50]])
    assert np.all(np.abs(r[np.triu_indices(3, 1)]) < 0.5)  # different offsets: the axes do not move together


def test_gradient_noise_is_zero_on_the_lattice_and_smooth() -> None:
    # one octave at 1 cycle per 10 frames: every 10th frame is a lattice point, where Perlin noise is 0
    settings = PerlinSettings(octaves=1, base_frequency_hz=3.0)
    noise = fractal_noise(101, fps=30, seed=1, settings=settings)
    np.testing.assert_allclose(noise[::10], 0.0, atol=1e-12)
    assert np.abs(np.diff(noise)).max() < 0.5  # gradients in [-1, 1] over a tenth of a cell


def test_perlin_octaves_sum_with_persistence() -> None:
    one = fractal_noise(300, fps=30, seed=2, settings=PerlinSettings(octaves=1))
    two = fractal_noise(300, fps=30, seed=2, settings=PerlinSettings(octaves=2, persistence=0.5))
    second = two - one
    assert np.abs(second).max() > 0
    assert np.abs(second).max() <= 0.5 * 0.5 + 1e-12  # |noise| <= 0.5 for unit gradients, times 0.5


# conditions -----------------------------------------------------------------------------------------------
def test_no_prosody_is_all_zero_and_active() -> None:
    features = make_features(np.full(20, 150.0), np.full(20, 60.0))
    stream = condition_stream(Condition.NO_PROSODY, features)
    assert stream.active_faps == (31, 32, 33, 34, 48, 49, 50)
    assert np.all(stream.values == 0)


def test_speech_driven_combines_the_rule_and_the_model() -> None:
    f0 = np.full(90, 150.0)
    f0[60:75] = 250.0  # an accent 8.8 semitones above the speaker's median, for 0.5 s
    features = make_features(f0, np.full(90, 60.0))
    stream = condition_stream(Condition.SPEECH_DRIVEN, features)
    assert stream.active_faps == (31, 32, 33, 34, 48, 49, 50)
    brow = stream.curve(31)
    assert np.all(brow[:60] == 0) and np.all(brow[60:75] > 0) and np.all(brow[78:] == 0)
    # rise over 3 frames to 12 + 3 x (8.84 - 4) ENS at people's size (BROW_SCALE times), hold, fall over 3 frames
    height = (12 + 3 * (12 * np.log2(250 / 150) - 4)) * BROW_SCALE
    np.testing.assert_allclose(brow[60:63], height * np.array([1, 2, 3]) / 3)
    np.testing.assert_allclose(brow[75:78], height * np.array([2, 1, 0]) / 3, atol=1e-12)
    assert np.all(np.isfinite(stream.curves((48, 49, 50))))
    assert np.abs(stream.curves((48, 49, 50))).max() > 0


def test_condition_names_parse() -> None:
    assert Condition.parse("speech") is Condition.SPEECH_DRIVEN
    assert Condition.parse("GROUND_TRUTH") is Condition.GROUND_TRUTH
    with pytest.raises(ConfigError, match="unknown condition"):
        Condition.parse("loud")
    with pytest.raises(ConfigError, match="ground_truth=FILE"):
        condition_stream(Condition.GROUND_TRUTH, make_features(np.full(5, 100.0), np.full(5, 50.0)))


# ground truth ---------------------------------------------------------------------------------------------
def test_head_csv_maps_rx_ry_rz_to_fap_48_49_50_minus_median(tmp_path) -> None:
    rx = [0.01, 0.02, 0.03, 0.05]
    ry = [-0.1, -0.1, -0.1, -0.1]
    rz = [0.0, 0.001, -0.001, 0.002]
    stream = read_head_csv(_write_head_csv(tmp_path / "clip.head.csv", rx, ry, rz))
    assert stream.fps == 30 and stream.name == "clip" and stream.active_faps == (48, 49, 50)
    # medians 0.025, -0.1, 0.0005 rad; 1 AU = 1e-5 rad
    np.testing.assert_allclose(stream.curve(48), [-1500, -500, 500, 2500])
    np.testing.assert_allclose(stream.curve(49), [0, 0, 0, 0])
    np.testing.assert_allclose(stream.curve(50), [-50, 50, -150, 150])


@pytest.mark.shared_data
def test_real_head_csv_first_frame(shared_data) -> None:
    path = shared_data / "talking-heads" / "Obama_clip1.head.csv"
    if not path.exists():
        pytest.skip(f"{path} not found")
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    stream = read_head_csv(path)
    # first row of the file: rx = -0.0664939 rad, read by hand
    assert raw[0, 2] == pytest.approx(-0.0664939)
    assert stream.curve(48)[0] == pytest.approx((-0.0664939 - np.median(raw[:, 2])) * 1e5)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("frame,time,rx,ry,rz\n0,0,0,0,0\n", "expected the header"),
        ("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0,0,0\n", "line 2"),
        ("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0,0,x,0\n", "line 2"),
        ("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0,0,0,0\n2,0,0,0,0\n", "line 3"),
        ("frame,time_s,rx_rad,ry_rad,rz_rad\n", "no frames"),
        ("frame,time_s,rx_rad,ry_rad,rz_rad\n0,0,nan,0,0\n", "finite"),
    ],
)
def test_malformed_head_csv(tmp_path, text, problem) -> None:
    path = tmp_path / "bad.head.csv"
    path.write_text(text)
    with pytest.raises(GroundTruthError, match=problem) as caught:
        read_head_csv(path)
    assert str(path) in str(caught.value)


def test_fit_to_grid_trims_pads_and_refuses_big_mismatch() -> None:
    motion = FapStream.from_curves({48: np.arange(10.0)}, fps=30)
    np.testing.assert_array_equal(fit_to_grid(motion, n_frames=8, fps=30, source="m").curve(48), np.arange(8.0))
    padded = fit_to_grid(motion, n_frames=12, fps=30, source="m").curve(48)
    np.testing.assert_array_equal(padded, [*range(10), 9, 9])
    with pytest.raises(GroundTruthError, match="differ by more than 2 frames"):
        fit_to_grid(motion, n_frames=20, fps=30, source="m")


# prosody convert ------------------------------------------------------------------------------------------
@pytest.fixture
def speech_like(tmp_path) -> Path:
    signal = segments(SR, (0.5, 150, 0.5), (0.4, 250, 0.5), (0.6, 160, 0.5), (0.5, 0, 0))
    path = tmp_path / "speech.wav"
    soundfile.write(path, signal, SR)
    return path


def test_convert_random_is_byte_for_byte_reproducible(tmp_path, speech_like) -> None:
    outputs = []
    for seed, name in ((5, "a.fap"), (5, "b.fap"), (6, "c.fap")):
        assert main(["convert", str(speech_like), "-o", str(tmp_path / name), "--condition", "random",
                     "--seed", str(seed)]) == 0
        outputs.append((tmp_path / name).read_bytes())
    # the header carries the file name: compare the bodies
    bodies = [data.split(b"\n", 1)[1] for data in outputs]
    assert bodies[0] == bodies[1]
    assert bodies[0] != bodies[2]


def test_convert_speech_writes_brows_at_the_crossing(tmp_path, speech_like) -> None:
    out = tmp_path / "speech.fap"
    assert main(["convert", str(speech_like), "-o", str(out), "--lips", "none"]) == 0
    fap = read_fap(out)
    assert fap.stream.n_frames == 60 and fap.stream.active_faps == (31, 32, 33, 34, 48, 49, 50)
    brows = fap.stream.curve(31)
    onset = int(np.flatnonzero(brows > 0)[0])
    assert abs(onset - 15) <= 1  # the F0 jumps through 207 Hz at 0.5 s


def test_convert_truth_from_head_csv_and_base_lips(tmp_path, speech_like, capsys) -> None:
    n = 60
    rx = 0.01 * np.sin(np.arange(n) / 5)
    truth = _write_head_csv(tmp_path / "speech.head.csv", rx, np.zeros(n), np.zeros(n))
    base = FapStream.from_curves({3: np.full(n, 120.0), 48: np.full(n, 999.0)}, fps=30)
    write_fap(base, tmp_path / "base.fap")
    out = tmp_path / "truth.fap"
    assert main(["convert", str(speech_like), "-o", str(out), "--condition", "truth", "--ground-truth",
                 str(truth), "--base", str(tmp_path / "base.fap")]) == 0
    err = capsys.readouterr().err
    assert "warning: recorded motion has no eyebrow FAPs" in err  # one line, not a source listing
    stream = read_fap(out).stream
    np.testing.assert_array_equal(stream.curve(3), 120)  # lips carried from the base
    np.testing.assert_array_equal(stream.curve(48), np.rint((rx - np.median(rx)) * 1e5))  # ours win


def test_convert_truth_without_file_is_a_usage_error(tmp_path, speech_like, capsys) -> None:
    assert main(["convert", str(speech_like), "-o", str(tmp_path / "x.fap"), "--condition", "truth"]) == 2
    assert "--ground-truth" in capsys.readouterr().err
    assert not (tmp_path / "x.fap").exists()


def test_convert_with_mismatched_truth_fails_cleanly(tmp_path, speech_like, capsys) -> None:
    truth = _write_head_csv(tmp_path / "short.head.csv", np.zeros(20), np.zeros(20), np.zeros(20))
    code = main(["convert", str(speech_like), "-o", str(tmp_path / "x.fap"), "--condition", "truth",
                 "--ground-truth", str(truth)])
    err = capsys.readouterr().err
    assert code == 1 and "short.head.csv" in err and err.count("\n") == 1
    assert not (tmp_path / "x.fap").exists()


def test_train_command_on_synthetic_pairs(tmp_path, rng) -> None:
    data = tmp_path / "pairs"
    data.mkdir()
    for index in range(3):
        soundfile.write(data / f"clip{index}.wav", harmonic_tone(140 + 40 * index, 2.0, SR), SR)
        wobble = 0.01 * rng.standard_normal((60, 3))
        _write_head_csv(data / f"clip{index}.head.csv", *wobble.T)
    # a pair whose motion is far shorter than its audio is skipped by name
    soundfile.write(data / "bad.wav", harmonic_tone(200, 2.0, SR), SR)
    _write_head_csv(data / "bad.head.csv", np.zeros(10), np.zeros(10), np.zeros(10))
    out = tmp_path / "model.json"
    assert main(["train", "--data", str(data), "-o", str(out), "--kind", "arx", "--na", "1", "--nb", "2"]) == 0
    from prosody.motion.heads.arx import ArxHeadModel

    model = ArxHeadModel.load(out)
    assert [clip.name for clip in model.training_] == ["clip0", "clip1", "clip2"]
    assert model.spectral_radius_ < 1
    import json

    assert any("bad" in line for line in json.loads(out.read_text())["skipped"])
    # ARX orders without --kind arx are a usage error; the default kind is the prosodic generator
    assert main(["train", "--data", str(data), "-o", str(tmp_path / "p.json"), "--na", "2"]) == 2
    assert not (tmp_path / "p.json").exists()
    assert main(["train", "--data", str(data), "-o", str(tmp_path / "p.json")]) == 0
    from prosody.motion.heads.models import load_head_model
    from prosody.motion.heads.prosodic import ProsodicHeadModel

    prosodic = load_head_model(tmp_path / "p.json")
    assert isinstance(prosodic, ProsodicHeadModel)
    assert json.loads((tmp_path / "p.json").read_text())["kind"] == "prosodic"


@pytest.mark.slow
def test_train_prosodic_with_cv_stores_held_out_figures(tmp_path, rng) -> None:
    data = tmp_path / "pairs"
    data.mkdir()
    for index in range(3):
        soundfile.write(data / f"clip{index}.wav", harmonic_tone(140 + 40 * index, 6.0, SR), SR)
        walk = np.cumsum(0.002 * rng.standard_normal((180, 3)), axis=0)
        _write_head_csv(data / f"clip{index}.head.csv", *walk.T)
    out = tmp_path / "model.json"
    assert main(["train", "--data", str(data), "-o", str(out), "--cv"]) == 0
    import json

    payload = json.loads(out.read_text())
    cv = payload["cross_validation"]
    assert cv["seeds"] == 10 and set(cv["per_recording"]) == {"clip0", "clip1", "clip2"}
    assert set(cv["settings"]) == {"pitch_share", "speed_iterations", "envelope_power", "pitch_follow_s"}
    assert payload["settings"]["envelope_power"] == cv["settings"]["envelope_power"]
    assert set(cv["mean"]) == {"speed_envelope_r", "pitch_r", "velocity_spectrum_distance_db", "std_ratio"}
    assert payload["settings"]["pitch_share"] == cv["settings"]["pitch_share"]
    diagnostics = payload["diagnostics"]
    assert diagnostics["ljung_box_lags"] == 10
    assert set(diagnostics["ljung_box_p"]) == {"speed_envelope", "pitch"}
    assert set(diagnostics["ljung_box_p"]["pitch"]) == {"clip0", "clip1", "clip2"}


def test_random_channels_are_independent_and_never_repeat() -> None:
    from prosody.motion.perlin import perlin_curves

    n = 30 * 2000  # 2000 s: the old 256-cell lattice at 0.4 Hz repeated every 640 s
    curves = perlin_curves(n, fps=30, seed=4)
    for a, b in ((31, 48), (48, 49), (49, 50), (31, 50)):
        assert abs(np.corrcoef(curves[a], curves[b])[0, 1]) < 0.1
    period = 640 * 30
    for fap in (31, 48):
        assert not np.allclose(curves[fap][:900], curves[fap][period:period + 900])
    # seeded: the same seed, the same bytes; another seed, other noise
    again = perlin_curves(n, fps=30, seed=4)
    assert all(again[fap].tobytes() == curves[fap].tobytes() for fap in curves)
    assert not np.array_equal(perlin_curves(300, fps=30, seed=5)[48], perlin_curves(300, fps=30, seed=4)[48])
