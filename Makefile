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

.PHONY: demo test install bench lint clean

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

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks scripts

clean:
	rm -rf $(VENV) .pytest_cache build src/*.egg-info
