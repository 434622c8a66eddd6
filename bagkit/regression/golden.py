"""Golden checks: run a fixture's inputs through today's code, compare, explain a failure."""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.compare import CompareReport, TopicResult, compare_bags
from bagkit.compare.bags import events_of, iter_samples
from bagkit.decode import MessageTypes
from bagkit.regression.lockstep import LockstepResult, run_lockstep
from bagkit.regression.spec import BAG_DIR, FixtureSpec

MAX_PLOTTED_FIELDS = 6


@dataclass(frozen=True, slots=True)
class GoldenCheck:
    """The outcome of one fixture in one mode."""

    spec: FixtureSpec
    mode: str
    candidate: Path
    report: CompareReport
    lockstep: LockstepResult | None = None

    @property
    def passed(self) -> bool:
        """Whether the candidate's outputs match the golden's."""
        return self.report.passed

    def summary(self, limit: int = 8) -> str:
        """A few lines naming the failing topics and fields and the first divergences."""
        lines = [f"{self.spec.name} ({self.mode}): {'pass' if self.passed else 'FAIL'}"]
        for topic in self.report.topics:
            if topic.passed:
                continue
            fields = ", ".join(
                f"{f.path} (max |err| {f.max_abs_error:.3g})" for f in topic.failed_fields
            )
            counts = f"missing {topic.missing}, extra {topic.extra}"
            lines.append(f"  {topic.topic}: {counts}; fields: {fields or '-'}")
        lines += [f"  {d.describe()}" for d in self.report.first_divergences(limit)]
        return "\n".join(lines)


def check_lockstep(spec: FixtureSpec, workdir: Path) -> GoldenCheck:
    """Run ``spec``'s golden inputs through the processors and compare the outputs."""
    candidate = workdir / "candidate"
    result = run_lockstep(
        spec.bag, candidate, nodes=spec.nodes, input_topics=spec.inputs, output_topics=spec.outputs
    )
    report = compare_bags(spec.bag, candidate, spec.compare_options("lockstep"))
    return GoldenCheck(spec, "lockstep", candidate, report, result)


def update_golden(spec: FixtureSpec) -> LockstepResult:
    """Rewrite ``spec``'s golden bag: every non-output topic kept as recorded, the outputs
    replaced by what lockstep computes today (the accepted new behaviour)."""
    with BagReader(spec.bag) as reader:
        kept = [t for t in reader.topics if t not in spec.outputs]
    with tempfile.TemporaryDirectory(dir=spec.directory, prefix=".update-") as tmp:
        fresh = Path(tmp) / BAG_DIR
        result = run_lockstep(
            spec.bag,
            fresh,
            nodes=spec.nodes,
            input_topics=spec.inputs,
            output_topics=spec.outputs,
            copy_topics=kept,
        )
        old = Path(tmp) / "old"
        spec.bag.rename(old)
        fresh.rename(spec.bag)
    return result


def write_failure_artefacts(check: GoldenCheck, folder: Path) -> list[Path]:
    """Write ``report.json`` and one PNG per failing topic (golden vs candidate) to ``folder``.

    Returns the files written. The folder is emptied first so that it shows one failure.
    """
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    written = [folder / "report.json"]
    written[0].write_text(json.dumps(check.report.to_dict(), indent=2) + "\n")
    failing = [t for t in check.report.topics if not t.passed]
    if not failing:
        return written
    with BagReader(check.spec.bag) as golden, BagReader(check.candidate) as candidate:
        g_types = MessageTypes.from_definitions(golden.definitions)
        c_types = MessageTypes.from_definitions(candidate.definitions)
        for topic in failing:
            png = folder / f"{topic.topic.strip('/').replace('/', '_')}.png"
            _plot_topic(
                topic,
                golden=golden,
                g_types=g_types,
                candidate=candidate,
                c_types=c_types,
                png=png,
            )
            written.append(png)
    return written


def _plot_topic(
    topic: TopicResult,
    *,
    golden: BagReader,
    g_types: MessageTypes,
    candidate: BagReader,
    c_types: MessageTypes,
    png: Path,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = topic.topic
    t0 = golden.start_ns
    g_samples = list(iter_samples(golden, name, g_types)) if name in golden.topics else []
    c_samples = list(iter_samples(candidate, name, c_types)) if name in candidate.topics else []
    if topic.matched_by == "event":
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for samples, label, marker in ((g_samples, "golden", "o"), (c_samples, "candidate", "x")):
            events = events_of(samples)
            ax.scatter(
                [(e.time_ns - t0) / 1e9 for e in events],
                [f"{e.name} [{e.level}]" for e in events],
                marker=marker,
                label=label,
            )
        ax.set_title(f"{name}: events (name [level])")
        ax.legend()
        ax.set_xlabel("time since the golden's start (s)")
    else:
        # The scalar fields that failed, each with candidate - golden on a second axis;
        # without any, the message counts over time show the missing and extra messages.
        paths = [f.path for f in topic.failed_fields if f.numeric and "[]" not in f.path]
        paths = paths[:MAX_PLOTTED_FIELDS] or ["(message count)"]
        fig, axes = plt.subplots(len(paths), 1, figsize=(10, 2.8 * len(paths)), squeeze=False)
        for ax, path in zip(axes[:, 0], paths, strict=True):
            series = {}
            for samples, label, style in (
                (g_samples, "golden", "-"),
                (c_samples, "candidate", "--"),
            ):
                if path == "(message count)":
                    times = [(s.time_ns - t0) / 1e9 for s in samples]
                    ax.plot(times, range(len(times)), style, label=label)
                    continue
                series[label] = {
                    (s.time_ns - t0) / 1e9: float(s.fields[path])
                    for s in samples
                    if isinstance(s.fields.get(path), int | float)
                }
                ax.plot(list(series[label]), list(series[label].values()), style, label=label)
            if series:
                common = sorted(series["golden"].keys() & series["candidate"].keys())
                diff_ax = ax.twinx()
                diff_ax.plot(
                    common,
                    [series["candidate"][t] - series["golden"][t] for t in common],
                    ":",
                    color="tab:red",
                    label="candidate - golden",
                )
                diff_ax.set_ylabel("candidate - golden", color="tab:red", fontsize=8)
                diff_ax.legend(fontsize=8, loc="upper right")
            ax.set_title(f"{name} {path}", fontsize=9)
            ax.legend(fontsize=8, loc="upper left")
        axes[-1, 0].set_xlabel("time since the golden's start (s)")
    fig.tight_layout()
    fig.savefig(png, dpi=80)
    plt.close(fig)
