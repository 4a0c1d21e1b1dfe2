"""A whole study in a real headless Chromium, as participants and an organiser run it: the plan, the videos,
``prosody study serve`` in its own process, two participants answering every trial (one closes the tab half-way
and comes back; the server is killed and restarted between two of their answers), then ``study export`` and
``study analyze``.

Needs Debian's ``chromium`` and ``chromium-driver``, the ``selenium`` package (the test extra) and ffmpeg (the
imageio-ffmpeg package); skipped with a reason where they are missing.
"""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile
from conftest import REPO, headless_chromium, needs_chromium, wait_in_page

from prosody.cli import main
from prosody.evaluation.preview import find_ffmpeg

pytestmark = [needs_chromium,
              pytest.mark.skipif(find_ffmpeg() is None, reason="needs ffmpeg (pip install imageio-ffmpeg)")]
#: Trials per participant: the ordered pairs of three conditions of one stimulus.
TRIALS = 9
BREAK_EVERY = 4


@pytest.fixture
def browser():
    driver = headless_chromium("--window-size=900,760", "--mute-audio")
    yield driver
    driver.quit()


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Server:
    """``prosody study serve`` in its own process."""

    def __init__(self, folder: Path, port: int) -> None:
        self.folder, self.port = folder, port
        self.process: subprocess.Popen | None = None
        self.token = ""

    def start(self) -> Server:
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        self.process = subprocess.Popen(
            [sys.executable, "-m", "prosody", "study", "serve", "plan.csv", "--stimuli", "stimuli", "--db",
             "study.sqlite", "--listen", f"127.0.0.1:{self.port}", "--break-every", str(BREAK_EVERY)],
            cwd=self.folder, env=env, stderr=subprocess.PIPE, text=True)
        assert self.process.stderr is not None
        lines = []
        while not any("organiser's token" in line for line in lines):
            line = self.process.stderr.readline()
            assert line, f"the server stopped: {''.join(lines)}"
            lines.append(line)
        self.token = lines[-1].split("token ", 1)[1].split()[0]
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:  # listening once it answers
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.5).close()
                break
            except OSError:
                time.sleep(0.05)
        return self

    def kill(self) -> None:
        assert self.process is not None
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(10)
        self.process.stderr.close()

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            self.process.wait(10)
            self.process.stderr.close()


def _make_study(folder: Path, conditions: str, *more: str) -> None:
    """A paired plan of one 0.8 s stimulus, ``hello``, in ``conditions``, and its videos (``more``: options of
    study stimuli)."""
    samples, rate = soundfile.read(REPO / "samples" / "arctic_a0009.wav")
    (folder / "recordings").mkdir()
    soundfile.write(folder / "recordings" / "hello.wav", samples[int(0.8 * rate): int(1.6 * rate)], rate)
    assert main(["study", "plan", "--stimuli", "hello", "--conditions", conditions, "--seed", "3",
                 "-o", str(folder / "plan.csv")]) == 0
    assert main(["study", "stimuli", str(folder / "plan.csv"), "--recordings", str(folder / "recordings"),
                 "--width", "160", "-o", str(folder / "stimuli"), *more]) == 0


@pytest.fixture
def study(tmp_path):
    """A paired study of one 0.8 s stimulus in three conditions (9 ordered pairs), its videos made."""
    _make_study(tmp_path, "none,random,speech")
    server = Server(tmp_path, _free_port())
    yield server
    server.stop()


def _wait_for(driver, script: str, timeout_s: float = 30.0):
    return wait_in_page(driver, script, "return JSON.stringify(window.studyState) + ' / status: ' + "
                                        "document.getElementById('status').textContent", timeout_s)


def _answer(driver, answered: int, choice: str) -> None:
    """Answer the trial shown (after ``answered`` answers), passing the break screen if it comes first."""
    _wait_for(driver, f"const s = window.studyState; return s && s.answered === {answered} && "
                      "(s.screen === 'trial' || s.screen === 'pause')")
    if driver.execute_script("return window.studyState.screen") == "pause":
        assert answered % BREAK_EVERY == 0
        driver.find_element("id", "resume").click()
    _wait_for(driver, f"return window.studyState.screen === 'trial' && window.studyState.answered === {answered}")
    assert driver.find_element("id", "count").text == f"Trial {answered + 1} of {TRIALS}"
    # the answers wait until the video has played to its end
    _wait_for(driver, "const b = document.querySelector('#answers button'); return b && !b.disabled")
    driver.find_element("css selector", f"#answers button[data-answer='{choice}']").click()


