"""Shared fixtures: synthetic signals with known answers, and the real data in ../shared/data."""

from __future__ import annotations

import gc
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("PROSODY_SHARED_DATA", REPO.parent / "shared" / "data"))


SHARED_MISSING = f"real data not found at {SHARED_DATA} (set PROSODY_SHARED_DATA)"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if SHARED_DATA.is_dir():
        return
    skip = pytest.mark.skip(reason=SHARED_MISSING)
    for item in items:
        if "shared_data" in item.keywords:
            item.add_marker(skip)


# Reads of ../shared outside a test marked shared_data ----------------------------------------------------------
# A user's clone has no ../shared: a test that reads it must carry the marker, so that it skips there with its
# reason instead of failing. An audit hook sees every file opened, folder listed and process started while a
# test runs; a test without the marker that touches SHARED_DATA fails with the path it touched.
_SHARED_ROOTS = tuple(dict.fromkeys(str(path) for path in (SHARED_DATA, SHARED_DATA.resolve())))
_AUDITED = {"open", "os.listdir", "os.scandir", "glob.glob", "subprocess.Popen", "os.exec", "os.posix_spawn"}


class SharedReads:
    """What an unmarked test read of the shared data: ``watching`` is set while such a test runs."""

    watching = False
    seen: list[str] = []

    @classmethod
    def audit(cls, event: str, args: tuple) -> None:
        if not cls.watching or event not in _AUDITED:
            return
        for value in _audit_strings(args):
            if value.startswith(_SHARED_ROOTS):
                cls.seen.append(f"{event} {value}")
                return


def _audit_strings(args) -> list[str]:
    found: list[str] = []
    for value in args:
        if isinstance(value, (str, bytes, os.PathLike)):
            try:
                found.append(os.fsdecode(value))
            except TypeError:
                pass
        elif isinstance(value, (list, tuple)):
            found.extend(_audit_strings(value))
    return found


sys.addaudithook(SharedReads.audit)


def _watch_shared_reads(item: pytest.Item):
    marked = item.get_closest_marker("shared_data") is not None
    SharedReads.watching, SharedReads.seen = not marked, []
    failure = None
    try:
        return (yield)
    except Exception as error:  # a read that failed (no such file in a user's clone) is told as the rule broken
        failure = error
        raise
    finally:
        SharedReads.watching = False
        if SharedReads.seen and not isinstance(failure, pytest.fail.Exception):
            pytest.fail(f"{item.nodeid} reads the shared data without @pytest.mark.shared_data (a user's clone "
                        f"has none, so it must skip there): {SharedReads.seen[0]}", pytrace=False)


pytest_runtest_setup = pytest.hookimpl(wrapper=True)(_watch_shared_reads)


# Tests that take long without the slow marker --------------------------------------------------------------------
# make test-fast leaves out the tests marked slow: a test that takes 2 s or more must carry the marker, so that the
# fast tier stays fast. Time is counted as this process's processor time (all its threads), which a loaded machine
# changes far less than the time on the clock (the limits stretch with the machine's load: machine_load); a test
# that waits (servers, browsers, pacing, subprocesses) is held to a looser limit in wall time. The subprocesses'
# own time is not counted: a child that ends during a later test would be charged to it; nor is the time Numba
# spends compiling (once per machine: a fresh checkout's first run compiles).
# PROSODY_SLOW_CPU_S lowers the limit to find the tests near it (those within a quarter of it are marked too,
# so that a slower machine does not fail them).
SLOW_CPU_S = float(os.environ.get("PROSODY_SLOW_CPU_S", "2.0"))
SLOW_WALL_S = 10.0


def machine_load() -> float:
    """How many times over its cores the machine is busy (1 when idle or when the system does not say).

    The limits above are for a quiet machine. On a busy one a test's processor time grows too: the native
    libraries' worker threads (OpenMP under Numba, OpenCV, MediaPipe) spin while they wait for a core, and that
    spinning is this process's time. The limits are stretched by this factor there, so that a loaded machine
    never fails a test for being loaded."""
    try:
        return max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))
    except (AttributeError, OSError):  # pragma: no cover - not every system reports its load
        return 1.0




