"""Which of fleetrl's files a reader opens to follow one round: the files whose functions run in round 2.

    python lab/benchmarks/round_files.py [--scheme pergrad]

Profiles a 2-unit federated cartpole run on the in-process bus and lists the fleetrl files called in round 2.
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import threading
from pathlib import Path
from types import FrameType
from typing import Any

import fleetrl
from fleetrl.cli.main import main as fleetrl_main

PACKAGE = str(Path(fleetrl.__file__).resolve().parent) + "/"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", default="pergrad")
    args = parser.parse_args()
    plays, recording, files = [0], [False], set()

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        name = frame.f_code.co_filename
        if event != "call" or not name.startswith(PACKAGE):
            return
        if frame.f_code.co_name == "play_episodes" and name.endswith("agent/learner.py"):
            plays[0] += 1
            recording[0] = 3 <= plays[0] < 5  # both units' round 2
        if recording[0]:
            files.add(name[len(PACKAGE) :])

    out = Path(tempfile.mkdtemp()) / "run"
    argv = ["train", "--env", "cartpole", "--units", "2", "--mode", "federated", "--transport", "local"]
    argv += ["--scheme", args.scheme, "--max-rounds", "4", "--seed", "0", "--no-live", "--out", str(out)]
    sys.setprofile(profile)
    threading.setprofile(profile)
    try:
        fleetrl_main(argv)
    except SystemExit:
        pass
    finally:
        sys.setprofile(None)
        threading.setprofile(None)
    by_package = collections.Counter(f.split("/")[0] for f in files)
    print(f"{len(files)} files in round 2 ({args.scheme}, 2 units): {dict(sorted(by_package.items()))}")
    for name in sorted(files):
        print(f"  {name}")


if __name__ == "__main__":
    main()
