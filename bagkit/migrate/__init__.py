"""Message migration: messages of one definition rewritten to another, field by field.

- :mod:`~bagkit.migrate.rules`: the rules file (renames, computed fields, drops, a function)
- :mod:`~bagkit.migrate.targets`: the definitions to migrate to (installed, another bag's,
  an interface package directory's)
- :mod:`~bagkit.migrate.values`: one value made to fit a field of the new definition
- :mod:`~bagkit.migrate.plan`: per type, where each new field comes from; what is dropped
- :mod:`~bagkit.migrate.topics`: a topic's payloads rewritten (decode, convert, encode, check)

No rclpy here: ``play --on-drift migrate`` and ``bagkit migrate`` (bag surgery,
:mod:`bagkit.surgery.migrate`) share this core.
"""

from __future__ import annotations

from bagkit.migrate.errors import DataLossError, MigrateError, RuleError
from bagkit.migrate.rules import Rules, load_rules
from bagkit.migrate.targets import Target
from bagkit.migrate.topics import TopicMigration, migrate_topic

__all__ = [
    "DataLossError",
    "MigrateError",
    "RuleError",
    "Rules",
    "Target",
    "TopicMigration",
    "load_rules",
    "migrate_topic",
]
