# fleetrl: the two commands a newcomer needs are `make demo` and `make test`.
# Every target installs what it needs first (idempotent), so a fresh clone works.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install demo test lint bench results clean

install: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# torch pinned first: this exact version is the CPU build; a looser range pulls a CUDA build of several GB.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)

demo: install
	$(VENV)/bin/fleetrl demo

test: install
	$(PY) -m pytest -q

lint: install
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/ruff format --check src tests benchmarks
	$(VENV)/bin/mypy

bench: install
	$(PY) benchmarks/physics_speed.py
	$(PY) benchmarks/device_link.py
	$(PY) benchmarks/round_overhead.py
	$(PY) benchmarks/learning.py

results: install
	$(VENV)/bin/fleetrl experiment all --seeds 5 --out runs/experiments

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info
