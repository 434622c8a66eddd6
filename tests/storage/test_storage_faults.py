"""Bad URLs and failing stores: one ``error:`` line naming the URL without its secrets, exit
2; retries ride out a few 5xx answers; an object that changes while read is an error, not a
mix. Faults come from the HTTP server on loopback; missing buckets and objects that are no bag
from every store (moto's S3 server, gcp-storage-emulator, Azurite)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from bagkit.storage.urls import shown_url
from tests.storage.conftest import Store
from tests.storage.servers import Faults, HttpStore
from tests.storage.test_storage_read import cli

# Retries quick, timeouts short: the faults below stay cheap.
QUICK = {
    "BAGKIT_STORAGE_BACKOFF": "0.05",
    "BAGKIT_STORAGE_ATTEMPTS": "3",
    "BAGKIT_STORAGE_TIMEOUT": "1",
}


@pytest.fixture
def http(http_store: tuple[Store, HttpStore], local_bags: Path) -> HttpStore:
    objects = http_store[1]
    http_store[0].put(local_bags / "fleet" / "a" / "a_0.mcap", "faulty.mcap")
    objects.faults.clear()
    objects.gets.clear()
    return objects


def one_error(args: list[str], env: dict[str, str | None] | None = None) -> str:
    result = cli(args, {**QUICK, **(env or {})})
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


def test_a_few_server_errors_are_retried(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(fail=2, status=503)
    result = cli(["info", f"{http.url}/faulty.mcap", "--format", "json"], QUICK)
    assert result.returncode == 0, result.stderr
    assert http.faults["/faulty.mcap"].fail == 0


def test_server_errors_past_the_retries_are_one_error(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(fail=100, status=502)
    line = one_error(["info", f"{http.url}/faulty.mcap"])
    assert f"{http.url}/faulty.mcap" in line and "3 attempts" in line


def test_a_request_that_times_out_is_retried_then_one_error(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(stall_s=2.5)
    line = one_error(["info", f"{http.url}/faulty.mcap"])
    assert "faulty.mcap" in line


def test_a_truncated_answer_is_an_error(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(truncate=True)
    line = one_error(["echo", f"{http.url}/faulty.mcap", "/gps/fix"])
    assert "faulty.mcap" in line


def test_an_object_that_changes_while_read_is_reported(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(change_after=3)  # after the summary, before the chunks
    line = one_error(["echo", f"{http.url}/faulty.mcap", "/gps/fix"])
    assert "changed while read" in line


def test_forbidden_is_access_denied(http: HttpStore) -> None:
    http.faults["/faulty.mcap"] = Faults(fail=100, status=403)
    assert "access denied" in one_error(["info", f"{http.url}/faulty.mcap"])


@pytest.mark.parametrize("store", ["s3", "gs", "az", "http"], indirect=True)
def test_an_object_that_is_no_bag(store: Store, tmp_path: Path) -> None:
    (tmp_path / "notes.mcap").write_bytes(b"not a bag at all, " * 100)
    store.put(tmp_path / "notes.mcap", "notes.mcap")
    line = one_error(["info", f"{store.base}/notes.mcap"], store.env)
    assert f"{store.base}/notes.mcap" in line
    assert not any(secret in line for secret in store.env.values() if "Key=" in secret)


def test_an_http_prefix_of_bags_is_one_error(
    http_store: tuple[Store, HttpStore], local_bags: Path
) -> None:
    """HTTP lists no prefixes (fsspec would list the links of a page): a URL that is neither a
    bag file nor a bag's prefix is one error saying to name the bags."""
    store, objects = http_store
    store.put(local_bags / "fleet" / "a", "listed/a")
    objects.objects["/listed/index.html"] = b'<a href="a/a_0.mcap">a</a>'
    for url in (f"{store.base}/listed", f"{store.base}/listed/index.html"):
        line = one_error(["stats", "summary", url, "--workers", "0"])
        assert "an HTTP server lists no prefixes: name each bag" in line
    assert cli(["info", f"{store.base}/listed/a"], {}).returncode == 0


