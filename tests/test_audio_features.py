"""F0, conditioning and energy on synthetic tones with computed answers, and on real speech."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
import soundfile
from conftest import REPO, harmonic_tone, sine, sine_level_db

from audio_features import (
    Audio,
    F0Track,
    NoVoicedFramesWarning,
    ParameterError,
    Track,
    condition_f0,
    extract_features,
    frame_count,
    load_audio,
)


def _steady_f0(features, margin_frames: int = 5) -> float:
    voiced = features.f0.values[margin_frames:-margin_frames]
    voiced = voiced[~np.isnan(voiced)]
    assert voiced.size > 10, "a steady tone must be mostly voiced"
    return float(np.median(voiced))


@pytest.mark.parametrize("sample_rate_hz", [8000, 16000, 22050, 44100, 48000])
@pytest.mark.parametrize("f0_hz", [80.0, 130.0, 207.0, 330.0, 450.0])
def test_harmonic_tone_f0_within_one_percent(f0_hz: float, sample_rate_hz: int) -> None:
    audio = Audio(harmonic_tone(f0_hz, 1.0, sample_rate_hz), sample_rate_hz)
    measured = _steady_f0(extract_features(audio))
    assert abs(measured / f0_hz - 1) < 0.01


@pytest.mark.parametrize(
    ("subtype", "channels"),
    [("PCM_U8", 1), ("PCM_16", 1), ("PCM_24", 2), ("PCM_32", 1), ("FLOAT", 2), ("DOUBLE", 1)],
)
def test_wav_subtypes_and_channels(tmp_path, subtype: str, channels: int) -> None:
    tone = harmonic_tone(180.0, 1.0, 16000)
    data = np.column_stack([tone] * channels) if channels > 1 else tone
    path = tmp_path / f"tone_{subtype}.wav"
    soundfile.write(path, data, 16000, subtype=subtype)
    features = extract_features(path)
    assert abs(_steady_f0(features) / 180.0 - 1) < 0.01
    assert features.n_frames == 30


def test_flac_and_ogg(tmp_path) -> None:
    tone = harmonic_tone(150.0, 1.0, 22050)
    for extension in ("flac", "ogg"):
        path = tmp_path / f"tone.{extension}"
        soundfile.write(path, tone, 22050)
        assert abs(_steady_f0(extract_features(path)) / 150.0 - 1) < 0.01


def test_stereo_is_mixed_to_mono(tmp_path) -> None:
    left = sine(200.0, 1.0, 16000, amplitude=0.4)
    path = tmp_path / "stereo.wav"
    soundfile.write(path, np.column_stack([left, np.zeros_like(left)]), 16000, subtype="FLOAT")
    audio = load_audio(path)
    np.testing.assert_allclose(audio.samples, left / 2, atol=1e-7)


@pytest.mark.parametrize("amplitude", [0.01, 0.1, 0.5, 0.9])
def test_sine_energy_within_one_db(amplitude: float) -> None:
    features = extract_features(Audio(sine(440.0, 1.0, 16000, amplitude=amplitude), 16000))
    middle = features.energy.values[5:-5]
    np.testing.assert_allclose(middle, sine_level_db(amplitude), atol=1.0)


def test_grid_has_one_frame_per_video_frame() -> None:
    features = extract_features(Audio(harmonic_tone(200, 2.5, 16000), 16000), fps=25)
    assert features.n_frames == frame_count(2.5, fps=25) == 63
    assert features.fps == 25
    np.testing.assert_allclose(features.f0.times_s[:3], [0.0, 0.04, 0.08])


def test_gap_is_bridged_smoothly_and_edges_hold() -> None:
    sr = 16000
    silence = np.zeros(int(0.3 * sr))
    gap = np.zeros(int(0.5 * sr))
    signal = np.concatenate([silence, harmonic_tone(150, 1.0, sr), gap, harmonic_tone(250, 1.0, sr), silence])
    features = extract_features(Audio(signal, sr))
    raw, conditioned = features.f0, features.f0_conditioned.values
    voiced = np.flatnonzero(raw.voiced)
    first, last = voiced[0], voiced[-1]
    # leading and trailing unvoiced frames hold the nearest voiced value
    assert first >= 5 and last <= features.n_frames - 6
    np.testing.assert_allclose(conditioned[:first], raw.values[first])
    np.testing.assert_allclose(conditioned[last + 1 :], raw.values[last])
    # the spline passes through every voiced frame
    np.testing.assert_allclose(conditioned[voiced], raw.values[voiced])
    # the gap: the longest run of unvoiced frames between the tones
    unvoiced = np.flatnonzero(~raw.voiced[first:last + 1]) + first
    assert unvoiced.size >= 12
    gap_values = conditioned[unvoiced]
    assert np.all(gap_values >= 150 * 0.99) and np.all(gap_values <= 250 * 1.01)
    assert conditioned.max() <= np.nanmax(raw.values)
    # smooth: no frame-to-frame jump inside the gap larger than the whole step spread over the gap
    assert np.max(np.abs(np.diff(gap_values))) < 2 * (250 - 150) / 12


def test_condition_f0_clips_overshoot_to_voiced_maximum() -> None:
    raw = np.array([100, 200, np.nan, np.nan, np.nan, np.nan, 200, 100, np.nan, 150])
    track = F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))
    conditioned = condition_f0(track).values
    # a cubic through 100, 200 | gap | 200, 100 bulges above 200 in the gap; it must be clipped there
    assert conditioned[2:6].max() == pytest.approx(200.0)
    assert np.all(conditioned <= 200.0) and np.all(conditioned >= 0.0)
    np.testing.assert_allclose(conditioned[[0, 1, 6, 7, 9]], [100, 200, 200, 100, 150])


@pytest.mark.parametrize("n_knots", [2, 3, 7, 400])
def test_shape_preserving_spline_equals_scipys_pchip(n_knots: int, rng: np.random.Generator) -> None:
    from scipy.interpolate import PchipInterpolator

    from audio_features.features import shape_preserving_spline

    x = np.sort(rng.choice(np.arange(4 * n_knots), size=n_knots, replace=False)).astype(float)
    y = np.round(rng.normal(200.0, 40.0, size=n_knots) / 20.0) * 20.0  # repeated values: flat stretches too
    at = np.linspace(x[0], x[-1], 5 * n_knots)
    expected = PchipInterpolator(x, y)(at)
    np.testing.assert_allclose(shape_preserving_spline(x, y, at), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(shape_preserving_spline(x, y, x), y, atol=1e-9)


def test_a_gap_is_bridged_between_its_ends_without_overshoot() -> None:
    # a falling then rising contour with a long gap: a natural cubic spline swings far outside 100-220 Hz
    # here; the bridge stays between the values at the gap's ends and is monotone across it
    raw = np.full(60, np.nan)
    raw[:10] = np.linspace(220.0, 180.0, 10)
    raw[40:50] = np.linspace(100.0, 160.0, 10)
    raw[55:] = 150.0
    conditioned = condition_f0(F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))).values
    gap = conditioned[9:41]
    assert np.all(np.diff(gap) <= 1e-9) and gap[0] == 180.0 and gap[-1] == 100.0
    assert np.all((conditioned[50:56] >= 150.0) & (conditioned[50:56] <= 160.0))


def test_condition_f0_single_voiced_frame_holds_it() -> None:
    raw = np.array([np.nan, np.nan, 180.0, np.nan])
    conditioned = condition_f0(F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))).values
    np.testing.assert_allclose(conditioned, 180.0)


@pytest.mark.parametrize("kind", ["silence", "noise"])
def test_no_voiced_frame_gives_zero_and_warning(kind: str, rng: np.random.Generator) -> None:
    sr = 16000
    signal = np.zeros(sr) if kind == "silence" else 0.1 * rng.standard_normal(sr)
    with pytest.warns(NoVoicedFramesWarning):
        features = extract_features(Audio(signal, sr))
    assert not features.f0.voiced.any()
    np.testing.assert_array_equal(features.f0_conditioned.values, 0.0)


def test_tracks_refuse_mismatched_lengths() -> None:
    with pytest.raises(ParameterError):
        F0Track(np.array([100.0, np.nan]), 30.0, "Hz", "f0", np.array([True]))
    with pytest.raises(ParameterError):
        F0Track(np.array([100.0, np.nan]), 30.0, "Hz", "f0", np.array([True, True]))
    with pytest.raises(ParameterError):
        Track(np.zeros(3), 0.0, "dB", "energy")


def test_bad_parameters_are_named() -> None:
    audio = Audio(harmonic_tone(200, 0.5, 16000), 16000)
    with pytest.raises(ParameterError, match="f0_floor_hz"):
        extract_features(audio, f0_floor_hz=600, f0_ceiling_hz=500)
    with pytest.raises(ParameterError, match="Nyquist"):
        extract_features(Audio(harmonic_tone(200, 0.5, 8000), 8000), f0_ceiling_hz=4500)


def tones_and_pauses(seed: int, count: int, *, pitch_hz=(100, 300), tone_s=(0.2, 0.6), pause_s=(0.05, 0.3),
                     sr: int = 16000) -> Audio:
    """Harmonic tones of random pitch, length and level, each followed by a pause of digital silence."""
    rng = np.random.default_rng(seed)
    pieces = []
    for f0 in rng.uniform(*pitch_hz, size=count):
        pieces += [harmonic_tone(f0, rng.uniform(*tone_s), sr, amplitude=rng.uniform(0.05, 0.8)),
                   np.zeros(int(rng.uniform(*pause_s) * sr))]
    return Audio(np.concatenate(pieces), sr)


def test_chunked_analysis_equals_single_pass() -> None:
    audio = tones_and_pauses(7, 8)
    whole = extract_features(audio, chunk_s=3600)
    chunked = extract_features(audio, chunk_s=0.7, margin_s=1.0)
    np.testing.assert_array_equal(whole.f0.voiced, chunked.f0.voiced)
    np.testing.assert_allclose(whole.f0.values, chunked.f0.values, rtol=1e-3, equal_nan=True)
    np.testing.assert_allclose(whole.energy.values, chunked.energy.values, atol=0.01)


def test_chunks_analysed_by_forked_workers_give_the_same_features_to_the_bit(tmp_path, monkeypatch) -> None:
    """Several processes analyse the chunks of a recording (an Audio, a file read whole, a file read chunk by
    chunk, each worker opening it itself): the features and the progress reports are those of one process."""
    import soundfile

    import audio_features.features as features_module
    from audio_features.analysis import forked_workers

    sr = 16000
    audio = tones_and_pauses(11, 10, pitch_hz=(90, 280), tone_s=(0.2, 0.5), pause_s=(0.05, 0.2), sr=sr)
    soundfile.write(tmp_path / "speech.wav", audio.samples, sr, subtype="FLOAT")
    soundfile.write(tmp_path / "stereo.wav", np.column_stack([audio.samples, -0.5 * audio.samples]), sr,
                    subtype="PCM_16")
    opened = tmp_path / "opened-by.txt"
    for source in (audio, tmp_path / "speech.wav", tmp_path / "stereo.wav"):
        if source == tmp_path / "stereo.wav":  # read chunk by chunk, as a file too long to hold is
            monkeypatch.setattr(features_module, "IN_MEMORY_SAMPLES", 1000)

            class Logged(soundfile.SoundFile):  # every opening noted with its process
                def __init__(self, *args, log_file=opened, **kwargs) -> None:
                    with open(log_file, "a") as log:
                        log.write(f"{os.getpid()}\n")
                    super().__init__(*args, **kwargs)

            monkeypatch.setattr(soundfile, "SoundFile", Logged)
        reports: dict[int, list] = {1: [], 3: []}
        one, three = (extract_features(source, chunk_s=0.6, workers=workers,
                                       progress=lambda done, total, w=workers, r=reports: r[w].append((done, total)))
                      for workers in (1, 3))
        assert one.f0.values.tobytes() == three.f0.values.tobytes()
        assert one.energy.values.tobytes() == three.energy.values.tobytes()
        assert one.f0_conditioned.values.tobytes() == three.f0_conditioned.values.tobytes()
        assert reports[1] == reports[3] and len(reports[1]) > 5
    if forked_workers() > 1:  # each worker read through its own opening of the file, not the parent's
        assert set(opened.read_text().split()) - {str(os.getpid())}
    assert 1 <= forked_workers() <= (os.cpu_count() or 1)
    assert forked_workers(1) == 1
    for bad in (0, -2, 1.5, True, "2"):
        with pytest.raises(ParameterError, match="workers must be a whole number") as caught:
            extract_features(audio, workers=bad)
        assert caught.value.parameters == ("workers",)


def test_features_csv_columns(tmp_path) -> None:
    sr = 16000
    signal = np.concatenate([harmonic_tone(200, 0.5, sr), np.zeros(sr // 2)])
    features = extract_features(Audio(signal, sr))
    out = tmp_path / "features.csv"
    features.write_csv(out)
    lines = out.read_text().splitlines()
    assert lines[0] == "frame,time_s,f0_hz,f0_conditioned_hz,energy_db"
    assert len(lines) == features.n_frames + 1 == 31
    last = lines[-1].split(",")
    assert last[0] == "29" and float(last[1]) == pytest.approx(29 / 30)
    assert last[2] == ""  # unvoiced: empty
    assert float(last[3]) == pytest.approx(features.f0_conditioned.values[-1], abs=1e-3)


@pytest.mark.shared_data
@pytest.mark.parametrize(("clip", "low_hz", "high_hz"), [("arctic_a0007", 85, 180), ("arctic_a0009", 150, 260)])
def test_real_speech_f0_is_plausible(shared_data, clip: str, low_hz: float, high_hz: float) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        features = extract_features(shared_data / "speech" / f"{clip}.wav")
    median = np.nanmedian(features.f0.values)
    assert low_hz < median < high_hz
    assert 0.3 < features.f0.voiced.mean() < 0.9
    # speech is far above 45 dB when voiced, and the conditioned F0 stays in the voiced range
    assert np.median(features.energy.values[features.f0.voiced]) > 55
    assert features.f0_conditioned.values.max() <= np.nanmax(features.f0.values)


@pytest.mark.shared_data
def test_real_speech_float_wav_and_chunk_seams(shared_data) -> None:
    path = shared_data / "speech" / "beat_2_scott_0_1_1.wav"
    whole = extract_features(path)
    chunked = extract_features(path, chunk_s=2.0)
    assert 80 < np.nanmedian(whole.f0.values) < 200
    mismatched_voicing = np.sum(whole.f0.voiced != chunked.f0.voiced)
    assert mismatched_voicing <= 2
    both = whole.f0.voiced & chunked.f0.voiced
    np.testing.assert_allclose(whole.f0.values[both], chunked.f0.values[both], rtol=0.01)
    # chunk and whole file can place Praat's frames up to half a sample apart: 0.1 dB on real speech
    np.testing.assert_allclose(whole.energy.values, chunked.energy.values, atol=0.1)


@pytest.mark.shared_data
@pytest.mark.slow
def test_ten_minutes_of_speech_in_chunks_equals_one_pass(tmp_path) -> None:
    import sys

    sys.path.insert(0, str(REPO))  # the benchmarks run from a checkout
    from benchmarks.bench import build_speech

    path = build_speech(tmp_path / "long.wav", duration_s=600.0)
    whole = extract_features(path, chunk_s=3600.0)
    chunked = extract_features(path)  # 60 s chunks: nine seams
    assert whole.n_frames == chunked.n_frames == 18000
    # voicing agrees on all but a handful of the 18 000 frames, and F0 within 1 % on all but 0.1 % of the
    # voiced ones: Praat's path finder is global, and a chunk's frames may sit up to half a sample away from
    # the whole file's, which can tip an ambiguous frame to another candidate (2 of 9 236 here, neither at a seam)
    assert np.sum(whole.f0.voiced != chunked.f0.voiced) <= 5
    both = whole.f0.voiced & chunked.f0.voiced
    relative = np.abs(chunked.f0.values[both] / whole.f0.values[both] - 1)
    assert np.mean(relative > 0.01) <= 0.001
    assert np.median(relative) < 1e-6
    np.testing.assert_allclose(whole.energy.values, chunked.energy.values, atol=0.1)


def test_streamed_file_reading_equals_reading_at_once(tmp_path, monkeypatch) -> None:
    import soundfile

    from audio_features import features as features_module

    sr = 16000
    rng = np.random.default_rng(11)
    signal = np.concatenate([harmonic_tone(f0, 0.4, sr, amplitude=a)
                             for f0, a in zip(rng.uniform(120, 280, 6), rng.uniform(0.1, 0.7, 6), strict=True)])
    soundfile.write(tmp_path / "tone.wav", np.column_stack([signal, 0.5 * signal]), sr, subtype="FLOAT")
    at_once = extract_features(tmp_path / "tone.wav", chunk_s=0.5)
    monkeypatch.setattr(features_module, "IN_MEMORY_SAMPLES", 0)  # force the peak scan and chunked reads
    streamed = extract_features(tmp_path / "tone.wav", chunk_s=0.5)
    np.testing.assert_array_equal(at_once.f0.values, streamed.f0.values)
    np.testing.assert_array_equal(at_once.energy.values, streamed.energy.values)


def test_analysis_reports_its_progress_chunk_by_chunk() -> None:
    from conftest import harmonic_tone

    from audio_features import Audio

    calls: list[tuple[int, int]] = []
    extract_features(Audio(harmonic_tone(150, 5.0, 16000), 16000), chunk_s=2.0,
                     progress=lambda done, total: calls.append((done, total)))
    assert calls == [(0, 150), (60, 150), (120, 150), (150, 150)]


@pytest.mark.parametrize("rate", [8000, 16000, 22050, 44100, 48000])
def test_the_mel_filterbank_is_librosas_to_the_bit(rate) -> None:
    # built by hand so that the live path does not import librosa; librosa's own is the known answer
    import librosa

    from audio_features.spectral import MEL_HIGH_HZ, MEL_LOW_HZ, N_MELS, mel_filterbank

    window = int(round(0.025 * rate))
    n_fft = 1 << (window - 1).bit_length()
    high = min(MEL_HIGH_HZ, 0.475 * rate)
    expected = librosa.filters.mel(sr=rate, n_fft=n_fft, n_mels=N_MELS, fmin=MEL_LOW_HZ, fmax=high)
    assert np.array_equal(mel_filterbank(rate, n_fft, N_MELS, MEL_LOW_HZ, high), expected)


def test_the_live_path_imports_neither_librosa_nor_scipy() -> None:
    import subprocess
    import sys

    code = ("import sys, numpy as np; from prosody.live.converter import LiveConverter; c = LiveConverter(16000); "
            "c.push(np.zeros(16000)); c.finish(); print(sorted({'librosa', 'numba', 'scipy'} & set(sys.modules)))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_the_cepstra_dct_is_scipys(rng) -> None:
    from scipy.fft import dct

    from audio_features.spectral import N_CEPSTRA, N_MELS, _dct_rows

    x = rng.normal(size=(50, N_MELS))
    np.testing.assert_allclose(x @ _dct_rows(N_MELS, N_CEPSTRA).T,
                               dct(x, type=2, norm="ortho", axis=1)[:, :N_CEPSTRA], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("container", "subtype"), [("WAV", "PCM_16"), ("WAV", "PCM_24"), ("WAV", "PCM_32"),
                                                    ("FLAC", "PCM_16"), ("FLAC", "PCM_24"), ("AIFF", "PCM_16")])
def test_integer_samples_read_quickly_are_libsndfiles_doubles_bit_for_bit(tmp_path, container, subtype) -> None:
    import soundfile

    from audio_features.audio import read_whole

    signal = np.random.default_rng(7).uniform(-1, 1, (4000, 2))
    signal[:2] = [[-1.0, 1.0], [0.99999, -0.99999]]  # full scale both ways (+1 clips to the largest code)
    path = tmp_path / f"x.{container.lower()}"
    soundfile.write(path, signal, 16000, format=container, subtype=subtype)
    expected, _ = soundfile.read(path, dtype="float64", always_2d=True)
    with soundfile.SoundFile(path) as sound:
        got = read_whole(sound)
    assert got.dtype == np.float64 and np.array_equal(got, expected)


def test_forked_workers_that_stop_answering_leave_the_rest_to_this_process(monkeypatch) -> None:
    """A worker that hangs (killed, or stuck on a lock it inherited) is given up after the patience, and what is
    left is analysed here; an error in a worker is the caller's error."""
    import time

    import audio_features.analysis as analysis

    if analysis.forked_workers() < 2:
        pytest.skip("one core: no workers are forked")
    parent = os.getpid()

    def square_here(item: int) -> int:
        if os.getpid() != parent and item >= 3:
            time.sleep(60)  # a worker that never answers
        return item * item

    monkeypatch.setattr(analysis, "FORKED_PATIENCE_S", 0.5)
    started = time.monotonic()
    assert list(analysis._mapped(square_here, list(range(6)), 2)) == [(k, k * k) for k in range(6)]
    assert time.monotonic() - started < 10

    def fails(item: int) -> int:
        raise ParameterError(f"item {item} is bad")

    with pytest.raises(ParameterError, match="item 0 is bad"):
        list(analysis._mapped(fails, [0, 1, 2], 2))


