# whexar: `make check` is the inner loop, `make test` runs the whole suite; `make sim` runs
# the main job. All create the virtual environment on first use.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: check test sim gl lint typecheck firmware clean native-deps

$(STAMP): pyproject.toml setup.py whexar/bus/_wire.c
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "whexar needs Python >= 3.11")'
	@$(MAKE) --no-print-directory native-deps
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]'
	@touch $@

# The compiled bus path (whexar/bus/_wire.c) needs a C compiler and Python's headers: the
# Debian packages are installed when missing (as root). Where they cannot be, the install
# goes on and the bus takes dynamixel-sdk's pure-Python path (the same results).
NATIVE_DEBS := gcc python3-dev

native-deps:
	@if ! command -v cc >/dev/null 2>&1 || ! $(PYTHON) -c 'import os, sys, sysconfig; \
		sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then \
		echo "installing $(NATIVE_DEBS) (the compiled bus path)"; \
		(apt-get update -qq && apt-get install -y -qq $(NATIVE_DEBS)) || \
		echo "could not install them: the bus will take dynamixel-sdk's pure-Python path"; \
	fi

# ruff, then the architecture: the import contracts in pyproject.toml (layers, no cycles).
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports

typecheck: $(STAMP)
	$(BIN)/mypy

# The sensor-board firmware: built with avr-gcc, host-tested, run in simavr
# (firmware/Makefile installs its Debian packages when they are missing).
firmware:
	$(MAKE) -C firmware test

# The inner loop, in under a minute: ruff, the import contracts, mypy, and the tests not
# marked slow (pyproject.toml: campaigns, Ray, Valgrind, simavr, long simulations,
# rendering, subprocesses, ptys and real time). None of them needs the firmware's build
# or the OpenGL libraries. They run on two workers (pytest-xdist): none waits on real
# time, so they share the machine safely.
check: lint typecheck
	$(BIN)/pytest -q -m "not slow" -n 2

# Everything: the inner loop, then the firmware and the slow tests (which use its build
# and the OpenGL libraries): every test once. The slow tests in two steps: on two workers,
# then those marked serial one at a time (pyproject.toml: ptys, signals, real-time
# emulators, tight bounds on the wall clock), where no other test's load can fail them.
test: check firmware gl
	$(BIN)/pytest -q -m "slow and not serial" -n 2
	$(BIN)/pytest -q -m "slow and serial"

# Headless OpenGL for MuJoCo's renderer (the sim's video and its test): EGL or
# OSMesa, their Debian packages installed when missing (as root).
SIM_DEBS := libegl1 libgl1 libosmesa6

gl:
	@missing=""; for p in $(SIM_DEBS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
		echo "installing$$missing (headless OpenGL for the simulation's video)"; \
		apt-get update -qq && apt-get install -y -qq $$missing; \
	fi

# The main job: the full runtime drives the simulated WHexaR (MuJoCo) over the default
# course; summary on the terminal, plots and a video in sim-report/.
sim: $(STAMP) gl
	$(BIN)/whexar sim --report sim-report --video sim-report/course.mp4

clean:
	rm -rf $(VENV) .mypy_cache .pytest_cache .ruff_cache .hypothesis
	$(MAKE) -C firmware clean
