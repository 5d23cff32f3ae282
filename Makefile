# fleetrl: the two commands a newcomer needs are `make demo` and `make test`.
# Every target installs what it needs first (idempotent), so a fresh clone works.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# requirements.lock pins every package the venv holds (transitive ones, the build backend and torch's CPU
# build included); pyproject.toml keeps the compatible ranges for people who install fleetrl as a library.
LOCK := requirements.lock
PIP_VERSION := 26.3

.PHONY: install lock demo example test test-fast lint bench results report clean

install: $(STAMP)

$(STAMP): pyproject.toml lab/pyproject.toml $(LOCK)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet pip==$(PIP_VERSION)
	$(PY) -m pip install --quiet -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e lab
	$(PY) -m pip check
	touch $(STAMP)

# Refresh the lock: resolve pyproject.toml's ranges afresh in a scratch venv (torch pinned to its CPU build:
# a looser range pulls a CUDA build of several GB) and write down every version installed.
lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/python -m pip install --quiet pip==$(PIP_VERSION)
	.lock-venv/bin/python -m pip install --quiet 'torch==2.13.0+cpu' setuptools wheel
	.lock-venv/bin/python -m pip install --quiet --no-build-isolation -e '.[test,bench]'
	.lock-venv/bin/python -m pip check
	{ echo "# Every package of fleetrl's development venv, exactly; written by 'make lock' (do not edit)."; \
	  .lock-venv/bin/python -m pip freeze --exclude-editable --all | grep -v '^pip=='; } > $(LOCK)
	rm -rf .lock-venv

demo: install
	$(VENV)/bin/fleetrl demo

# Your own unit type, worked through (examples/dc-motor, docs/byod.md): the example package installed into the
# venv, then a federated fleet of 3 DC motors trained on an embedded MQTT broker.
example: install
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e examples/dc-motor
	$(VENV)/bin/fleetrl train --env fleet_dc_motor.units:factory --units 3 --mode federated --preset standard \
		--target-score -10 --out runs/motor-$$(date +%Y%m%d-%H%M%S)

# Two test processes per two cores (pytest-xdist): the suite is mostly child processes and brokers waiting.
# Whole modules go to a process (a module's shared fixtures run once), the longest first (tests/conftest.py,
# START_FIRST); the 15 slowest tests are listed at the end.
test: install
	$(PY) -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder --durations=15

# The edit-run loop: unit tests only (no broker, no training), well under a minute.
test-fast: install
	$(PY) -m pytest -q -m "not slow and not mqtt and not mosquitto"

lint: install
	$(VENV)/bin/ruff check src tests lab examples
	$(VENV)/bin/ruff format --check src tests lab examples
	$(VENV)/bin/mypy

bench: install
	$(PY) lab/benchmarks/physics_speed.py
	$(PY) lab/benchmarks/device_link.py
	$(PY) lab/benchmarks/round_overhead.py
	$(PY) lab/benchmarks/learning.py

results: install
	$(VENV)/bin/fleetrl experiment all --other-seeds 5 --out runs/experiments --records lab/records
	$(VENV)/bin/fleetrl experiment uneven --fleet-seed 1 --out runs/experiments \
		--records lab/records
	$(VENV)/bin/fleetrl experiment argmax --first-seed 200 --fleet-seed 1 --out runs/experiments \
		--records lab/records
	$(VENV)/bin/fleetrl experiment fleet-scale --seeds 5 --out runs/experiments --records lab/records
	$(VENV)/bin/fleetrl experiment qube-scale --seeds 5 --out runs/experiments --records lab/records
	$(VENV)/bin/fleetrl experiment fig5 --fleet-seed 1 --headline-only --out runs/experiments \
		--records lab/records --publish docs/results.md
	$(PY) -m fleetrl_lab.headline --records lab/records --readme README.md

# docs/results.md and README's results table again from the committed records alone (runs nothing; arms not
# run yet are named as such)
report: install
	$(VENV)/bin/fleetrl experiment all --from-records --other-seeds 5 --out runs/report --records lab/records
	$(VENV)/bin/fleetrl experiment uneven --from-records --fleet-seed 1 --out runs/report \
		--records lab/records
	$(VENV)/bin/fleetrl experiment argmax --from-records --first-seed 200 --fleet-seed 1 --out runs/report \
		--records lab/records
	$(VENV)/bin/fleetrl experiment fleet-scale --from-records --seeds 5 --out runs/report \
		--records lab/records
	$(VENV)/bin/fleetrl experiment qube-scale --from-records --seeds 5 --out runs/report \
		--records lab/records
	$(VENV)/bin/fleetrl experiment fig5 --from-records --fleet-seed 1 --headline-only --out runs/report \
		--records lab/records --publish docs/results.md
	$(PY) -m fleetrl_lab.headline --records lab/records --readme README.md

clean:
	rm -rf $(VENV) .lock-venv build *.egg-info src/*.egg-info
