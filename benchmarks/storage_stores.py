"""The stores of ``bench_storage`` on 127.0.0.1 and how their requests are counted: moto's S3
server (requests counted by each s3fs client, per operation), the tests' range-capable HTTP
server in a process of its own (requests counted by the server, per method), and the bags of
camera images put in them."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _serving(
    command: list[str], port: int, env: dict[str, str] | None = None
) -> tuple[subprocess.Popen[bytes], str]:
    """Start a server's ``command`` and wait (up to 30 s) until ``port`` of 127.0.0.1 takes
    connections; the process and its endpoint."""
    server = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env
    )
    for _ in range(300):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            break
        except OSError:
            time.sleep(0.1)
    return server, f"http://127.0.0.1:{port}"


def start_moto() -> tuple[subprocess.Popen[bytes], str]:
    """moto's S3 server on a free port of 127.0.0.1, and its endpoint."""
    port = _free_port()
    moto = str(Path(sys.executable).with_name("moto_server"))
    return _serving([moto, "-H", "127.0.0.1", "-p", str(port)], port)


S3RVER = REPO / ".s3rver" / "node_modules" / ".bin" / "s3rver"


def start_s3rver(directory: Path, bucket: str) -> tuple[subprocess.Popen[bytes], str]:
    """s3rver (an S3-compatible server of npm that keeps each object as a file under
    ``directory``, ``make bench`` installs it) on a free port of 127.0.0.1 with ``bucket``,
    and its endpoint."""
    port = _free_port()
    command = [str(S3RVER), "-d", str(directory), "-a", "127.0.0.1", "-p", str(port)]
    # Its listings' continuation tokens are DES-encrypted: Node's OpenSSL 3 keeps DES in the
    # legacy provider (without it a listing of more than 1,000 keys is HTTP 500).
    env = {**os.environ, "NODE_OPTIONS": "--openssl-legacy-provider"}
    return _serving([*command, "--configure-bucket", bucket, "--silent"], port, env)


def cpu_s(pid: int) -> float:
    """CPU seconds (user + system) the process ``pid`` has used."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def peak_rss_mb(pid: int) -> int:
    """The largest resident memory the process ``pid`` has had so far, in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024 // 10**6
    return 0


class S3Requests:
    """Requests an s3fs filesystem sent, by operation (``GetObject``, ``HeadObject``,
    ``ListObjectsV2``...): every attempt, from botocore's ``before-send`` event."""

    def __init__(self, fs: Any) -> None:
        self.counts: Counter[str] = Counter()
        fs.s3.meta.events.register("before-send.s3", self._sent)

    def _sent(self, event_name: str, **_: Any) -> None:
        self.counts[event_name.rsplit(".", 1)[-1]] += 1


class HttpServer:
    """The tests' HTTP range server holding ``bags`` copies of the bag ``template`` under
    ``/large/bag_NN/``, in a process of its own (in this one it would share the GIL with the
    reads); ``requests()``: what it has answered so far, by method."""

    def __init__(self, template: Path, bags: int) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.storage_stores", str(template), str(bags)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            cwd=REPO,
        )
        assert self.process.stdout is not None
        self.url = self.process.stdout.readline().decode().strip()

    def requests(self) -> Counter[str]:
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(b"requests\n")
        self.process.stdin.flush()
        return Counter(json.loads(self.process.stdout.readline()))

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait()


def per_bag(counts: Counter[str], bags: int) -> str:
    """``2.00 GetObject + 0.00 ListObjectsV2`` a bag."""
    parts = [f"{n / bags:.2f} {what}" for what, n in sorted(counts.items()) if n]
    return " + ".join(parts) or "none"


def write_images(path: Path, megabytes: int) -> None:
    """A bag of about ``megabytes`` MB: 640x480 RGB images at 10 Hz (random pixels:
    incompressible) and a 100 Hz Imu, in chunks of 4 MiB."""
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagWriter, TopicInfo

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    rng = np.random.default_rng(5)
    t0 = 1_700_000_000_000_000_000
    image_type, imu_type = "sensor_msgs/msg/Image", "sensor_msgs/msg/Imu"
    stamp = types["builtin_interfaces/msg/Time"]
    vec = types["geometry_msgs/msg/Vector3"]
    frames = megabytes * (1 << 20) // (640 * 480 * 3)
    with BagWriter(path, chunk_size=4 << 20) as bag:
        bag.add_topic(TopicInfo("/camera/image", image_type))
        bag.add_topic(TopicInfo("/imu/data", imu_type))
        for i in range(frames * 10):
            t = t0 + i * 10_000_000
            header = types["std_msgs/msg/Header"](
                stamp=stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="cam"
            )
            if i % 10 == 0:
                image = types[image_type](
                    header=header,
                    height=480,
                    width=640,
                    encoding="rgb8",
                    is_bigendian=0,
                    step=640 * 3,
                    data=rng.integers(0, 256, 640 * 480 * 3, dtype=np.uint8),
                )
                data = bytes(store.serialize_cdr(image, image_type))
                bag.write("/camera/image", data, log_time=t)
            imu = types[imu_type](
                header=header,
                orientation=types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(0.0, 0.0, 0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(0.0, 0.0, 9.81),
                linear_acceleration_covariance=np.zeros(9),
            )
            bag.write("/imu/data", bytes(store.serialize_cdr(imu, imu_type)), log_time=t)


def _serve(template: Path, bags: int) -> None:
    """Serve ``bags`` copies of ``template`` (one bytes object behind all: memory for one);
    print the URL, then the request counts (JSON) for each ``requests`` line read."""
    from tests.storage.servers import HttpStore, start_http

    store = HttpStore()
    for file in template.iterdir():
        data = file.read_bytes()
        for i in range(bags):
            store.objects[f"/large/bag_{i:02d}/{file.name}"] = data
    start_http(store)
    print(store.url, flush=True)
    for _ in sys.stdin:
        print(json.dumps(dict(store.requests)), flush=True)
    threading.Event().wait()


if __name__ == "__main__":
    _serve(Path(sys.argv[1]), int(sys.argv[2]))
