"""bagkit.processes: real subprocesses started in their own groups, stopped in steps, reaped."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bagkit.processes import Command, ProcessError, StopPolicy, Supervisor

# A child that dies of SIGINT (not KeyboardInterrupt), ignores the signals named in argv[1:],
# says it is ready, then waits to be stopped.
IGNORING = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_DFL)
for name in sys.argv[1:]:
    signal.signal(getattr(signal, name), signal.SIG_IGN)
print("ready", flush=True)
time.sleep(60)
"""


def python(name: str, code: str, *args: str, **fields: object) -> Command:
    return Command(name, [sys.executable, "-c", code, *args], **fields)  # type: ignore[arg-type]


def wait_for_line(lines: list[str], text: str) -> None:
    deadline = time.monotonic() + 20
    while text not in lines:
        assert time.monotonic() < deadline, lines
        time.sleep(0.02)


def test_environment_log_and_exit_code(tmp_path: Path) -> None:
    log = tmp_path / "child.log"
    code = "import os, sys; print(os.environ['GREETING']); sys.exit(3)"
    with Supervisor() as group:
        child = group.start(python("child", code, env={**os.environ, "GREETING": "hi"}, log=log))
        child.process.wait(timeout=20)
        assert group.exited() is child
    assert child.returncode == 3
    assert log.read_text() == "hi\n"
    assert group.log_tail(child) == "hi"


@pytest.mark.parametrize(
    ("ignored", "expected"),
    [
        ((), -signal.SIGINT),
        (("SIGINT",), -signal.SIGTERM),
        (("SIGINT", "SIGTERM"), -signal.SIGKILL),
    ],
)
def test_stop_goes_from_sigint_to_sigterm_to_sigkill(
    ignored: tuple[str, ...], expected: int
) -> None:
    lines: list[str] = []
    group = Supervisor(StopPolicy(interrupt_s=0.5, terminate_s=0.5))
    child = group.start(python("child", IGNORING, *ignored, on_line=lines.append))
    wait_for_line(lines, "ready")
    assert group.stop(child) == expected
    assert child.reader is not None and not child.reader.is_alive()


# A supervisor started with SIGINT ignored (as bash starts a script's background job) stops
# `sleep`, which sets no handler of its own, and prints how it ended.
SUPERVISOR_IGNORING_SIGINT = """
import signal, time
from bagkit.processes import Command, StopPolicy, Supervisor
signal.signal(signal.SIGINT, signal.SIG_IGN)
group = Supervisor(StopPolicy(interrupt_s=5.0, terminate_s=5.0))
child = group.start(Command("sleep", ["sleep", "60"]))
time.sleep(0.2)
print(group.stop(child))
"""


def test_a_child_stops_on_sigint_though_its_supervisor_ignores_it() -> None:
    done = subprocess.run(
        [sys.executable, "-c", SUPERVISOR_IGNORING_SIGINT],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert int(done.stdout) == -signal.SIGINT  # not -SIGTERM, 5 s later


def test_stop_reaches_the_whole_process_group() -> None:
    lines: list[str] = []
    # The child starts a grandchild that ignores nothing, prints its pid and sleeps.
    code = (
        "import subprocess, sys, time\n"
        "g = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])\n"
        "print(g.pid, flush=True)\n"
        "time.sleep(60)\n"
    )
    with Supervisor(StopPolicy(interrupt_s=5.0, terminate_s=5.0)) as group:
        group.start(python("parent", code, on_line=lines.append))
        deadline = time.monotonic() + 20
        while not lines:
            assert time.monotonic() < deadline
            time.sleep(0.02)
    grandchild = int(lines[0])
    deadline = time.monotonic() + 10
    while Path(f"/proc/{grandchild}").exists() and _state(grandchild) != "Z":
        assert time.monotonic() < deadline, "the grandchild outlived the stop"
        time.sleep(0.05)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return "Z"


def test_wait_ready_returns_once_the_condition_holds(tmp_path: Path) -> None:
    flag = tmp_path / "flag"
    code = f"import pathlib, time; time.sleep(0.3); pathlib.Path({str(flag)!r}).touch(); "
    code += "time.sleep(60)"
    with Supervisor() as group:
        group.start(python("writer", code))
        group.wait_ready(flag.exists, timeout=20.0, what="the flag")
        assert group.exited() is None


def test_wait_ready_fails_when_a_process_exits_first(tmp_path: Path) -> None:
    log = tmp_path / "dies.log"
    code = "import sys; print('bad parameter'); sys.exit(2)"
    with Supervisor() as group, pytest.raises(ProcessError) as raised:
        group.start(python("dies", code, log=log))
        group.wait_ready(lambda: False, timeout=20.0)
    assert str(raised.value) == "dies exited early with code 2; the end of its log:\nbad parameter"


def test_wait_ready_times_out() -> None:
    with (
        Supervisor() as group,
        pytest.raises(ProcessError, match=r"the bag not ready after 0\.2 s"),
    ):
        group.start(python("sleeper", "import time; time.sleep(60)"))
        group.wait_ready(lambda: False, timeout=0.2, what="the bag")


def test_a_program_that_does_not_exist_is_one_error(tmp_path: Path) -> None:
    with pytest.raises(ProcessError, match=r"cannot start ghost \(.*no-such-program\)"):
        Supervisor().start(Command("ghost", [str(tmp_path / "no-such-program")]))


PRINT_BLAS = "import os; print(os.environ.get('OPENBLAS_NUM_THREADS', 'unset'), flush=True)"


@pytest.mark.parametrize(("users", "programs"), [(None, "unset"), ("3", "3")])
def test_a_started_program_gets_the_users_blas_threads_not_bagkits(
    monkeypatch: pytest.MonkeyPatch, users: str | None, programs: str
) -> None:
    from bagkit import own_environment

    monkeypatch.setattr(own_environment, "_SET_FOR_BAGKIT", set())
    if users is None:
        monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    else:
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", users)
    own_environment.single_threaded_blas()  # what the console script does first
    assert os.environ["OPENBLAS_NUM_THREADS"] == (users or "1")
    lines: list[str] = []
    with Supervisor() as group:
        inherited = group.start(python("inherits", PRINT_BLAS, on_line=lines.append))
        given = group.start(python("given", PRINT_BLAS, env=dict(os.environ), on_line=lines.append))
        assert inherited.process.wait(20) == 0 and given.process.wait(20) == 0
    assert lines == [programs, programs]  # the readers are joined when the group stops
