"""The root of bagkit's exceptions: the CLI prints these as one line, without a traceback."""

from __future__ import annotations


class BagkitError(Exception):
    """An error the user can act on; ``exit_code`` is what the CLI exits with."""

    exit_code: int = 2


def not_read(bag: str, why: str, undone: str = "not read") -> str:
    """``BAG: not read: why``, what every many-bag command says of a bag it cannot read
    (docs/fleet.md; export: ``not exported``), the bag named once: a reader's error starts
    with its path."""
    return f"{bag}: {undone}: {why.removeprefix(f'{bag}: ')}"


class OptionError(BagkitError):
    """A value of an options dataclass that cannot be: ``field`` names it as the library does
    (``snapshot.max_duration_ns``), so that the CLI can name its flag instead.

    Args:
        problem: what is wrong with it.
        field: the field's path in the options (None: not one field's fault).
    """

    def __init__(self, problem: str, field: str | None = None) -> None:
        super().__init__(f"{field}: {problem}" if field else problem)
        self.problem = problem
        self.field = field


class SettingWarning(UserWarning):
    """A warning whose remedy is a setting: ``setting`` names it as the library knows it
    (``BAGKIT_DISTRO``), so that the CLI can name its flag instead.

    Args:
        problem: what happened.
        setting: what chooses otherwise.
    """

    def __init__(self, problem: str, setting: str) -> None:
        super().__init__(f"{problem} ({setting} chooses)")
        self.problem = problem
        self.setting = setting

    def __reduce__(self) -> tuple[type[SettingWarning], tuple[str, str]]:
        # Rebuilt from both parts: pytest-xdist and Dask pickle warnings between processes.
        return type(self), (self.problem, self.setting)
