"""A stranger's fixture made in a test: a Float64 doubler core and a golden of its inputs."""

from __future__ import annotations

import hashlib
import shutil
import textwrap
from pathlib import Path

import yaml

from bagkit.bag import BagWriter, TopicInfo
from bagkit.ros.serialization import serialize

CORE = '''
"""A doubler: /value in, /doubled out (std_msgs/Float64), and a running sum on a timer."""

from std_msgs.msg import Float64

FACTOR = {factor!r}


class Doubler:
    input_topics = ("/value",)
    output_topics = ("/doubled", "/sum")
    timer_period_ns = 1_000_000_000

    def __init__(self, factor):
        self.factor = factor
        self.total = 0.0

    def on_message(self, topic, msg, now_ns):
        self.total += msg.data
        return [("/doubled", Float64(data=self.factor * msg.data))]

    def on_timer(self, now_ns):
        return [("/sum", Float64(data=self.total))]


def make_processors(factor=FACTOR):
    return [Doubler(factor)]
'''


def write_core(package_dir: Path, factor: float = 2.0) -> Path:
    """``<package_dir>/doubler_core.py`` with the constant ``FACTOR``."""
    package_dir.mkdir(parents=True, exist_ok=True)
    core = package_dir / "doubler_core.py"
    core.write_text(textwrap.dedent(CORE.format(factor=factor)))
    # Rewritten within the second at the same size, the core's old bytecode would pass as fresh.
    shutil.rmtree(package_dir / "__pycache__", ignore_errors=True)
    return core


def write_fixture(fixture: Path, *, samples: int = 50) -> Path:
    """A fixture directory: spec.yaml naming ``doubler_core:make_processors`` and a golden bag
    holding only the inputs (``update_golden`` adds the outputs)."""
    fixture.mkdir(parents=True)
    from std_msgs.msg import Float64

    with BagWriter(fixture / "golden") as bag:
        bag.add_topic(TopicInfo("/value", "std_msgs/msg/Float64"))
        for i in range(samples):
            t = 1_000_000_000 + i * 100_000_000
            bag.write("/value", serialize(Float64(data=0.5 * i - 3.0)), log_time=t, publish_time=t)
    spec = {
        "description": "a doubler",
        "processor": "doubler_core:make_processors",
        "inputs": ["/value"],
        "outputs": ["/doubled", "/sum"],
        "compare": {"atol": 1e-9, "rtol": 1e-9},
    }
    (fixture / "spec.yaml").write_text(yaml.safe_dump(spec))
    return fixture


def digest(directory: Path) -> dict[str, str]:
    """SHA-256 of every file under ``directory`` by relative path."""
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }
