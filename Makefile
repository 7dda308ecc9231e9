# a5mi: two commands do everything on a fresh Debian machine (as root): `make demo`, `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.a5mi-installed
DEMO_FLAGS := -size 300 300 -shadows -bounces 4 -jitter -filter

.PHONY: setup llvm sandbox demo test fuzz lint bench clean

setup: llvm sandbox $(STAMP)

# `a5mi difftest` runs the other a5 binary inside bubblewrap (no network, read-only file system): install it
# if missing (root with apt), else say how.
sandbox:
	@command -v bwrap >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq bubblewrap; \
	  else echo "a5mi: warning: bubblewrap (bwrap) is not installed; a5mi difftest will run binaries unsandboxed" \
	    "(apt-get install bubblewrap)" >&2; fi; }

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

# The thorough hypothesis profile (tests/conftest.py): ten times the examples of `make test`, random seeds.
fuzz: setup
	HYPOTHESIS_PROFILE=thorough $(BIN)/python -m pytest -q -k fuzz

bench: setup
	$(BIN)/a5mi bench

clean:
	rm -rf $(VENV) out build *.egg-info