@pytest.mark.slow
def test_two_participants_a_closed_tab_and_a_killed_server_lose_nothing(study, browser, tmp_path):
    server = study.start()
    url = f"http://127.0.0.1:{server.port}/"
    # participant 1 answers every trial, left each time, and gets a completion code
    browser.get(url)
    _wait_for(browser, "return window.studyState.screen === 'welcome'")
    browser.find_element("id", "start").click()
    # the page draws both heads itself with WebGL, from the stimuli's frames, in step with the videos' clocks
    _wait_for(browser, "const s = window.studyState; return s.screen === 'trial' && s.heads === 2 && s.drawn >= 2")
    assert browser.execute_script("return window.studyState.face") == "head"
    canvases = browser.find_elements("css selector", "#videos canvas")
    assert len(canvases) == 2
    from PIL import Image

    for canvas in canvases:
        image = np.asarray(Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB")).astype(int)
        skin = (np.abs(image - [215, 165, 135]).max(axis=2) < 50).mean()
        assert skin > 0.05  # a face, not an empty canvas
    assert all("sound-only" in video.get_attribute("class")
               for video in browser.find_elements("css selector", "#videos video"))
    for answered in range(TRIALS):
        _answer(browser, answered, "left")
    _wait_for(browser, "return window.studyState.screen === 'thanks'")
    first_code = browser.find_element("id", "code").text
    assert len(first_code) == 8
    first = browser.execute_script("return window.studyState.participant")

    # participant 2, on a browser of their own (a fresh profile: no stored ID)
    browser.execute_script("localStorage.clear()")
    browser.get(url)
    _wait_for(browser, "return window.studyState.screen === 'welcome'")
    browser.find_element("id", "start").click()
    for answered in range(3):
        _answer(browser, answered, "right")
    _wait_for(browser, "return window.studyState.answered === 3")
    second = browser.execute_script("return window.studyState.participant")
    assert second != first
    browser.get("about:blank")  # the tab is closed half-way
    browser.get(url)  # and opened again: the study goes on at trial 4
    _wait_for(browser, "return window.studyState.screen === 'trial' && window.studyState.answered === 3")
    assert browser.execute_script("return window.studyState.participant") == second
    # the server is killed while they watch; their answer waits and is sent when it is back
    _wait_for(browser, "const b = document.querySelector('#answers button'); return b && !b.disabled")
    server.kill()
    browser.find_element("css selector", "#answers button[data-answer='right']").click()
    _wait_for(browser, "return window.studyState.errors > 0")
    assert "not answering" in browser.find_element("id", "status").text
    server.start()
    for answered in range(4, TRIALS):
        _answer(browser, answered, "right")
    _wait_for(browser, "return window.studyState.screen === 'thanks'")
    second_code = browser.find_element("id", "code").text
    assert second_code != first_code

    # the organiser's export: every answer exactly once
    ballots = tmp_path / "ballots.csv"
    assert main(["study", "export", str(tmp_path / "study.sqlite"), "-o", str(ballots)]) == 0
    with ballots.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 * TRIALS
    assert sorted((row["subject"], int(row["order"])) for row in rows) == sorted(
        (subject, order) for subject in (first, second) for order in range(1, TRIALS + 1))
    assert {row["choice"] for row in rows if row["subject"] == first} == {"left"}
    assert {row["choice"] for row in rows if row["subject"] == second} == {"right"}
    # the second participant saw every pair with the sides swapped: each ordered pair once per participant
    pairs = {subject: sorted((row["left"], row["right"]) for row in rows if row["subject"] == subject)
             for subject in (first, second)}
    assert pairs[first] == pairs[second] and len(set(pairs[first])) == TRIALS
    results = tmp_path / "results.json"
    assert main(["study", "analyze", str(ballots), "--plan", str(tmp_path / "plan.csv"), "-o", str(results)]) == 0
    scores = json.loads(results.read_text())["scores"]["hello"]
    # one always chose left, the other always right: each condition is on each side 3 times per participant
    assert scores == {"NO_PROSODY": 6, "RANDOM": 6, "SPEECH_DRIVEN": 6}


@pytest.mark.slow
def test_a_study_of_a_photo_head_draws_it_on_the_ballot(tmp_path, browser):
    """study stimuli --face PHOTO: the videos show the photo's head, the photo is kept beside them, and the
    ballot's WebGL head is made from it (the photo's colours, not the 3D head's)."""
    pytest.importorskip("mediapipe", reason="the face landmarker (pip install 'visual-prosody[track]')")
    from PIL import Image

    from prosody.head.render import HeadRenderer

    plain = HeadRenderer(320, 320).render(np.zeros(68))
    photo = plain.copy()
    photo[:, :, 2] = np.minimum(photo[:, :, 2].astype(int) + 60, 255)  # a blue cast the 3D head has not
    plain_cast = float((plain[..., 2].astype(int) - plain[..., 0]).mean())
    Image.fromarray(photo).save(tmp_path / "me.png")
    _make_study(tmp_path, "none,speech", "--face", str(tmp_path / "me.png"))
    manifest = json.loads((tmp_path / "stimuli" / "stimuli.json").read_text())
    assert manifest["face"]["file"] == "face.png" and (tmp_path / "stimuli" / "face.png").is_file()
    server = Server(tmp_path, _free_port()).start()
    try:
        browser.get(f"http://127.0.0.1:{server.port}/")
        _wait_for(browser, "return window.studyState.screen === 'welcome'")
        browser.find_element("id", "start").click()
        _wait_for(browser, "const s = window.studyState; return s.screen === 'trial' && s.heads === 2 && s.drawn >= 2")
        for canvas in browser.find_elements("css selector", "#videos canvas"):
            image = np.asarray(Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB")).astype(int)
            assert image.shape[0] == image.shape[1]  # the photo's proportions (square here)
            # the photo's blue cast: the head is drawn from its own texture, not the 3D head's colours
            assert (image[..., 2] - image[..., 0]).mean() > plain_cast + 25
    finally:
        server.stop()
