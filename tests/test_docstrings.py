"""Every Examples section in the two packages runs, and gives what it says."""

from __future__ import annotations

import doctest
import importlib
import importlib.util
import pkgutil
from pathlib import Path

import pytest

import audio_features
import prosody


def _has_examples(name: str) -> bool:
    spec = importlib.util.find_spec(name)
    return spec is not None and spec.origin is not None and ">>> " in Path(spec.origin).read_text()


#: The modules whose docstrings hold examples (read as text: nothing is imported to find them).
MODULES = sorted(
    info.name
    for package in (audio_features, prosody)
    for info in pkgutil.walk_packages(package.__path__, prefix=package.__name__ + ".")
    if info.name not in {"prosody.cli", "prosody.__main__"} and _has_examples(info.name)
)


def test_the_modules_with_examples_are_found() -> None:
    assert len(MODULES) >= 20 and "prosody.motion.settings" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.attempted > 0, f"{name} has '>>> ' in its source but no example doctest runs"
    assert result.failed == 0, f"{result.failed} example(s) failed in {name}"
