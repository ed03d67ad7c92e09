# Set-up, the main job and the checks in one command each (GNU make):
#
#   make demo    create .venv if it is missing, install what the main job needs (the core and
#                matplotlib, about 0.4 GB), run the simulated search
#   make test    install every extra (torch, dask, Playwright, mypy, ...: about 1.9 GB), then
#                the test suite (ARGS="-x tests/core" to narrow it)
#   make lint    the full set-up, then ruff and mypy (configured in pyproject.toml)
#
# Each level is reinstalled when pyproject.toml changes. Variables:
#   PYTHON=python3.12          the interpreter that creates the environment
#   VENV=.ci-venv              where the environment lives (default .venv)
#   TORCH_INDEX=https://download.pytorch.org/whl/cpu
#                              install torch from this index first (a CPU build, without
#                              the multi-GB CUDA libraries that PyPI's Linux wheels pull in)

PYTHON ?= python3
VENV ?= .venv
DEMO_EXTRAS ?= plots
EXTRAS ?= all,test,lint
TORCH_INDEX ?=
ARGS ?=
# pytest-xdist workers for `make test` (auto: one per CPU); WORKERS=0 runs in this process.
WORKERS ?= auto
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_STAMP := $(VENV)/.installed-demo

.PHONY: all demo test lint clean

all: test

demo: $(DEMO_STAMP)
	$(BIN)/hapticframe run examples/search-ellipse.yaml --out runs/demo --overwrite

test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(WORKERS) $(ARGS)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

# The stamps, not the directory, are the targets: a directory's time changes with its contents.
# The full set-up includes the demo's, so it stamps both.
$(DEMO_STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -e ".[$(DEMO_EXTRAS)]"
	touch $@

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
ifneq ($(TORCH_INDEX),)
	$(BIN)/python -m pip install "torch>=2.2,<2.14" --index-url $(TORCH_INDEX)
endif
	$(BIN)/python -m pip install -e ".[$(EXTRAS)]"
	touch $@ $(DEMO_STAMP)

clean:
	rm -rf runs/demo build dist *.egg-info .ci-venv
