"""Plain coercion of string, path, flag, number and choice parameters, without pydantic.

typer (0.29, pinned) coerces every parameter through a pydantic ``TypeAdapter``: importing
pydantic for that costs every command more than reading a small bag. Strings, paths, ints and
floats (with the option's ``min``/``max``), lists of them, enum choices and options with their
own ``parser`` (sizes) need no validation library; this gives those parameters a plain
``process_value`` (click's public step from parsed text to argument, per parameter) and leaves
any other parameter (clamped numbers, ...) to typer. typer 0.29 has no public hook before its
adapter: ``parser=`` and ``callback=`` both run after it, and it takes no click ParamType.
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Any

from typer import BadParameter
from typer.core import TyperGroup

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


class _Missing(BadParameter):
    """A required parameter without a value, worded as click words it."""

    def format_message(self) -> str:
        return self.message


class _PlainValue:
    """A parameter's value processing without pydantic: a string, path, number or enum (or a
    list of them) converted, then what click does with any value (required, callback).

    Set as the parameter's ``process_value``, click's public per-parameter step between the
    parsed text and the command's argument: typer's own builds a pydantic adapter first.
    """

    def __init__(self, param: Any, convert: Any) -> None:
        self.param = param
        self.convert = convert
        info = param.type_descriptor.parameter_info
        self.low, self.high = getattr(info, "min", None), getattr(info, "max", None)

    def __call__(self, ctx: ClickContext, value: Any) -> Any:
        param = self.param
        if value is None:
            value = () if param.multiple or param.nargs == -1 else None
        elif isinstance(value, (list, tuple)):
            value = [self._one(v, ctx) for v in value]
        elif param.multiple or param.nargs == -1:
            raise BadParameter("Value must be an iterable.", ctx=ctx, param=param)
        else:
            value = self._one(value, ctx)
        if param.required and param.value_is_missing(value):
            raise _Missing(f"Missing {param.param_type_name} {param.get_error_hint()}.", ctx)
        if param.callback is not None:
            value = param.callback(ctx, param, value)
        return value

    def _one(self, value: Any, ctx: ClickContext) -> Any:
        if self.convert in _NUMBER_NAMES:
            return self._number(value, ctx)
        if isinstance(self.convert, type) and issubclass(self.convert, enum.Enum):
            try:
                return self.convert(value)
            except ValueError:
                choices = ", ".join(f"'{c.value}'" for c in self.convert)
                raise BadParameter(
                    f"{value!r} is not one of {choices}.", ctx=ctx, param=self.param
                ) from None
        try:
            return self.convert(value)
        except BadParameter as exc:  # a parser's: named after the option, as typer's
            raise BadParameter(exc.message, ctx=ctx, param=self.param) from None

    def _number(self, value: Any, ctx: ClickContext) -> Any:
        """An int or float option, within the option's ``min``/``max`` (as typer's messages)."""
        try:
            number = self.convert(value)
        except (TypeError, ValueError):
            raise BadParameter(
                f"Input should be {_NUMBER_NAMES[self.convert]}, got {value!r}",
                ctx=ctx,
                param=self.param,
            ) from None
        if self.low is not None and not number >= self.low:
            raise BadParameter(
                f"Input should be greater than or equal to {self.low}", ctx=ctx, param=self.param
            )
        if self.high is not None and not number <= self.high:
            raise BadParameter(
                f"Input should be less than or equal to {self.high}", ctx=ctx, param=self.param
            )
        return number


def _plain(annotation: Any) -> Any | None:
    if annotation in _SCALARS:
        return _SCALARS[annotation]
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return annotation
    return None


def use_plain_params(params: list[Any]) -> None:
    """Give the plain ones of ``params`` the plain value processing (once each)."""
    for param in params:
        descriptor = getattr(param, "type_descriptor", None)
        info = getattr(descriptor, "parameter_info", None)
        if descriptor is None or info is None or descriptor.file_annotation is not None:
            continue
        if isinstance(vars(param).get("process_value"), _PlainValue):
            continue
        # An option's own parser (a size, ...) converts it plainly too.
        convert = getattr(info, "parser", None) or _plain(descriptor.annotation)
        if convert is None:
            continue
        if getattr(info, "clamp", False):  # clamped numbers: typer's own coercion
            continue
        param.process_value = _PlainValue(param, convert)


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
