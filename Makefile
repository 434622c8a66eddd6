# Everything the project needs is installed here, into .venv, on first use: the exact versions
# of requirements/lock.txt (docs/install.md says how to refresh it), then bagkit and fusion
# editable, without dependencies.
# The first Python 3.10 - 3.13 found (the ROS 2 Jazzy wheels exist for each): the machine's
# python3 where it is one (Ubuntu 24.04's 3.12), else python3.12, 3.11, 3.13, 3.10.
# PYTHON=/path/to/python to choose.
PYTHONS := python3 python3.12 python3.11 python3.13 python3.10
ifeq ($(origin PYTHON),undefined)
PYTHON := $(firstword $(foreach p,$(PYTHONS),$(shell $(p) -c 'import sys; \
	print("$(p)") if (3, 10) <= sys.version_info[:2] <= (3, 13) else None' 2>/dev/null)))
endif
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
LOCK := requirements/lock.txt
SOURCES := pyproject.toml fusion/pyproject.toml setup.py bagkit/ros/record/_take.c $(LOCK)
# Every ROS process started from here stays on this machine, on a domain of its own.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export RMW_IMPLEMENTATION := rmw_fastrtps_cpp

.PHONY: demo test test-dds test-fast test-py venv-py lint format bench golden lock dist clean

# Azurite, Azure Storage's emulator, for tests/storage: npm's package at this version, in
# .azurite/ (3.35 is the last that runs on Node.js 20). Without npm the step says so and the
# Azure tests skip (under CI=true they fail).
AZURITE_VERSION := 3.35.0
AZURITE := .azurite/.installed-$(AZURITE_VERSION)
$(AZURITE):
	@if command -v npm >/dev/null 2>&1; then \
		rm -rf .azurite && npm install --prefix .azurite --no-fund --no-audit --loglevel=error \
			azurite@$(AZURITE_VERSION) && touch $@; \
	else echo "note: no npm: Azurite not installed, the az:// tests will skip" >&2; fi

# s3rver, an S3-compatible server of npm that keeps each object as a file, for the storage
# benchmark of 1,000 bags of test-drive size (benchmarks/bench_storage_fleet.py): in .s3rver/.
S3RVER_VERSION := 3.7.1
S3RVER := .s3rver/.installed-$(S3RVER_VERSION)
$(S3RVER):
	@if command -v npm >/dev/null 2>&1; then \
		rm -rf .s3rver && npm install --prefix .s3rver --no-fund --no-audit --loglevel=error \
			s3rver@$(S3RVER_VERSION) && touch $@; \
	else echo "note: no npm: s3rver not installed, the storage_fleet benchmark will say so" >&2; fi

# uv (pinned in the lock) installs the lock: pip would take minutes longer. Unlike pip, uv
# writes no bytecode unless asked; where PYTHONDONTWRITEBYTECODE is set (as in CI) every process
# would then compile numpy, pandas and rclpy from source at each start (benchmarks/README.md).
# .venv's uv installs the other Pythons' venvs too: they need no pip of their own to get one.
UV := $(VENV)/bin/uv
define install_locked
	$(UV) pip install --quiet --compile-bytecode --python $(1)/bin/python -r $(LOCK)
	$(UV) pip install --quiet --python $(1)/bin/python --no-deps -e . -e ./fusion
endef

$(STAMP): $(SOURCES)
	@test -n "$(PYTHON)" || { echo "error: no Python 3.10-3.13 found (tried $(PYTHONS)); \
		give one: make PYTHON=/path/to/python3.12" >&2; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet "$$(grep -m1 '^uv==' $(LOCK))"
	$(call install_locked,$(VENV))
	touch $(STAMP)

demo: $(STAMP)
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-77} bash scripts/demo.sh

