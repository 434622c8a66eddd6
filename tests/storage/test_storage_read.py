"""Bags read from storage by range requests: the same values as on disk, from the bytes the
indexes point at (info: the summary; a topic: its chunks), on moto's S3 server, an HTTP server
and a real bucket when one is configured."""

from __future__ import annotations

import functools
import json
import os
import struct
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from bagkit.bag import BagReader, bag_info
from bagkit.bag.mcap_file import McapFile
from bagkit.storage.errors import OutputExistsError
from bagkit.storage.paths import UrlPath
from bagkit.storage.range_file import FIRST_TAIL_BYTES, fetched
from bagkit.storage.transfer import written_to
from tests.storage.conftest import Store


def cli(args: list[str], env: dict[str, str | None]) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` with ``env`` over this process's (None: unset)."""
    merged = {k: v for k, v in {**os.environ, **env}.items() if v is not None}
    return subprocess.run(
        [str(Path(sys.executable).with_name("bagkit")), *args],
        env=merged,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@functools.cache
def local_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` on bags on disk, run once: what each store's run is compared with."""
    return cli(list(args), {})


def summary_bytes(file: Path) -> int:
    """The summary section's size, from the footer (``summary_start`` after the opcode and
    length), as the MCAP specification lays it out."""
    data = file.read_bytes()
    footer = data[-8 - 29 :]
    (summary_start,) = struct.unpack_from("<Q", footer, 9)
    return len(data) - summary_start


def chunk_bytes_holding(file: Path, topic: str) -> int:
    mcap = McapFile(file)
    mcap.open()
    try:
        channels = {c.id for c in mcap.index.channels.values() if c.topic == topic}
        return sum(
            c.chunk_length + c.message_index_length
            for c in mcap.index.chunk_indexes
            if channels & set(c.message_index_offsets)
        )
    finally:
        mcap.close()


def without_paths(info: dict[str, object]) -> dict[str, object]:
    return {k: v for k, v in info.items() if k not in ("path", "files", "exact_rates")}


def chunk_bounded_rates(file: Path) -> dict[str, float]:
    """Each topic's (count - 1) / span, the span from the start of the first chunk holding it
    to the end of the last, from the summary as the ``mcap`` package reads it."""
    from mcap.reader import make_reader

    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    rates = {}
    for channel in summary.channels.values():
        holding = [c for c in summary.chunk_indexes if channel.id in c.message_index_offsets]
        span = max(c.message_end_time for c in holding) - min(c.message_start_time for c in holding)
        rates[channel.topic] = (summary.statistics.channel_message_counts[channel.id] - 1) / (
            span / 1e9
        )
    return rates


@pytest.mark.parametrize("bag", ["a.mcap", "fleet/a"])
def test_info_reads_the_summary_only(store: Store, local_bags: Path, bag: str) -> None:
    """The summary, not the message indexes: each rate over the chunks holding its topic, a
    lower bound of the exact one (which ``exact_rates`` reads). A single ``.mcap``, and a
    bag's prefix (its metadata.yaml too)."""
    file = local_bags / "fleet" / "a" / "a_0.mcap"
    local = file if bag.endswith(".mcap") else file.parent
    before = fetched()[0]
    remote = bag_info(f"{store.base}/{bag}")
    spent = fetched()[0] - before
    on_disk = bag_info(local)
    assert not remote.exact_rates and on_disk.exact_rates
    rates = {t.topic: t.rate_hz for t in remote.topics}
    expected = chunk_bounded_rates(file)
    assert rates == pytest.approx(expected, rel=1e-12)
    for topic in on_disk.topics:
        assert topic.rate_hz is not None and rates[topic.topic] <= topic.rate_hz
    unrated = [replace(t, rate_hz=None) for t in remote.topics]
    assert without_paths({**remote.to_dict(), "topics": unrated}) == without_paths(
        {**on_disk.to_dict(), "topics": [replace(t, rate_hz=None) for t in on_disk.topics]}
    )
    assert remote.path == f"{store.base}/{bag}"
    metadata = 0 if local == file else (local / "metadata.yaml").stat().st_size
    assert 0 < spent <= 2 * summary_bytes(file) + metadata
    assert spent < file.stat().st_size / 4
    exact = bag_info(f"{store.base}/{bag}", exact_rates=True)
    assert exact.exact_rates and exact.topics == on_disk.topics


def test_a_topic_fetches_the_chunks_that_hold_it(store: Store, local_bags: Path) -> None:
    local = local_bags / "fleet" / "a"
    with BagReader(local) as bag:
        expected = [(m.log_time, m.data) for m in bag.messages(topics={"/gps/fix"})]
    before = fetched()[0]
    with BagReader(f"{store.base}/fleet/a") as bag:
        got = [(m.log_time, m.data) for m in bag.messages(topics={"/gps/fix"})]
    spent = fetched()[0] - before
    assert got == expected and len(got) == 3
    file = local / "a_0.mcap"
    needed = chunk_bytes_holding(file, "/gps/fix") + summary_bytes(file)
    metadata = (local / "metadata.yaml").stat().st_size
    # The first read of the end fetches FIRST_TAIL_BYTES (the summary and what is before it).
    guessed = max(0, FIRST_TAIL_BYTES - summary_bytes(file))
    assert spent <= 1.2 * needed + metadata + guessed
    assert spent < file.stat().st_size / 3


