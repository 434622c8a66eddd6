"""Errors of message migration: rules that do not parse or do not fit, data that would be lost."""

from __future__ import annotations

from bagkit.errors import OptionError


class MigrateError(OptionError):
    """A migration that cannot be made as asked (bad input: exit 2); ``field`` names the option
    that would allow it (``allow_drop``)."""

    exit_code = 2


class RuleError(MigrateError):
    """A rule that does not parse, names a field that does not exist, or yields a value that
    does not fit the new type; the message names the rule (``rules.yaml: pkg/msg/T compute
    x``)."""


class DataLossError(MigrateError):
    """Fields whose values the migration would drop with no rule saying so (``allow_drop``)."""
