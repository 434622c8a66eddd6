"""Errors of bag surgery (all exit code 2: the input or the output path is unusable)."""

from __future__ import annotations

from bagkit.errors import OptionError


class SurgeryError(OptionError):
    """A bag cannot be rewritten as asked (bad option, output exists, nothing to write); a
    bad option's ``field`` is its path in the options (``output.force``)."""

    exit_code = 2


class NothingToCutError(SurgeryError):
    """``--around``'s condition holds for no message: no window to cut (a result, not bad
    input)."""

    exit_code = 1
