# dancekit — the two commands a new user needs: `make demo` and `make test`.
# Both create .venv if needed and install the tested set: pip install -c constraints.txt -e '.[dev]'.
# Python 3.11, 3.12 or 3.13: python3.11 if it runs, else python3; `make PYTHON=python3.12 test` picks one.
ifeq ($(origin PYTHON),undefined)
PYTHON := $(shell for p in python3.11 python3; do $$p -c '' >/dev/null 2>&1 && { echo $$p; exit; }; done; echo python3)
endif
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SONG   ?=
OUT    ?= demo_out

.PHONY: demo test install bench bench-memory lint clean

$(PY):
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' >/dev/null 2>&1 || { \
	  echo "error: dancekit needs Python >= 3.11 (tested: 3.11, 3.12, 3.13); '$(PYTHON)' is missing or older." >&2; \
	  echo "       Install one and run e.g. 'make PYTHON=python3.12 test'." >&2; exit 1; }
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml constraints.txt | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt -e '.[dev]'
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(PY) scripts/demo.py $(if $(SONG),--song "$(SONG)") --out "$(OUT)"

# The tests in one process per core (at most 4; pytest-xdist), a test file's tests together in one process (their
# module fixtures made once); each process runs torch and the BLAS on one thread (tests/conftest.py). A test process
# that crashes ends the run (--max-worker-restart=0: xdist's restart after a crash can leave the run waiting).
test: $(STAMP)
	$(PY) -m pytest -q -n logical --maxprocesses=4 --dist loadfile --max-worker-restart=0

# The speed figures of docs/BENCHMARKS.md (docs/results/speed_*.json), each by its own command (a few minutes;
# the memory figures take longer: `make bench-memory`). Then update the result files and run
# `$(PY) scripts/benchmarks_md.py` to regenerate docs/BENCHMARKS.md.
bench: $(STAMP)
	$(PY) benchmarks/bench_cold_start.py --model revolution --repeats 3
	$(PY) benchmarks/bench_cold_start.py --model music2dance --repeats 3
	$(PY) benchmarks/bench_seeds.py --repeats 3 --formats npz
	$(PY) benchmarks/bench_paper_size.py speed --only paper --threads 2 --repeats 3 --no-unfused
	OMP_NUM_THREADS=1 $(PY) benchmarks/bench_render.py --figure body --repeats 3
	OMP_NUM_THREADS=1 $(PY) benchmarks/bench_render.py --figure stick --repeats 3

bench-memory: $(STAMP)
	$(PY) benchmarks/bench_memory.py --minutes 60 20

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks scripts

clean:
	rm -rf $(VENV) .pytest_cache build src/*.egg-info
