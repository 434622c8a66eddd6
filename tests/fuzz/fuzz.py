"""Run a fuzz campaign on demand and print the table of outcomes and the findings.

    python tests/fuzz/fuzz.py --runs 20000 --seed 7          # a long campaign
    python tests/fuzz/fuzz.py --seed 7 --case 123 --keep /tmp/case   # rebuild and rerun one case

Runs = cases x 3 commands (info, stats summary, compare). Exit 1 when anything is not clean.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import campaign
import runner


def run_campaign(
    seed: int,
    cases: range,
    directory: Path,
    *,
    jobs: int,
    timeout: float,
    subprocess_sample: int,
    full_fixtures: bool = True,
    campaign_size: int | None = None,
) -> tuple[list[campaign.Case], list[runner.Outcome]]:
    """Build the cases, run every command in-process and a sample as real subprocesses.

    ``campaign_size``: the cases of the whole campaign when ``cases`` is one part of it; the
    sample is spread over the whole, so the parts together repeat the runs it would.
    """
    built = campaign.make_cases(seed, cases, directory, full_fixtures=full_fixtures)
    commands = campaign.COMMANDS
    tasks = [runner.Task(f"{c.number} {cmd}", c.argv(cmd)) for c in built for cmd in commands]
    outcomes = runner.run_in_process(tasks, jobs=jobs, timeout=timeout)
    # Place of each task in the whole campaign (case number x commands + command).
    places = [c.number * len(commands) + i for c in built for i in range(len(commands))]
    total = (campaign_size or len(cases)) * len(commands)
    step = max(1, total // subprocess_sample) if subprocess_sample else 0
    for place, task in zip(places, tasks, strict=True) if step else []:
        if place % step == 0:
            outcome = runner.run_subprocess(task, timeout=timeout)
            outcomes.append(dataclasses.replace(outcome, key=outcome.key + " (subprocess)"))
    return built, outcomes


def report(cases: list[campaign.Case], outcomes: list[runner.Outcome]) -> str:
    lines = [campaign.table(cases, outcomes), ""]
    for finding in campaign.findings(cases, outcomes):
        lines.append(
            f"[{finding.category}] x{finding.count} bagkit {finding.command}: {finding.line}"
        )
        lines.append(f"    {finding.recipe}")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=1200, help="runs (3 per case)")
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--case", type=int, help="only this case")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds per run")
    parser.add_argument("--subprocess", type=int, default=30, help="runs repeated as subprocesses")
    parser.add_argument(
        "--small-fixtures", action="store_true", help="the first 120 messages of each fixture"
    )
    parser.add_argument("--keep", type=Path, help="build the cases here and keep them")
    args = parser.parse_args(argv)
    cases = range(args.case, args.case + 1) if args.case is not None else range(args.runs // 3)
    with tempfile.TemporaryDirectory(prefix="bagkit-fuzz-") as tmp:
        directory = args.keep or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        start = time.monotonic()
        built, outcomes = run_campaign(
            args.seed,
            cases,
            directory,
            jobs=args.jobs,
            timeout=args.timeout,
            subprocess_sample=args.subprocess,
            full_fixtures=not args.small_fixtures,
        )
        print(report(built, outcomes))
        for case in built if args.case is not None else []:
            print(f"case {case.number}: {case.recipe}\n  bag: {case.bag}\n  golden: {case.golden}")
        print(
            f"\n{len(outcomes)} runs of {len(built)} cases, seed {args.seed}, "
            f"{time.monotonic() - start:.0f} s"
        )
    return 0 if all(o.category == "clean" for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