# The tests that start DDS participants on three workers: they mostly wait for processes and
# discovery, below two cores of CPU; each worker holds ROS domains of its own
# (tests/domains.py). Beside them, at the lowest CPU priority, the tests that start none, on two
# workers: they take the core the DDS tests leave idle (benchmarks/README.md). Each part's output
# is printed when it ends (--output-sync). Last the DDS tests that assert timings (`serial`,
# tests/conftest.py), one at a time, with nothing beside them. Azurite (for tests/storage, not
# DDS) is installed as the offline part's prerequisite, while the DDS tests start.
test: $(STAMP)
	$(PY) -m compileall -q bagkit fusion
	$(MAKE) --no-print-directory -j2 --output-sync=target test-dds test-fast NICE="nice -n 19"
	$(PY) -m pytest -q -m "ros and serial" --durations=5

test-dds: $(STAMP)
	$(PY) -m pytest -q -m "ros and not serial" -n 3 --dist loadgroup --durations=10

# The fast loop: every test that starts no DDS participant, on two worker processes (NICE: a
# prefix, `nice -n 19` beside the DDS tests).
NICE ?=
test-fast: $(STAMP) $(AZURITE)
	$(NICE) $(PY) -m pytest -q -m "not ros" -n 2

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy --num-workers auto

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

bench: $(STAMP) $(S3RVER)
	$(PY) -m benchmarks

# Re-record the golden fixtures from the live system (about 2 minutes), outputs from lockstep.
golden: $(STAMP)
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-78} $(VENV)/bin/bagkit golden record

# Another Python (3.10 - 3.13, from pyenv unless XPYTHON names it) in .venv-PYV, .venv stays:
# the offline suite on two workers, then record -> replay -> echo over DDS.
#   make test-py PYV=3.12                          the lock's versions
#   make test-py PYV=3.10 RESOLUTION=lowest-direct  the oldest versions pyproject.toml allows
PYV ?= 3.12
RESOLUTION ?= locked
XVENV := .venv-$(PYV)$(if $(filter locked,$(RESOLUTION)),,-$(RESOLUTION))
XPYTHON ?= $(shell pyenv prefix $$(pyenv versions --bare | grep -m1 '^$(PYV)\.'))/bin/python$(PYV)

$(XVENV)/.installed: $(SOURCES) | $(STAMP)
	$(XPYTHON) -m venv --clear --without-pip $(XVENV)
ifeq ($(RESOLUTION),locked)
	$(call install_locked,$(XVENV))
else
	$(UV) pip install --quiet --compile-bytecode --python $(XVENV)/bin/python \
		--resolution $(RESOLUTION) -e '.[all,dev]' -e ./fusion
endif
	touch $@

# Only the venv (.ci/run builds the three while make test runs).
venv-py: $(XVENV)/.installed

# PYTESTS: which tests (default: the whole offline suite).
PYTESTS ?= tests
test-py: $(XVENV)/.installed $(AZURITE)
	$(XVENV)/bin/python -m compileall -q bagkit fusion
	$(XVENV)/bin/python -m pytest -q -p no:cacheprovider -m "not ros" -n 2 $(PYTESTS)
	$(XVENV)/bin/python -m pytest -q -p no:cacheprovider tests/install/test_dds_smoke.py

# Re-resolve requirements/lock.txt for 3.10 - 3.13 after pyproject.toml changed; the versions
# already locked are kept where still allowed. The newest of everything: make lock UPGRADE=-U;
# of one package: make lock UPGRADE="-P pandas".
UPGRADE ?=
lock: $(STAMP)
	$(VENV)/bin/uv pip compile --quiet pyproject.toml --extra all --extra dev --universal \
		--python-version 3.10 $(UPGRADE) -o $(LOCK)

# The wheels and source distributions of bagkit and bagkit-fusion, in dist/ (bagkit's wheel is
# built for this machine's Python and platform: it holds the recorder's C extension).
dist: $(STAMP)
	$(VENV)/bin/uv build --quiet --out-dir dist .
	$(VENV)/bin/uv build --quiet --out-dir dist fusion
	@ls -1 dist

clean:
	rm -rf $(VENV) .venv-* .azurite .s3rver .pytest_cache .mypy_cache .ruff_cache dist
