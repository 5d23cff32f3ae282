"""A ratio of two arms compares like with like: the runs of the seeds both arms have, named when one arm has
more."""

from fleetrl_lab.plan import on_shared_seeds
from fleetrl_lab.records import RunRecord


def runs(*seeds: int) -> list[RunRecord]:
    return [RunRecord({"result_settings": {"seed": s}}) for s in seeds]


def seeds_of(records: list[RunRecord]) -> list[int]:
    return [r.result_settings["seed"] for r in records]


def test_a_ratio_keeps_the_seeds_both_arms_have_and_names_them() -> None:
    alone, fleet, note = on_shared_seeds(runs(100, 101, 102, 103, 104), runs(100, 101, 102, 103))
    assert seeds_of(alone) == seeds_of(fleet) == [100, 101, 102, 103]
    assert note == " (on seeds 100–103, the seeds both arms have)"
    alone, fleet, note = on_shared_seeds(runs(100, 102), runs(102, 100))
    assert (seeds_of(alone), seeds_of(fleet), note) == ([100, 102], [102, 100], "")
    alone, fleet, note = on_shared_seeds(runs(100), runs(101))
    assert (alone, fleet, note) == ([], [], " (on seeds none, the seeds both arms have)")
