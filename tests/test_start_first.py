"""The modules ``make test`` starts first (tests/conftest.py) exist: a renamed one would silently fall back to
pytest's order and put a long module at the end of the run again."""

from pathlib import Path

from module_order import START_FIRST


def test_every_module_started_first_exists() -> None:
    here = Path(__file__).resolve().parent
    assert len(set(START_FIRST)) == len(START_FIRST)
    missing = [m for m in START_FIRST if not (here / m).is_file() and not (here.parent / m).is_file()]
    assert not missing, f"tests/module_order.py START_FIRST names modules that are not there: {missing}"
