"""The .glb as other programs show it: drawn by three.js (npm ``three``, GLTFLoader) in headless Chromium beside
the CPU preview at the same moments, and checked by the Khronos validator (npm ``gltf-validator``).

Needs Debian's ``chromium`` and ``chromium-driver``, the ``selenium`` package (the test extra) and ``npm``,
which installs the two npm packages into ``out/npm`` the first time (about 30 MB); skipped with a reason where
any is missing.
"""

from __future__ import annotations

import functools
import http.server
import io
import json
import math
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, headless_chromium, needs_chromium, wait_in_page

from prosody.fap.stream import FapStream
from prosody.fap.table import RADIANS_PER_AU
from prosody.head.gltf import glb_document, write_glb
from prosody.head.render import HeadRenderer

pytestmark = [needs_chromium, pytest.mark.slow]

NPM_FOLDER = REPO / "out" / "npm"
PACKAGES = ("three@0.187.0", "gltf-validator@2.0.0-dev.3.10")
SIZE = 480


@pytest.fixture(scope="module")
def npm_packages() -> Path:
    npm = shutil.which("npm")
    if npm is None:
        pytest.skip("needs npm (apt-get install npm) to install three and gltf-validator")
    if not all((NPM_FOLDER / "node_modules" / name.rsplit("@", 1)[0]).is_dir() for name in PACKAGES):
        NPM_FOLDER.mkdir(parents=True, exist_ok=True)
        done = subprocess.run([npm, "install", "--prefix", str(NPM_FOLDER), "--no-audit", "--no-fund", "--silent",
                               *PACKAGES], capture_output=True, text=True, timeout=600)
        if done.returncode != 0:
            pytest.skip(f"npm could not install {', '.join(PACKAGES)}: {done.stderr.strip()[-300:]}")
    return NPM_FOLDER / "node_modules"


