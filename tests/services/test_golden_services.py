"""Golden regression with a service: lockstep answers through on_request, live through DDS."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from conftest import CALLS, NODE

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.regression.golden import check_lockstep
from bagkit.regression.live import check_live
from bagkit.regression.spec import load_spec
from bagkit.ros.serialization import serialize

pytestmark = pytest.mark.ros

EVENTS = "/svc/toggle/_service_event"
CORE = '''
"""A toggle core: answers /svc/toggle (std_srvs/SetBool) with success = data (or negated)."""

from std_srvs.srv import SetBool

NEGATE = {negate!r}


class Toggle:
    input_topics = ("/value",)
    output_topics = ()
    timer_period_ns = None
    services = {{"/svc/toggle": SetBool}}

    def on_message(self, topic, msg, now_ns):
        return []

    def on_timer(self, now_ns):
        return []

    def on_request(self, service, request, now_ns):
        return SetBool.Response(success=request.data != NEGATE, message=f"set {{request.data}}")


def make_processors():
    return [Toggle()]
'''


def write_fixture(root: Path, events_bag: Path, *, negate: bool) -> Path:
    """A fixture whose golden holds a /value input and the recorded events of /svc/toggle."""
    from std_msgs.msg import Float64

    (root / "toggle_core.py").write_text(textwrap.dedent(CORE.format(negate=negate)))
    fixture = root / "toggle"
    fixture.mkdir()
    with BagReader(events_bag) as recorded, BagWriter(fixture / "golden") as golden:
        start = recorded.start_ns
        golden.add_topic(TopicInfo("/value", "std_msgs/msg/Float64"))
        golden.add_topic(recorded.topics[EVENTS])
        for i in range(5):
            t = start - 1_000_000_000 + i * 100_000_000
            golden.write("/value", serialize(Float64(data=float(i))), log_time=t, publish_time=t)
        for m in recorded.messages([EVENTS]):
            golden.write(EVENTS, m.data, log_time=m.log_time, publish_time=m.publish_time)
    spec = {
        "processor": "toggle_core:make_processors",
        "launch": f"{sys.executable} {NODE}" + (" --negate" if negate else ""),
        "inputs": ["/value"],
        "outputs": [],
        "services": ["/svc/toggle"],
        "wait_for": {"/clock": 0},
        "modes": ["lockstep", "live"],
    }
    (fixture / "spec.yaml").write_text(yaml.safe_dump(spec))
    return fixture


@pytest.mark.parametrize("negate", [False, True])
def test_lockstep_answers_recorded_requests(
    server_bag: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, negate: bool
) -> None:
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "toggle_core", raising=False)  # the other case's
    spec = load_spec(write_fixture(tmp_path, server_bag, negate=negate))
    assert EVENTS in spec.outputs
    check = check_lockstep(spec, tmp_path / "work")
    assert check.passed is (not negate), check.summary()
    with BagReader(check.candidate) as candidate:
        assert candidate.topic_counts[EVENTS] == 2 * CALLS


@pytest.mark.parametrize("negate", [False, True])
def test_live_sends_recorded_requests(server_bag: Path, tmp_path: Path, negate: bool) -> None:
    spec = load_spec(write_fixture(tmp_path, server_bag, negate=negate))
    check = check_live(spec, tmp_path / "work")
    assert check.passed is (not negate), check.summary()
    with BagReader(check.candidate) as candidate:
        assert candidate.topic_counts[EVENTS] == 2 * CALLS
