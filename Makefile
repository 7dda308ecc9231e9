# a5mi: two commands do everything on a fresh Debian machine (as root): `make demo`, `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.a5mi-installed
DEMO_FLAGS := -size 300 300 -shadows -bounces 4 -jitter -filter
# `make setup` says what it does in a line per step; what the steps print (apt-get, pip) goes to this log.
SETUP_LOG := $(VENV)/setup.log

.PHONY: setup llvm tools demo test test-all check fuzz lint bench gpu-check clean

# `$(STEP) "what it does" COMMAND ARGS...`: print "a5mi setup: what it does" and append the command's output to
# $(SETUP_LOG); when it fails, print the last 30 lines of that output and the log's path, and stop with the
# command's status.
STEP = step() { echo "a5mi setup: $$1"; shift; mkdir -p $(VENV); \
	printf '\n=== %s  %s\n' "$$(date -u +%FT%TZ)" "$$*" >> $(SETUP_LOG); n=$$(wc -l < $(SETUP_LOG)); \
	"$$@" >> $(SETUP_LOG) 2>&1 || { s=$$?; echo "a5mi setup: error: '$$*' failed (status $$s):" >&2; \
	  tail -n +$$((n + 1)) $(SETUP_LOG) | tail -n 30 >&2; echo "a5mi setup: the full log is $(SETUP_LOG)" >&2; \
	  exit $$s; }; }; step

setup: llvm tools $(STAMP)
	@$(BIN)/python -m compileall -q a5mi plugins converters >/dev/null  # bytecode: ~0.3 CPU-s of each a5 start where PYTHONDONTWRITEBYTECODE is set (docs/SPEED.md)

# a5mi grade's and a5mi difftest's sandbox (bubblewrap), the report's headless-browser test (chromium) and the
# single-node SLURM the --slurm tests start (munge, slurmctld, slurmd, slurm-client): install if root. Debian's
# policy-rc.d / no init system leaves the daemons stopped: the tests start their own and stop them.
APT_TOOLS := bwrap:bubblewrap chromium:chromium munged:munge slurmctld:slurmctld slurmd:slurmd sbatch:slurm-client
tools:
	@missing=""; for t in $(APT_TOOLS); do command -v $${t%%:*} >/dev/null || missing="$$missing $${t#*:}"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    $(STEP) "apt-get install$$missing (the sandbox of a5mi grade and difftest; the report's browser test; SLURM for the --slurm tests)" \
	      sh -c "apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y$$missing"; \
	  else echo "a5mi: note: apt-get install$$missing (sandbox for a5mi grade and difftest, report test, SLURM tests)" >&2; fi; fi

# Dr.Jit's llvm variant needs libLLVM >= 16 (Debian 12 ships 15 by default): check, install if root.
llvm:
	@$(STEP) "libLLVM >= 16 for Dr.Jit's llvm variant (apt-get install if missing)" $(PYTHON) -m a5mi.cli.setup llvm

# Everything, for the tests: a5mi, every command's extras (pyproject.toml) and the test tools.
$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import ensurepip, venv' 2>/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    $(STEP) "apt-get install python3-venv" \
	      sh -c "apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y python3-venv"; \
	  else echo "a5mi: error: python3 has no venv module; install python3-venv" >&2; exit 1; fi; }
	@$(STEP) "virtual environment $(VENV) ($(PYTHON))" $(PYTHON) -m venv $(VENV)
	@$(STEP) "pip install -e '.[test]' (a5mi, every extra, the test tools)" \
	  sh -c "$(BIN)/python -m pip install --upgrade pip && $(BIN)/python -m pip install -e '.[test]'"
	@touch $(STAMP)
	@echo "a5mi setup: done: $(BIN)/a5 and $(BIN)/a5mi (log: $(SETUP_LOG))"

demo: setup
	@mkdir -p out
	$(BIN)/a5 -input scenes/demo.txt -output out/demo.png $(DEMO_FLAGS)
	@echo "wrote out/demo.png"

lint: setup
	$(BIN)/ruff check .

# `make test`: the everyday suite; `make test-all` adds the slow tier (pytest marker `slow`: full reference
# renders, campaigns, sweeps, each with a faster test of the same behaviour in `make test`). Both run on
# TEST_JOBS pytest-xdist workers (the cores, at most 4: each worker holds its own Mitsuba and JIT), a test file
# whole on one worker, so module fixtures are built once (tests/conftest.py groups the files that must not overlap).
TEST_JOBS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); echo $$(( n < 4 ? n : 4 )))
PYTEST := $(BIN)/python -m pytest -q -n $(TEST_JOBS) --dist loadfile
test: setup lint
	$(PYTEST) -m "not slow"

test-all: setup lint
	$(PYTEST)

# `make check`: what a developer runs on every save: ruff and the unit tests (pytest marker `unit`: no Mitsuba
# variant, no child process; ~20 s on 2 cores, BENCHMARKS.md "make check").
check: setup lint
	$(BIN)/python -m pytest -q -n $(TEST_JOBS) -m "unit and not slow and not course_data"

# The thorough hypothesis profile (tests/conftest.py): ten times the examples of `make test`, random seeds;
# plus the mutation campaign (tests/fuzzing.py) through real renders, bounded in time and seeded (scenes, meshes,
# images, every sub-command, E.1-E.24 numeric keywords at their bounds, the view's HTTP surface):
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
