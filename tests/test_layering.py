"""The import graph: nothing under bagkit/ imports fusion; rclpy only under bagkit/ros/ and
fusion/nodes/. Walks the AST of every module, function-level imports included."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RCLPY_HOMES = (REPO / "bagkit" / "ros", REPO / "fusion" / "nodes")


def imported_modules(source: str) -> set[str]:
    """Every module an ``import`` or ``from ... import`` anywhere in ``source`` names."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def top_level(modules: set[str]) -> set[str]:
    return {m.split(".")[0] for m in modules}


def modules_under(package: str) -> list[Path]:
    return sorted((REPO / package).rglob("*.py"))


def test_the_walker_sees_function_level_and_nested_imports() -> None:
    source = (
        "def f():\n    if x:\n        from fusion.params import flatten\n    import rclpy.node\n"
    )
    assert top_level(imported_modules(source)) == {"fusion", "rclpy"}


@pytest.mark.parametrize("path", modules_under("bagkit"), ids=lambda p: str(p.relative_to(REPO)))
def test_bagkit_does_not_import_fusion(path: Path) -> None:
    assert "fusion" not in top_level(imported_modules(path.read_text()))


OUTSIDE_THE_SHELLS = [
    p
    for p in modules_under("bagkit") + modules_under("fusion")
    if not any(p.is_relative_to(home) for home in RCLPY_HOMES)
]


@pytest.mark.parametrize("path", OUTSIDE_THE_SHELLS, ids=lambda p: str(p.relative_to(REPO)))
def test_rclpy_only_behind_the_ros_shells(path: Path) -> None:
    assert "rclpy" not in top_level(imported_modules(path.read_text())), (
        f"{path.relative_to(REPO)} imports rclpy: move that code under bagkit/ros/ or fusion/nodes/"
    )


# bagkit's packages from the bottom up: a package imports only packages of lower layers.
LAYERS: tuple[frozenset[str], ...] = (
    frozenset({"errors", "compat"}),
    frozenset({"times", "extras"}),
    frozenset({"selection"}),
    frozenset({"bag"}),
    frozenset({"decode", "ros"}),
    frozenset({"stats", "compare"}),
    frozenset({"data", "surgery"}),
    frozenset({"fleet"}),
    frozenset({"regression"}),
    frozenset({"cli", "pytest_plugin", "__init__"}),
)
LAYER_OF = {package: level for level, packages in enumerate(LAYERS) for package in packages}


def bagkit_package(path: Path) -> str:
    """``bag`` for bagkit/bag/reader.py, ``errors`` for bagkit/errors.py."""
    return path.relative_to(REPO / "bagkit").parts[0].removesuffix(".py")


def test_every_package_has_a_layer() -> None:
    packages = {bagkit_package(p) for p in modules_under("bagkit")}
    assert packages <= LAYER_OF.keys(), f"no layer for {sorted(packages - LAYER_OF.keys())}"


@pytest.mark.parametrize("path", modules_under("bagkit"), ids=lambda p: str(p.relative_to(REPO)))
def test_imports_go_down_the_layers(path: Path) -> None:
    own = bagkit_package(path)
    upward = sorted(
        module
        for module in imported_modules(path.read_text())
        if module.startswith("bagkit.")
        and (target := module.split(".")[1]) != own
        and LAYER_OF.get(target, len(LAYERS)) >= LAYER_OF[own]
    )
    assert not upward, f"{path.relative_to(REPO)} ({own}) imports {upward}: against the layering"
