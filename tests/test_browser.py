"""The live page in a real headless Chromium: it connects, draws the frames it is sent, and sends its
microphone (Chromium's fake device playing a WAV file) to the server, whose frames move the face.

Needs Debian's ``chromium`` and ``chromium-driver`` and the ``selenium`` package (in the test extra); skipped
with a reason where they are missing (``apt-get install chromium chromium-driver``).
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
from conftest import REPO, headless_chromium, needs_chromium, wait_in_page

from prosody.jobs.server import FrameServer
from prosody.jobs.stream import LiveConverter, LiveFrame

pytestmark = needs_chromium


@pytest.fixture
def browser():
    driver = headless_chromium("--disable-quic", "--window-size=520,760", "--use-fake-ui-for-media-stream",
                               "--use-fake-device-for-media-stream",
                               f"--use-file-for-fake-audio-capture={REPO / 'samples' / 'arctic_a0009.wav'}")
    yield driver
    driver.quit()


def _wait_for(driver, script: str, timeout_s: float = 30.0):
    return wait_in_page(driver, script, "return JSON.stringify(window.prosodyStats)", timeout_s)


def _face(driver) -> np.ndarray:
    """The canvas's face square as an RGB array, from a screenshot of the page."""
    from PIL import Image

    canvas = driver.find_element("id", "face")
    image = Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB")
    array = np.asarray(image)
    return array[: array.shape[1]]  # the face square, above the strip


