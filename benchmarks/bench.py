"""Benchmark (``make bench``, ``python benchmarks/bench.py``): stage times on 10 minutes of real speech,
the whole ``prosody convert`` as a ratio to Praat's pitch and intensity alone (both measured here, side by
side, start-up included), the real-time factor, peak memory, the peak memory of converting a 2-hour
44.1 kHz recording, and batch throughput at 1 and 2 jobs.

The speech is built from the recordings in ../shared/data (or ``PROSODY_SHARED_DATA``), repeated to 10
minutes and written as 16 kHz WAV to a temporary folder.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from experiments.common import shared_data

REPO = Path(__file__).resolve().parents[1]
DURATION_S = 600.0
SAMPLE_RATE_HZ = 16000
REPEATS = 3
T = TypeVar("T")
# The child reports its own peak: VmHWM is the high-water mark of its memory since exec. (ru_maxrss is not:
# Linux carries the parent's peak into a child started by vfork and exec, so every child would show at least
# the benchmark's own peak.)
# (Kept free of imports beyond the function measured, so that the reference run pays for nothing else.)
_PEAK_SNIPPET = ("import sys; sys.path.insert(0, {folder!r}); from {module} import {function}; "
                 "code = {function}({args!r}); "
                 "status = open('/proc/self/status').read().split('VmHWM:')[1]; "
                 "print(int(status.split()[0]), file=sys.stderr); sys.exit(code or 0)")


def build_speech(path: Path, *, duration_s: float = DURATION_S) -> Path:
    """Concatenate the shared recordings (resampled to 16 kHz) until ``duration_s`` and write a WAV."""
    import numpy as np
    import soundfile
    from scipy.signal import resample_poly

    sources = sorted((shared_data() / "talking-heads").glob("*.wav")) + sorted(
        (shared_data() / "speech").glob("*.wav"))
    if not sources:
        raise SystemExit(f"{shared_data()}: no recordings found. The benchmark needs real speech: the project's "
                         "shared data folder beside the checkout (../shared/data), or set "
                         "PROSODY_SHARED_DATA=/path/to/data")
    pieces = []
    for source in sources:
        data, rate = soundfile.read(source, dtype="float64", always_2d=True)
        mono = data.mean(axis=1)
        if rate != SAMPLE_RATE_HZ:
            mono = resample_poly(mono, SAMPLE_RATE_HZ, rate)
        pieces.append(mono)
    speech = np.concatenate(pieces)
    repeats = int(np.ceil(duration_s * SAMPLE_RATE_HZ / speech.size))
    signal = np.tile(speech, repeats)[: int(duration_s * SAMPLE_RATE_HZ)]
    soundfile.write(path, signal, SAMPLE_RATE_HZ, subtype="PCM_16")
    return path


def build_long_recording(speech: Path, path: Path, *, hours: float = 2.0, sample_rate_hz: int = 44100) -> Path:
    """``hours`` of 16-bit audio at ``sample_rate_hz``, written block by block from ``speech`` resampled."""
    import soundfile
    from scipy.signal import resample_poly

    data, rate = soundfile.read(speech, dtype="float64")
    block = resample_poly(data, sample_rate_hz, rate)
    total = int(hours * 3600 * sample_rate_hz)
    with soundfile.SoundFile(path, "w", sample_rate_hz, 1, "PCM_16") as out:
        written = 0
        while written < total:
            piece = block[: total - written]
            out.write(piece)
            written += piece.size
    return path


def _timed(function: Callable[[], T]) -> tuple[float, T]:
    started = time.perf_counter()
    result = function()
    return time.perf_counter() - started, result


def _run_measured(module: str, function: str, args: list[str]) -> tuple[float, float]:
    """Run ``module.function(args)`` in a fresh interpreter: (wall seconds, peak resident MB)."""
    code = _PEAK_SNIPPET.format(folder=str(Path(__file__).resolve().parents[1]), module=module, function=function,
                                args=args)
    # as an installed package runs: its bytecode written once and read after (an environment that forbids
    # writing it, as some containers do, would make every run compile the package from source)
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, env=env)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{module}.{function} failed: {done.stderr.strip()}")
    peak_kb = int(done.stderr.strip().splitlines()[-1])
    return seconds, peak_kb / 1024


def praat_only(args: list[str]) -> int:
    """Praat's pitch and intensity of a file at the tool's analysis step, nothing else (the reference)."""
    import parselmouth

    sound = parselmouth.Sound(args[0])
    sound.to_pitch_ac(time_step=1 / 120, pitch_floor=75.0, pitch_ceiling=500.0)
    sound.to_intensity(minimum_pitch=100.0, time_step=1 / 120, subtract_mean=False)
    return 0


def stage_times(path: Path, out: Path) -> dict[str, float]:
    """Seconds per stage of a conversion, run in this process."""
    import parselmouth

    from audio_features import F0Track, condition_f0, extract_features, load_audio
    from prosody.fap.fapfile import write_fap
    from prosody.fap.stream import FapStream
    from prosody.motion.eyebrows import accent_raises, eyebrow_raises
    from prosody.motion.heads.arx import default_model
    from prosody.motion.heads.models import default_head_model
    from prosody.motion.perlin import perlin_curves

    times: dict[str, float] = {}
    times["load"], audio = _timed(lambda: load_audio(path))
    sound = parselmouth.Sound(audio.samples, sampling_frequency=audio.sample_rate_hz)
    times["F0 (Praat pitch)"], _ = _timed(lambda: sound.to_pitch_ac(time_step=1 / 120, pitch_floor=75.0,
                                                                     pitch_ceiling=500.0))
    times["energy (Praat intensity)"], _ = _timed(lambda: sound.to_intensity(minimum_pitch=100.0, time_step=1 / 120,
                                                                             subtract_mean=False))
    times["features on the grid (chunked, all of the above)"], features = _timed(lambda: extract_features(path))
    raw = F0Track(features.f0.values, features.fps, "Hz", "f0", features.f0.voiced)
    times["conditioning (spline)"], _ = _timed(lambda: condition_f0(raw))
    times["eyebrow rule (thesis)"], _ = _timed(lambda: eyebrow_raises(features))
    times["eyebrow accent rule (default)"], raises = _timed(lambda: accent_raises(features))
    model = default_model()
    times["ARX head (thesis, free run)"], _ = _timed(lambda: model.generate(features))
    prosodic = default_head_model()
    times["prosodic head (default)"], head = _timed(lambda: prosodic.generate(features, seed=0))
    times["Perlin"], _ = _timed(lambda: perlin_curves(features.n_frames, fps=features.fps, seed=0))
    from audio_features.phones import recognise_phones
    from prosody.motion.face.lips import shape_faps, shapes_from_phones
    from prosody.motion.face.mouth_model import AcousticMouthModel

    times["phones (PocketSphinx phone loop)"], phones = _timed(lambda: recognise_phones(audio))
    times["visemes and dominance blending"], _ = _timed(
        lambda: shape_faps(shapes_from_phones(phones, features.n_frames, fps=features.fps)))
    mouth = AcousticMouthModel.load()
    times["acoustic mouth model (cepstra and ridge)"], _ = _timed(
        lambda: mouth.predict(audio, features.n_frames, fps=features.fps))
    stream = FapStream.from_curves({**raises.curves(), **head}, fps=features.fps)
    times["writing .fap"], _ = _timed(lambda: write_fap(stream, out))
    return times


def _cpu_seconds() -> float:
    import resource

    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def batch_throughput(path: Path, folder: Path, *, files: int = 12,
                     clip_s: float = 60.0) -> dict[int, tuple[float, float]]:
    """``run_batch`` at 1 and 2 jobs on ``files`` clips of ``clip_s`` seconds, alternated ``REPEATS`` times:
    jobs -> (median files per second, median cores kept busy = CPU seconds / wall seconds)."""
    import numpy as np
    import soundfile

    from prosody.jobs.batch import run_batch

    data, rate = soundfile.read(path, frames=int(clip_s * SAMPLE_RATE_HZ))
    indir = folder / "batch-in"
    indir.mkdir()
    for index in range(files):
        soundfile.write(indir / f"clip{index}.wav", np.roll(data, index * 1000), rate)
    runs: dict[int, list[tuple[float, float]]] = {1: [], 2: []}
    for repeat in range(REPEATS):
        for jobs in (1, 2):
            outdir = folder / f"batch-out-{jobs}-{repeat}"
            cpu_before, started = _cpu_seconds(), time.perf_counter()
            summary = run_batch(indir, outdir, jobs=jobs)
            seconds = time.perf_counter() - started
            assert summary["counts"]["done"] == files
            runs[jobs].append((files / seconds, (_cpu_seconds() - cpu_before) / seconds))
    return {jobs: (float(np.median([rate for rate, _ in results])), float(np.median([busy for _, busy in results])))
            for jobs, results in runs.items()}


def main() -> int:
    import numpy as np

    from audio_features.analysis import forked_workers

    folder = Path(tempfile.mkdtemp(prefix="prosody-bench-"))
    try:
        speech = build_speech(folder / "speech-10min.wav")
        print(f"benchmark input: {DURATION_S / 60:.0f} min of real speech at {SAMPLE_RATE_HZ} Hz "
              f"({speech.stat().st_size / 1e6:.1f} MB), {os.cpu_count()} cores")
        stages = stage_times(speech, folder / "stages.fap")
        print("\nstage times (in one process):")
        for name, seconds in stages.items():
            print(f"  {name:<52} {seconds:8.3f} s")
        # side by side, each in a fresh interpreter so start-up and imports are counted
        # alternated and repeated, medians taken: the machine's load drifts
        runs: dict[str, list] = {"praat": [], "none": [], "visemes": [], "acoustic": []}
        _run_measured("prosody.cli", "main", ["convert", str(speech), "-o", str(folder / "warm.fap"), "--lips",
                                              "acoustic"])  # writes the bytecode, as installing does
        for _ in range(REPEATS):
            runs["praat"].append(_run_measured("benchmarks.bench", "praat_only", [str(speech)]))
            for lips in ("none", "visemes", "acoustic"):
                runs[lips].append(_run_measured("prosody.cli", "main", ["convert", str(speech), "-o",
                                                                        str(folder / "convert.fap"), "--lips", lips]))
        (praat_s, praat_mb), (convert_s, convert_mb), (lips_s, lips_mb), (acoustic_s, acoustic_mb) = (
            tuple(float(np.median(column)) for column in zip(*runs[key], strict=True))
            for key in ("praat", "none", "visemes", "acoustic"))
        import_s, _ = _run_measured("benchmarks.bench", "praat_only_import", [])
        print(f"\nwhole runs in fresh interpreters (start-up included; median of {REPEATS}, alternated):")
        print(f"  Praat pitch + intensity alone      {praat_s:7.2f} s   peak {praat_mb:6.0f} MB")
        print(f"  convert, head and brows (--lips none) {convert_s:4.2f} s   peak {convert_mb:6.0f} MB")
        print(f"  convert with lips (visemes, default) {lips_s:5.2f} s   peak {lips_mb:6.0f} MB")
        print(f"  convert with lips (--lips acoustic) {acoustic_s:6.2f} s   peak {acoustic_mb:6.0f} MB")
        print(f"  python start-up + parselmouth import {import_s:5.2f} s")
        print(f"  ratio head and brows / Praat alone {convert_s / praat_s:7.2f} x   (aim: <= 1.3 x; convert "
              f"analyses the minutes in {forked_workers()} process(es), Praat alone in one)")
        print(f"  real-time factor, head and brows   {DURATION_S / convert_s:7.0f} x faster than real time")
        print(f"  real-time factor, with visemes     {DURATION_S / lips_s:7.0f} x   (aim: >= 30 x)")
        print(f"  real-time factor, acoustic lips    {DURATION_S / acoustic_s:7.0f} x   (aim: >= 30 x)")
        long_file = build_long_recording(speech, folder / "long-2h-44k.wav")
        long_s, long_mb = _run_measured("prosody.cli", "main",
                                        ["convert", str(long_file), "-o", str(folder / "long.fap"), "--lips", "none"])
        long_file.unlink()
        long_fap = folder / "long.fap"
        read_s, read_mb = _run_measured("prosody.cli", "main", ["inspect", str(long_fap)])
        print("\n2-hour recording at 44.1 kHz (16-bit WAV, 635 MB):")
        print(f"  convert --lips none                {long_s:7.2f} s   peak {long_mb:6.0f} MB   (aim: < 600 MB)")
        print(f"  inspect its .fap ({long_fap.stat().st_size / 1e6:.0f} MB)         {read_s:7.2f} s   peak "
              f"{read_mb:6.0f} MB   ({read_s / long_s:.2f} x the conversion)")
        batch = batch_throughput(speech, folder)
        print(f"\nbatch throughput (12 clips of 60 s, all conditions, no plots; median of {REPEATS}, alternated):")
        for jobs, (rate, busy) in batch.items():
            print(f"  --jobs {jobs}: {rate:5.2f} files/s   {busy:4.2f} cores busy on average")
        ceiling = (os.cpu_count() or 1) / batch[1][1]
        print(f"  speed-up 2 jobs / 1 job: {batch[2][0] / batch[1][0]:.2f} x   (Praat's pitch tracker is "
              f"multithreaded: one job already keeps {batch[1][1]:.2f} cores busy, so {os.cpu_count()} cores allow "
              f"at most {ceiling:.2f} x)")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


def praat_only_import(args: list[str]) -> int:
    """Only the interpreter start-up and the parselmouth import (the fixed cost inside both runs)."""
    import parselmouth  # noqa: F401

    return 0


if __name__ == "__main__":
    sys.exit(main())
