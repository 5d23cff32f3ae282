"""Start-up: from typing ``fleetrl train`` to the first round's episode starting, in-process and with worker
processes on the embedded broker; and what the time goes to.

    python lab/benchmarks/startup.py [--repeats 3] [--modes local,mqtt] [--env cartpole] [--no-breakdown]

Times come from the run's log lines against the launch; the breakdown (``PYTHONPROFILEIMPORTTIME=1``) shows
the timeline and the import time between log lines.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

STAMP = re.compile(r"^(\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2},\d{3}) (.*)$")
IMPORT = re.compile(r"^import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)")
WELCOMED = re.compile(r"worker (\d+): welcomed at round 1\b")
ROUND_ONE = re.compile(r"worker (\d+) round 1: score")
# log lines left out of the timeline (one per optimisation step of a per-step scheme, or said twice)
TIMELINE_SKIP = re.compile(
    r"round 1: (answered|averaged|accepted|welcome of|worker \d+ joined)|sending|ignoring"
)
Import = tuple[str, str, float, float, int]
"""(the last log line before, module, seconds (self), seconds (cumulative), nesting) of an import"""


@dataclass
class Line:
    """One log line of a run: its time since the launch, the file it came from, its text."""

    at: float
    source: str
    text: str


@dataclass
class Run:
    """What one launch of the command showed."""

    mode: str
    wall: float
    cpu: float  # user + system seconds of the command and every process it waited for
    lines: list[Line]
    imports: dict[str, list[Import]] = field(default_factory=dict)  # by source

    def marker(self, pattern: re.Pattern[str]) -> list[float]:
        """Times of the lines matching ``pattern``, earliest first."""
        return sorted(line.at for line in self.lines if pattern.search(line.text))


def fleetrl_command() -> list[str]:
    """The ``fleetrl`` script of this Python's environment (as a user types it), else ``python -m``."""
    script = Path(sys.executable).with_name("fleetrl")
    return [str(script)] if script.exists() else [sys.executable, "-m", "fleetrl.cli.main"]


def parse_log(path: Path, source: str, launched: float) -> tuple[list[Line], list[Import]]:
    """The timestamped lines of ``path`` and the ``-X importtime`` lines between them."""
    lines: list[Line] = []
    imports: list[Import] = []
    last = "(before the first log line)"
    if not path.exists():
        return lines, imports
    for raw in path.read_text(errors="replace").splitlines():
        if match := IMPORT.match(raw):
            nesting = (len(match[3]) - 1) // 2
            imports.append((last, match[4], int(match[1]) / 1e6, int(match[2]) / 1e6, nesting))
            continue
        if match := STAMP.match(raw):
            at = datetime.strptime(match[1], "%Y-%m-%d %H:%M:%S,%f").timestamp() - launched
            text = match[2]
            lines.append(Line(at, source, text))
            last = f"{at:5.2f} s {text[:80]}"
    return lines, imports


def launch(mode: str, env: str, units: int, work: Path, profile_imports: bool) -> Run:
    """Run the command once in ``mode`` (local or mqtt) and collect its logs."""
    out = work / f"{mode}-{time.monotonic_ns()}"
    argv = [*fleetrl_command(), "-v", "train", "--env", env, "--units", str(units), "--max-rounds", "1"]
    argv += ["--out", str(out), "--no-live", "--transport", mode]
    environ = dict(os.environ)
    if profile_imports:
        environ["PYTHONPROFILEIMPORTTIME"] = "1"
    stderr_path = work / f"{out.name}.stderr"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with stderr_path.open("w") as stderr:
        launched = time.time()
        done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=stderr, env=environ, check=False)
        wall = time.time() - launched
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} exited {done.returncode}: see {stderr_path}")
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    run = Run(mode, wall, cpu, [])
    sources = [(stderr_path, "command")]
    sources += [(out / "logs" / "run.log", "run.log")]
    sources += [(out / "logs" / f"worker-{k}.log", f"worker-{k}") for k in range(units)]
    for path, source in sources:
        lines, imports = parse_log(path, source, launched)
        run.lines += lines
        if imports:
            run.imports[source] = imports
    run.lines.sort(key=lambda line: line.at)
    return run


