# a5mi: two commands do everything on a fresh Debian machine (as root): `make demo`, `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.a5mi-installed
DEMO_FLAGS := -size 300 300 -shadows -bounces 4 -jitter -filter

.PHONY: setup llvm tools demo test fuzz lint bench gpu-check clean

setup: llvm tools $(STAMP)

# a5mi grade's and a5mi difftest's sandbox (bubblewrap) and the report's headless-browser test (chromium):
# install if root.
APT_TOOLS := bwrap:bubblewrap chromium:chromium
tools:
	@missing=""; for t in $(APT_TOOLS); do command -v $${t%%:*} >/dev/null || missing="$$missing $${t#*:}"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	  else echo "a5mi: note: apt-get install$$missing (sandbox for a5mi grade and difftest, report test)" >&2; fi; fi

# Dr.Jit's llvm variant needs libLLVM >= 16 (Debian 12 ships 15 by default): check, install if root.
llvm:
	@$(PYTHON) -m a5mi.cli.setup llvm

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import ensurepip, venv' 2>/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv; \
	  else echo "a5mi: error: python3 has no venv module; install python3-venv" >&2; exit 1; fi; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	@touch $(STAMP)

demo: setup
	@mkdir -p out
	$(BIN)/a5 -input scenes/demo.txt -output out/demo.png $(DEMO_FLAGS)
	@echo "wrote out/demo.png"

lint: setup
	$(BIN)/ruff check .

test: setup lint
	$(BIN)/python -m pytest -q

# The thorough hypothesis profile (tests/conftest.py): ten times the examples of `make test`, random seeds;
# plus the issue-19 mutation campaign (tests/fuzzing.py) through real renders, bounded in time and seeded:
# `make fuzz FUZZ_SECONDS=300 FUZZ_SEED=7`; counts in out/fuzz-report.json.
FUZZ_SECONDS ?= 1800
FUZZ_SEED ?= 1
fuzz: setup
	@mkdir -p out
	HYPOTHESIS_PROFILE=thorough A5MI_FUZZ_SECONDS=$(FUZZ_SECONDS) A5MI_FUZZ_SEED=$(FUZZ_SEED) \
	  A5MI_FUZZ_REPORT=out/fuzz-report.json $(BIN)/python -m pytest -q -s -k fuzz

# The cuda variant against the llvm one (needs an NVIDIA GPU; exit 2 without one): benchmarks/gpu_check.py.
gpu-check: setup
	$(BIN)/python benchmarks/gpu_check.py

bench: setup
	$(BIN)/a5mi bench

clean:
	rm -rf $(VENV) out build *.egg-info