class CompileTime:
    """Seconds Numba spent compiling (the rasteriser, librosa's DTW) while a test ran: paid once per machine and
    cached after, so a fresh checkout's first run is not held against the test that happened to compile."""

    seconds = 0.0

    @classmethod
    def install(cls) -> None:
        try:
            from numba.core import event
        except ImportError:  # pragma: no cover - numba is a dependency of the package
            return

        class Timer(event.Listener):
            depth, started = 0, 0.0

            def on_start(self, _event) -> None:
                if self.depth == 0:
                    self.started = time.perf_counter()
                self.depth += 1

            def on_end(self, _event) -> None:
                self.depth -= 1
                if self.depth == 0:
                    cls.seconds += time.perf_counter() - self.started

        event.register("numba:compiler_lock", Timer())  # held for the whole of each compilation


CompileTime.install()


class CollectTime:
    """Seconds the garbage collector spent while a test ran: a full collection walks every object the whole
    session keeps (seconds on a loaded machine), started by whichever test happens to allocate at that moment,
    so it is not that test's own time."""

    seconds = 0.0
    _started = 0.0

    @classmethod
    def callback(cls, phase: str, _info: dict) -> None:
        if phase == "start":
            cls._started = time.perf_counter()
        else:
            cls.seconds += time.perf_counter() - cls._started


gc.callbacks.append(CollectTime.callback)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item):
    cpu, wall, compiling = time.process_time(), time.perf_counter(), CompileTime.seconds + CollectTime.seconds
    result = yield from _watch_shared_reads(item)
    compiling = CompileTime.seconds + CollectTime.seconds - compiling
    cpu, wall = time.process_time() - cpu - compiling, time.perf_counter() - wall - compiling
    load = machine_load()
    if item.get_closest_marker("slow") is None and (cpu >= SLOW_CPU_S * load or wall >= SLOW_WALL_S * load):
        stretched = f", stretched {load:.1f} times for the machine's load" if load > 1 else ""
        pytest.fail(f"{item.nodeid} took {cpu:.1f} s of processor time ({wall:.1f} s in all) without "
                    f"@pytest.mark.slow: mark it, or make it quicker (limits {SLOW_CPU_S:g} s and {SLOW_WALL_S:g} s"
                    f"{stretched})", pytrace=False)
    return result


@pytest.fixture
def shared_data(request: pytest.FixtureRequest) -> Path:
    """The real data folder; only for tests marked ``shared_data`` (they skip where it is absent)."""
    if request.node.get_closest_marker("shared_data") is None:
        pytest.fail(f"{request.node.nodeid} uses the shared_data fixture without @pytest.mark.shared_data",
                    pytrace=False)
    if not SHARED_DATA.is_dir():
        pytest.skip(SHARED_MISSING)
    return SHARED_DATA


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20051201)


def harmonic_tone(f0_hz: float, duration_s: float, sample_rate_hz: int, *, amplitude: float = 0.5,
                  n_harmonics: int = 5) -> np.ndarray:
    """A steady voiced-like tone: harmonics of ``f0_hz`` with 1/h amplitudes, peak ``amplitude``."""
    t = np.arange(int(round(duration_s * sample_rate_hz))) / sample_rate_hz
    signal = np.zeros_like(t)
    for h in range(1, n_harmonics + 1):
        if h * f0_hz < 0.45 * sample_rate_hz:
            signal += np.sin(2 * np.pi * h * f0_hz * t) / h
    return amplitude * signal / np.max(np.abs(signal))


