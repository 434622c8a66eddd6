"""The import graph: nothing under bagkit/ imports fusion; rclpy only under bagkit/ros/ and
fusion/nodes/; bagkit's packages import downwards only, never the root, never a sibling of
their layer; fusion imports only bagkit's public API; no import cycles between bagkit's modules.
Walks the AST of every module, function-level imports included.
The rules are written out in docs/architecture.md."""

from __future__ import annotations

import ast
import functools
from collections.abc import Iterator, Set
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RCLPY_HOMES = (REPO / "bagkit" / "ros", REPO / "fusion" / "nodes")


# Several tests read each module: parsed and walked once per test process.
@functools.cache
def parsed(source: str) -> ast.Module:
    """``source``'s syntax tree (never changed by its readers)."""
    return ast.parse(source)


@functools.cache
def imported_modules(source: str) -> frozenset[str]:
    """Every module an ``import`` or ``from ... import`` anywhere in ``source`` names."""
    names: set[str] = set()
    for node in ast.walk(parsed(source)):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return frozenset(names)


def top_level(modules: Set[str]) -> set[str]:
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


def private_imports(modules: Set[str]) -> list[str]:
    """The modules of other packages among ``modules`` that are private (``typer._click``)."""
    return sorted(
        m
        for m in modules
        if m.split(".")[0] != "bagkit"
        and any(part.startswith("_") and not part.startswith("__") for part in m.split("."))
    )


def test_the_private_import_check() -> None:
    assert private_imports(
        {"typer._click.exceptions", "typer.core", "bagkit.ros.record._take"}
    ) == ["typer._click.exceptions"]


@pytest.mark.parametrize("path", modules_under("bagkit"), ids=lambda p: str(p.relative_to(REPO)))
def test_no_private_module_of_another_package(path: Path) -> None:
    """A dependency's private module (typer's vendored click, ...) changes without notice."""
    assert private_imports(imported_modules(path.read_text())) == []


# bagkit's packages and top-level modules from the bottom up: each imports only lower layers.
LAYERS: tuple[frozenset[str], ...] = (
    frozenset({"errors", "version", "compat", "own_environment", "words"}),
    frozenset({"processes", "prefetch", "extras", "native", "storage"}),
    frozenset({"selection"}),
    frozenset({"bag"}),
    frozenset({"recording", "playback"}),
    frozenset({"decode"}),
    frozenset({"migrate"}),
    frozenset({"ros"}),
    frozenset({"stats", "compare"}),
    frozenset({"data"}),
    frozenset({"surgery"}),
    frozenset({"fleet"}),
    frozenset({"health"}),
    frozenset({"regression"}),
    frozenset({"cli", "pytest_plugin", "__init__"}),
)
LAYER_OF = {package: level for level, packages in enumerate(LAYERS) for package in packages}


def bagkit_package(path: Path) -> str:
    """``bag`` for bagkit/bag/reader.py, ``errors`` for bagkit/errors.py."""
    return path.relative_to(REPO / "bagkit").parts[0].removesuffix(".py")


def layering_violations(own: str, modules: Set[str]) -> list[str]:
    """What is wrong with package ``own`` importing ``modules``: the root, upwards, sideways."""
    found = []
    for module in sorted(modules):
        if module == "bagkit":
            found.append(f"{module} (the root: import the module that defines the name)")
            continue
        if not module.startswith("bagkit.") or (target := module.split(".")[1]) == own:
            continue
        level, mine = LAYER_OF.get(target, len(LAYERS)), LAYER_OF[own]
        if level > mine:
            found.append(f"{module} (upwards: {target} is above {own})")
        elif level == mine:
            found.append(f"{module} (sideways: {target} and {own} share a layer)")
    return found


def test_the_layering_check_sees_root_upward_and_sideways_imports() -> None:
    modules = {"bagkit", "bagkit.compare.core", "bagkit.fleet", "bagkit.bag", "bagkit.stats.x"}
    assert [v.split()[0] for v in layering_violations("stats", modules)] == [
        "bagkit",
        "bagkit.compare.core",
        "bagkit.fleet",
    ]
    assert layering_violations("data", {"bagkit.stats", "bagkit.errors"}) == []
    # Matching and episodes (data) sit below surgery, which regression builds on.
    assert layering_violations("surgery", {"bagkit.data.episodes", "bagkit.selection"}) == []
    assert layering_violations("data", {"bagkit.surgery"})[0].split()[1:3] == [
        "(upwards:",
        "surgery",
    ]


