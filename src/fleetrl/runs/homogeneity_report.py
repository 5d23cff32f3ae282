"""The homogeneity test (the paper's Table 2) as a printed report with CSV files."""

from pathlib import Path

from fleetrl.devices.homogeneity import format_tables, homogeneity_test, write_csv


def homogeneity_report(
    units: int, fleet_seed: int, impulses: int, seed: int, out: Path | None, profile: str | None = None
) -> str:
    """Run the test on ``units`` simulated units of fleet profile ``profile`` (None: the default); write the
    two matrices as CSV under ``out`` if given."""
    if units < 2:
        raise ValueError(f"--units must be at least 2 to correlate units, got {units}")
    if impulses < 3:
        raise ValueError(f"--impulses must be at least 3, got {impulses}")
    result = homogeneity_test(units, fleet_seed, impulses, seed, profile=profile)
    text = format_tables(result)
    if out is not None:
        paths = write_csv(result, Path(out))
        text += "\n" + "\n".join(f"wrote {p}" for p in paths)
    return text