def sine(frequency_hz: float, duration_s: float, sample_rate_hz: int, *, amplitude: float) -> np.ndarray:
    t = np.arange(int(round(duration_s * sample_rate_hz))) / sample_rate_hz
    return amplitude * np.sin(2 * np.pi * frequency_hz * t)


def sine_level_db(amplitude: float) -> float:
    """Level of a sine of peak ``amplitude`` pascals in dB re 2e-5 Pa: mean square A^2/2."""
    return float(10 * np.log10(amplitude**2 / 2 / (2e-5) ** 2))


def gliding_tone(f0_hz: np.ndarray, sample_rate_hz: int, *, amplitude: np.ndarray | float = 0.5) -> np.ndarray:
    """A harmonic tone whose F0 follows ``f0_hz`` sample by sample (phase-continuous); 0 Hz is silence."""
    phase = 2 * np.pi * np.cumsum(f0_hz) / sample_rate_hz
    signal = sum(np.sin(h * phase) / h for h in range(1, 4))
    signal = signal / 1.5 * amplitude
    return np.where(f0_hz > 0, signal, 0.0)


def segments(sample_rate_hz: int, *parts: tuple[float, float, float]) -> np.ndarray:
    """Concatenate (duration_s, f0_hz, amplitude) parts into one phase-continuous tone."""
    f0 = np.concatenate([np.full(int(round(d * sample_rate_hz)), f) for d, f, _ in parts])
    amplitude = np.concatenate([np.full(int(round(d * sample_rate_hz)), a) for d, _, a in parts])
    return gliding_tone(f0, sample_rate_hz, amplitude=amplitude)


def make_features(f0_conditioned_hz, energy_db, *, fps: float = 30.0):
    """Features built directly from conditioned F0 and energy arrays (every frame voiced)."""
    from audio_features import F0Track, Features, Track

    f0 = np.asarray(f0_conditioned_hz, float)
    return Features(
        f0=F0Track(f0, fps, "Hz", "f0", np.ones(f0.shape, bool)),
        f0_conditioned=Track(f0, fps, "Hz", "f0_conditioned"),
        energy=Track(np.asarray(energy_db, float), fps, "dB", "energy"),
        duration_s=f0.shape[0] / fps,
        source="<synthetic>",
    )


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
#: Marks a test that drives Debian's headless Chromium.
needs_chromium = pytest.mark.skipif(CHROMIUM is None or CHROMEDRIVER is None,
                                    reason="needs Debian's chromium and chromium-driver "
                                           "(apt-get install chromium chromium-driver)")


def headless_chromium(*flags: str):
    """A selenium driver of headless Chromium with ``flags`` besides the quiet, sandbox-free defaults; skips
    the test where the selenium package (the test extra) is missing."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="needs the selenium package (the test extra)")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--autoplay-policy=no-user-gesture-required", "--enable-unsafe-swiftshader", *flags):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def wait_in_page(driver, script: str, describe: str, timeout_s: float = 30.0):
    """The first truthy value of ``script`` run in the page, polled; on timeout an AssertionError with what the
    ``describe`` script returns (the page's own account of its state)."""
    import time

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {script!r}; page: {driver.execute_script(describe)}")


@pytest.fixture
def frame_server():
    """A live frame server on a free loopback port, with a converter per client; ``.lines`` holds what it
    reported."""
    from prosody.live.converter import LiveConverter
    from prosody.live.server import FrameServer

    lines: list[str] = []
    running = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lines.append)
    running.start()
    running.lines = lines  # type: ignore[attr-defined]
    yield running
    running.close(drain_s=0.2)


@pytest.fixture
def speech(tmp_path) -> Path:
    """1.7 s of a speech-like tone (140 Hz, an accent at 230 Hz, 150 Hz) at 16 kHz: 51 frames at 30 fps."""
    import soundfile

    path = tmp_path / "speech.wav"
    soundfile.write(path, segments(16000, (0.6, 140, 0.5), (0.5, 230, 0.5), (0.6, 150, 0.5)), 16000)
    return path
