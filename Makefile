# The two set-up commands of the README: `make demo` and `make test`.
# Both create .venv, install everything from this project's files, then run.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test install lint bench clean

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# torch first, pinned to the CPU build: a fresh install never pulls the CUDA build.
	$(BIN)/pip install --quiet -c constraints.txt torch==2.13.0
	$(BIN)/pip install --quiet -c constraints.txt -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/gva reproduce real --out runs/demo --tasks single --models kqv --no-robustness \
		--train-threads 2

# One worker per core, each at one torch thread (OMP_NUM_THREADS=1: two workers at two threads
# each on two cores cost a fifth more CPU); a module's tests stay together, so its module
# fixtures are made once, the modules with slow tests first (tests/conftest.py orders them;
# xdist keeps that order).
# The Ray tests then run alone: a local Ray beside two busy workers on two cores misses its
# health checks and takes the worker down with it (docs/testing.md). They live in
# tests/**/test_ray_*.py (tests/conftest.py refuses a Ray test elsewhere).
RAY_TESTS := $(shell find tests -name 'test_ray_*.py')

test: $(STAMP)
	OMP_NUM_THREADS=1 $(BIN)/python -m pytest -q -n auto --dist loadscope --no-loadscope-reorder \
		-m "not ray"
	$(BIN)/python -m pytest -q -p no:xdist -m ray $(RAY_TESTS)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_ik.py
	$(BIN)/python benchmarks/bench_trials.py
	$(BIN)/python benchmarks/bench_depth_obstacles.py
	$(BIN)/python benchmarks/bench_kqv.py

clean:
	rm -rf $(VENV) runs .pytest_cache .mypy_cache .ruff_cache