def test_stats_of_a_prefix_equal_the_local_stats(store: Store, local_bags: Path) -> None:
    args = ["stats", "summary", "-t", "/gps/fix", "--format", "json", "--workers", "0"]
    # An HTTP server lists no prefixes: its bags are named one by one.
    named = (
        [f"{store.base}/fleet/{b}" for b in "ab"]
        if store.name == "http"
        else [f"{store.base}/fleet"]
    )
    remote = cli([*args, *named], store.env)
    local = local_cli(*args, str(local_bags / "fleet"))
    assert remote.returncode == 0, remote.stderr
    assert json.loads(remote.stdout)["topics"] == json.loads(local.stdout)["topics"]


@pytest.mark.parametrize("store", ["s3", "gs", "az", "real"], indirect=True)
def test_info_of_a_prefix_lists_its_bags(store: Store, local_bags: Path) -> None:
    """Each store's listing (an HTTP server lists no prefixes)."""
    # A prefix of its own: other tests put more bags into the store.
    for bag in ("a", "b"):
        store.put(local_bags / "fleet" / bag, f"listed/fleet/{bag}")
    store.put(local_bags / "fleet" / "a" / "a_0.mcap", "listed/a.mcap")
    base = f"{store.base}/listed"
    result = cli(["info", base, "--format", "json"], store.env)
    assert result.returncode == 0, result.stderr
    bags = json.loads(result.stdout)["bags"]
    assert sorted(b["path"] for b in bags) == [
        f"{base}/a.mcap",
        f"{base}/fleet/a",
        f"{base}/fleet/b",
    ]


# gs:// and az:// decode by the same range reads (test_a_topic_fetches_the_chunks_that_hold_it)
# and are compared with the bags on disk by stats: a CLI run that imports their clients costs
# a second or two more.
@pytest.mark.parametrize("store", ["s3", "http", "real"], indirect=True)
def test_echo_of_a_url(store: Store, local_bags: Path) -> None:
    args = ["echo", "/gps/fix", "--format", "json", "-n", "2"]
    remote = cli(["echo", f"{store.base}/fleet/b", *args[1:]], store.env)
    local = local_cli("echo", str(local_bags / "fleet" / "b"), *args[1:])
    assert remote.returncode == 0, remote.stderr
    assert remote.stdout == local.stdout and remote.stdout.strip()


def test_outputs_to_urls_are_uploaded(moto_store: Store, local_bags: Path) -> None:
    base = moto_store.base
    for bag in ("a", "b"):
        moto_store.put(local_bags / "fleet" / bag, f"fleet/{bag}")
    cut = cli(
        ["filter", f"{base}/fleet/a", "-o", f"{base}/out/cut", "--topics", "/gps/fix"],
        moto_store.env,
    )
    assert cut.returncode == 0, cut.stderr
    again = cli(["filter", f"{base}/fleet/a", "-o", f"{base}/out/cut"], moto_store.env)
    assert again.returncode == 2 and "exists (use --force to replace it)" in again.stderr
    with pytest.raises(OutputExistsError) as raised, written_to(UrlPath(f"{base}/out/cut")):
        pass  # the library names its own field; the CLI named the flag
    assert raised.value.field == "output.force"
    info = cli(["info", f"{base}/out/cut", "--format", "json"], moto_store.env)
    assert json.loads(info.stdout)["message_count"] == 3
    catalog = cli(
        ["catalog", "build", f"{base}/fleet", "-o", f"{base}/out/c.parquet", "--workers", "0"],
        moto_store.env,
    )
    assert catalog.returncode == 0, catalog.stderr
    update = cli(
        ["catalog", "build", f"{base}/fleet", "-o", f"{base}/out/c.parquet", "--workers", "0"],
        moto_store.env,
    )
    assert "0 read, 2 unchanged" in update.stderr.replace("\n", " ")
    assert update.stderr.startswith(f"{base}/out/c.parquet: 2 bags")
    query = ["catalog", "query", f"{base}/out/c.parquet", "-t", "/gps/fix", "--format", "json"]
    rows = json.loads(cli(query, moto_store.env).stdout)
    assert {r["path"]: r["count"] for r in rows} == {f"{base}/fleet/a": 3, f"{base}/fleet/b": 5}
    missing = cli([*query[:2], f"{base}/out/none.parquet"], moto_store.env)
    assert missing.returncode == 2 and "no such catalogue" in missing.stderr


