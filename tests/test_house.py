"""The house's rules, each a check that can fail: functions small enough to read, modules small enough to
navigate, no global state switched by a library call, and documentation a newcomer can find their way in."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from conftest import REPO
from radon.complexity import cc_visit

MAX_COMPLEXITY = 25
MAX_FUNCTION_LINES = 120
MAX_MODULE_LINES = 900
MAX_README_LINES = 300
PACKAGES = ("audio_features", "prosody")


def sources(root: Path = REPO) -> list[Path]:
    return sorted(path for package in PACKAGES for path in (root / package).rglob("*.py"))


def too_complex(path: Path) -> list[str]:
    """Functions, methods and classes of ``path`` whose cyclomatic complexity is too high, as radon counts it
    (McCabe's count, plus each boolean operator: stricter than ruff's C901)."""
    blocks = cc_visit(path.read_text())
    blocks += [method for block in blocks for method in getattr(block, "methods", [])]
    return [f"{path.name}:{block.lineno} {block.name} {block.complexity}"
            for block in blocks if block.complexity > MAX_COMPLEXITY]


def too_long(path: Path) -> list[str]:
    """Functions of ``path`` longer than the limit, docstring included."""
    return [f"{path.name}:{node.lineno} {node.name} {node.end_lineno - node.lineno + 1} lines"
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]


def test_no_function_is_too_complex() -> None:
    assert [problem for path in sources() for problem in too_complex(path)] == []


def test_no_function_is_too_long() -> None:
    assert [problem for path in sources() for problem in too_long(path)] == []


def test_no_module_is_too_long() -> None:
    assert [f"{path.relative_to(REPO)}: {n} lines" for path in sources()
            if (n := path.read_text().count("\n")) > MAX_MODULE_LINES] == []


def test_the_checks_can_fail(tmp_path) -> None:
    branches = "\n".join(f"    if x == {k}:\n        x += {k}" for k in range(30))
    (tmp_path / "tangled.py").write_text(f"def tangled(x):\n{branches}\n    return x\n")
    assert too_complex(tmp_path / "tangled.py") and too_long(tmp_path / "tangled.py") == []
    (tmp_path / "long.py").write_text("def long():\n" + "    x = 1\n" * 130)
    assert too_long(tmp_path / "long.py") and too_complex(tmp_path / "long.py") == []


def test_no_library_call_switches_matplotlibs_backend() -> None:
    offenders = [str(path.relative_to(REPO)) for path in sources()
                 if re.search(r"matplotlib\.use\(|pyplot\.switch_backend\(", path.read_text())]
    assert offenders == []


def test_the_readme_is_a_page_with_the_two_commands_first() -> None:
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= MAX_README_LINES
    first = "\n".join(lines[:60])
    assert "make demo" in first and "make test" in first


def test_the_docs_are_linked_and_their_links_resolve() -> None:
    pages = sorted((REPO / "docs").glob("*.md"))
    assert len(pages) >= 5 and (REPO / "CHANGELOG.md").is_file()
    broken = []
    for page in [REPO / "README.md", REPO / "CHANGELOG.md", *pages]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if not re.match(r"[a-z]+:", target) and not (page.parent / target).exists():
                broken.append(f"{page.name} -> {target}")
    assert broken == []
    readme = (REPO / "README.md").read_text()
    assert [page.name for page in pages if page.name not in ("index.md", "api.md")
            and f"docs/{page.name}" not in readme] == []


@pytest.mark.parametrize("anchor_page", ["cli.md", "evaluation.md"])
def test_anchors_into_the_docs_exist(anchor_page: str) -> None:
    """Links of the form page.md#anchor name a heading of that page (GitHub's anchors)."""
    def anchors(text: str) -> set[str]:
        return {re.sub(r"[^\w\- ]", "", heading.lower()).strip().replace(" ", "-")
                for heading in re.findall(r"^#+ (.+)$", text, re.M)}

    target = anchors((REPO / "docs" / anchor_page).read_text())
    for page in [REPO / "README.md", *(REPO / "docs").glob("*.md")]:
        for anchor in re.findall(rf"\]\((?:docs/)?{re.escape(anchor_page)}#([^)]+)\)", page.read_text()):
            assert anchor in target, f"{page.name}: {anchor_page}#{anchor}"


def test_the_docs_tables_are_the_recorded_ones() -> None:
    """Every ``<!-- results: NAME TABLE -->`` block of docs/ holds that table of ``results/NAME.json`` as
    ``python -m experiments.render`` fills it: no quoted figure drifts from its record."""
    from experiments.render import BLOCK, filled, quoting_pages

    pages = quoting_pages()
    assert pages, "no page quotes a recorded table"
    for path in pages:
        text = path.read_text()
        assert text == filled(text), (f"{path.name}: a results block differs from results/; run python -m "
                                      "experiments.render")
    stale = filled("<!-- results: head_loco 1 -->\n| a | b |\n<!-- /results -->")
    assert "| a | b |" not in stale and BLOCK.search(stale)  # the check can fail


ERROR_CLASSES = ("ConfigError", "ParameterError", "MissingExtraError", "ParameterNote", "BaseResampledWarning")


def unnamed_parameters(source: str, parameters: set[str]) -> list[tuple[int, list[str]]]:
    """The library's errors (and parameter notes) in ``source`` whose literal message names one of
    ``parameters`` (as ``name=`` or, with an underscore, as a word) without carrying it as data
    (``parameter=``): a command line could not say those by its options."""
    missing = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Call) and node.args
                and ast.unparse(node.func).split(".")[-1] in ERROR_CLASSES):
            continue
        carried = next((k.value for k in node.keywords if k.arg == "parameter"), None)
        said = set() if carried is None else {c.value for c in ast.walk(carried) if isinstance(c, ast.Constant)}
        text = ast.unparse(node.args[0])
        named = [m.group(1) for m in re.finditer(r"(?<![\w.{])([a-z][a-z0-9_]*)(=|\b)", text)
                 if m.group(1) in parameters and (m.group(2) == "=" or "_" in m.group(1))]
        if [name for name in named if name not in said] and not (carried is not None and not said):
            missing.append((node.lineno, sorted(set(named) - said)))
    return missing


def test_library_errors_carry_the_parameters_they_name() -> None:
    """A library error that names a parameter the command line has an option for carries that name as data,
    so the command says the option (``prosody.cli.messages.said``) without reading the message for names."""
    import argparse

    from prosody.cli.app import build_parser
    from prosody.cli.messages import flag_names

    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    options = {name for command in commands.values() for name in flag_names(command)} - {"help", "quiet", "messages"}
    found = {f"{path.relative_to(REPO)}:{line}": names
             for package in ("prosody", "audio_features") for path in sorted((REPO / package).rglob("*.py"))
             if "cli" not in path.parts for line, names in unnamed_parameters(path.read_text(), options)}
    assert found == {}
    said = 'raise ConfigError(f"f0_floor_hz={x} is low; lips=none", parameter="lips")'
    assert unnamed_parameters(said, {"f0_floor_hz", "lips"}) == [(1, ["f0_floor_hz"])]  # the check can fail
    assert unnamed_parameters('raise ConfigError(f"{name} must be > 0", parameter=name)', {"name"}) == []
