"""The package's layers: every import points down (or within its own layer), and the check can fail."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from conftest import REPO

#: The layers, lowest first: a module may import its own layer and the ones before it.
#: Inside ``prosody.motion``, its rooms: the shared pieces first (brows, expressivity, noise, recorded motion, model
#: files), then the face, then the head models, then what joins them (the settings groups, the conditions).
LAYERS = ("prosody", "prosody.errors", "prosody.validate", "prosody.net", "prosody.dsp", "prosody.fap",
          "prosody.head", "prosody.outputs", "prosody.measures", "prosody.motion", "prosody.motion.face",
          "prosody.motion.heads", "prosody.motion.settings", "prosody.motion.conditions", "prosody.tracking",
          "prosody.evaluation", "prosody.jobs", "prosody.live", "prosody.study", "prosody.cli", "prosody.__main__")


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imported_modules(source: str, module: str, *, is_package: bool) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in ``source``, relative ones resolved against ``module``."""
    package = module if is_package else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target))
            # `from . import x` and `from .fap import stream` may name modules too
            found += [(node.lineno, f"{target}.{alias.name}") for alias in node.names]
    return found


def layer_of(module: str) -> int | None:
    """Index in LAYERS of the deepest layer containing ``module``; None outside the package."""
    best = None
    for index, prefix in enumerate(LAYERS):
        if module == prefix or module.startswith(prefix + "."):
            if best is None or len(prefix) > len(LAYERS[best]):
                best = index
    return best


def upward_imports(root: Path, package: str = "prosody") -> list[str]:
    problems = []
    for path in sorted((root / package).rglob("*.py")):
        module = module_name(path, root)
        own = layer_of(module)
        assert own is not None, f"{module} is in no layer: add it to LAYERS"
        for line, target in imported_modules(path.read_text(), module, is_package=path.name == "__init__.py"):
            theirs = layer_of(target)
            if target.split(".")[0] == package and theirs is not None and theirs > own:
                problems.append(f"{path.relative_to(root)}:{line}: {module} ({LAYERS[own]}) imports {target} "
                                f"({LAYERS[theirs]})")
    return problems


def test_imports_point_down_only() -> None:
    assert upward_imports(REPO) == []


def test_audio_features_never_imports_prosody() -> None:
    for path in (REPO / "audio_features").rglob("*.py"):
        module = module_name(path, REPO)
        for line, target in imported_modules(path.read_text(), module, is_package=path.name == "__init__.py"):
            assert target.split(".")[0] != "prosody", f"{path}:{line} imports {target}"


@pytest.mark.parametrize("statement", [
    "from ..evaluation.compare import compare",  # relative, one level up
    "from ..evaluation import compare",  # a module named in the import list
    "from prosody.jobs.batch import run_batch",  # absolute
    "import prosody.cli",
])
def test_the_check_catches_an_upward_import(tmp_path, statement) -> None:
    for package in ("prosody", "prosody/motion", "prosody/evaluation", "prosody/jobs"):
        (tmp_path / package).mkdir(parents=True, exist_ok=True)
        (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / "prosody" / "cli.py").write_text("")
    (tmp_path / "prosody" / "motion" / "rule.py").write_text(f"def f():\n    {statement}\n")
    problems = upward_imports(tmp_path)
    assert len(problems) >= 1 and "prosody.motion.rule" in problems[0]


def test_the_public_facade_imports_lazily() -> None:
    import subprocess
    import sys

    code = ("import sys, prosody; before = 'prosody.jobs.pipeline' in sys.modules; "
            "from prosody import convert, compare, LiveConverter, read_fap, write_stream, FapStream; "
            "print(before, convert.__module__, LiveConverter.__module__, read_fap.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "prosody.jobs.pipeline", "prosody.live.converter", "prosody.fap.fapfile"]
    import prosody

    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        prosody.nothing  # noqa: B018
