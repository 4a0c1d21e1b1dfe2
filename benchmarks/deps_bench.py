"""Dependencies sized to the job (part of ``make bench``): what each install brings, and what each command imports.

1. **Install size**: for the base install and each extra, the distributions its requirements pull in (the
   closure of ``Requires-Dist`` over what is installed here) and their size on disk, from each distribution's
   RECORD. The base is what ``pip install visual-prosody`` (and ``make demo``) installs.
2. **Import time per command**: each command run on the sample in a fresh interpreter with ``-X importtime``;
   the time its imports took (the sum of the top-level imports' cumulative times, the median of three runs)
   and the installed distributions it loaded, so a command that pays for what it does not use shows.

Numbers are of this machine and this environment (which has every extra installed, for the tests).
"""

from __future__ import annotations

import importlib.metadata as metadata
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "samples" / "arctic_a0009.wav"
PROJECT = "visual-prosody"
RUNS = 3


def _name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[(]", requirement.strip(), maxsplit=1)[0].lower().replace("_", "-")


def _extras_of(requirement: str) -> list[str]:
    found = re.search(r"\[([^\]]+)\]", requirement.split(";")[0])
    return [extra.strip() for extra in found.group(1).split(",")] if found else []


def closure(extras: tuple[str, ...] = ()) -> set[str]:
    """Names of the installed distributions that the project with ``extras`` pulls in (itself left out)."""
    wanted: list[tuple[str, tuple[str, ...]]] = [(PROJECT, extras)]
    seen: set[str] = set()
    while wanted:
        name, chosen = wanted.pop()
        try:
            requirements = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        for requirement in requirements:
            marker = requirement.split(";", 1)[1] if ";" in requirement else ""
            extra = re.search(r"extra\s*==\s*['\"]([^'\"]+)['\"]", marker)
            if extra and extra.group(1) not in chosen:
                continue
            if not extra and marker and not _marker_holds(marker):
                continue
            dependency = _name(requirement)
            key = (dependency, tuple(_extras_of(requirement)))
            if dependency == PROJECT:
                wanted.append((PROJECT, key[1]))
                continue
            if dependency not in seen or key[1]:
                seen.add(dependency)
                wanted.append(key)
    return seen


def _marker_holds(marker: str) -> bool:
    from packaging.markers import Marker

    try:
        return Marker(marker).evaluate()
    except Exception:  # noqa: BLE001 - an unreadable marker is counted in
        return True


def installed_mb(names: set[str]) -> float:
    total = 0
    for name in names:
        try:
            files = metadata.distribution(name).files or []
        except metadata.PackageNotFoundError:
            continue
        for file in files:
            path = Path(file.locate())
            if path.is_file():
                total += path.stat().st_size
    return total / 1e6


def import_profile(argv: list[str]) -> tuple[float, set[str]]:
    """(seconds of imports, top-level third-party packages imported) of ``prosody ARGV``."""
    code = ("import sys; from prosody.cli import main; code = main(sys.argv[1:]); "
            "print('MODULES', ' '.join(sorted({m.split('.')[0] for m in sys.modules})), file=sys.stderr); "
            "sys.exit(code)")
    result = subprocess.run([sys.executable, "-X", "importtime", "-c", code, *argv], capture_output=True, text=True,
                            cwd=REPO, timeout=600)
    if result.returncode != 0:
        raise SystemExit(f"prosody {' '.join(argv)} failed:\n{result.stderr[-2000:]}")
    total_us = 0
    for line in result.stderr.splitlines():
        found = re.match(r"import time:\s+\d+ \|\s+(\d+) \| (\S.*)$", line)
        if found and not found.group(2).startswith(" "):  # a top-level import: its cumulative time
            total_us += int(found.group(1))
    modules = next(line for line in result.stderr.splitlines() if line.startswith("MODULES")).split()[1:]
    return total_us / 1e6, set(modules)


def commands(folder: Path) -> dict[str, list[str]]:
    out = str(folder)
    return {
        "features": ["features", str(SAMPLE), "-o", f"{out}/f.csv"],
        "convert": ["convert", str(SAMPLE), "-o", f"{out}/c.fap"],
        "convert --lips acoustic": ["convert", str(SAMPLE), "-o", f"{out}/a.fap", "--lips", "acoustic"],
        "inspect": ["inspect", f"{out}/c.fap"],
        "preview (GIF, 1 s)": ["preview", f"{out}/c.fap", "-o", f"{out}/p.gif", "--duration", "1"],
        "stream": ["stream", str(SAMPLE), "-o", f"{out}/s.fap"],
        "convert -o .glb": ["convert", str(SAMPLE), "-o", f"{out}/g.glb", "--lips", "none"],
    }


def module_owners() -> dict[str, set[str]]:
    """Top-level module name -> the installed distributions that hold it (extension modules included)."""
    owners: dict[str, set[str]] = {}
    for distribution in metadata.distributions():
        for file in distribution.files or []:
            top = file.parts[0]
            if top.endswith((".dist-info", ".data")) or top == "..":
                continue
            owners.setdefault(top.split(".")[0], set()).add(distribution.metadata["Name"])
    return owners


def main() -> None:
    owner = module_owners()
    print("Install size (distributions each install pulls in, measured on this machine's environment)")
    base = closure()
    print(f"  {'base (pip install visual-prosody, make demo)':48s} {len(base):3d} distributions "
          f"{installed_mb(base):8.0f} MB")
    extras = sorted({extra for requirement in (metadata.requires(PROJECT) or [])
                     for extra in re.findall(r"extra\s*==\s*['\"]([^'\"]+)['\"]", requirement)})
    for extra in extras:
        more = closure((extra,)) - base
        print(f"  {'+ [' + extra + ']':48s} {len(more):3d} more          {installed_mb(more):8.0f} MB")
    heavy = sorted(((installed_mb({name}), name) for name in base), reverse=True)[:6]
    print("  largest in the base: " + ", ".join(f"{name} {size:.0f} MB" for size, name in heavy))
    print()
    print(f"Import time per command (median of {RUNS} fresh runs) and the distributions it loads")
    with tempfile.TemporaryDirectory() as folder:
        for label, argv in commands(Path(folder)).items():
            seconds, modules = [], set()
            for _ in range(RUNS):
                taken, modules = import_profile(argv)
                seconds.append(taken)
            loaded = sorted({dist for module in modules for dist in owner.get(module, [])} - {PROJECT})
            print(f"  {label:26s} {statistics.median(seconds):5.2f} s  {', '.join(loaded)}")


if __name__ == "__main__":
    main()
