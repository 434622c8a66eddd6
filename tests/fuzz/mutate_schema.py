"""Bags written with hostile message definitions (recursive types, deep chains, garbage) or
hostile payloads (CDR lengths at edge values, truncations, flipped bits)."""

from __future__ import annotations

import random
import struct
from pathlib import Path

from bagkit.bag import BagWriter, TopicInfo

SEPARATOR = "=" * 80
NODE = "fuzz_msgs/msg/Node"
SEQ = "fuzz_msgs/msg/Seq"
SEQ_DEFINITION = "float64[] values\nstring[] names\nstring label\nuint8[] blob\nint32 tail\n"
CDR_HEADER = b"\x00\x01\x00\x00"
EDGE_LENGTHS = [0, 1, 7, 1 << 16, (1 << 31) - 1, 1 << 31, (1 << 32) - 1]


def _with(main: str, *deps: tuple[str, str]) -> str:
    return main + "".join(f"\n{SEPARATOR}\nMSG: {name}\n{text}" for name, text in deps)


def _chain(depth: int) -> str:
    deps = [(f"fuzz_msgs/T{i}", f"fuzz_msgs/T{i + 1} next") for i in range(depth)]
    deps.append((f"fuzz_msgs/T{depth}", "float64 x"))
    return _with("fuzz_msgs/T0 next\nfloat64 y", *deps)


def _garbage(rng: random.Random) -> str:
    alphabet = "abc[]<=/\n #=:-_09\t\x00\u00e9" + SEPARATOR[:3]
    return "".join(rng.choice(alphabet) for _ in range(rng.randint(0, 400)))


def definitions(rng: random.Random) -> dict[str, str]:
    """Hostile definitions of NODE, by name (built on demand: some are large)."""
    return {
        "self": "fuzz_msgs/Node child\nfloat64 x",
        "self-sequence": "fuzz_msgs/Node[] children\nfloat64 x",
        "self-array": "fuzz_msgs/Node[2] pair\nfloat64 x",
        "mutual": _with("fuzz_msgs/B b\nfloat64 x", ("fuzz_msgs/B", "fuzz_msgs/Node a")),
        "chain-100": _chain(100),
        "chain-1000": _chain(1000),
        "chain-5000": _chain(5000),
        "garbage": _garbage(rng),
        "huge-array": "float64[4294967295] x",
        "big-array": "uint8[100000000] blob",
        "bad-bound": "string<=-1 s\nint32[<=99999999999999999999] v",
        "unknown-type": "no_pkg/Missing m\nfloat64 x",
        "bad-constant": "int32 A=abc\nuint8 B=300\nfloat64 x",
        "empty": "",
        "bare-separator": _with("float64 x", ("", "")),
        "many-fields": "\n".join(f"float64 f{i}" for i in range(10_000)),
        "non-ascii": "float64 caf\u00e9\nstring \u6e2c",
        # Kilted+ forms (bagkit.decode.stored): IDL sections, SRV and ACTION texts.
        "idl-unparsable": _idl("module fuzz_msgs { module msg { struct Node { double x;; }; }; };"),
        "idl-other-type": _idl("module o { module msg { struct Other { double x; }; }; };"),
        "idl-garbage": _idl(_garbage(rng)),
        "idl-deep-modules": _idl("module m { " * 3000 + "struct Node { double x; };" + "};" * 3000),
        "idl-huge": _idl("// padding\n" * 40_000 + "module fuzz_msgs { };"),
        "action-missing-section": f"{SEPARATOR}\nACTION: fuzz_msgs/action/Node\nint32 a\n---\n",
        "action-garbage": f"{SEPARATOR}\nACTION: fuzz_msgs/action/Node\n{_garbage(rng)}",
        "srv-no-separator": f"{SEPARATOR}\nSRV: fuzz_msgs/srv/Node\nint32 a\n",
        "unknown-header": f"{SEPARATOR}\nFOO: fuzz_msgs/msg/Node\nint32 a\n",
    }


def _idl(body: str) -> str:
    return f'{SEPARATOR}\nIDL: {NODE}\n#include "fuzz_msgs/msg/Other.idl"\n{body}'


def _seq_payload(rng: random.Random) -> tuple[bytes, str]:
    """A Seq payload with one length field at an edge value (or cut short)."""
    which = rng.choice(["values", "names", "names[0]", "label", "blob", "cut", "empty", "random"])
    length = rng.choice(EDGE_LENGTHS)
    u32 = struct.Struct("<I").pack
    values = u32(length if which == "values" else 2) + b"\x00" * 4 + struct.pack("<dd", 1.5, -2.0)
    names = u32(length if which == "names" else 1) + u32(length if which == "names[0]" else 2)
    names += b"a\x00\x00\x00"
    label = u32(length if which == "label" else 3) + b"ok\x00\x00"
    blob = u32(length if which == "blob" else 2) + b"\x01\x02\x00\x00" + u32(7)
    payload = CDR_HEADER + values + names + label + blob
    if which == "cut":
        payload = payload[: rng.randrange(len(payload))]
    elif which == "empty":
        payload = b""
    elif which == "random":
        payload = rng.randbytes(rng.randrange(64))
    return payload, f"{which} length {length}"


def write_schema_bag(rng: random.Random, path: Path) -> str:
    """A bag whose NODE topic has a hostile definition; payloads are bytes of random length."""
    name, text = rng.choice(sorted(definitions(rng).items()))
    compression = rng.choice(["zstd", "lz4", "none"])
    with BagWriter(path, compression=compression) as bag:
        bag.add_topic(TopicInfo("/node", NODE), definition=text)
        bag.add_topic(TopicInfo("/seq", SEQ), definition=SEQ_DEFINITION)
        for i in range(10):
            bag.write("/node", CDR_HEADER + rng.randbytes(rng.randrange(40)), log_time=1000 + i)
            bag.write("/seq", _seq_payload(rng)[0] if i == 5 else _good_seq(), log_time=1000 + i)
    return f"schema {name} ({compression})"


def _good_seq() -> bytes:
    u32 = struct.Struct("<I").pack
    return (
        CDR_HEADER
        + u32(2) + b"\x00" * 4 + struct.pack("<dd", 1.5, -2.0)
        + u32(1) + u32(2) + b"a\x00\x00\x00"
        + u32(3) + b"ok\x00\x00"
        + u32(2) + b"\x01\x02\x00\x00" + u32(7)
    )  # fmt: skip


def write_payload_bag(rng: random.Random, path: Path) -> str:
    """A bag of Seq messages, a few of which have hostile lengths or are cut or random."""
    compression = rng.choice(["zstd", "lz4", "none"])
    recipes = []
    with BagWriter(path, compression=compression) as bag:
        bag.add_topic(TopicInfo("/seq", SEQ), definition=SEQ_DEFINITION)
        for i in range(20):
            if rng.random() < 0.2:
                payload, recipe = _seq_payload(rng)
                recipes.append(f"#{i} {recipe}")
            else:
                payload = _good_seq()
            bag.write("/seq", payload, log_time=1000 + i)
    return f"payload ({compression}): {', '.join(recipes) or 'none hostile'}"
