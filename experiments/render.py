"""Write ``docs/results.md`` from the records in ``results/`` (``python -m experiments.render``; ``make
evaluate`` runs it last): each experiment's tables as it printed them, with the commit and the data they were
measured on. It also fills the tables the other pages of ``docs/`` quote: a block

    <!-- results: NAME TABLE -->
    ...
    <!-- /results -->

is replaced by table number TABLE (from 1) of experiment NAME's printed report and the line saying where it was
measured, so a page's table is always the one recorded (``tests/test_house.py`` checks it)."""

from __future__ import annotations

import importlib
import json
import re
import sys
from pathlib import Path

from experiments.common import REPO, RESULTS

PAGE = REPO / "docs" / "results.md"


def summary(name: str) -> str:
    """The first paragraph of an experiment's module docstring."""
    try:
        doc = importlib.import_module(f"experiments.{name}").__doc__ or ""
    except ImportError:
        return ""
    return " ".join(doc.strip().split("\n\n")[0].split())


def render() -> str:
    records = [json.loads(path.read_text()) for path in sorted(RESULTS.glob("*.json"))]
    parts = ["# Results as recorded",
             "",
             "Rendered by `python -m experiments.render` from `results/*.json`, which each experiment writes when "
             "it runs (`make evaluate`, or `python -m experiments.NAME`). Every figure here was measured on data "
             "the model was not fitted to; the pages [evaluation.md](evaluation.md), [live.md](live.md) and "
             "[languages.md](languages.md) explain them. The data digest is SHA-256 over the files read.",
             ""]
    if not records:
        parts.append("No experiment has been recorded yet.")
    for entry in records:
        changes = " (with uncommitted changes)" if entry["uncommitted_changes"] else ""
        parts += [f"## {entry['experiment']}", "", summary(entry["experiment"]), "",
                  f"Commit `{entry['commit'][:12]}`{changes}, data `{entry['data_sha256'][:12]}`, "
                  f"{entry['started']}, {entry['seconds']:.0f} s on {entry['machine']}.", "",
                  "```text", entry["report"].rstrip(), "```", ""]
    return "\n".join(parts).rstrip() + "\n"


BLOCK = re.compile(r"(<!-- results: (\w+) (\d+) -->\n)(.*?)(<!-- /results -->)", re.DOTALL)


def tables(report: str) -> list[str]:
    """The markdown tables of a printed report (runs of lines starting with ``|``)."""
    found, current = [], []
    for line in [*report.splitlines(), ""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            found.append("\n".join(current))
            current = []
    return found


def record_of(name: str) -> dict:
    path = RESULTS / f"{name}.json"
    if not path.is_file():
        raise SystemExit(f"{path.relative_to(REPO)}: not recorded; run python -m experiments.{name}")
    return json.loads(path.read_text())


def filled(page: str) -> str:
    """``page`` with every results block holding its recorded table."""
    def table(match: re.Match) -> str:
        name, number = match.group(2), int(match.group(3))
        entry = record_of(name)
        found = tables(entry["report"])
        if not 1 <= number <= len(found):
            raise SystemExit(f"results/{name}.json: table {number} asked for, its report has {len(found)}")
        changes = " with uncommitted changes" if entry["uncommitted_changes"] else ""
        where = (f"*Recorded by `python -m experiments.{name}` at commit `{entry['commit'][:12]}`{changes}, "
                 f"{entry['started'][:10]} ([all of it](results.md#{name})).*")
        return f"{match.group(1)}{found[number - 1]}\n\n{where}\n{match.group(5)}"

    return BLOCK.sub(table, page)


def quoting_pages() -> list[Path]:
    """The pages of ``docs/`` with results blocks."""
    return [path for path in sorted((REPO / "docs").glob("*.md")) if BLOCK.search(path.read_text())]


def main() -> int:
    PAGE.write_text(render())
    print(f"{PAGE.relative_to(REPO)}: {len(list(RESULTS.glob('*.json')))} experiment(s)")
    for path in quoting_pages():
        path.write_text(filled(path.read_text()))
        print(f"{path.relative_to(REPO)}: {len(BLOCK.findall(path.read_text()))} table(s) from results/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
