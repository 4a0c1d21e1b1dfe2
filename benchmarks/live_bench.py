"""Live benchmark (part of ``make bench``): ``prosody stream`` fed real speech through a pipe.

- Latency, as a user of the stream sees it: for each frame, from the moment the audio for its time had been
  written to the command's input until the frame's line is read from its output; raw 16 kHz PCM is written
  in 10 ms pieces at real-time pace (30 s of speech per look-ahead), the first 2 s left out (start-up).
- CPU: the command's own CPU time over the same real-time run after its first 2 s of audio (and the 1 s after
  the input ends), as a share of one core; the clock of the audio starts once the command says it reads.
- Memory: the command's resident memory while 30 minutes of speech are streamed through it as fast as it
  goes (JSON lines to /dev/null), read every 5 minutes of audio: a stream of hours must not grow.

Usage: python benchmarks/live_bench.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from benchmarks.bench import SAMPLE_RATE_HZ, build_speech

LATENCY_AUDIO_S = 30.0
MEMORY_AUDIO_S = 1800.0
CHUNK_S = 0.01
WARM_UP_S = 2.0
PROSODY = [sys.executable, "-m", "prosody", "stream", "-", "--raw-rate", str(SAMPLE_RATE_HZ), "-o", "-"]


def _pcm(samples: np.ndarray) -> bytes:
    return (np.clip(samples, -1, 1) * 32767).astype("<i2").tobytes()


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mb(pid: int) -> float:
    status = Path(f"/proc/{pid}/status").read_text()
    return int(status.split("VmRSS:")[1].split()[0]) / 1024


def latency(samples: np.ndarray, lookahead_ms: float) -> dict:
    """Per-frame delay of a real-time run, and the command's CPU share."""
    process = subprocess.Popen([*PROSODY, "--lookahead-ms", str(lookahead_ms)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    arrivals: list[float] = []

    def read() -> None:
        for _ in iter(process.stdout.readline, b""):
            arrivals.append(time.monotonic())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    # the clock of the audio starts when the command says it reads its input (imports and models loaded)
    for line in iter(process.stderr.readline, b""):
        if b"prosody stream: reading" in line:
            break
    threading.Thread(target=lambda: process.stderr.read(), daemon=True).start()
    chunk = int(CHUNK_S * SAMPLE_RATE_HZ)
    written_at = []
    start = time.monotonic()
    cpu_start = None
    for offset in range(0, samples.size, chunk):
        delay = start + offset / SAMPLE_RATE_HZ - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if cpu_start is None and offset >= WARM_UP_S * SAMPLE_RATE_HZ:  # the CPU of the steady state
            cpu_start = _cpu_seconds(process.pid)
        process.stdin.write(_pcm(samples[offset:offset + chunk]))
        process.stdin.flush()
        written_at.append(time.monotonic())
    time.sleep(1.0)
    cpu = _cpu_seconds(process.pid) - cpu_start
    process.stdin.close()
    process.wait()
    reader.join()
    fps = 30.0
    delays = []
    for k, arrived in enumerate(arrivals):
        t = k / fps
        if t < WARM_UP_S or (t + lookahead_ms / 1000 + 0.05) * SAMPLE_RATE_HZ >= samples.size:
            continue  # start-up, and the last frames (given at the end of input, not by the clock)
        piece = int(t * SAMPLE_RATE_HZ) // chunk  # the piece that holds the audio for time t
        delays.append(arrived - written_at[piece])
    delays_ms = np.array(delays) * 1000
    return {"median": float(np.median(delays_ms)), "p95": float(np.percentile(delays_ms, 95)),
            "max": float(delays_ms.max()), "frames": len(arrivals),
            "cpu": cpu / (samples.size / SAMPLE_RATE_HZ - WARM_UP_S + 1.0)}


def memory(samples: np.ndarray) -> list[tuple[float, float]]:
    """Resident memory (MB) after each 5 minutes of audio streamed as fast as the command takes it."""
    process = subprocess.Popen(PROSODY, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    readings = []
    block = int(300 * SAMPLE_RATE_HZ)
    chunk = int(0.1 * SAMPLE_RATE_HZ)
    sent = 0
    total = int(MEMORY_AUDIO_S * SAMPLE_RATE_HZ)
    while sent < total:
        offset = sent % samples.size
        piece = samples[offset:offset + chunk]
        process.stdin.write(_pcm(piece))
        sent += piece.size
        if sent % block < piece.size:
            process.stdin.flush()
            readings.append((sent / SAMPLE_RATE_HZ / 60, _rss_mb(process.pid)))
    process.stdin.close()
    process.wait()
    return readings


def main() -> int:
    import soundfile

    with tempfile.TemporaryDirectory() as folder:
        path = build_speech(Path(folder) / "speech.wav", duration_s=LATENCY_AUDIO_S)
        samples, _ = soundfile.read(path)
    print(f"live: prosody stream fed {LATENCY_AUDIO_S:.0f} s of real speech at real-time pace in "
          f"{CHUNK_S * 1000:.0f} ms pieces (16 kHz PCM on a pipe)")
    print("  look-ahead   delay median    p95     max    CPU (one core)   (aims: median <= 150 ms, "
          "p95 <= 200 ms, CPU <= 8 %)")
    for lookahead_ms in (0, 100, 200):
        result = latency(samples, lookahead_ms)
        print(f"  {lookahead_ms:5.0f} ms   {result['median']:8.0f} ms {result['p95']:6.0f} ms {result['max']:6.0f} ms"
              f"   {result['cpu'] * 100:5.1f} %")
    readings = memory(samples)
    print(f"live: resident memory while {MEMORY_AUDIO_S / 60:.0f} min of speech stream through (MB after each "
          "5 min of audio):")
    print("  " + "  ".join(f"{minutes:.0f} min {mb:.0f}" for minutes, mb in readings))
    slope = np.polyfit([m for m, _ in readings[1:]], [mb for _, mb in readings[1:]], 1)[0] * 60
    print(f"  growth after the first 5 min: {slope:+.1f} MB per hour of audio")
    return 0


if __name__ == "__main__":
    sys.exit(main())
