"""BagReader.largest_message: what the player sizes its shared-memory segment by.

The oracle is the payloads the test wrote; MCAP files answer from Message Index records, so
the answer is also checked to come without numpy (the player asks before its participant
exists, and numpy's import would delay it).
"""

from __future__ import annotations

import random
import subprocess
import sys
from pathlib import Path

from bag_samples import STRING, string_cdr
from test_bag_sqlite_hostile import write_db3

from bagkit.bag import BagReader, BagWriter, TopicInfo

START = 1_700_000_000_000_000_000


def _write(path: Path, payloads: list[tuple[str, bytes]], chunk_size: int) -> None:
    with BagWriter(path, chunk_size=chunk_size) as bag:
        for topic in sorted({topic for topic, _ in payloads}):
            bag.add_topic(TopicInfo(topic, STRING))
        for i, (topic, data) in enumerate(payloads):
            bag.write(topic, data, log_time=START + i * 1_000_000)


def test_one_chunk_gives_each_topics_largest(tmp_path: Path) -> None:
    rng = random.Random(3)
    payloads = [
        (topic, string_cdr("x" * rng.randrange(0, 5000)))
        for _ in range(300)
        for topic in ("/scan", "/status")
    ]
    _write(tmp_path / "one", payloads, chunk_size=1 << 24)
    with BagReader(tmp_path / "one") as bag:
        for topic in ("/scan", "/status"):
            assert bag.largest_message([topic]) == max(len(d) for t, d in payloads if t == topic)
        assert bag.largest_message(["/scan", "/status"]) == max(len(d) for _, d in payloads)
        assert bag.largest_message([]) == 0


def test_many_chunks_of_one_size(tmp_path: Path) -> None:
    image = string_cdr("p" * 3000)
    payloads = [p for i in range(100) for p in (("/image", image), ("/tick", string_cdr(str(i))))]
    _write(tmp_path / "many", payloads, chunk_size=8000)
    with BagReader(tmp_path / "many") as bag:
        assert bag.largest_message(["/image"]) == len(image)


def test_sqlite3_gives_the_last_message(tmp_path: Path) -> None:
    with BagReader(write_db3(tmp_path / "b.db3", n=20, text_size=10)) as bag:
        expected = len(bag.last_messages(["/b"], bag.end_ns + 1)["/b"].data)
        assert bag.largest_message(["/b"]) == expected > 0


def test_mcap_answers_without_numpy(tmp_path: Path) -> None:
    _write(tmp_path / "bag", [("/a", string_cdr("a" * 700)), ("/b", b"")], chunk_size=1 << 20)
    code = (
        "import sys; from bagkit.bag import BagReader\n"
        f"with BagReader({str(tmp_path / 'bag')!r}) as bag: print(bag.largest_message(['/a']))\n"
        "print('numpy' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == [str(len(string_cdr("a" * 700))), "False"]
