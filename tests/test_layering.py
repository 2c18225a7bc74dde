"""Imports point down and never go round: dsage_ray is four layers, and no module imports one above its own.

Layers, lowest first (:data:`LAYERS`; a module may import its own layer and the ones below):

- **base**: what every other part stands on: errors, types (the Domain protocol), plug-in scanning, io, the
  allowlist unpickler (safe_pickle), memory, kernels, the run config, and the two registries that inject domains and
  agents by name
  (``dsage_ray.domains`` and ``domains.registry``, ``agent_registry``), which import no domain and no agent.
- **algorithm**: DSAGE itself: ``qd``, ``surrogate``, ``core``.
- **domains and agents**: each domain (``dsage_ray.domains.<name>``) and the agent loaders (``dsage_ray.agents``).
- **product**: what a user runs: Ray, the audit, integrations, the API, the CLIs, the config listing.

The graph is read from the source with :mod:`ast` (nothing is imported): every ``import`` and ``from ...
import`` of a dsage_ray module, at module level or inside a function (a lazy import is still a dependency),
relative ones resolved. Importing ``a.b.c`` also runs the packages ``a.b`` and ``a``, so they count as imported
too (except the importer's own packages, which are already running).

Two graphs are read. The layers are checked on the imports that run: ``if TYPE_CHECKING:`` blocks left out. Cycles
are checked with those blocks too: a type-only import never runs, but a loop of them is still two modules that
cannot be read, moved or tested one without the other.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Iterator, Mapping

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "dsage_ray"

#: Layer names, lowest first.
LAYERS = ("base", "algorithm", "domains and agents", "product")
BASE, ALGORITHM, DOMAINS_AND_AGENTS, PRODUCT = range(len(LAYERS))

#: The layer of a module and of everything below it; the longest matching name wins.
SUBTREES: dict[str, int] = {
    "dsage_ray.agent_registry": BASE, "dsage_ray.config": BASE, "dsage_ray.domains.registry": BASE,
    "dsage_ray.errors": BASE, "dsage_ray.io": BASE, "dsage_ray.kernels": BASE, "dsage_ray.memory": BASE,
    "dsage_ray.plugins": BASE, "dsage_ray.safe_pickle": BASE, "dsage_ray.types": BASE,
    "dsage_ray.core": ALGORITHM, "dsage_ray.qd": ALGORITHM, "dsage_ray.surrogate": ALGORITHM,
    "dsage_ray.agents": DOMAINS_AND_AGENTS, "dsage_ray.domains": DOMAINS_AND_AGENTS,
    "dsage_ray.api": PRODUCT, "dsage_ray.audit": PRODUCT, "dsage_ray.cli": PRODUCT,
    "dsage_ray.cli_args": PRODUCT, "dsage_ray.config_listing": PRODUCT, "dsage_ray.integrations": PRODUCT,
    "dsage_ray.preflight": PRODUCT, "dsage_ray.ray": PRODUCT, "dsage_ray.results": PRODUCT, "dsage_ray.runs": PRODUCT,
    "dsage_ray.surrogate_cli": PRODUCT,
}
#: Package ``__init__`` modules whose layer differs from their submodules' (matched exactly): the package
#: itself (it loads the API lazily, by name) and the domain registry's face (``build_domain``), which imports no
#: domain.
PACKAGE_INITS: dict[str, int] = {"dsage_ray": BASE, "dsage_ray.domains": BASE}

#: Areas of one layer, or of neighbouring ones, that must still not import each other: QD and the surrogate are
#: parts the core puts together, a domain is a plug-in the core calls through the Domain protocol
#: (dsage_ray.types), and agents are policies any domain may load by spec.
KEPT_APART: dict[str, tuple[str, ...]] = {
    "dsage_ray.qd": ("dsage_ray.core",),
    "dsage_ray.surrogate": ("dsage_ray.core",),
    "dsage_ray.domains": ("dsage_ray.core",),
    "dsage_ray.agents": ("dsage_ray.core", "dsage_ray.domains"),
}
#: The algorithm runs without Ray: only the product layer starts actors.
RAY_FREE = ("dsage_ray.core", "dsage_ray.qd", "dsage_ray.surrogate")

Graph = Mapping[str, set[str]]


# --- reading the imports ----------------------------------------------------------------------------------------


def module_name(path: Path, root: Path) -> str:
    """``dsage_ray.core.runner`` for ``root/core/runner.py``; a package's ``__init__.py`` is the package."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_modules(root: Path) -> dict[str, Path]:
    """Every module of the package at ``root``, by dotted name."""
    return {module_name(path, root): path for path in sorted(root.rglob("*.py"))}


def is_type_checking_block(node: ast.AST) -> bool:
    """``if TYPE_CHECKING:`` or ``if typing.TYPE_CHECKING:``."""
    if not isinstance(node, ast.If):
        return False
    test = node.test
    return getattr(test, "id", None) == "TYPE_CHECKING" or getattr(test, "attr", None) == "TYPE_CHECKING"


def import_nodes(node: ast.AST, *, type_checking: bool) -> Iterator[ast.AST]:
    """Every node below ``node``, function bodies included; ``if TYPE_CHECKING:`` bodies only when
    ``type_checking`` (otherwise only the nodes that can run)."""
    for child in ast.iter_child_nodes(node):
        if is_type_checking_block(child) and not type_checking:
            # Its ``else:`` runs; its body never does.
            for other in child.orelse:
                yield other
                yield from import_nodes(other, type_checking=False)
            continue
        yield child
        yield from import_nodes(child, type_checking=type_checking)


def absolute_base(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The module a ``from ... import`` reads from, with a relative one (``from ..x import y``) resolved."""
    if not node.level:
        return node.module or ""
    parts = module.split(".") if is_package else module.split(".")[:-1]
    parts = parts[:len(parts) - (node.level - 1)]
    return ".".join(parts + ([node.module] if node.module else []))


def imported_names(source: str, module: str, is_package: bool, *, type_checking: bool = False) -> set[str]:
    """Every dotted name ``source`` imports when it runs (and in its ``if TYPE_CHECKING:`` blocks when
    ``type_checking``): modules, and ``module.name`` for each ``from`` import (the name may be a submodule)."""
    names: set[str] = set()
    for node in import_nodes(ast.parse(source), type_checking=type_checking):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = absolute_base(node, module, is_package)
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def with_packages(name: str, importer: str) -> set[str]:
    """``name`` and the packages importing it runs, less the importer's own (already running) packages."""
    parts = name.split(".")
    running = {".".join(importer.split(".")[:i]) for i in range(1, importer.count(".") + 1)}
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)} - running


def import_graph(root: Path, *, type_checking: bool = False) -> dict[str, set[str]]:
    """Each module of the package at ``root`` and the package's modules it imports (itself left out), with the
    imports of its ``if TYPE_CHECKING:`` blocks when ``type_checking``."""
    modules = package_modules(root)
    graph = {}
    for module, path in modules.items():
        names = imported_names(path.read_text(), module, path.name == "__init__.py", type_checking=type_checking)
        reached = set().union(*(with_packages(name, module) for name in names)) if names else set()
        graph[module] = {name for name in reached if name in modules and name != module}
    return graph


# --- the checks --------------------------------------------------------------------------------------------------


def layer_of(module: str) -> int | None:
    """The layer of ``module`` (an index into :data:`LAYERS`), or None when the map does not place it."""
    if module in PACKAGE_INITS:
        return PACKAGE_INITS[module]
    covering = [name for name in SUBTREES if module == name or module.startswith(name + ".")]
    return SUBTREES[max(covering, key=len)] if covering else None


def upward_imports(graph: Graph) -> list[str]:
    """``"layer: a -> layer: b"`` for each import of a module in a higher layer than the importer's."""
    found = []
    for module in sorted(graph):
        for imported in sorted(graph[module]):
            unplaced = layer_of(module) is None or layer_of(imported) is None  # test_every_module_has_a_layer
            if not unplaced and layer_of(imported) > layer_of(module):
                found.append(f"{LAYERS[layer_of(module)]}: {module} -> {LAYERS[layer_of(imported)]}: {imported}")
    return found


def import_cycles(graph: Graph) -> list[list[str]]:
    """The modules that import each other round a loop: each strongly connected component of more than one
    module (Tarjan's algorithm), sorted."""
    order: dict[str, int] = {}
    lowest: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []

    def visit(module: str) -> None:
        order[module] = lowest[module] = len(order)
        stack.append(module)
        on_stack.add(module)
        for imported in graph.get(module, ()):
            if imported not in order:
                visit(imported)
                lowest[module] = min(lowest[module], lowest[imported])
            elif imported in on_stack:
                lowest[module] = min(lowest[module], order[imported])
        if lowest[module] == order[module]:  # ``module`` roots a component: pop it
            component = []
            while not component or component[-1] != module:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in sorted(graph):
        if module not in order:
            visit(module)
    return sorted(cycles)


def within(name: str, area: str) -> bool:
    return name == area or name.startswith(area + ".")


# --- the package --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(PACKAGE)


@pytest.fixture(scope="module")
def typed_graph() -> dict[str, set[str]]:
    """:func:`graph` with the type-only imports."""
    return import_graph(PACKAGE, type_checking=True)


def test_every_module_has_a_layer(graph):
    # A new top-level module must be placed in the map, so that it is checked.
    assert [module for module in graph if layer_of(module) is None] == []


def test_no_module_imports_a_higher_layer(graph):
    assert upward_imports(graph) == []


def test_no_import_cycles_type_only_imports_included(typed_graph):
    # The typed graph holds every edge of the runtime one, so this also covers the cycles that run.
    assert import_cycles(typed_graph) == []


def test_areas_kept_apart_do_not_import_each_other(graph):
    offences = [f"{module} -> {imported}" for module in sorted(graph) for imported in sorted(graph[module])
                for area, banned in KEPT_APART.items() if within(module, area)
                and any(within(imported, other) for other in banned)]
    assert offences == []


def test_the_algorithm_never_imports_ray():
    offences = []
    for module, path in package_modules(PACKAGE).items():
        if any(within(module, area) for area in RAY_FREE):
            names = imported_names(path.read_text(), module, path.name == "__init__.py")
            offences += [f"{module} imports {name}" for name in sorted(names) if within(name, "ray")]
    assert offences == []


def test_only_the_entry_point_is_the_cli(graph):
    assert [module for module in graph if "dsage_ray.cli" in graph[module]] == []


# --- the checker itself --------------------------------------------------------------------------------------------


def test_the_checker_reports_an_upward_import_and_a_cycle():
    graph = {
        "dsage_ray.errors": set(),
        "dsage_ray.core.loop": {"dsage_ray.errors", "dsage_ray.audit.report"},  # upward: algorithm -> product
        "dsage_ray.audit.report": {"dsage_ray.audit.run"},
        "dsage_ray.audit.run": {"dsage_ray.audit.series"},
        "dsage_ray.audit.series": {"dsage_ray.audit.report"},  # round: report -> run -> series -> report
    }
    assert upward_imports(graph) == ["algorithm: dsage_ray.core.loop -> product: dsage_ray.audit.report"]
    assert import_cycles(graph) == [["dsage_ray.audit.report", "dsage_ray.audit.run", "dsage_ray.audit.series"]]


def test_the_reader_sees_lazy_and_relative_imports_but_not_type_checking_ones(tmp_path):
    root = tmp_path / "dsage_ray"
    (root / "core").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "errors.py").write_text("")
    (root / "types.py").write_text("")
    (root / "core" / "__init__.py").write_text("from .loop import run\n")
    (root / "core" / "loop.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "from ..errors import InputError\n"
        "if TYPE_CHECKING:\n"
        "    from dsage_ray.types import Domain\n"
        "def run():\n"
        "    from dsage_ray.audit import report\n")
    (root / "audit").mkdir()
    (root / "audit" / "__init__.py").write_text("")
    (root / "audit" / "report.py").write_text("import dsage_ray.core.loop\n")
    graph = import_graph(root)
    assert graph["dsage_ray.core"] == {"dsage_ray.core.loop"}
    assert graph["dsage_ray.core.loop"] == {"dsage_ray.errors", "dsage_ray.audit", "dsage_ray.audit.report"}
    # ``import dsage_ray.core.loop`` runs the core package too.
    assert graph["dsage_ray.audit.report"] == {"dsage_ray.core", "dsage_ray.core.loop"}
    assert import_cycles(graph) == [["dsage_ray.audit.report", "dsage_ray.core", "dsage_ray.core.loop"]]
    # With the type-only imports, core.loop also imports dsage_ray.types.
    typed = import_graph(root, type_checking=True)
    assert typed["dsage_ray.core.loop"] == graph["dsage_ray.core.loop"] | {"dsage_ray.types"}
    assert typed["dsage_ray.audit.report"] == graph["dsage_ray.audit.report"]


def test_a_cycle_of_type_only_imports_is_found_in_the_typed_graph_alone(tmp_path):
    # The shape of the old core.outputs -> snapshot -> tensorboard_log -> outputs loop: two type-only imports
    # and a lazy one.
    root = tmp_path / "dsage_ray"
    (root / "core").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "core" / "__init__.py").write_text("")
    (root / "core" / "outputs.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n"
        "    from dsage_ray.core.snapshot import RunSnapshot\n")
    (root / "core" / "snapshot.py").write_text(
        "import typing\n"
        "if typing.TYPE_CHECKING:\n"
        "    from .tensorboard_log import GrowthPoint\n"
        "else:\n"
        "    import json\n")
    (root / "core" / "tensorboard_log.py").write_text(
        "def log():\n"
        "    from dsage_ray.core.outputs import heatmap_png\n")
    loop = ["dsage_ray.core.outputs", "dsage_ray.core.snapshot", "dsage_ray.core.tensorboard_log"]
    assert import_cycles(import_graph(root)) == []
    assert import_cycles(import_graph(root, type_checking=True)) == [loop]


def test_the_package_cites_decisions_not_the_records_sections():
    # The package points at docs/DECISIONS.md for why a default is what it is, not at a record's sections.
    citing = [str(path.relative_to(PACKAGE)) for path in sorted(PACKAGE.rglob("*"))
              if path.suffix in (".py", ".toml", ".md", ".css", ".js")
              and ("§" in (text := path.read_text()) or "equal_compute" in text)]
    assert citing == []
