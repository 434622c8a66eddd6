"""Golden checks in lockstep, and accepting today's behaviour as the new golden."""

from __future__ import annotations

import tempfile
import textwrap
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.compare import CompareReport, compare_bags
from bagkit.decode.drift import TopicDrift
from bagkit.health import HealthReport
from bagkit.regression.drift import drift_lines, golden_drift, refuse_drift
from bagkit.regression.errors import SpecError
from bagkit.regression.health import broken_lines
from bagkit.regression.lockstep import LockstepResult, run_lockstep
from bagkit.regression.processor import Processor, make_processors
from bagkit.regression.spec import BAG_DIR, SPEC_FILE, FixtureSpec


@dataclass(frozen=True, slots=True)
class GoldenCheck:
    """The outcome of one fixture in one mode.

    ``drift``: golden topics whose stored definition differs from the installed one; the
    system was not run (nothing compared, no candidate) and the check fails with them.
    """

    spec: FixtureSpec
    mode: str
    candidate: Path
    report: CompareReport
    lockstep: LockstepResult | None = None
    drift: tuple[TopicDrift, ...] = ()
    health: HealthReport | None = None
    """The spec's ``health:`` contract on the candidate (its topics among the outputs)."""
    golden_health: HealthReport | None = None
    """The whole contract on the golden."""

    @classmethod
    def drifted(cls, spec: FixtureSpec, mode: str, candidate: Path) -> GoldenCheck | None:
        """The failed check of a golden whose topics drifted; None when none did."""
        drifts = golden_drift(spec)
        if not drifts:
            return None
        report = CompareReport(str(spec.bag), str(candidate), [])
        return cls(spec, mode, candidate, report, drift=tuple(drifts))

    @property
    def matched(self) -> bool:
        """Whether the candidate's outputs match the golden's."""
        return not self.drift and self.report.passed

    @property
    def passed(self) -> bool:
        """Whether the outputs match and the golden and the candidate keep the contract."""
        healthy = all(h is None or h.passed for h in (self.health, self.golden_health))
        return self.matched and healthy

    def summary(self, limit: int = 8) -> str:
        """A few lines naming the failing topics and fields and the first divergences."""
        lines = [f"{self.spec.name} ({self.mode}): {'pass' if self.passed else 'FAIL'}"]
        if self.drift:
            return _fitted([*lines, *drift_lines(self.spec, list(self.drift))])
        for topic in self.report.topics:
            if topic.passed:
                continue
            fields = [f.describe() for f in topic.failed_fields]
            differ = (
                f"{topic.failed_messages} of {topic.golden_count} {topic.counted} differ"
                f" ({topic.allowed_failed_messages} allowed)"
            )
            counts = [differ, f"missing {topic.missing}", f"extra {topic.extra}"]
            lines += _packed(counts, lead=f"  {topic.topic}: ", indent="      ")
            lines += _packed([*fields, *topic.shape_fields] or ["-"], lead="      fields: ")
        lines += [f"  {d.describe()}" for d in self.report.first_divergences(limit)]
        for where, health in (("golden", self.golden_health), ("candidate", self.health)):
            if health is not None:
                lines += broken_lines(health, where)
        return _fitted(lines)


WIDTH = 80
"""The summary's width: a terminal's, a CI log's, a pytest failure's."""


def _fitted(lines: list[str]) -> str:
    """``lines`` joined, each longer than WIDTH broken at spaces (never inside a name or a
    value without one), its following lines indented under it."""
    return "\n".join(
        part
        for line in lines
        for part in textwrap.wrap(
            line,
            WIDTH,
            subsequent_indent=" " * (len(line) - len(line.lstrip()) + 4),
            break_long_words=False,
            break_on_hyphens=False,
        )
        or [""]
    )


def _packed(pieces: list[str], *, lead: str, indent: str | None = None) -> list[str]:
    """``pieces`` joined by ``, `` after ``lead``, as many to a line as fit WIDTH (a
    field and its error are never split), the following lines after ``indent`` (as far as
    ``lead`` by default)."""
    indent = " " * len(lead) if indent is None else indent
    lines = [lead + pieces[0]]
    for piece in pieces[1:]:
        if len(lines[-1]) + 2 + len(piece) > WIDTH:
            lines[-1] += ","
            lines.append(indent + piece)
        else:
            lines[-1] += ", " + piece
    return lines


def _processors(spec: FixtureSpec) -> list[Processor]:
    if spec.processor is None:
        raise SpecError(f"{spec.directory / SPEC_FILE}: lockstep needs a processor factory")
    return make_processors(spec.processor, spec.processor_args)


def check_lockstep(spec: FixtureSpec, workdir: Path) -> GoldenCheck:
    """Run ``spec``'s golden inputs through its processors and compare the outputs.

    Raises:
        SpecError: the spec has no processor factory, or the factory fails.
        RegressionError: the golden lacks an input topic.
    """
    candidate = workdir / "candidate"
    drifted = GoldenCheck.drifted(spec, "lockstep", candidate)
    if drifted is not None:
        return drifted
    result = run_lockstep(
        spec.bag,
        candidate,
        processors=_processors(spec),
        input_topics=spec.inputs,
        output_topics=spec.outputs,
        services=spec.services,
    )
    report = compare_bags(spec.bag, candidate, spec.compare_options("lockstep"))
    return GoldenCheck(spec, "lockstep", candidate, report, result)


@dataclass(frozen=True, slots=True)
class GoldenUpdate:
    """What accepting today's behaviour did to a fixture."""

    lockstep: LockstepResult
    rewritten: bool
    """False when today's outputs matched the golden's within the lockstep tolerance."""


def update_golden(spec: FixtureSpec) -> GoldenUpdate:
    """Accept today's behaviour: rewrite ``spec``'s golden bag with the outputs lockstep
    computes, every other topic kept as recorded.

    Outputs that match the golden's within the spec's lockstep tolerance are kept as they are
    (no file is touched), so that accepting unchanged behaviour, on any CPU, rewrites nothing.

    Raises:
        GoldenDriftError: the golden's definitions drifted (``golden migrate`` first).
    """
    refuse_drift(spec)
    with BagReader(spec.bag) as reader:
        kept = [t for t in reader.topics if t not in spec.outputs]
    with tempfile.TemporaryDirectory(dir=spec.directory, prefix=".update-") as tmp:
        fresh = Path(tmp) / BAG_DIR
        result = run_lockstep(
            spec.bag,
            fresh,
            processors=_processors(spec),
            input_topics=spec.inputs,
            output_topics=spec.outputs,
            copy_topics=kept,
            services=spec.services,
        )
        if compare_bags(spec.bag, fresh, spec.compare_options("lockstep")).passed:
            return GoldenUpdate(result, rewritten=False)
        old = Path(tmp) / "old"
        spec.bag.rename(old)
        fresh.rename(spec.bag)
    return GoldenUpdate(result, rewritten=True)