def test_stopping_forked_workers_never_waits_for_ever(monkeypatch) -> None:
    """A worker killed while it sends its answer keeps the answers' lock, and the pool's own ``terminate`` then
    waits without end (a fresh clone's suite hung there once). Here ``terminate`` finds that lock held, as such a
    worker leaves it: the rest is still analysed in this process, after at most the stopping's patience."""
    import multiprocessing
    import multiprocessing.pool
    import threading
    import time

    import audio_features.analysis as analysis

    if analysis.forked_workers() < 2:
        pytest.skip("one core: no workers are forked")
    fork, held = multiprocessing.get_context("fork"), []

    class KilledWhileAnswering(multiprocessing.pool.Pool):
        def terminate(self) -> None:
            self._outqueue._wlock.acquire()
            held.append(self)
            super().terminate()

    class Context:
        @staticmethod
        def Pool(processes, initializer=None):  # noqa: N802 - multiprocessing's name
            return KilledWhileAnswering(processes, initializer=initializer, context=fork)

    parent = os.getpid()

    def square_here(item: int) -> int:
        if os.getpid() != parent and item >= 3:
            time.sleep(60)  # a worker that never answers: the pool is stopped
        return item * item

    monkeypatch.setattr(analysis.multiprocessing, "get_context", lambda method: Context())
    monkeypatch.setattr(analysis, "FORKED_PATIENCE_S", 0.5)
    monkeypatch.setattr(analysis, "FORKED_STOP_S", 1.0, raising=False)
    results: list = []
    worker = threading.Thread(target=lambda: results.extend(analysis._mapped(square_here, list(range(6)), 2)),
                              daemon=True)
    started = time.monotonic()
    worker.start()
    worker.join(20)
    try:
        assert not worker.is_alive(), "stopping the workers waited for a lock no one will release"
        assert results == [(k, k * k) for k in range(6)]
        assert time.monotonic() - started < 10
    finally:
        for pool in held:  # let the stopping finish, so nothing is left behind
            pool._outqueue._wlock.release()


def test_forked_workers_finish_cleanly_under_a_program_that_handles_sigterm(tmp_path) -> None:
    """The command line turns SIGTERM into KeyboardInterrupt; a worker that kept that handler, stopped by a
    signal, died holding the pool's lock (the caller then waited for ever) or printed a traceback. Workers now
    leave when told there is no more work, and a signal stops them outright."""
    import subprocess
    import sys
    import textwrap

    script = tmp_path / "handled.py"
    script.write_text(textwrap.dedent(f"""
        import signal, sys
        sys.path.insert(0, {str(REPO)!r})
        from audio_features.analysis import _mapped

        def terminated(signum, frame):
            raise KeyboardInterrupt

        def square(x):
            return x * x

        signal.signal(signal.SIGTERM, terminated)
        for _ in range(40):
            assert [r for _, r in _mapped(square, list(range(8)), 2)] == [x * x for x in range(8)]
        print("done")
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "done", done.stderr[-2000:]
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr
