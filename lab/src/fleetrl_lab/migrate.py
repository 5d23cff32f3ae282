"""The one migration of run records from format 1 to 2: ``python -m fleetrl_lab.migrate lab/records``."""

import argparse
import json
from pathlib import Path
from typing import Any

from fleetrl.envs.catalog import get_env_spec
from fleetrl_lab.records import FORMAT, write_record

LEFT_OUT_IN_FORMAT_1: dict[str, Any] = {
    "scheme_params": {},
    "device_driver": None,
    "max_staleness": None,
    "units_per_host": 1,
    "pace": None,
    "slow": {},
    "link_delay": {},
    "absent": 0.0,
    "absent_rounds": 3.0,
    "stall": {},
}
"""the result settings format 1 left out at these values (a built-in's own target too)"""


def migrated(record: dict[str, Any]) -> dict[str, Any]:
    """A format-1 record as format 2: every result setting named, every single-episode round's steps kept
    (format 1 read a round's steps from its score: reward 1 per step)."""
    if record.get("format") != 1:
        raise ValueError(f"not a format-1 record (format {record.get('format')!r})")
    settings = {**LEFT_OUT_IN_FORMAT_1, **record["result_settings"]}
    settings.setdefault("target_score", get_env_spec(settings["env"]).declared_target)
    for worker in record["workers"].values():
        if "steps" not in worker and "episodes" not in worker:
            worker["steps"] = [round(score or 0) for score in worker["score"]]
    return record | {"format": FORMAT, "result_settings": dict(sorted(settings.items()))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("records", type=Path)
    root = parser.parse_args().records
    paths = [p for p in sorted(root.rglob("seed-*.json")) if json.loads(p.read_text()).get("format") == 1]
    for path in paths:
        write_record(path, migrated(json.loads(path.read_text())))
    print(f"{len(paths)} records migrated to format {FORMAT}")


if __name__ == "__main__":
    main()
