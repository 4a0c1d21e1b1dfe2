"""Live analysis (audio_features.streaming, audio_features.pcm): frames that do not depend on how the audio
arrives, agree with the whole-file analysis, and never read the future."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
import soundfile
from conftest import harmonic_tone, segments

from audio_features import Audio, AudioLoadError, ParameterError, condition_f0, extract_features
from audio_features.pcm import PcmDecoder, PcmFormat, read_wav_header
from audio_features.streaming import CausalF0Bridge, RunningMedian, StreamingAnalyser, stream_file
from audio_features.tracks import F0Track


def _analyse(samples: np.ndarray, rate: int, pieces: list[int] | None = None, **options):
    analyser = StreamingAnalyser(rate, **options)
    parts = []
    if pieces is None:
        parts.append(analyser.push(samples))
    else:
        start = 0
        for size in pieces:
            parts.append(analyser.push(samples[start:start + size]))
            start += size
        parts.append(analyser.push(samples[start:]))
    parts.append(analyser.finish())
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def test_frames_do_not_depend_on_how_the_audio_arrives(rng):
    samples = segments(16000, (0.4, 140, 0.5), (0.3, 0, 0.0), (0.5, 230, 0.3))
    whole = _analyse(samples, 16000)
    sizes = rng.integers(1, 700, size=200).tolist()
    pieced = _analyse(samples, 16000, sizes)
    np.testing.assert_array_equal(whole[0], pieced[0])
    np.testing.assert_array_equal(whole[1], pieced[1])


@pytest.mark.parametrize("rate", [8000, 16000, 44100])
def test_tone_pitch_and_frame_count(rate):
    samples = harmonic_tone(180.0, 1.0, rate)
    f0, energy = _analyse(samples, rate)
    offline = extract_features(Audio(samples, rate))
    assert f0.size == energy.size == offline.n_frames == 30
    voiced = ~np.isnan(f0)
    assert voiced[2:-2].all()
    assert np.max(np.abs(1200 * np.log2(f0[voiced] / 180.0))) < 10  # cents
    np.testing.assert_allclose(energy[2:-2], offline.energy.values[2:-2], atol=0.05)


def test_a_frame_never_reads_audio_after_its_window():
    # two signals equal up to 0.6 s: every frame whose window ends before then is identical
    rate = 16000
    a = harmonic_tone(150.0, 1.2, rate)
    b = a.copy()
    b[int(0.6 * rate):] = harmonic_tone(260.0, 0.6, rate) * 0.2
    analyser = StreamingAnalyser(rate)
    fa, ea = _analyse(a, rate)
    fb, eb = _analyse(b, rate)
    known = int((0.6 - analyser.latency_s()) * 30)  # frames computed before 0.6 s of audio had arrived
    np.testing.assert_array_equal(fa[:known], fb[:known])
    np.testing.assert_array_equal(ea[:known], eb[:known])
    assert not np.allclose(ea[known + 2:], eb[known + 2:])


def test_frames_arrive_as_soon_as_their_audio_is_in():
    rate = 16000
    analyser = StreamingAnalyser(rate)
    samples = harmonic_tone(200.0, 1.0, rate)
    seen = 0
    for start in range(0, samples.size, 160):
        f0, _ = analyser.push(samples[start:start + 160])
        seen += f0.size
        # frame k at k/30 s is out once its audio and half the 64 ms intensity window are in, not before
        end_s = (start + 160) / rate
        assert abs(seen - max(0.0, (end_s - analyser.latency_s()) * 30 + 1)) < 1.5


@pytest.mark.shared_data
@pytest.mark.parametrize("clip", ["Obama_clip1", "andrew_clip_1"])
def test_agrees_with_the_whole_file_analysis_on_real_speech(shared_data, clip):
    path = shared_data / "talking-heads" / f"{clip}.wav"
    f0, energy = stream_file(str(path))
    offline = extract_features(path)
    assert f0.size == offline.n_frames
    voiced = ~np.isnan(f0)
    assert np.mean(voiced == offline.f0.voiced) > 0.88  # the path finder sees no future audio
    both = voiced & offline.f0.voiced
    cents = np.abs(1200 * np.log2(f0[both] / offline.f0.values[both]))
    assert np.mean(cents < 50) > 0.97
    assert np.max(np.abs(energy - offline.energy.values)) < 0.2


def test_nonfinite_and_bad_parameters_are_refused():
    with pytest.raises(AudioLoadError, match="not finite"):
        StreamingAnalyser(16000).push(np.array([0.0, np.nan]))
    for options in ({"fps": 0.0}, {"f0_floor_hz": 600.0}, {"context_s": -1.0}):
        with pytest.raises(ParameterError):
            StreamingAnalyser(16000, **options)
    with pytest.raises(ParameterError):
        StreamingAnalyser(4000)


def test_running_median_matches_numpy_within_its_resolution(rng):
    values = rng.normal(70.0, 8.0, size=501)
    median = RunningMedian(0.0, 200.0, resolution=0.1)
    for value in values:
        median.add(value)
    assert abs(median.value - np.median(values)) <= 0.1
    assert median.count == 501


def test_running_median_forgets_an_old_voice():
    median = RunningMedian(0.0, 100.0, resolution=0.5, half_life=100)
    for _ in range(1000):
        median.add(20.0)
    for _ in range(400):
        median.add(60.0)
    assert median.value == pytest.approx(60.0, abs=0.5)


def test_bridge_without_gaps_and_with_short_gaps_matches_condition_f0():
    raw = np.array([120.0, 125.0, np.nan, np.nan, 140.0, 138.0, np.nan, 130.0, 131.0, 129.0])
    offline = condition_f0(F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))).values
    bridge = CausalF0Bridge(lookahead_frames=3)
    live = [v for v in (bridge.push(value) for value in raw) if v is not None] + bridge.finish()
    assert len(live) == raw.size
    voiced = ~np.isnan(raw)
    np.testing.assert_array_equal(np.array(live)[voiced], raw[voiced])
    # the last gap's end is at the look-ahead's edge, so the voiced frame after it is not in sight: close
    np.testing.assert_allclose(live, offline, atol=3.0)


def test_bridge_equals_condition_f0_exactly_when_the_look_ahead_sees_past_every_gap(rng):
    raw = 120.0 + 60.0 * rng.random(400)
    starts = rng.choice(np.arange(5, 380), size=40, replace=False)
    for start in starts:  # gaps of 1 to 15 frames, some touching
        raw[start:start + rng.integers(1, 16)] = np.nan
    raw[:3] = np.nan
    raw[-4:] = np.nan
    offline = condition_f0(F0Track(raw, 30.0, "Hz", "f0", ~np.isnan(raw))).values
    voiced = np.flatnonzero(~np.isnan(raw))
    assert np.diff(voiced).max() == 42  # merged gaps: the look-ahead must reach two voiced frames past each
    bridge = CausalF0Bridge(lookahead_frames=60)
    live = [v for v in (bridge.push(value) for value in raw) if v is not None] + bridge.finish()
    np.testing.assert_allclose(live, offline, rtol=0, atol=1e-9)


def test_bridge_is_causal_and_continuous():
    raw = [100.0] * 5 + [np.nan] * 10 + [200.0] * 5
    bridge = CausalF0Bridge(lookahead_frames=2)
    out = [v for v in (bridge.push(value) for value in raw) if v is not None] + bridge.finish()
    assert out[5:12] == [100.0] * 7  # the gap's end is not in sight yet: hold
    assert max(np.abs(np.diff(out))) < 50  # then a ramp to 200 Hz, not a jump
    assert out[-1] == 200.0
    changed = raw[:13] + [300.0] * 7
    other = CausalF0Bridge(lookahead_frames=2)
    again = [v for v in (other.push(value) for value in changed) if v is not None] + other.finish()
    assert again[:11] == out[:11]  # frame k reads frames up to k + 2 only


# byte streams ---------------------------------------------------------------------------------------------
def _wav_header(rate: int, *, tag: int = 1, bits: int = 16, channels: int = 1, data_size: int = 0xFFFFFFFF,
                extra_chunk: bytes = b"") -> bytes:
    block = channels * bits // 8
    fmt = struct.pack("<HHIIHH", tag, channels, rate, rate * block, block, bits)
    if tag == 0xFFFE:
        fmt += struct.pack("<HHIH", 22, bits, 0, 1) + b"\x00" * 14  # the sub-format GUID opens with the tag
    return (b"RIFF" + struct.pack("<I", 0xFFFFFFFF) + b"WAVE" + b"fmt " + struct.pack("<I", len(fmt)) + fmt
            + extra_chunk + b"data" + struct.pack("<I", data_size))


def test_wav_stream_header_of_unknown_length_is_read():
    stream = io.BytesIO(_wav_header(22050, extra_chunk=b"LIST" + struct.pack("<I", 3) + b"abc\x00") + b"\x00\x40")
    pcm, size = read_wav_header(stream.read)
    assert (pcm.sample_rate_hz, pcm.encoding, pcm.channels, size) == (22050, "s16le", 1, None)
    assert PcmDecoder(pcm).decode(stream.read()).tolist() == [0.5]


def test_wav_stream_with_a_known_length_and_extensible_format():
    stream = io.BytesIO(_wav_header(16000, tag=0xFFFE, bits=16, channels=2, data_size=8))
    pcm, size = read_wav_header(stream.read)
    assert (pcm.encoding, pcm.channels, size) == ("s16le", 2, 8)


def test_a_real_wav_file_read_as_a_stream_matches_soundfile(tmp_path):
    path = tmp_path / "float.wav"
    samples = harmonic_tone(150.0, 0.2, 16000) * 0.7
    soundfile.write(path, np.column_stack([samples, -samples * 0.5]), 16000, subtype="FLOAT")
    with open(path, "rb") as handle:
        pcm, size = read_wav_header(handle.read)
        decoded = PcmDecoder(pcm).decode(handle.read(size))
    assert pcm.encoding == "f32le"
    np.testing.assert_allclose(decoded, (samples - samples * 0.5) / 2, atol=1e-6)


@pytest.mark.parametrize("data, message", [
    (b"OggS" + b"\x00" * 20, "Ogg is read from a file, not from a stream"),
    (b"JUNK" + b"\x00" * 20, "not a WAV stream"),
    (b"RIFF\x00\x00\x00\x00WAVEfmt ", "ended inside the WAV header"),
    (b"RIFF\xff\xff\xff\xffWAVEdata\x00\x00\x00\x00", "before its format"),
])
def test_bad_wav_streams_are_refused(data, message):
    with pytest.raises(AudioLoadError, match=message):
        read_wav_header(io.BytesIO(data).read)


@pytest.mark.parametrize("encoding, payload, expected", [
    ("s16le", struct.pack("<hh", -32768, 16384), [-1.0, 0.5]),
    ("s24le", bytes([0x00, 0x00, 0x40, 0x00, 0x00, 0xC0]), [0.5, -0.5]),
    ("s32le", struct.pack("<i", -(1 << 30)), [-0.5]),
    ("f32le", struct.pack("<f", 0.25), [0.25]),
    ("f64le", struct.pack("<d", -0.125), [-0.125]),
    ("u8", bytes([128, 192]), [0.0, 0.5]),
])
def test_raw_formats_decode_to_full_scale(encoding, payload, expected):
    decoder = PcmDecoder(PcmFormat(16000, encoding))
    # one byte at a time: a sample split between pieces waits for the rest
    out = np.concatenate([decoder.decode(payload[i:i + 1]) for i in range(len(payload))])
    assert out.tolist() == expected
    assert decoder.pending_bytes == 0


def test_raw_channels_are_mixed_and_nonfinite_floats_refused():
    decoder = PcmDecoder(PcmFormat(16000, "f32le", channels=2))
    assert decoder.decode(struct.pack("<ff", 0.5, -0.25)).tolist() == [0.125]
    with pytest.raises(AudioLoadError, match="not finite"):
        PcmDecoder(PcmFormat(16000, "f32le")).decode(struct.pack("<f", float("nan")))
    with pytest.raises(ParameterError):
        PcmFormat(16000, "mp3")


def test_digital_silence_keeps_the_buffer_bounded():
    # an all-zero window asks no peak; the audio before the frames must still be let go (a minute of
    # silence once grew the buffer to every sample received)
    analyser = StreamingAnalyser(16000)
    frames = 0
    for _ in range(600):  # 60 s in 0.1 s pieces
        f0, _ = analyser.push(np.zeros(1600))
        frames += f0.size
    assert frames >= 1795
    assert analyser._buffer.size < 16000  # below a second of audio, whatever the silence's length
    tone = harmonic_tone(200.0, 1.0, 16000)
    f0 = np.concatenate([analyser.push(tone)[0], analyser.finish()[0]])
    assert abs(1200 * np.log2(np.nanmedian(f0) / 200.0)) < 20  # the voice after it is still heard
