"""The shape of fleetrl's source, read with ``ast``: layers, import cycles, long files, lazy imports.

tests/test_architecture.py asserts these rules (docs/architecture.md says why); run this file to print the
figures: ``python tests/architecture_report.py``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
MAX_LINES = 400

LAYERS: tuple[tuple[str, ...], ...] = (
    ("fleetrl.coercion", "fleetrl.portable"),
    ("fleetrl.devices", "fleetrl.transport"),
    ("fleetrl.link",),
    ("fleetrl.envs",),
    ("fleetrl.agent",),
    ("fleetrl.federation", "fleetrl.control"),
    ("fleetrl.runs",),
    ("fleetrl.cli",),
)
"""The layers, lowest first. A module imports its own package and the packages of lower rows, nothing beside
it on its row nor above it. The package's own ``__init__`` (it registers the envs) stands above them all."""

LAZY_IMPORTS: dict[tuple[str, str], str] = {
    ("fleetrl", "torch"): "about 1 s to import; the chief, a device bridge and --help never need it",
    ("fleetrl", "numba"): "about 0.2 s to import; the chief, the broker and --help never need it",
    ("fleetrl", "onnx"): "an optional extra (fleetrl[export]) of about 0.6 s; only `fleetrl export` writes",
    ("fleetrl", "onnxruntime"): "an optional extra (fleetrl[onnx]); only an exported policy runs on it",
    ("fleetrl", "spidev"): "an optional extra (fleetrl[pi]); only the QUBE's SPI driver on a Raspberry Pi",
    ("fleetrl", "amqtt"): "about 0.1 s to import; only the embedded broker, where mosquitto is missing",
    ("fleetrl.portable", "numpy"): "portable mode sets numpy's variables before numpy loads",
    (
        "fleetrl.cli",
        "fleetrl.transport.mqtt",
    ): "paho, about 30 ms; only the commands that connect to a broker",
    (
        "fleetrl.runs",
        "fleetrl.transport.mqtt",
    ): "paho, about 30 ms; the settings every command builds check a broker's address without it",
    (
        "fleetrl.cli",
        "fleetrl.transport.broker",
    ): "asyncio and ssl, about 20 ms; only the commands that start one",
    ("fleetrl.cli", "fleetrl.runs.fleet_summary"): "about 3 ms; only a run that ended prints its summary",
    ("fleetrl.cli", "fleetrl.runs.dirlock"): "about 2 ms; only a chief or a worker locks its run directory",
    ("fleetrl.cli.roles", "fleetrl.runs.secure"): "about 3 ms; only `fleetrl secure-config` writes a config",
    (
        "fleetrl.runs.settings",
        "fleetrl.federation.chief.answer",
    ): "about 5 ms; only a federated run's settings check its round rules",
    ("fleetrl.cli.main", "importlib.metadata"): "about 40 ms; only `fleetrl experiment` looks for the lab",
    ("fleetrl.runs.live", "rich"): "about 60 ms; only a run that shows its progress (not --quiet) draws",
    (
        "fleetrl.runs.rundir",
        "fleetrl.runs.plots",
    ): "matplotlib, about 0.5 s; only when a run ends, never in a worker that records rows",
}
"""(importing package or module, imported module) → why the import may sit in a function. The first names a
module or a package and all it holds, the second a module and its submodules."""

LAZY_FROM = ("fleetrl.cli", "fleetrl.runs")
"""Besides, a command's handler, or the settings and launch code it runs, may import when it runs a fleetrl
module that loads one of the modules the list allows everywhere (devices load numba, the agent torch):
``fleetrl --help``, a settings error and a worker process that needs none of it stay quick."""


@dataclass(frozen=True)
class Import:
    """One imported module, as the importing module names it."""

    importer: str
    imported: str
    line: int
    nested: bool  # inside a function, a class or an if / try / with block (not `if TYPE_CHECKING`)

    def __str__(self) -> str:
        return f"{self.importer}:{self.line} imports {self.imported}"


@cache
def modules() -> dict[str, Path]:
    """Every module under src/, by dotted name (a package by its ``__init__``)."""
    found = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _is_type_checking(node: ast.stmt) -> bool:
    return isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING")


def _statements(body: list[ast.stmt]) -> Iterator[tuple[ast.stmt, bool]]:
    """The module's import statements, each with whether it is nested (a type-checking block's are not)."""
    for node in body:
        if _is_type_checking(node):
            assert isinstance(node, ast.If)
            yield from _statements(node.body)
            for inner in node.orelse:
                yield from ((found, True) for found in ast.walk(inner) if isinstance(found, ast.stmt))
        elif isinstance(node, ast.Import | ast.ImportFrom):
            yield node, False
        else:
            yield from ((found, True) for found in ast.walk(node) if isinstance(found, ast.stmt))


def _resolve(importer: str, node: ast.Import | ast.ImportFrom) -> Iterator[str]:
    if isinstance(node, ast.Import):
        yield from (alias.name for alias in node.names)
        return
    base = node.module or ""
    if node.level:
        package = importer.split(".")
        if modules()[importer].name != "__init__.py":
            package = package[:-1]
        base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
    for alias in node.names:
        yield f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules() else base