def test_export_to_a_url_names_the_url(moto_store: Store, local_bags: Path) -> None:
    """What export prints is where the files are: under the URL, not a temporary folder."""
    import s3fs

    base = moto_store.base
    moto_store.put(local_bags / "fleet" / "b", "fleet/b")
    result = cli(
        ["export", f"{base}/fleet/b", "-o", f"{base}/tables/b", "-t", "/gps/fix"], moto_store.env
    )
    assert result.returncode == 0, result.stderr
    printed = result.stdout.split("-> ")[-1].strip()
    assert printed == f"{base}/tables/b/gps/fix.parquet", result.stdout
    assert s3fs.S3FileSystem().exists(printed.removeprefix("s3://"))
    assert "bagkit-storage-" not in result.stdout + result.stderr


def test_presigned_urls_keep_their_signature(moto_store: Store, local_bags: Path) -> None:
    """moto checks the signature of a presigned URL (403 without it): the fleet commands
    open each bag by its full URL, and never print the signed query."""
    import s3fs

    fs = s3fs.S3FileSystem()
    moto_store.put(local_bags / "fleet" / "a" / "a_0.mcap", "signed/a.mcap")
    moto_store.put(local_bags / "fleet" / "b" / "b_0.mcap", "signed/b.mcap")
    urls = [fs.url(f"bagkit-test/signed/{n}.mcap", expires=600) for n in "ab"]
    assert all("Signature=" in url for url in urls)
    unsigned = urls[0].split("?", 1)[0]
    assert cli(["info", unsigned], {}).returncode == 2  # moto refuses it: 403
    local = [str(local_bags / "fleet" / n / f"{n}_0.mcap") for n in "ab"]
    options = ["--format", "json", "--workers", "0"]
    stats = ["stats", "summary", "-t", "/gps/fix", *options]
    remote, on_disk = cli([*stats, *urls], {}), cli([*stats, *local], {})
    assert remote.returncode == 0, remote.stderr
    assert json.loads(remote.stdout)["topics"] == json.loads(on_disk.stdout)["topics"]
    find = ["find", "--when", "/gps/fix: latitude > 48.000001", *options]
    found, expected = cli([*find, *urls], {}), cli([*find, *local], {})
    assert found.returncode == 0, found.stderr
    episodes = json.loads(found.stdout)
    assert episodes and [e["count"] for e in episodes] == [
        e["count"] for e in json.loads(expected.stdout)
    ]
    assert all(e["bag"].endswith(".mcap?...") for e in episodes)
    for result in (remote, found):
        assert "Signature" not in result.stdout + result.stderr


def test_golden_check_of_fixtures_in_storage(moto_store: Store, tmp_path: Path) -> None:
    """A fixture's prefix (spec, inputs, golden bag) checked as its folder on disk is; an
    HTTP URL, which lists nothing, is one error."""
    fixture = Path(__file__).resolve().parents[2] / "fixtures" / "nominal"
    moto_store.put(fixture, "fixtures/nominal")
    args = ["golden", "check", "--workers", "0", "--failures", str(tmp_path)]
    remote = cli([*args, f"{moto_store.base}/fixtures/nominal"], moto_store.env)
    local = cli([*args, str(fixture)], {})
    assert remote.returncode == local.returncode == 0, remote.stderr
    assert (
        remote.stdout.splitlines()[0] == local.stdout.splitlines()[0] == "nominal (lockstep): pass"
    )
    http = cli([*args, "http://127.0.0.1:9/fixtures/nominal"], {})
    assert http.returncode == 2 and "lists no prefixes" in http.stderr


def test_dask_workers_read_the_store_themselves(moto_store: Store, local_bags: Path) -> None:
    """Two local workers, each opening its bags by URL (the driver sends URLs, not bytes):
    the figures one process gives."""
    for bag in ("a", "b"):
        moto_store.put(local_bags / "fleet" / bag, f"fleet/{bag}")
    args = ["stats", "summary", "-t", "/gps/fix", "--format", "json"]
    remote = cli([*args, f"{moto_store.base}/fleet", "--workers", "2"], moto_store.env)
    local = cli([*args, str(local_bags / "fleet"), "--workers", "0"], {})
    assert remote.returncode == 0, remote.stderr
    assert "local Dask cluster of 2 workers" in remote.stderr
    # Partials merged on Dask: the same figures up to the order of float sums.
    (got,), (expected,) = json.loads(remote.stdout)["topics"], json.loads(local.stdout)["topics"]
    assert got["count"] == expected["count"] == 8
    for mine, theirs in zip(got["fields"], expected["fields"], strict=True):
        assert mine["field"] == theirs["field"] and mine["count"] == theirs["count"]
        assert (mine["min"], mine["max"]) == (theirs["min"], theirs["max"])
        assert mine["mean"] == pytest.approx(theirs["mean"], rel=1e-12, abs=1e-9)
        assert mine["std"] == pytest.approx(theirs["std"], rel=1e-9, abs=1e-9)