def test_every_package_has_a_layer() -> None:
    packages = {bagkit_package(p) for p in modules_under("bagkit")}
    assert packages <= LAYER_OF.keys(), f"no layer for {sorted(packages - LAYER_OF.keys())}"


@pytest.mark.parametrize("path", modules_under("bagkit"), ids=lambda p: str(p.relative_to(REPO)))
def test_imports_go_down_the_layers(path: Path) -> None:
    own = bagkit_package(path)
    wrong = layering_violations(own, imported_modules(path.read_text()))
    assert not wrong, f"{path.relative_to(REPO)} ({own}) imports {wrong}: against the layering"


def module_path(module: str) -> Path | None:
    """The file of bagkit module ``module`` (a package's ``__init__.py``), None if none."""
    base = REPO.joinpath(*module.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def public_names(module: str) -> set[str]:
    """The names ``module`` offers: its ``__all__``, else every name without a leading ``_``."""
    path = module_path(module)
    assert path is not None, module
    tree = parsed(path.read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            return set(ast.literal_eval(node.value))
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef | ast.AsyncFunctionDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        elif isinstance(node, ast.ImportFrom | ast.Import):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return {n for n in names if not n.startswith("_")}


def bagkit_imports(source: str) -> Iterator[tuple[str, list[str]]]:
    """Each import of bagkit in ``source``: ``(module, names)``, names empty for ``import``."""
    for node in ast.walk(parsed(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "bagkit":
                    yield alias.name, []
        elif (
            isinstance(node, ast.ImportFrom)
            and node.level == 0
            and node.module
            and node.module.split(".")[0] == "bagkit"
        ):
            yield node.module, [alias.name for alias in node.names]


def private_uses(module: str, names: list[str]) -> list[str]:
    """What of ``from module import names`` is not bagkit's public API.

    Public: ``bagkit`` itself and its direct children (``bagkit.regression``,
    ``bagkit.processes``), and of those only the names in their ``__all__`` (every name without
    a leading underscore where they have none). A module inside a package is private.
    """
    if module.count(".") > 1 or module_path(module) is None:
        return [f"{module} (inside a package: import from the package)"]
    offered = public_names(module)
    return [f"{module}.{name}" for name in names if name not in offered]


def test_the_public_api_check() -> None:
    assert private_uses("bagkit.cli.common", ["fail"]) == [
        "bagkit.cli.common (inside a package: import from the package)"
    ]
    assert private_uses("bagkit.regression", ["Processor", "make_processors"]) == [
        "bagkit.regression.make_processors"
    ]
    assert private_uses("bagkit.errors", ["BagkitError"]) == []
    source = "import bagkit.stats.moments\nfrom bagkit.stats import Moments\n"
    assert list(bagkit_imports(source)) == [
        ("bagkit.stats.moments", []),
        ("bagkit.stats", ["Moments"]),
    ]


@pytest.mark.parametrize("path", modules_under("fusion"), ids=lambda p: str(p.relative_to(REPO)))
def test_fusion_uses_only_the_public_api(path: Path) -> None:
    private = [
        use
        for module, names in bagkit_imports(path.read_text())
        for use in private_uses(module, names)
    ]
    assert not private, f"{path.relative_to(REPO)} uses bagkit's private {private}"


def module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_dependencies(path: Path) -> set[str]:
    """The bagkit modules ``path`` imports, wherever the import is (a function-level or
    ``TYPE_CHECKING`` import that closes a circle only hides it); ``from a import b`` names
    ``a.b`` where that is a module. Importing ``a.b`` imports package ``a`` first: both count,
    except the importer's own enclosing packages (being imported already)."""
    name = module_name(path)
    found = set(imported_modules(path.read_text()))
    for node in ast.walk(parsed(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    with_packages = {".".join(m.split(".")[:i]) for m in found for i in range(2, m.count(".") + 2)}
    own_packages = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)}
    return {
        m
        for m in with_packages
        if m.startswith("bagkit.") and m not in own_packages and m != name and module_path(m)
    }


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                connect(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    return sorted(cycles)


def test_the_cycle_finder() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert import_cycles(graph) == [["a", "b", "c"]]


# Cycles known and accepted for now: none. A cycle breaks when a module of it is imported first
# from elsewhere, half-initialised; break one by moving what both need below both.
KNOWN_CYCLES: list[list[str]] = []


def test_no_import_cycles_between_bagkit_modules() -> None:
    graph = {module_name(p): module_dependencies(p) for p in modules_under("bagkit")}
    cycles = [c for c in import_cycles(graph) if c not in KNOWN_CYCLES]
    assert not cycles, f"import cycles between bagkit modules: {cycles}"
