"""Every Examples section in the two packages runs, and gives what it says."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import audio_features
import prosody

MODULES = sorted(
    info.name
    for package in (audio_features, prosody)
    for info in pkgutil.walk_packages(package.__path__, prefix=package.__name__ + ".")
    if info.name not in {"prosody.cli", "prosody.__main__"}
)


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} example(s) failed in {name}"
