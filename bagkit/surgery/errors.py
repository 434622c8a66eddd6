"""Errors of bag surgery (all exit code 2: the input or the output path is unusable)."""

from __future__ import annotations

from collections.abc import Sequence

from bagkit.errors import OptionError


class SurgeryError(OptionError):
    """A bag cannot be rewritten as asked (bad option, output exists, nothing to write); a
    bad option's ``field`` is its path in the options (``output.force``)."""

    exit_code = 2


class NothingToCutError(SurgeryError):
    """``--around``'s condition holds for no message: no window to cut (a result, not bad
    input)."""

    exit_code = 1


def holding_no_topic(inputs: Sequence[object]) -> SurgeryError:
    """The error of a copy of ``inputs`` that list no topic at all (not "no topic is
    selected": the selection is not at fault)."""
    verb = "holds" if len(inputs) == 1 else "hold"
    return SurgeryError(f"nothing to write: {', '.join(map(str, inputs))} {verb} no topic")
