"""Plain coercion of string, path, flag, number and choice parameters, without pydantic.

typer (0.29, pinned) coerces every parameter through a pydantic ``TypeAdapter``: importing
pydantic for that costs every command more than reading a small bag. Strings, paths, ints and
floats (with the option's ``min``/``max``), lists of them, enum choices and options with their
own ``parser`` (sizes) need no validation library; this gives those parameters a plain coercion
(``_runtime_param``, typer's own lazily built slot) and leaves any other parameter (clamped
numbers, ...) to typer.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from typer import BadParameter
from typer.core import RuntimeParam, TyperGroup

from bagkit.cli.common import ClickCommand, ClickContext


def _flag(value: Any) -> Any:
    """A flag's value: click gives flags as bools, environment values as text.

    Other text passes through: ``--install-completion SHELL`` is a flag that takes a value.
    """
    if isinstance(value, str):
        word = value.strip().lower()
        if word in ("1", "true", "yes", "on", "0", "false", "no", "off", ""):
            return word in ("1", "true", "yes", "on")
        return value
    return bool(value)


_SCALARS: dict[Any, Any] = {
    str: str,
    Path: Path,
    bool: _flag,
    int: int,
    float: float,
    list[str]: str,
    list[Path]: Path,
}
_NUMBER_NAMES = {int: "an integer", float: "a number"}


@dataclass(frozen=True)
class _PlainParam(RuntimeParam):
    """A string, path, number or enum (or a list of them), converted without pydantic."""

    convert: Any

    def _coerce_value(self, value: Any, param: Any, ctx: ClickContext) -> Any:
        if isinstance(value, (list, tuple)):
            return [self._one(v, param, ctx) for v in value]
        return self._one(value, param, ctx)

    def _one(self, value: Any, param: Any, ctx: ClickContext) -> Any:
        if self.convert in _NUMBER_NAMES:
            return self._number(value, param, ctx)
        if isinstance(self.convert, type) and issubclass(self.convert, enum.Enum):
            try:
                return self.convert(value)
            except ValueError:
                choices = ", ".join(f"'{c.value}'" for c in self.convert)
                raise BadParameter(
                    f"{value!r} is not one of {choices}.", ctx=ctx, param=param
                ) from None
        try:
            return self.convert(value)
        except BadParameter as exc:  # a parser's: named after the option, as typer's
            raise BadParameter(exc.message, ctx=ctx, param=param) from None

    def _number(self, value: Any, param: Any, ctx: ClickContext) -> Any:
        """An int or float option, within the option's ``min``/``max`` (as typer's messages)."""
        try:
            number = self.convert(value)
        except (TypeError, ValueError):
            raise BadParameter(
                f"Input should be {_NUMBER_NAMES[self.convert]}, got {value!r}",
                ctx=ctx,
                param=param,
            ) from None
        low, high = self.parameter_info.min, self.parameter_info.max
        if low is not None and not number >= low:
            raise BadParameter(
                f"Input should be greater than or equal to {low}", ctx=ctx, param=param
            )
        if high is not None and not number <= high:
            raise BadParameter(
                f"Input should be less than or equal to {high}", ctx=ctx, param=param
            )
        return number


def _plain(annotation: Any) -> Any | None:
    if annotation in _SCALARS:
        return _SCALARS[annotation]
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return annotation
    return None


def use_plain_params(params: list[Any]) -> None:
    """Give the plain ones of ``params`` the plain coercion (unless they have one)."""
    for param in params:
        descriptor = getattr(param, "type_descriptor", None)
        info = getattr(descriptor, "parameter_info", None)
        if descriptor is None or info is None or descriptor.file_annotation is not None:
            continue
        # An option's own parser (a size, ...) converts it plainly too.
        convert = getattr(info, "parser", None) or _plain(descriptor.annotation)
        if convert is None:
            continue
        if getattr(info, "clamp", False):  # clamped numbers: typer's own coercion
            continue
        if getattr(param, "_runtime_param", None) is None:
            param._runtime_param = _PlainParam(
                annotation=descriptor.annotation, parameter_info=info, convert=convert
            )


def use_plain_coercion(command: ClickCommand) -> None:
    """Give the plain parameters of ``command`` and its subcommands the plain coercion.

    Applied when a command parses its arguments: click creates the help option per context.
    """
    parse_args = command.parse_args

    def parse_plainly(ctx: ClickContext, args: list[str]) -> list[str]:
        use_plain_params(command.get_params(ctx))
        return parse_args(ctx, args)

    command.parse_args = parse_plainly
    if isinstance(command, TyperGroup):
        for sub in command.commands.values():
            use_plain_coercion(sub)
