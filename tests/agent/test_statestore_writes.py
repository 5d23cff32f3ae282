"""Checkpoint writes that cannot collide (issue 42, item 4): each temporary file is the write's own, and a
failed write is one StateWriteError line naming the file while the last committed state stays loadable."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fleetrl.agent.statestore import StateStore, StateWriteError


def test_two_writers_never_share_a_temporary_name_and_a_failed_write_is_one_line(tmp_path: Path) -> None:
    first, second = StateStore(tmp_path, "chief"), StateStore(tmp_path, "chief")
    first.save({"round": 1}, {"x": np.ones(3, np.float32)})
    second.save({"round": 2}, {"x": np.zeros(3, np.float32)})  # its own temp names: no raw rename error
    assert StateStore(tmp_path, "chief").load()[0] == {"round": 2}
    record = tmp_path / "chief.json"
    record.unlink()
    record.mkdir()  # the record cannot be replaced: the write fails
    with pytest.raises(StateWriteError) as failed:
        first.save({"round": 3}, {"x": np.full(3, 2.0, np.float32)})
    line = str(failed.value)
    assert "\n" not in line and str(record) in line and "stays loadable" in line, line
    assert not list(tmp_path.glob(".*.partial"))  # its temporary file removed
