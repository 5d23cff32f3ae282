"""The Table 2 homogeneity test on simulated units."""

import csv
from pathlib import Path

import numpy as np
import pytest

from fleetrl.devices.homogeneity import format_tables, homogeneity_test, write_csv


def test_matrices_are_correlations_and_units_differ(tmp_path: Path) -> None:
    result = homogeneity_test(units=3, fleet_seed=0, impulses=100, seed=0)
    for matrix in (result.motor, result.pendulum):
        assert matrix.shape == (3, 3)
        np.testing.assert_allclose(matrix, matrix.T)
        np.testing.assert_allclose(np.diag(matrix), 1.0)
        off_diagonal = matrix[~np.eye(3, dtype=bool)]
        assert np.all(off_diagonal < 0.999), "simulated units should not respond identically"
        assert np.all(off_diagonal > 0.0), "the same impulses should give related responses"
    assert result.motor_changes.shape == (3, 100)
    # the same fleet and seed give the same matrices
    np.testing.assert_array_equal(result.motor, homogeneity_test(3, 0, 100, 0).motor)

    paths = write_csv(result, tmp_path)
    assert [p.name for p in paths] == ["motor_correlation.csv", "pendulum_correlation.csv"]
    rows = list(csv.reader(paths[0].open()))
    assert rows[0] == ["", "unit 0", "unit 1", "unit 2"]
    assert float(rows[2][1]) == pytest.approx(result.motor[1, 0], abs=1e-4)
    text = format_tables(result)
    assert "motor angle changes" in text and "pendulum angle changes" in text


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="units must be an integer of at least 2"):
        homogeneity_test(units=1)
    with pytest.raises(ValueError, match="fleet_seed must be a non-negative integer"):
        homogeneity_test(fleet_seed=-1)
