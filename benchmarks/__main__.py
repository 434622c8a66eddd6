"""``make bench``: run every ``benchmarks/bench_*.py`` module's ``main()`` (or the ones named)."""

from __future__ import annotations

import importlib
import pkgutil
import sys

import benchmarks


def main(argv: list[str]) -> int:
    """Run the named benchmarks (all when none is named); return non-zero if a target is missed."""
    names = sorted(
        info.name
        for info in pkgutil.iter_modules(benchmarks.__path__)
        if info.name.startswith("bench_")
    )
    selected = [n for n in names if not argv or n.removeprefix("bench_") in argv or n in argv]
    failed = []
    for name in selected:
        print(f"\n=== {name} ===", flush=True)
        module = importlib.import_module(f"benchmarks.{name}")
        if not module.main():
            failed.append(name)
    if failed:
        print(f"\ntargets missed in: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
