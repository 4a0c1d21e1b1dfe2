"""The README's Python example runs as written, and gives the stream it says."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re

from conftest import REPO


def test_the_readme_example_runs(tmp_path) -> None:
    text = (REPO / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1
    (tmp_path / "samples").symlink_to(REPO / "samples")
    here = os.getcwd()
    printed = io.StringIO()
    try:
        os.chdir(tmp_path)
        with contextlib.redirect_stdout(printed):
            exec(compile(blocks[0], "README.md", "exec"), {})
    finally:
        os.chdir(here)
    first, second = printed.getvalue().splitlines()
    frames, fps = first.split()[:2]
    assert float(fps) == 30 and (tmp_path / "a0009.fap").is_file()
    # the live frames cover the same recording as the offline stream, frame for frame
    count, frame = second.split(" ", 1)
    assert count == frames and json.loads(frame)["frame"] == 40