def test_secrets_in_a_url_are_never_shown(http: HttpStore) -> None:
    host = http.url.removeprefix("http://")
    url = f"http://user:hunter2@{host}/missing.mcap?X-Amz-Signature=s3cr3t"
    line = one_error(["info", url])
    assert "hunter2" not in line and "s3cr3t" not in line
    assert f"http://{host}/missing.mcap" in line


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        ("https://user:pw@host/a.mcap?sig=1", "https://host/a.mcap?..."),
        ("https://token@host/a.mcap", "https://host/a.mcap"),
        (
            "abfs://bags@acct.dfs.core.windows.net/a.mcap",
            "abfs://bags@acct.dfs.core.windows.net/a.mcap",
        ),
        ("abfs://bags:key@acct.dfs.core.windows.net/a", "abfs://acct.dfs.core.windows.net/a"),
        ("az://bags/a.mcap?sv=2024&sig=s3cr3t", "az://bags/a.mcap?..."),
    ],
)
def test_urls_are_shown_without_secrets(url: str, shown: str) -> None:
    assert shown_url(url) == shown


def test_an_unknown_scheme(tmp_path: Path) -> None:
    assert "unknown URL scheme 'nosuch'" in one_error(["info", "nosuch://bucket/bag.mcap"])


@pytest.mark.parametrize(
    ("url", "package", "extra"),
    [
        ("s3://b/x.mcap", "s3fs", "storage"),
        ("gs://b/x.mcap", "gcsfs", "gcs"),
        ("az://c/x", "adlfs", "azure"),
    ],
)
def test_a_scheme_whose_package_is_missing_names_it(
    url: str, package: str, extra: str, tmp_path: Path
) -> None:
    """Each client library in an extra of its own: without it, one error naming the extra (the
    package hidden by one on PYTHONPATH that does not import, as an absent one does not)."""
    hidden = tmp_path / package
    hidden.mkdir()
    message = f"No module named {package!r}"
    (hidden / "__init__.py").write_text(f"raise ModuleNotFoundError({message!r}, name={package!r})")
    error = one_error(["info", url], {"PYTHONPATH": str(tmp_path)})
    assert error == f"error: {url}: reading {url[:2]}:// URLs needs {package}: " + (
        f"pip install 'bagkit[{extra}]'"
    )


@pytest.mark.parametrize(
    ("store", "url"),
    [
        ("s3", "s3://no-such-bucket-here/bag.mcap"),
        ("gs", "gs://no-such-bucket-here/bag.mcap"),
        ("az", "az://no-such-container/bag.mcap"),
    ],
    indirect=["store"],
)
def test_a_bucket_that_does_not_exist(store: Store, url: str) -> None:
    line = one_error(["info", url], store.env)
    assert line.startswith(f"error: {url}: no such ")


def test_no_credentials(moto_store: Store, tmp_path: Path) -> None:
    env = {
        "AWS_ENDPOINT_URL": moto_store.env["AWS_ENDPOINT_URL"],
        "AWS_SHARED_CREDENTIALS_FILE": str(tmp_path / "none"),
        "AWS_CONFIG_FILE": str(tmp_path / "none"),
        "AWS_EC2_METADATA_DISABLED": "true",
        "AWS_DEFAULT_REGION": "us-east-1",
    }
    hidden = dict.fromkeys(
        ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN", "AWS_PROFILE")
    )
    result = cli(["info", "s3://bagkit-test/a.mcap"], {**QUICK, **env, **hidden})
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "error: s3://bagkit-test/a.mcap: no credentials found "
        "(environment, profile or instance role)"
    ]
    assert "testing-secret" not in result.stderr
    assert os.environ.get("AWS_SECRET_ACCESS_KEY") == "testing-secret"
