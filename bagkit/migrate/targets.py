"""The definitions a migration writes: installed today, another bag's, or a package directory's.

A target gives, per message type, the full ``ros2msg`` text (dependencies included, as a bag
stores it) or None when it does not have the type (such topics are copied unchanged).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from bagkit.bag.definitions import (
    canonical_type_name,
    compose_definition,
    interface_source,
    interface_text,
    message_definition,
    type_description_hash,
)
from bagkit.bag.errors import UnknownMessageTypeError
from bagkit.migrate.errors import MigrateError

_PACKAGE_NAME = re.compile(r"<name>\s*([A-Za-z0-9_]+)\s*</name>")


@dataclass(frozen=True)
class Target:
    """Where the new definitions come from.

    Attributes:
        kind: ``installed``, ``bag`` or ``package``.
        source: the bag or package directory ("" when installed).
        definitions: a bag's stored texts by type (kind ``bag``).
        package: the package name of a directory (kind ``package``).
    """

    kind: str = "installed"
    source: str = ""
    definitions: dict[str, str] = field(default_factory=dict)
    package: str = ""

    @classmethod
    def from_bag(cls, bag: Path) -> Target:
        """The definitions stored in ``bag``.

        Raises:
            BagError: the bag cannot be opened.
        """
        from bagkit.bag.reader import BagReader

        with BagReader(bag, allow_empty=True) as reader:
            texts = {canonical_type_name(t): d for t, d in reader.definitions.items()}
        return cls("bag", str(bag), texts)

    @classmethod
    def from_package(cls, directory: Path) -> Target:
        """The interface files (``msg/*.msg``, ``srv/*.srv``, ``action/*.action``) of a
        package's source directory; its name from ``package.xml`` (else the directory's).

        Raises:
            MigrateError: ``directory`` holds no interface files.
        """
        if not any((directory / kind).is_dir() for kind in ("msg", "srv", "action")):
            raise MigrateError(
                f"{directory}: no msg/, srv/ or action/ folder (not an interface package)"
            )
        manifest = directory / "package.xml"
        found = (
            _PACKAGE_NAME.search(manifest.read_text(errors="replace"))
            if manifest.is_file()
            else None
        )
        return cls(
            "package", str(directory), package=found[1] if found else directory.resolve().name
        )

    def describe(self) -> str:
        """``the installed definitions``, ``the definitions of bag B`` ..."""
        if self.kind == "installed":
            return "the installed definitions"
        return f"the definitions of {self.kind} {self.source}"

    def definition(self, type_name: str) -> str | None:
        """The full text of ``type_name`` in this target, None when it lacks the type."""
        name = canonical_type_name(type_name)
        try:
            if self.kind == "bag":
                return self.definitions.get(name)
            if self.kind == "package":
                return compose_definition(name, self._text)
            return message_definition(name)
        except UnknownMessageTypeError:
            return None

    def type_hash(self, type_name: str, text: str) -> str:
        """The RIHS01 hash to stamp on a topic written with ``text``: the installed type's
        when ``text`` is its definition, else none (a hash is only known for what is
        installed)."""
        try:
            if message_definition(type_name) == text:
                return type_description_hash(type_name)
        except UnknownMessageTypeError:
            pass
        return ""

    def _text(self, type_name: str) -> str:
        package, kind, stem, suffix = interface_source(type_name)
        if package != self.package:
            return interface_text(type_name)
        path = Path(self.source) / kind / f"{stem}{suffix}"
        if not path.is_file():
            raise UnknownMessageTypeError(f"{path}: no such interface file")
        return path.read_text(encoding="utf-8")
