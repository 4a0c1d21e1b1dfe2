"""Write ``docs/results.md`` from the records in ``results/`` (``python -m experiments.render``; ``make
evaluate`` runs it last): each experiment's tables as it printed them, with the commit and the data they were
measured on."""

from __future__ import annotations

import importlib
import json
import sys

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


def main() -> int:
    PAGE.write_text(render())
    print(f"{PAGE.relative_to(REPO)}: {len(list(RESULTS.glob('*.json')))} experiment(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