@cache
def imports() -> tuple[Import, ...]:
    """Every import in src/, type-checking ones included."""
    found = []
    for name, path in modules().items():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node, nested in _statements(tree.body):
            if isinstance(node, ast.Import | ast.ImportFrom):
                found += [Import(name, imported, node.lineno, nested) for imported in _resolve(name, node)]
    return tuple(dict.fromkeys(found))


def _within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def layer_of(module: str) -> tuple[int, str] | None:
    """The module's row in :data:`LAYERS` and the package it stands for there (None: no row)."""
    if module == "fleetrl":
        return len(LAYERS), module
    for rank, row in enumerate(LAYERS):
        for package in row:
            if _within(module, package):
                return rank, package
    return None


def unplaced_modules() -> list[str]:
    """The modules of fleetrl that no row of :data:`LAYERS` holds."""
    return [module for module in modules() if layer_of(module) is None]


def upward_imports() -> list[Import]:
    """Imports of a module beside or above the importer's layer."""
    found = []
    for imp in imports():
        source, target = layer_of(imp.importer), layer_of(imp.imported)
        if source is None or target is None or source[1] == target[1]:
            continue
        if target[0] >= source[0]:
            found.append(imp)
    return found


def import_cycles() -> list[list[str]]:
    """Each set of modules that import one another in a circle (Tarjan's strongly connected components)."""
    graph: dict[str, set[str]] = {module: set() for module in modules()}
    for imp in imports():
        if imp.imported in graph and imp.imported != imp.importer:
            graph[imp.importer].add(imp.imported)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in sorted(graph[module]):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component: list[str] = []
            while not component or component[-1] != module:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return sorted(cycles)


def long_files() -> dict[str, int]:
    """Files over :data:`MAX_LINES` lines, with their length."""
    lengths = {str(path.relative_to(SRC)): len(path.read_text().splitlines()) for path in modules().values()}
    return {path: n for path, n in lengths.items() if n > MAX_LINES}


def _lazy_module(imported: str, importer: str) -> bool:
    return any(_within(importer, who) and _within(imported, what) for who, what in LAZY_IMPORTS)


@cache
def loads_lazy_module(module: str) -> bool:
    """True when importing ``module`` loads a module of :data:`LAZY_IMPORTS` (through top-level imports)."""
    seen, todo = {module}, [module]
    while todo:
        for imported in _top_level_imports().get(todo.pop(), ()):
            if _lazy_module(imported, "fleetrl"):
                return True
            if imported in modules() and imported not in seen:
                seen.add(imported)
                todo.append(imported)
    return False


@cache
def _top_level_imports() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for imp in imports():
        if not imp.nested:  # importing a.b.c runs a's and a.b's __init__ too
            parts = imp.imported.split(".")
            found.setdefault(imp.importer, []).extend(".".join(parts[:n]) for n in range(1, len(parts) + 1))
    return found


def unused_lazy_entries() -> list[tuple[str, str]]:
    """Entries of :data:`LAZY_IMPORTS` that no function-level import needs any more."""
    nested = [imp for imp in imports() if imp.nested]
    return [
        (who, what)
        for who, what in LAZY_IMPORTS
        if not any(_within(imp.importer, who) and _within(imp.imported, what) for imp in nested)
    ]


def unlisted_function_imports() -> list[Import]:
    """Function-level imports that neither :data:`LAZY_IMPORTS` nor :data:`LAZY_FROM` allows."""
    return [
        imp
        for imp in imports()
        if imp.nested
        and not _lazy_module(imp.imported, imp.importer)
        and not (
            any(_within(imp.importer, package) for package in LAZY_FROM)
            and imp.imported in modules()
            and loads_lazy_module(imp.imported)
        )
    ]


def source_lines() -> int:
    """Lines of Python under src/ (as ``find src -name '*.py' | xargs cat | wc -l`` counts them)."""
    return sum(path.read_text().count("\n") for path in modules().values())


def main() -> None:
    """Print the figures."""
    cycles, upward, long, unlisted = (
        import_cycles(),
        upward_imports(),
        long_files(),
        unlisted_function_imports(),
    )
    print(f"lines of Python under src/: {source_lines()}")
    print(
        f"function-level imports: {sum(imp.nested for imp in imports())}, outside the list: {len(unlisted)}"
    )
    print(f"import cycles: {len(cycles)}")
    for cycle in cycles:
        print("  " + " ↔ ".join(cycle))
    print(f"imports beside or up the layers: {len(upward)}")
    for imp in upward:
        print(f"  {imp}")
    print(f"files over {MAX_LINES} lines: {len(long)}")
    for path, n in sorted(long.items(), key=lambda item: -item[1]):
        print(f"  {n:5} {path}")
    print("function-level imports outside the list:")
    for imp in unlisted:
        print(f"  {imp}")


if __name__ == "__main__":
    main()
