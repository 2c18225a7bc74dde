"""Imports point down: the pure core never reaches the Ray layer, the audit or the CLI, and nothing imports the CLI.

Read from the source (every ``import``, including those inside functions), so an upward import hidden
in a function body counts too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "dsage_ray"

#: Package areas and what they must never import (dsage_ray modules, or third-party top-level names).
FORBIDDEN = {
    "dsage_ray.core": ("dsage_ray.cli", "dsage_ray.audit", "dsage_ray.ray", "dsage_ray.api", "dsage_ray.runs", "ray"),
    "dsage_ray.qd": ("dsage_ray.cli", "dsage_ray.audit", "dsage_ray.ray", "dsage_ray.core", "ray"),
    "dsage_ray.surrogate": ("dsage_ray.cli", "dsage_ray.audit", "dsage_ray.ray", "dsage_ray.core", "ray"),
    "dsage_ray.ray": ("dsage_ray.cli", "dsage_ray.audit"),
    "dsage_ray.audit": ("dsage_ray.cli",),
    # A domain is a plug-in the core calls through the Domain protocol (dsage_ray.types), never the other way.
    "dsage_ray.domains": ("dsage_ray.cli", "dsage_ray.audit", "dsage_ray.ray", "dsage_ray.core", "dsage_ray.api",
                          "dsage_ray.runs"),
    # Agents are policies any domain may load by spec; the Maze uses them, they know no domain.
    "dsage_ray.agents": ("dsage_ray.cli", "dsage_ray.audit", "dsage_ray.ray", "dsage_ray.core", "dsage_ray.domains",
                         "dsage_ray.api", "dsage_ray.runs"),
}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def within(name: str, area: str) -> bool:
    return name == area or name.startswith(area + ".")


@pytest.mark.parametrize("area", sorted(FORBIDDEN))
def test_an_area_imports_nothing_above_it(area):
    offences = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = module_name(path)
        if within(module, area):
            offences += [f"{module} imports {name}" for name in sorted(imports(path))
                         if any(within(name, banned) for banned in FORBIDDEN[area])]
    assert not offences


def test_only_the_entry_point_is_the_cli():
    importers = [module_name(path) for path in sorted(PACKAGE.rglob("*.py"))
                 if module_name(path) != "dsage_ray.cli" and "dsage_ray.cli" in imports(path)]
    assert not importers


def runtime_imports(path: Path) -> set[str]:
    """The dsage_ray modules ``path`` imports when it runs (``if TYPE_CHECKING:`` blocks left out)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    skipped = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
               and getattr(block.test, "id", getattr(block.test, "attr", None)) == "TYPE_CHECKING"
               for node in ast.walk(block)}
    names = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return {name for name in names if within(name, "dsage_ray")}


def test_no_module_imports_one_that_imports_it_back():
    modules = {module_name(path): path for path in PACKAGE.rglob("*.py")}
    graph = {module: {name for name in runtime_imports(path) if name in modules and name != module}
             for module, path in modules.items()}
    # A package's __init__ importing its own submodules is how packages expose names, not a cycle.
    cycles = sorted(f"{a} <-> {b}" for a in graph for b in graph[a]
                    if a < b and a in graph.get(b, ()) and not (within(b, a) or within(a, b)))
    assert not cycles
