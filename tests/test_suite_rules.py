"""The suite's own rules: a test that reads ../shared carries the shared_data marker, so that a user's clone,
which has no ../shared, skips it with its reason instead of failing.

The inner suites below run the project's conftest in a fresh process, against a shared-data folder made here."""

from __future__ import annotations

import pytest
from conftest import REPO

pytest_plugins = ["pytester"]

INNER_TESTS = '''
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import SHARED_DATA


def test_unmarked_open():
    (SHARED_DATA / "clip.wav").read_bytes()


def test_unmarked_listing():
    list(SHARED_DATA.iterdir())


def test_unmarked_process():
    subprocess.run([sys.executable, "-c", "pass", str(SHARED_DATA / "clip.wav")], check=True)


def test_unmarked_fixture(shared_data):
    assert shared_data


@pytest.fixture
def from_shared():
    return (SHARED_DATA / "clip.wav").read_bytes()


def test_unmarked_through_a_fixture(from_shared):
    assert from_shared


@pytest.mark.shared_data
def test_marked(shared_data):
    assert (shared_data / "clip.wav").read_bytes() == b"RIFF"


def test_elsewhere(tmp_path):
    (tmp_path / "x").write_text("x")
    assert (tmp_path / "x").read_text() == "x"
'''


def _inner(pytester: pytest.Pytester, data) -> pytest.RunResult:
    pytester.makeconftest((REPO / "tests" / "conftest.py").read_text())
    pytester.makeini("[pytest]\nmarkers =\n    shared_data: needs the shared data\n")
    pytester.makepyfile(test_inner=INNER_TESTS)
    pytester._monkeypatch.setenv("PROSODY_SHARED_DATA", str(data))
    return pytester.runpytest_subprocess("-p", "no:cacheprovider", "-rA")


def test_an_unmarked_test_that_reads_the_shared_data_fails_and_says_why(pytester, tmp_path):
    data = tmp_path / "shared" / "data"
    data.mkdir(parents=True)
    (data / "clip.wav").write_bytes(b"RIFF")
    result = _inner(pytester, data)
    result.assert_outcomes(passed=2, failed=3, errors=2)
    text = result.stdout.str()
    for name in ("test_unmarked_open", "test_unmarked_listing", "test_unmarked_process",
                 "test_unmarked_through_a_fixture"):
        assert f"test_inner.py::{name} reads the shared data without @pytest.mark.shared_data" in text, name
    assert "test_unmarked_fixture uses the shared_data fixture without @pytest.mark.shared_data" in text


def test_where_the_shared_data_is_absent_a_marked_test_skips_with_its_reason(pytester, tmp_path):
    missing = tmp_path / "nowhere"
    result = _inner(pytester, missing)
    result.assert_outcomes(passed=1, failed=3, errors=2, skipped=1)
    text = result.stdout.str()
    assert f"real data not found at {missing}" in text
    assert "test_inner.py::test_unmarked_open reads the shared data without @pytest.mark.shared_data" in text


SLOW_TESTS = '''
import os
import time

import pytest


def _burn(seconds):
    until = time.process_time() + seconds
    while time.process_time() < until:
        pass


def test_unmarked_and_long(monkeypatch):
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))  # an idle machine, whatever this one is
    _burn(0.6)


@pytest.mark.slow
def test_marked_and_long():
    _burn(0.6)


def test_unmarked_and_long_on_a_busy_machine(monkeypatch):
    monkeypatch.setattr(os, "getloadavg", lambda: (4.0 * (os.cpu_count() or 1), 0.0, 0.0))
    _burn(0.6)


def test_unmarked_and_short():
    _burn(0.05)


KEPT = [(k, str(k)) for k in range(400_000)]  # what a long session keeps alive: every collection walks it


def test_unmarked_but_collecting_the_sessions_garbage(monkeypatch):
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    import gc

    until = time.perf_counter() + 0.6
    while time.perf_counter() < until:  # full collections only: not this test's own work
        gc.collect()
'''


def test_an_unmarked_long_test_fails_unless_the_machine_is_busy(pytester):
    """The tiers' rule: a test over the processor-time limit must carry the slow marker (the limit lowered here
    to 0.3 s); on a machine busy four times over its cores the limit is stretched four times; the garbage
    collector's time (a full collection walks what the whole session keeps) is not the test's."""
    pytester.makeconftest((REPO / "tests" / "conftest.py").read_text())
    pytester.makeini("[pytest]\nmarkers =\n    shared_data: needs the shared data\n    slow: long\n")
    pytester.makepyfile(test_inner=SLOW_TESTS)
    pytester._monkeypatch.setenv("PROSODY_SLOW_CPU_S", "0.3")
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-rA")
    result.assert_outcomes(passed=4, failed=1)
    assert "test_inner.py::test_unmarked_and_long took 0.6 s of processor time" in result.stdout.str()
