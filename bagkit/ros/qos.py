"""QoS profiles: rosbag2's ``offered_qos_profiles`` YAML, adapted subscriptions, override files.

rosbag2 stores the QoS profiles a topic's publishers offered as a YAML *string* holding a list of
profiles. Metadata versions 4 to 8 write the policies as integers (the rmw enum values); Jazzy
(version 9, also in MCAP channel metadata) writes the rmw short names (``reliable``,
``transient_local``...). Both are read here; both are written (``version``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSPolicyEnum,
    QoSProfile,
    ReliabilityPolicy,
)

from bagkit.bag import TopicInfo, safe_yaml
from bagkit.ros.errors import QosProfileError
from bagkit.words import counted

# rosbag2's default depth for a profile whose history is not known (Rosbag2QoS default).
DEFAULT_DEPTH = 10
# The recorder's best-effort subscriptions: deep enough to absorb a burst while the wait-set
# loop is busy.
RECORD_DEPTH = 1000
# Publisher history for replayed volatile topics. A reliable keep-last publisher overwrites what
# a subscriber has not acknowledged once its history is full, so the history must cover the
# messages in flight: HISTORY_WINDOW_S of wall time at the topic's replay rate, at least
# REPLAY_DEPTH, at most the whole topic within HISTORY_BUDGET_BYTES (an as-fast-as-possible
# replay gets the whole topic). Not deeper: Fast DDS acknowledges a reliable writer's samples in
# batches that grow with its history, and each batch holds up publish() for a time that grows
# with it (benchmarks/README.md, "Measurements behind the code").
REPLAY_DEPTH = 100
HISTORY_WINDOW_S = 0.1
HISTORY_BUDGET_BYTES = 256 << 20
# What rclcpp's ClockQoS offers and what every use_sim_time node subscribes with.
CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
# Jazzy metadata writes strings from this version on.
STRING_POLICY_VERSION = 9
# RMW_DURATION_INFINITE as written by rosbag2: {sec: 9223372036, nsec: 854775807}.
INFINITE_NS = 2**63 - 1
# "Infinite" as Foxy-era middlewares reported it; rosbag2 reads these as RMW_DURATION_INFINITE.
_FOXY_INFINITES = {
    (0x7FFFFFFF, 0xFFFFFFFF),
    (0x7FFFFFFF, 0x7FFFFFFF),
    divmod(INFINITE_NS, 1_000_000_000),
}

_POLICIES: dict[str, type[QoSPolicyEnum]] = {
    "history": HistoryPolicy,
    "reliability": ReliabilityPolicy,
    "durability": DurabilityPolicy,
    "liveliness": LivelinessPolicy,
}
_DURATIONS = ("deadline", "lifespan", "liveliness_lease_duration")
_KEYS = frozenset([*_POLICIES, *_DURATIONS, "depth", "avoid_ros_namespace_conventions"])


def _policy(kind: str, value: Any) -> QoSPolicyEnum:
    enum = _POLICIES[kind]
    try:
        if isinstance(value, bool):
            raise ValueError(value)
        if isinstance(value, int):
            return enum(value)
        name = str(value).strip().upper()
        # rmw's "manual_by_node" was removed; older bags may still name it.
        if enum is LivelinessPolicy and name == "MANUAL_BY_NODE":
            name = "MANUAL_BY_TOPIC"
        return enum[name]
    except (KeyError, ValueError):
        choices = ", ".join(enum.short_keys())
        raise QosProfileError(f"bad {kind} {value!r} (one of: {choices})") from None


def _duration(kind: str, value: Any) -> Duration:
    if not isinstance(value, Mapping) or not {"sec", "nsec"} <= value.keys():
        raise QosProfileError(f"bad {kind} {value!r}: expected {{sec: S, nsec: NS}}")
    try:
        sec, nsec = int(value["sec"]), int(value["nsec"])
    except (TypeError, ValueError):
        raise QosProfileError(f"bad {kind} {value!r}: sec and nsec must be integers") from None
    if (sec, nsec) in _FOXY_INFINITES:
        return Duration(nanoseconds=INFINITE_NS)
    return Duration(nanoseconds=min(sec * 1_000_000_000 + nsec, INFINITE_NS))


def profile_from_dict(
    values: Mapping[str, Any], *, default_depth: int = DEFAULT_DEPTH
) -> QoSProfile:
    """Build a profile from a rosbag2 profile mapping (integer or short-name policies).

    Policies that are absent keep rclpy's defaults; a missing history means keep-last with
    ``default_depth`` (or ``depth`` when given).

    Raises:
        QosProfileError: an unknown key or value.
    """
    unknown = set(values) - _KEYS
    if unknown:
        listed = ", ".join(sorted(map(str, unknown)))
        raise QosProfileError(f"{counted(len(unknown), 'unknown QoS setting')}: {listed}")
    kwargs: dict[str, Any] = {}
    for key, value in values.items():
        if key in _POLICIES:
            kwargs[key] = _policy(key, value)
        elif key in _DURATIONS:
            kwargs[key] = _duration(key, value)
        elif key == "depth":
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise QosProfileError(f"bad depth {value!r}: expected an integer >= 0")
            kwargs[key] = value
        else:
            kwargs[key] = bool(value)
    history = kwargs.setdefault("history", HistoryPolicy.KEEP_LAST)
    if history == HistoryPolicy.KEEP_LAST and not kwargs.get("depth"):
        # rosbag2 records keep-all publishers as depth 0; a keep-last queue of 0 is unusable.
        kwargs["depth"] = default_depth
    kwargs.setdefault("depth", 0)
    return QoSProfile(**kwargs)


def _duration_dict(duration: Duration) -> dict[str, int]:
    sec, nsec = divmod(duration.nanoseconds, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def profile_to_dict(profile: QoSProfile, *, version: int = STRING_POLICY_VERSION) -> dict[str, Any]:
    """Return the rosbag2 mapping of ``profile``: short names from ``version`` 9, else integers."""

    def policy(value: QoSPolicyEnum) -> str | int:
        if version < STRING_POLICY_VERSION:
            return int(value)
        return value.short_key

    return {
        "history": policy(profile.history),
        "depth": profile.depth,
        "reliability": policy(profile.reliability),
        "durability": policy(profile.durability),
        "deadline": _duration_dict(profile.deadline),
        "lifespan": _duration_dict(profile.lifespan),
        "liveliness": policy(profile.liveliness),
        "liveliness_lease_duration": _duration_dict(profile.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": profile.avoid_ros_namespace_conventions,
    }


def dump_offered_qos_profiles(
    profiles: Iterable[QoSProfile], *, version: int = STRING_POLICY_VERSION
) -> str:
    """Serialize offered profiles as the YAML string rosbag2 stores (``""`` for none)."""
    items = [profile_to_dict(p, version=version) for p in profiles]
    if not items:
        return ""
    # rosbag2 (yaml-cpp) writes no trailing newline.
    return yaml.safe_dump(items, sort_keys=False, default_flow_style=False).rstrip("\n")


def parse_offered_qos_profiles(text: str) -> list[QoSProfile]:
    """Parse rosbag2's ``offered_qos_profiles`` string (metadata v4-v9 or MCAP channel metadata).

    Raises:
        QosProfileError: not YAML, or not a list of profiles.
    """
    if not text.strip():
        return []
    try:
        items = safe_yaml.load(text)  # read from a bag: untrusted
    except yaml.YAMLError as exc:
        raise QosProfileError(f"offered_qos_profiles is not YAML: {exc}") from None
    if items is None:
        return []
    if not isinstance(items, list) or not all(isinstance(i, Mapping) for i in items):
        raise QosProfileError("offered_qos_profiles is not a list of QoS profiles")
    return [profile_from_dict(item) for item in items]


def adapt_subscription_qos(
    offered: Sequence[QoSProfile], *, depth: int = RECORD_DEPTH
) -> QoSProfile:
    """Return a subscription profile that matches every offer and loses nothing it can keep.

    Reliable only if every publisher is reliable and transient-local only if every publisher
    is (a best-effort or volatile publisher does not match a stricter request); deadline stays
    unspecified and liveliness automatic, the weakest requests, so that they match any offer.

    A reliable subscription keeps all: a keep-last reader drops its oldest samples when it
    falls behind, even from a keep-all publisher, while a keep-all reader leaves them
    unacknowledged so that the publisher resends them. Keep-last publishers are never slowed
    by it (they overwrite their own history), keep-all publishers get the flow control they
    asked for. A best-effort subscription keeps the last ``depth``.
    """
    reliable = bool(offered) and all(p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
    latched = bool(offered) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if reliable else HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        liveliness=LivelinessPolicy.AUTOMATIC,
    )


def adapt_publisher_qos(offered: Sequence[QoSProfile]) -> QoSProfile:
    """Return a publisher profile that every subscriber of the original publishers accepts.

    An offer satisfies a request when it is at least as strict, so the strictest recorded
    policy wins: reliable if any publisher was, transient-local if any was, the shortest
    deadline and lease, manual liveliness if any. rosbag2 falls back to a reliable volatile
    default when offers differ, which transient-local subscribers reject. Keep-all if any
    publisher kept all, else the deepest keep-last depth (what a late subscriber is replayed).
    """
    if not offered:
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DEFAULT_DEPTH)

    def strictest(durations: Iterable[Duration]) -> Duration:
        # 0 means "unspecified" (= infinite) for deadline and lease.
        finite = [d.nanoseconds for d in durations if 0 < d.nanoseconds < INFINITE_NS]
        return Duration(nanoseconds=min(finite)) if finite else Duration()

    keep_all = any(p.history == HistoryPolicy.KEEP_ALL for p in offered)
    depths = [p.depth for p in offered if p.history == HistoryPolicy.KEEP_LAST and p.depth > 0]
    manual = any(p.liveliness == LivelinessPolicy.MANUAL_BY_TOPIC for p in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=max(depths, default=DEFAULT_DEPTH),
        reliability=ReliabilityPolicy.RELIABLE
        if any(p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
        else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL
        if any(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered)
        else DurabilityPolicy.VOLATILE,
        deadline=strictest(p.deadline for p in offered),
        liveliness=LivelinessPolicy.MANUAL_BY_TOPIC if manual else LivelinessPolicy.AUTOMATIC,
        liveliness_lease_duration=strictest(p.liveliness_lease_duration for p in offered),
    )


def publisher_qos(topic: TopicInfo, override: QoSProfile | None = None) -> QoSProfile:
    """The profile to replay ``topic`` with: ``override`` if given, else adapted to its offers.

    Raises:
        QosProfileError: the topic's stored ``offered_qos_profiles`` cannot be parsed.
    """
    if override is not None:
        return override
    try:
        offered = parse_offered_qos_profiles(topic.offered_qos_profiles)
    except QosProfileError as exc:
        raise QosProfileError(f"topic {topic.name}: {exc}") from None
    return adapt_publisher_qos(offered)


def replay_publisher_qos(
    info: TopicInfo, *, count: int, mean_size: int, messages_per_s: float
) -> QoSProfile:
    """The profile to replay ``info`` with: the recorded offer, with a history that covers the
    messages in flight (see ``HISTORY_WINDOW_S``).

    Args:
        info: the recorded topic.
        count: its messages in the bag.
        mean_size: their mean serialized size (bytes).
        messages_per_s: how fast they are published at the replay's rate (inf: at once).

    Transient-local topics keep the recorded depth: it is what a late subscriber gets replayed.

    Raises:
        QosProfileError: the topic's stored ``offered_qos_profiles`` cannot be parsed.
    """
    qos = publisher_qos(info)
    if (
        qos.history == HistoryPolicy.KEEP_LAST
        and qos.durability != DurabilityPolicy.TRANSIENT_LOCAL
    ):
        whole_topic = min(count, HISTORY_BUDGET_BYTES // mean_size)
        in_flight = math.ceil(min(messages_per_s * HISTORY_WINDOW_S, whole_topic))
        qos.depth = max(qos.depth, REPLAY_DEPTH, in_flight)
    return qos


def load_qos_overrides(path: str | Path) -> dict[str, QoSProfile]:
    """Read a rosbag2 ``--qos-profile-overrides-path`` file: ``{topic: {policy: value}}``.

    Policies are rmw short names (``reliability: best_effort``) or integers; durations are
    ``{sec, nsec}``. A policy that is not given keeps rclpy's default; a missing history is
    keep-last with ``depth`` (10 when not given), as in ``ros2 bag``.

    Raises:
        QosProfileError: the file is missing, not YAML, or holds an unknown policy or value.
    """
    path = Path(path)
    try:
        data = safe_yaml.load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise QosProfileError(f"cannot read QoS overrides {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise QosProfileError(f"QoS overrides {path}: not UTF-8 (byte {exc.start})") from None
    except yaml.YAMLError as exc:
        raise QosProfileError(f"QoS overrides {path} is not YAML: {exc}") from None
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise QosProfileError(f"QoS overrides {path}: expected a mapping of topic -> profile")
    overrides: dict[str, QoSProfile] = {}
    for topic, values in data.items():
        if not isinstance(values, Mapping):
            raise QosProfileError(f"QoS overrides {path}: {topic}: expected a mapping of policies")
        try:
            overrides[str(topic)] = profile_from_dict(values)
        except QosProfileError as exc:
            raise QosProfileError(f"QoS overrides {path}: {topic}: {exc}") from None
    return overrides
