"""Write the person segmentation model, ``prosody/head/data/selfie_segmentation.tflite``, from MediaPipe's wheel.

A photo head tells the person from the background with MediaPipe's selfie segmentation model (Apache-2.0,
250 KB). MediaPipe's newer wheels no longer carry it; the PyPI wheel of ``mediapipe`` 0.10.14 does, as
``mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite``. This script downloads that wheel with pip
(``--no-deps``: nothing is installed; any platform's wheel carries the same file), takes the one file out, checks
its SHA-256 and writes it where the package reads it. The notice beside it says where it comes from.

``python -m scripts.segmentation_model [WHEEL] [--check]``: ``--check`` compares the shipped file with the
wheel's instead of writing it (exit 1 when they differ).
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from prosody.head.person import SEGMENTATION_MODEL, SEGMENTATION_SHA256

WHEEL_REQUIREMENT = "mediapipe==0.10.14"
MEMBER = "mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite"


def download_wheel(folder: Path) -> Path:
    """The mediapipe 0.10.14 wheel for Linux x86-64 and CPython 3.11, downloaded by pip into ``folder``."""
    command = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--platform",
               "manylinux2014_x86_64", "--python-version", "3.11", "-d", str(folder), WHEEL_REQUIREMENT]
    subprocess.run(command, check=True)
    wheels = sorted(folder.glob("mediapipe-0.10.14-*.whl"))
    if not wheels:
        sys.exit(f"pip downloaded no wheel of {WHEEL_REQUIREMENT} into {folder}")
    return wheels[0]


def model_bytes(wheel: Path) -> bytes:
    """The model file inside ``wheel``, checked against its SHA-256."""
    with zipfile.ZipFile(wheel) as archive:
        data = archive.read(MEMBER)
    digest = hashlib.sha256(data).hexdigest()
    if digest != SEGMENTATION_SHA256:
        sys.exit(f"{MEMBER} in {wheel.name} has SHA-256 {digest}, expected {SEGMENTATION_SHA256}")
    return data


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("wheel", nargs="?", type=Path, help="a mediapipe 0.10.14 wheel (default: downloaded)")
    parser.add_argument("--check", action="store_true", help="compare the shipped file with the wheel's")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        data = model_bytes(args.wheel or download_wheel(Path(folder)))
    if args.check:
        same = SEGMENTATION_MODEL.is_file() and SEGMENTATION_MODEL.read_bytes() == data
        print(f"{SEGMENTATION_MODEL}: {'the same as the wheel' if same else 'differs from the wheel'}")
        return 0 if same else 1
    partial = SEGMENTATION_MODEL.with_suffix(".partial")
    partial.write_bytes(data)
    partial.replace(SEGMENTATION_MODEL)
    print(f"wrote {SEGMENTATION_MODEL} ({len(data)} bytes, SHA-256 {SEGMENTATION_SHA256})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