def test_page_draws_the_frames_the_server_sends(frame_server, browser, tmp_path):
    browser.get(frame_server.url)
    _wait_for(browser, "return window.prosodyStats && window.prosodyStats.connected")
    still = _face(browser)
    # a head turned 8 degrees to its left and tilted, brows raised
    pose = {31: 30.0, 32: 30.0, 33: 30.0, 34: 30.0, 48: 0.0, 49: 14000.0, 50: 6000.0}
    frame_server.publish([LiveFrame(k, k / 30, pose) for k in range(5)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 5")
    time.sleep(0.3)  # a few animation frames
    moved = _face(browser)
    (tmp_path / "moved.png").write_bytes(browser.find_element("id", "face").screenshot_as_png)
    changed = np.any(np.abs(still.astype(int) - moved.astype(int)) > 30, axis=2)
    assert changed.mean() > 0.01  # the head outline and the features moved
    assert "frame 4" in browser.find_element("id", "status").text


def test_microphone_audio_reaches_the_server_and_moves_the_face(frame_server, browser, tmp_path):
    browser.get(frame_server.url + "?mic=1")
    _wait_for(browser, "return window.prosodyStats.micStarted")
    _wait_for(browser, "return window.prosodyStats.clientFrames >= 45")  # 1.5 s of frames back
    first = _face(browser)
    time.sleep(1.0)
    second = _face(browser)
    (tmp_path / "mic.png").write_bytes(browser.find_element("id", "face").screenshot_as_png)
    assert frame_server.audio_messages > 10
    assert any("is sending audio" in line for line in frame_server.lines)
    stats = browser.execute_script("return window.prosodyStats")
    assert stats["errors"] == []
    assert stats["last"]["source"] == "client"
    assert stats["micNode"] == "AudioWorklet"  # not the deprecated ScriptProcessorNode
    # the speech keeps the head moving: two moments a second apart differ
    assert np.any(np.abs(first.astype(int) - second.astype(int)) > 30, axis=2).mean() > 0.001


def test_page_reconnects_when_the_server_comes_back(browser):
    lines: list[str] = []
    first = FrameServer("127.0.0.1", 0, make_converter=lambda rate: LiveConverter(rate), report=lines.append).start()
    port = first.port
    browser.get(first.url)
    _wait_for(browser, "return window.prosodyStats.connected")
    first.close(drain_s=0.1)
    _wait_for(browser, "return !window.prosodyStats.connected")
    assert browser.execute_script("return window.prosodyStats.ended")
    assert "stream ended" in browser.find_element("id", "status").text
    second = FrameServer("127.0.0.1", port, make_converter=lambda rate: LiveConverter(rate),
                         report=lines.append).start()
    try:
        _wait_for(browser, "return window.prosodyStats.connected", timeout_s=10)
        second.publish([LiveFrame(k, k / 30, {48: 1000.0}) for k in range(3)])
        _wait_for(browser, "return window.prosodyStats.inputFrames >= 3")
    finally:
        second.close(drain_s=0.1)


def test_page_draws_an_open_mouth_apart_from_a_closed_one(frame_server, browser, tmp_path):
    browser.get(frame_server.url)
    _wait_for(browser, "return window.prosodyStats && window.prosodyStats.connected")
    closed = {3: 0.0, 4: 0.0, 5: 0.0, 48: 0.0}
    frame_server.publish([LiveFrame(k, k / 30, closed) for k in range(3)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 3")
    time.sleep(0.3)
    shut = _face(browser)
    opened = {3: 300.0, 4: -75.0, 5: -125.0, 6: -40.0, 7: -40.0, 48: 0.0}  # an open, slightly rounded /o/
    frame_server.publish([LiveFrame(k, k / 30, opened) for k in range(3, 6)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 6")
    time.sleep(0.3)
    open_mouth = _face(browser)
    (tmp_path / "open.png").write_bytes(browser.find_element("id", "face").screenshot_as_png)
    changed = np.any(np.abs(shut.astype(int) - open_mouth.astype(int)) > 30, axis=2)
    rows = np.flatnonzero(changed.any(axis=1))
    assert changed.sum() > 100  # the mouth's inside shows
    size = shut.shape[0]
    assert rows.min() > 0.6 * size and rows.max() < 0.85 * size  # and only the mouth changed
    dark = np.all(open_mouth < [120, 60, 70], axis=2) & changed
    assert dark.sum() > 50  # dark red: the inside of the mouth


def test_expressivity_sliders_change_the_controls_on_the_server(frame_server, browser, tmp_path):
    browser.get(frame_server.url)
    _wait_for(browser, "return window.prosodyStats.expressivity !== undefined")
    browser.find_element("css selector", "#expressivity summary").click()
    names = [element.get_attribute("id") for element in browser.find_elements("css selector", "#sliders input")]
    assert names == ["x-activation", "x-spatial", "x-temporal", "x-fluidity", "x-power", "x-repetition"]
    slider = browser.find_element("id", "x-spatial")
    assert (slider.get_attribute("min"), slider.get_attribute("max"), slider.get_attribute("value")) == ("-1", "1", "0")
    slider.click()  # focus, then keys as a user would: two steps of 0.05 to the left of the middle
    from selenium.webdriver.common.keys import Keys

    slider.send_keys(Keys.ARROW_LEFT, Keys.ARROW_LEFT)
    # the server answers with the controls now in force, which the page keeps
    _wait_for(browser, "return window.prosodyStats.expressivity.spatial === -0.1")
    assert browser.find_element("id", "x-spatial-value").text == "-0.10"
    (tmp_path / "sliders.png").write_bytes(browser.get_screenshot_as_png())
    browser.find_element("xpath", "//button[text()='Still']").click()
    _wait_for(browser, "return window.prosodyStats.expressivity.activation === 0")
    assert browser.execute_script("return window.prosodyStats.expressivity.spatial") == 0
    assert browser.execute_script("return window.prosodyStats.errors") == []


def test_page_closes_the_eyelids_by_fap_19_to_22(frame_server, browser, tmp_path):
    browser.get(frame_server.url)
    _wait_for(browser, "return window.prosodyStats && window.prosodyStats.connected")
    frame_server.publish([LiveFrame(k, k / 30, {48: 0.0}) for k in range(3)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 3")
    time.sleep(0.3)
    opened = _face(browser)
    shut = {19: 600.0, 20: 600.0, 21: 600.0, 22: 600.0, 48: 0.0}  # the lids meet: 2 x 600 > 1024 IRISD
    frame_server.publish([LiveFrame(k, k / 30, shut) for k in range(3, 6)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 6")
    time.sleep(0.3)
    closed = _face(browser)
    (tmp_path / "closed.png").write_bytes(browser.find_element("id", "face").screenshot_as_png)
    size = opened.shape[1]
    scale, cx, cy = 0.30 * size, size / 2, 0.47 * size  # the page's drawing geometry
    for sign in (1, -1):  # both pupils: dark when open, skin when shut
        u, v = int(cx + scale * sign * 0.30), int(cy - scale * 0.09)
        assert opened[v, u].max() < 100
        assert np.abs(closed[v + 3, u].astype(int) - [236, 200, 170]).max() < 30
    changed = np.any(np.abs(opened.astype(int) - closed.astype(int)) > 30, axis=2)
    rows = np.flatnonzero(changed.any(axis=1))
    assert rows.min() > cy - scale * 0.21 and rows.max() < cy + 1  # only the eyes (y 0 to 0.2) changed


def test_the_input_sound_plays_and_the_face_moves_in_step_with_it(frame_server, browser):
    browser.get(frame_server.url)
    _wait_for(browser, "return window.prosodyStats && window.prosodyStats.connected")
    browser.find_element("id", "sound").click()
    time.sleep(0.5)  # the page asks the server for the sound
    rate, seconds = 16000, 2.0
    t = np.arange(int(rate * seconds)) / rate
    tone = 0.3 * np.sin(2 * np.pi * 220 * t)
    for k in range(20):  # the sound and its frames arrive together, faster than they play
        frame_server.publish_audio(tone[k * 1600:(k + 1) * 1600], rate)
        frame_server.publish([LiveFrame(j, j / 30, {49: 1000.0 * j}) for j in range(3 * k, 3 * k + 3)])
    _wait_for(browser, "return window.prosodyStats.inputFrames >= 60 && window.prosodyStats.soundPieces >= 19")
    samples = []
    for _ in range(8):  # while the sound plays, the face shows the frame of what is heard
        shown, heard = browser.execute_script(
            "return [window.prosodyStats.shownFrame, window.prosodySoundTime()]")
        samples.append((shown, heard))
        time.sleep(0.15)
    stats = browser.execute_script("return window.prosodyStats")
    assert stats["errors"] == []
    during = [(shown, heard) for shown, heard in samples if heard is not None and 0.1 < heard < 1.9]
    assert len(during) >= 4, samples
    for shown, heard in during:
        assert shown is not None and abs(shown / 30 - heard) < 0.1, samples  # in step, not all at once
    _wait_for(browser, "return window.prosodyStats.shownFrame === 59", 10)