def figures(run: Run, units: int) -> dict[str, float]:
    """The start-up figures of one run (seconds since the launch)."""
    welcomed = run.marker(WELCOMED)
    ended = run.marker(ROUND_ONE)
    if len(welcomed) < units or len(ended) < units:
        raise SystemExit(f"{run.mode}: the markers are missing from the logs ({welcomed}, {ended})")
    return {
        "first episode": welcomed[0],
        "every episode": welcomed[units - 1],
        "round 1 ended": ended[units - 1],
        "command": run.wall,
        "CPU": run.cpu,
    }


def print_timeline(run: Run) -> None:
    """fleetrl's log lines of the run with their times (the run's log repeats the command's: left out)."""
    print(f"\ntimeline of one {run.mode} run (seconds since the command was launched):")
    for line in run.lines:
        if line.source == "run.log" or "fleetrl" not in line.text or TIMELINE_SKIP.search(line.text):
            continue
        print(f"  {line.at:6.2f}  {line.source:9s} {line.text[:110]}")


def print_imports(run: Run, top: int) -> None:
    """Per process: import seconds between consecutive log lines, and the heaviest top-level packages."""
    for source in ("command", "worker-0"):
        imports = run.imports.get(source)
        if not imports:
            continue
        total = sum(seconds for _, _, seconds, _, _ in imports)
        print(f"\nimports of the {run.mode} run's {source} process: {total:.2f} s (self times summed)")
        by_phase: dict[str, float] = {}
        outer: dict[str, list[tuple[float, str]]] = {}
        by_package: dict[str, float] = {}
        for phase, module, seconds, cumulative, nesting in imports:
            by_phase[phase] = by_phase.get(phase, 0.0) + seconds
            if nesting == 0:
                outer.setdefault(phase, []).append((cumulative, module))
            package = module.split(".")[0] if not module.startswith("torch._dynamo") else "torch._dynamo"
            by_package[package] = by_package.get(package, 0.0) + seconds
        print("  imported after the log line (the largest imports there):")
        for phase, seconds in by_phase.items():
            if seconds >= 0.02:
                largest = sorted(outer.get(phase, []), reverse=True)[:3]
                names = ", ".join(f"{module} {cumulative:.2f}" for cumulative, module in largest)
                print(f"    {seconds:5.2f} s  after {phase}\n             ({names})")
        heaviest = sorted(by_package.items(), key=lambda item: -item[1])[:top]
        print("  heaviest packages: " + ", ".join(f"{name} {seconds:.2f} s" for name, seconds in heaviest))


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--modes", default="local,mqtt", help="comma-separated: local, mqtt")
    parser.add_argument("--env", default="cartpole")
    parser.add_argument("--units", type=int, default=3)
    parser.add_argument("--no-breakdown", dest="breakdown", action="store_false")
    parser.add_argument("--top", type=int, default=10, help="packages listed in the import breakdown")
    args = parser.parse_args()
    from fleetrl import portable

    print(f"host: {portable.describe_host()}; load average {os.getloadavg()[0]:.1f} at the start")
    print(f"command: {' '.join(fleetrl_command())} -v train --env {args.env} --units {args.units} ...")
    modes = args.modes.split(",")
    with tempfile.TemporaryDirectory(prefix="fleetrl-startup-") as tmp:
        work = Path(tmp)
        runs = {
            mode: [launch(mode, args.env, args.units, work, False) for _ in range(args.repeats)]
            for mode in modes
        }
        print(
            f"\nmedian of {args.repeats} (min-max), seconds from the launch; load average now "
            f"{os.getloadavg()[0]:.1f}"
        )
        for mode in modes:
            table = [figures(run, args.units) for run in runs[mode]]
            cells = []
            for name in table[0]:
                values = [row[name] for row in table]
                cells.append(f"{name} {statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})")
            print(f"  {mode:5s}: " + " | ".join(cells))
        if args.breakdown:
            for mode in modes:
                run = launch(mode, args.env, args.units, work, True)
                print_timeline(run)
                print_imports(run, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
