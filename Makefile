# twinsense — set-up, demo and tests. Every target creates/updates .venv first,
# so a fresh machine needs only Python >= 3.11 and make.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint bench clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	# robosuite's MIT-licensed MJCF robots (UR5e, Panda) for the tests and examples: only its
	# files are read, never imported, so its dependencies (which pin numpy < 2) are left out.
	$(BIN)/python -m pip install --quiet --no-deps "robosuite>=1.5"
	touch $(STAMP)

demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/twinsense demo office -o out/

test: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q
	$(BIN)/ruff check --no-cache src tests benchmarks examples

lint: $(STAMP)
	$(BIN)/ruff check --no-cache src tests benchmarks examples

bench: $(STAMP)
	for f in benchmarks/bench_*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) out .pytest_cache
