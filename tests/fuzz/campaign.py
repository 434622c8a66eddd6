"""A fuzz campaign: cases made deterministically from (seed, case number), each run through
``bagkit info``, ``stats summary`` and ``compare``; outcomes tallied and findings grouped."""

from __future__ import annotations

import random
import re
import shutil
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import mutate_db3
import mutate_mcap
import mutate_schema
import mutate_yaml
import runner
from seeds import Seed, build_seeds

# How often each family of mutation is drawn.
FAMILIES = {"mcap": 46, "yaml": 18, "db3": 16, "schema": 10, "payload": 8, "bomb": 2}
COMMANDS = ("info", "stats", "compare")


@dataclass(frozen=True, slots=True)
class Case:
    """One fuzzed input: ``bag`` to read, ``golden`` the pristine bag it is compared with."""

    number: int
    family: str
    recipe: str
    bag: Path
    golden: Path

    def argv(self, command: str) -> list[str]:
        if command == "info":
            return ["info", str(self.bag)]
        if command == "stats":
            return ["stats", "summary", str(self.bag)]
        return ["compare", str(self.golden), str(self.bag)]


def _copy_seed(seed: Seed, target: Path) -> Path:
    if seed.path.is_file():
        shutil.copyfile(seed.path, target / seed.path.name)
        return target / seed.path.name
    shutil.copytree(seed.path, target / "bag")
    return target / "bag"


def _pick(rng: random.Random, seeds: list[Seed]) -> Seed:
    return rng.choices(seeds, weights=[s.weight for s in seeds])[0]


def make_case(run_seed: int, number: int, seeds: list[Seed], directory: Path) -> Case:
    """Build case ``number`` of the campaign ``run_seed`` under ``directory`` (reproducible)."""
    rng = random.Random(f"{run_seed}:{number}")
    family = rng.choices(list(FAMILIES), weights=list(FAMILIES.values()))[0]
    target = directory / f"case{number}"
    target.mkdir()
    if family in ("schema", "payload", "bomb"):
        return _written_case(rng, number, family, target, seeds)
    if family == "db3":
        pool = [s for s in seeds if s.storage == "db3"]
    elif family == "yaml":
        pool = [s for s in seeds if s.path.is_dir() and (s.path / "metadata.yaml").is_file()]
    else:
        pool = [s for s in seeds if s.storage == "mcap"]
    seed = _pick(rng, pool)
    bag = _copy_seed(seed, target)
    if family == "yaml":
        outside = target / "outside.mcap"
        shutil.copyfile(
            next(s for s in seeds if s.name == "gen_zstd").path / "gen_zstd_0.mcap", outside
        )
        recipe = mutate_yaml.mutate(rng, bag, outside)
    else:
        suffix = ".db3" if family == "db3" else ".mcap"
        files = [bag] if bag.is_file() else sorted(p for p in bag.iterdir() if p.suffix == suffix)
        file = rng.choice(files)
        if family == "db3":
            recipe = f"{file.name}: {mutate_db3.mutate(rng, file)}"
        else:
            data = bytearray(file.read_bytes())
            recipe = f"{file.name}: {mutate_mcap.mutate(rng, data)}"
            file.write_bytes(bytes(data))
    return Case(number, family, f"seed {seed.name}: {recipe}", bag, seed.path)


def _written_case(
    rng: random.Random, number: int, family: str, target: Path, seeds: list[Seed]
) -> Case:
    bag = target / "bag"
    if family == "schema":
        recipe = mutate_schema.write_schema_bag(rng, bag)
    elif family == "payload":
        recipe = mutate_schema.write_payload_bag(rng, bag)
    else:
        bag = target / "bomb.mcap"
        compression = rng.choice(["zstd", "lz4"])
        declared = rng.choice([None, None, 0, 100, 1 << 62])
        recipe = mutate_mcap.write_bomb(bag, compression, 1280 << 20, declared)
    golden = next(s for s in seeds if s.name == "gen_zstd").path
    return Case(number, family, recipe, bag, golden)


def make_cases(
    run_seed: int, numbers: range, directory: Path, *, full_fixtures: bool = True
) -> list[Case]:
    """Seeds under ``directory/seeds``, then the cases ``numbers`` of campaign ``run_seed``."""
    (directory / "seeds").mkdir()
    seeds = build_seeds(directory / "seeds", full_fixtures=full_fixtures)
    return [make_case(run_seed, n, seeds, directory) for n in numbers]


@dataclass(frozen=True, slots=True)
class Finding:
    """A distinct failure: its category, command and line, the first case that showed it."""

    category: str
    command: str
    line: str
    recipe: str
    count: int


def _signature(line: str) -> str:
    """The line with numbers and paths blanked, to group runs that failed the same way."""
    line = re.sub(r"/\S+/", "/.../", line)
    return re.sub(r"\d+", "N", line)[:160]


def findings(cases: list[Case], outcomes: list[runner.Outcome]) -> list[Finding]:
    """The non-clean outcomes grouped by (category, command, signature of the line)."""
    by_number = {c.number: c for c in cases}
    groups: dict[tuple[str, str, str], list[runner.Outcome]] = {}
    for outcome in outcomes:
        if outcome.category != "clean":
            command = outcome.key.split(" ", 1)[1]
            groups.setdefault(
                (outcome.category, command, _signature(outcome.last_line)), []
            ).append(outcome)
    result = []
    for (category, command, _), runs in sorted(groups.items()):
        first = by_number[int(runs[0].key.split()[0])]
        recipe = f"case {first.number} ({first.family}) {first.recipe}"
        result.append(Finding(category, command, runs[0].last_line, recipe, len(runs)))
    return result


def table(cases: list[Case], outcomes: list[runner.Outcome]) -> str:
    """Outcomes per family and category, as a text table."""
    family = {c.number: c.family for c in cases}
    counts = Counter((family[int(o.key.split()[0])], o.category) for o in outcomes)
    header = f"{'family':10}" + "".join(f"{c:>13}" for c in runner.CATEGORIES) + f"{'runs':>8}"
    rows = [header]
    for name in [*FAMILIES, "all"]:
        cells = [
            sum(n for (f, c), n in counts.items() if c == category and name in (f, "all"))
            for category in runner.CATEGORIES
        ]
        rows.append(f"{name:10}" + "".join(f"{n:>13}" for n in cells) + f"{sum(cells):>8}")
    return "\n".join(rows)
