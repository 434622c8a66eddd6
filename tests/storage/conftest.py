"""Stores on 127.0.0.1 for the storage tests (moto's S3 server, gcp-storage-emulator,
Azurite, a range-capable HTTP server), a real bucket when ``BAGKIT_TEST_BUCKET`` names one,
and the bags put in them."""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo
from tests.storage.servers import (
    Emulator,
    HttpStore,
    real_bucket,
    start_azurite,
    start_gcs,
    start_http,
    start_moto,
)

STORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_700_000_000_000_000_000


def write_imu_gps(path: Path, seconds: int = 20, gps_seconds: int = 3) -> Path:
    """Imu at 100 Hz for ``seconds``, NavSatFix at 1 Hz in the first ``gps_seconds`` only: one
    small chunks, so /gps/fix lives in a few chunks of many."""
    types = STORE.types
    rng = np.random.default_rng(7)
    stamp = types["builtin_interfaces/msg/Time"]
    header = types["std_msgs/msg/Header"]
    vec = types["geometry_msgs/msg/Vector3"]
    with BagWriter(path, chunk_size=24_000) as bag:
        bag.add_topic(TopicInfo("/imu/data", "sensor_msgs/msg/Imu"))
        bag.add_topic(TopicInfo("/gps/fix", "sensor_msgs/msg/NavSatFix"))
        for i in range(seconds * 100):
            t = T0 + i * 10_000_000
            h = header(stamp=stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="imu")
            imu = types["sensor_msgs/msg/Imu"](
                header=h,
                orientation=types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(*rng.normal(0, 0.01, 3)),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(*rng.normal([0, 0, 9.81], 0.05)),
                linear_acceleration_covariance=np.zeros(9),
            )
            bag.write(
                "/imu/data", bytes(STORE.serialize_cdr(imu, "sensor_msgs/msg/Imu")), log_time=t
            )
            if i % 100 == 0 and i < gps_seconds * 100:
                fix = types["sensor_msgs/msg/NavSatFix"](
                    header=h,
                    status=types["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                    latitude=48.0 + i * 1e-6,
                    longitude=11.0,
                    altitude=500.0 + rng.normal(),
                    position_covariance=np.zeros(9),
                    position_covariance_type=0,
                )
                data = bytes(STORE.serialize_cdr(fix, "sensor_msgs/msg/NavSatFix"))
                bag.write("/gps/fix", data, log_time=t)
    return path


@pytest.fixture(scope="session")
def local_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``fleet/a`` and ``fleet/b``: bag directories of Imu + GPS."""
    root = tmp_path_factory.mktemp("local")
    write_imu_gps(root / "fleet" / "a")
    write_imu_gps(root / "fleet" / "b", seconds=10, gps_seconds=5)
    return root


@dataclass
class Store:
    """A store the tests put bags in: ``base`` URL, the ``env`` a client needs."""

    name: str
    base: str
    env: dict[str, str]
    put: Callable[[Path, str], None]


@contextmanager
def serving(server: Emulator) -> Iterator[Emulator]:
    """``server``'s environment in this process's (the library's calls here read it), until
    the server is stopped."""
    saved = {k: os.environ.get(k) for k in server.env}
    os.environ.update(server.env)
    try:
        yield server
    finally:
        server.stop()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def fsspec_store(name: str, fs: Any, bucket: str, env: dict[str, str]) -> Store:
    """A store served by the fsspec filesystem ``fs``, its ``bucket`` made."""
    fs.mkdir(bucket)

    def put(local: Path, key: str) -> None:
        fs.put(str(local), f"{bucket}/{key}", recursive=local.is_dir())

    return Store(name, f"{name}://{bucket}", env, put)


@pytest.fixture(scope="session")
def moto_store() -> Iterator[Store]:
    with serving(start_moto()) as server:
        import s3fs

        yield fsspec_store("s3", s3fs.S3FileSystem(), "bagkit-test", server.env)


@pytest.fixture(scope="session")
def gcs_store() -> Iterator[Store]:
    with serving(start_gcs()) as server:
        from gcsfs.core import GCSFileSystem

        yield fsspec_store("gs", GCSFileSystem(token="anon"), "bagkit-test", server.env)


@pytest.fixture(scope="session")
def azure_store() -> Iterator[Store]:
    with serving(start_azurite()) as server:
        from adlfs import AzureBlobFileSystem

        yield fsspec_store("az", AzureBlobFileSystem(), "bagkit-test", server.env)


@pytest.fixture(scope="session")
def http_store() -> Iterator[tuple[Store, HttpStore]]:
    objects = HttpStore()
    server = start_http(objects)

    def put(local: Path, key: str) -> None:
        files = [local] if local.is_file() else sorted(p for p in local.rglob("*") if p.is_file())
        for file in files:
            name = key if file == local else f"{key}/{file.relative_to(local).as_posix()}"
            objects.objects[f"/{name}"] = file.read_bytes()

    try:
        yield Store("http", objects.url, {}, put), objects
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture(scope="session")
def real_store() -> Store:
    bucket = real_bucket()
    if bucket is None:
        pytest.skip("BAGKIT_TEST_BUCKET is not set (e.g. s3://bucket/prefix, with credentials)")
    import fsspec

    base = f"{bucket.rstrip('/')}/bagkit-test-{uuid.uuid4().hex[:8]}"
    fs, root = fsspec.core.url_to_fs(base)

    def put(local: Path, key: str) -> None:
        fs.put(str(local), f"{root}/{key}", recursive=local.is_dir())

    return Store("real", base, {}, put)


STORES = {"s3": "moto_store", "gs": "gcs_store", "az": "azure_store", "real": "real_store"}


@pytest.fixture(params=["s3", "gs", "az", "http", "real"])
def store(request: pytest.FixtureRequest, local_bags: Path) -> Store:
    """Each store, holding ``fleet/a``, ``fleet/b`` (bag prefixes) and ``a.mcap``."""
    if request.param == "http":
        chosen: Store = request.getfixturevalue("http_store")[0]
    else:
        chosen = request.getfixturevalue(STORES[request.param])
    if not getattr(chosen, "_filled", False):
        chosen.put(local_bags / "fleet" / "a", "fleet/a")
        chosen.put(local_bags / "fleet" / "b", "fleet/b")
        chosen.put(local_bags / "fleet" / "a" / "a_0.mcap", "a.mcap")
        chosen._filled = True  # type: ignore[attr-defined]
    return chosen
