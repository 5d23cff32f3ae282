"""The source keeps the shape docs/architecture.md draws: layers, no import cycle, short files."""

from collections.abc import Iterable

from architecture_report import (
    LAZY_IMPORTS,
    MAX_LINES,
    import_cycles,
    long_files,
    modules,
    unlisted_function_imports,
    unplaced_modules,
    unused_lazy_entries,
    upward_imports,
)


def listing(found: Iterable[object]) -> str:
    return "\n".join(f"  {item}" for item in found)


def test_the_report_reads_the_package() -> None:
    assert "fleetrl.cli.main" in modules() and "fleetrl.devices.qube" in modules()
    assert not unplaced_modules(), (
        f"modules in no layer (add their package to LAYERS):\n{listing(unplaced_modules())}"
    )


def test_no_module_imports_beside_or_up_the_layers() -> None:
    upward = upward_imports()
    assert not upward, (
        f"imports beside or up the layers (tests/architecture_report.py LAYERS):\n{listing(upward)}"
    )


def test_no_import_cycle() -> None:
    cycles = [" ↔ ".join(cycle) for cycle in import_cycles()]
    assert not cycles, f"modules that import one another in a circle:\n{listing(cycles)}"


def test_no_file_over_the_limit() -> None:
    long = [f"{n} lines: {path}" for path, n in long_files().items()]
    assert not long, f"files over {MAX_LINES} lines:\n{listing(long)}"


def test_every_lazy_entry_is_still_needed() -> None:
    unused = unused_lazy_entries()
    assert not unused, f"LAZY_IMPORTS entries no import needs (remove them):\n{listing(unused)}"


def test_function_level_imports_only_from_the_list() -> None:
    unlisted = unlisted_function_imports()
    assert not unlisted, (
        f"imports in a function or a block that LAZY_IMPORTS ({len(LAZY_IMPORTS)} entries) does not allow: "
        f"move them to the module's top, or list them with a reason:\n{listing(unlisted)}"
    )
