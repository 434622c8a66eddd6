# Everything the project needs is installed here, into .venv, on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Every ROS process started from here stays on this machine, on a domain of its own.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export RMW_IMPLEMENTATION := rmw_fastrtps_cpp

.PHONY: demo test test-fast lint format bench golden clean

$(STAMP): pyproject.toml setup.py bagkit/ros/record/_take.c
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-77} bash scripts/demo.sh

test: $(STAMP)
	$(PY) -m pytest -q --durations=10

# The fast loop: every test that starts no DDS participant, on two worker processes.
test-fast: $(STAMP)
	$(PY) -m pytest -q -m "not ros" -n 2

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

bench: $(STAMP)
	$(PY) -m benchmarks

# Re-record the golden fixtures from the live system (about 2 minutes), outputs from lockstep.
golden: $(STAMP)
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-78} $(VENV)/bin/bagkit golden record

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
