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