@pytest.fixture(scope="module")
def site(npm_packages, tmp_path_factory):
    """A loopback web server over a folder holding the page, three.js and the .glb files."""
    root = tmp_path_factory.mktemp("site")
    shutil.copy(Path(__file__).with_name("threejs") / "view.html", root / "view.html")
    (root / "three").symlink_to(npm_packages / "three", target_is_directory=True)
    handler = functools.partial(_QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield root, f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def browser():
    driver = headless_chromium("--window-size=800,800", "--use-angle=swiftshader", "--ignore-gpu-blocklist")
    yield driver
    driver.quit()


def _validate(npm_packages: Path, path: Path) -> dict:
    script = ("const v = require(process.argv[1]); const fs = require('fs');"
              "v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2])))"
              ".then(r => console.log(JSON.stringify(r.issues)))")
    done = subprocess.run(["node", "-e", script, str(npm_packages / "gltf-validator"), str(path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def _three(browser, site, name: str, time_s: float) -> np.ndarray:
    from PIL import Image

    root, url = site
    browser.get(f"{url}/view.html?file={name}&time={time_s}&size={SIZE}")
    wait_in_page(browser, "return window.drawn || window.failed", "return String(window.failed)")
    assert browser.execute_script("return window.failed || null") is None
    canvas = browser.find_element("tag name", "canvas")
    return np.asarray(Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB"))[:SIZE, :SIZE]


def _stream() -> FapStream:
    """Still for 1 s, then the jaw open, the brows raised and the lids half closed."""
    n = 50
    ramp = np.clip((np.arange(n) - 25) / 5, 0, 1)
    return FapStream.from_curves({3: 700 * ramp, 31: 200 * ramp, 32: 200 * ramp, 19: -100 * ramp,
                                  20: -100 * ramp, 4: -150 * ramp}, fps=25, name="three")


def _at(values: np.ndarray, point: np.ndarray, radius: int = 3) -> np.ndarray:
    x, y = int(round(point[0])), int(round(point[1]))
    return values[y - radius:y + radius + 1, x - radius:x + radius + 1].reshape(-1, 3).astype(float)


def test_threejs_shows_the_head_as_the_cpu_preview_does(npm_packages, site, browser, tmp_path: Path) -> None:
    """Eyes with a dark pupil (not blank white), a dark open mouth (not a light gap), skin of the preview's
    colour (linear vertex colours), brows raised: the same moments drawn by three.js and by the CPU renderer."""
    stream = _stream()
    write_glb(stream, site[0] / "head.glb")
    issues = _validate(npm_packages, site[0] / "head.glb")
    assert (issues["numErrors"], issues["numWarnings"]) == (0, 0), issues["messages"][:5]
    cpu = HeadRenderer(SIZE, SIZE)
    rig = cpu.rig
    for time_s in (0.0, 1.9):
        frame = round(time_s * stream.fps)
        values = np.where(stream.mask[frame], stream.values[frame], 0.0)
        expected = cpu.render(values)
        shown = _three(browser, site, "head.glb", time_s)
        from PIL import Image

        Image.fromarray(np.hstack([expected, shown])).save(tmp_path / f"three_{time_s:g}.png")
        screen = cpu.project(rig.deform(values))
        mesh = rig.mesh
        pupils = [mesh.eye_centres[k] + np.array([0, 0, 1.2]) for k in range(2)]
        for pupil in cpu.project(np.asarray(pupils, float)):
            assert _at(shown, pupil, 1).mean() < 90, "three.js shows no dark pupil"
            assert _at(expected, pupil, 1).mean() < 90
        cheek = screen[mesh.feature_points["5.3"]]
        skin_three, skin_cpu = _at(shown, cheek, 4).mean(axis=0), _at(expected, cheek, 4).mean(axis=0)
        assert np.abs(skin_three - skin_cpu).max() < 30, (skin_three, skin_cpu)
        # the skin's hue: red over blue as the preview's (pale grey skin fails)
        assert (skin_three[0] - skin_three[2]) > 0.6 * (skin_cpu[0] - skin_cpu[2])
        mouth = (screen[mesh.feature_points["2.2"]] + screen[mesh.feature_points["2.3"]]) / 2
        if time_s > 1:
            assert _at(shown, mouth, 2).mean() < 110, "the open mouth shows a light gap"
            assert _at(expected, mouth, 2).mean() < 110


def test_blender_keeps_the_lips_weights_in_range(tmp_path: Path) -> None:
    """Every keyed morph weight lies in 0..1 (Blender's importer cuts what is below 0): a lip FAP that goes
    negative keys its NAME- target; the pair together gives back the value."""
    stream = _stream()
    document, binary = glb_document(stream)
    names = document["meshes"][0]["extras"]["targetNames"]
    units = document["meshes"][0]["extras"]["targetUnits"]
    sampler = document["animations"][0]["samplers"][0]
    accessor = document["accessors"][sampler["output"]]
    view = document["bufferViews"][accessor["bufferView"]]
    weights = np.frombuffer(binary, np.float32, accessor["count"], view["byteOffset"]).reshape(-1, len(names))
    assert weights.min() >= 0.0 and weights.max() <= 1.0
    up, down = names.index("lower_t_midlip+"), names.index("lower_t_midlip-")
    value = (weights[:, up] * units[up] - weights[:, down] * units[down])
    assert value == pytest.approx(np.where(stream.mask[:, 3], stream.values[:, 3], 0.0), abs=0.01)
    assert "open_jaw+" in names and "open_jaw-" not in names  # one-way and never negative here


def test_threejs_shows_a_photo_head_as_the_photo(npm_packages, site, browser, tmp_path: Path) -> None:
    """A photo head's .glb: the photo as the base-colour texture with TEXCOORD_0, the person and the
    background behind; at rest three.js shows the photo."""
    pytest.importorskip("mediapipe", reason="the face landmarker (pip install 'visual-prosody[track]')")
    from skimage.metrics import structural_similarity

    from prosody.head.photo import photo_head

    photo = HeadRenderer(SIZE, SIZE).render(np.zeros(68))
    head = photo_head(photo, name="canonical.png")
    stream = FapStream.from_curves({49: np.linspace(0, math.radians(12) / RADIANS_PER_AU, 25)}, fps=25)
    write_glb(stream, site[0] / "photo.glb", photo=head)
    issues = _validate(npm_packages, site[0] / "photo.glb")
    assert (issues["numErrors"], issues["numWarnings"]) == (0, 0), issues["messages"][:5]
    rest = _three(browser, site, "photo.glb", 0.0)
    turned = _three(browser, site, "photo.glb", 0.96)
    from PIL import Image

    Image.fromarray(np.hstack([photo, rest, turned])).save(tmp_path / "photo_three.png")
    grey = np.array([0.299, 0.587, 0.114])
    assert structural_similarity(rest @ grey, photo @ grey, data_range=255.0) >= 0.8
    # round the closed mouth the skin is the photo's: no dark speck of the mouth's inside comes through it
    # (specks 25-38 grey levels darker did before the inside was set back, under 17 since; the lips' own dark
    # line is left out, 2 pixels either side)
    lips = head.uv[list(range(468))][[61, 291, 0, 17]]
    left, right = int(lips[0, 0]) - 12, int(lips[1, 0]) + 12
    top, bottom = int(lips[2, 1]) - 10, int(lips[3, 1]) + 15
    line = int(round((head.uv[13, 1] + head.uv[14, 1]) / 2))
    around = np.ones((bottom - top, right - left), bool)
    around[line - top - 2:line - top + 3, :] = False
    darker = (photo[top:bottom, left:right] @ grey) - (rest[top:bottom, left:right] @ grey)
    assert int((darker[around] > 25).sum()) == 0
    # the turned head moves the nose tip to the viewer's right
    assert np.abs(turned.astype(float) - rest).mean() > 1.0
