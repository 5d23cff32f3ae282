"""README's results table is generated from the committed records (one source with docs/results.md)."""

from pathlib import Path

import pytest

from fleetrl_lab import headline
from fleetrl_lab.headline import BEGIN, END, headline_table, replace_table, rows, table_in

ROOT = Path(__file__).resolve().parents[2]
RECORDS = ROOT / "lab" / "records"


def test_readme_s_results_table_is_the_one_the_records_give() -> None:
    readme = (ROOT / "README.md").read_text()
    assert table_in(readme) == headline_table(RECORDS), "README's table is stale: run make report"


def test_every_row_divides_one_unit_alone_by_a_fleet_with_the_same_settings() -> None:
    for row in rows():
        alone, fleet = row.ratio.slower, row.ratio.faster
        assert alone.units == 1 or alone.settings["mode"] == "individual"
        same = ("env", "preset", "overrides", "fleet_seed", "max_rounds")
        assert [alone.settings.get(k) for k in same] == [fleet.settings.get(k) for k in same], row.task


def test_the_table_replaces_only_what_lies_between_its_markers() -> None:
    text = f"before\n{BEGIN}\nold\n{END}\nafter\n"
    assert replace_table(text, "| new |\n") == f"before\n{BEGIN}\n| new |\n{END}\nafter\n"
    with pytest.raises(ValueError, match="markers"):
        replace_table("no markers", "| new |\n")


def test_a_missing_record_is_an_error_not_a_shorter_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(headline, "rows", lambda: rows()[:1])
    with pytest.raises(FileNotFoundError, match="no record of seed"):
        headline_table(tmp_path)
