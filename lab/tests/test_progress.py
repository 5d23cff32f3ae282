"""A sweep shows where it is: a bar rewritten in place in a terminal, one line per finished run otherwise;
the estimate of what is left comes from runs finished here, not from reused ones."""

import io

from fleetrl_lab.sweep import Progress, duration


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_durations_read_like_a_person_writes_them() -> None:
    assert [duration(s) for s in (4.4, 65, 3 * 3600 + 7 * 60)] == ["4 s", "1 min 05 s", "3 h 07 min"]


def test_outside_a_terminal_each_finished_run_is_one_line() -> None:
    clock, stream = Clock(), io.StringIO()
    progress = Progress(5, parallel=2, stream=stream, clock=clock, terminal=False)
    progress.reuse(1)
    progress.start("a seed 100")
    progress.start("a seed 101")
    clock.now += 60
    progress.tick()
    assert stream.getvalue() == ""  # nothing until a run finishes
    progress.finish("a seed 100")
    clock.now += 30
    progress.start("b seed 100")
    progress.finish("a seed 101")
    lines = stream.getvalue().splitlines()
    # 2 waiting and 1 running with 0 s left, at 60 s a run, 2 at a time: 1 min left
    assert lines[0] == (
        "finished a seed 100 in 1 min 00 s; 2/5 runs done (1 reused), running: a seed 101; "
        "elapsed 1 min 00 s, about 1 min 00 s left"
    )
    assert lines[1].startswith(
        "finished a seed 101 in 1 min 30 s; 3/5 runs done (1 reused), running: b seed 100;"
    )
    assert len(lines) == 2


def test_before_any_run_finishes_there_is_no_estimate_and_reused_runs_do_not_make_one() -> None:
    progress = Progress(4, stream=io.StringIO(), clock=Clock(), terminal=False)
    progress.reuse(3)
    assert progress.left() is None
    assert (
        "3/4 runs done (3 reused)" in progress.status()
        and "estimate after the first run" in progress.status()
    )


def test_in_a_terminal_one_line_is_rewritten_and_finished_runs_stay_above_it() -> None:
    clock, stream = Clock(), io.StringIO()
    progress = Progress(2, stream=stream, clock=clock, terminal=True)
    progress.start("a seed 100")
    clock.now += 5
    progress.tick()
    progress.tick()  # unchanged text: not written again
    clock.now += 5
    progress.finish("a seed 100")
    progress.close()
    text = stream.getvalue()
    assert text.count("\n") == 2  # the finished run's line, and the bar's end
    frames = text.split("\r")
    assert frames[1].startswith("[..........") and "running: a seed 100; elapsed 0 s" in frames[1]
    assert "elapsed 5 s" in frames[2] and sum("elapsed 5 s" in f for f in frames) == 1
    assert "finished a seed 100 in 10 s; 1/2 runs done; elapsed 10 s" in text
    assert text.rstrip("\n").split("\r")[-1].startswith("[##########..........] 1/2 runs done")
