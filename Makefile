PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint docs install bench clean wheel-check docs-check

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[all,dev,docs]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/robointel demo

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples tools
	$(BIN)/mypy

# lint, the documentation, the wheel and the front door's figures, then the suite on 2 pytest-xdist workers,
# grouped as tests/conftest.py says (docs/design/testing.md); TEST_WORKERS=0 runs it in one process
TEST_WORKERS ?= 2
test: $(STAMP) lint docs docs-check
	$(BIN)/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --dist loadgroup --no-loadscope-reorder tests

# the documentation site (docs/, mkdocs.yml): a broken link or docstring reference fails
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict --quiet --site-dir $(VENV)/site

# the wheel built, installed with its core dependencies (and WHEEL_EXTRAS) in a fresh virtual environment outside
# the repository, and used from there (tools/wheel_check.py: packaged files, the first quickstart, demo --quick)
# (the first quickstart plans for the UR5 of example-robot-data: the robots extra)
WHEEL_EXTRAS ?= robots
wheel-check: $(STAMP)
	$(BIN)/python tools/wheel_check.py --extras "$(WHEEL_EXTRAS)" --out build/wheel-check.json

# the front door's figures (tools/docs_check.py: README length, process words, import cycles, core
# dependencies, mkdocs --strict (passed: docs ran first), the wheel's quickstart); with the gate on, make test
# fails when one misses its target
FRONT_DOOR_GATE ?= on
docs-check: docs wheel-check
	$(BIN)/python tools/docs_check.py --json --mkdocs-passed --wheel-report build/wheel-check.json \
	  || [ "$(FRONT_DOOR_GATE)" = off ]

bench: $(STAMP)
	for b in benchmarks/*.py; do $(BIN)/python $$b --json || exit 1; done

clean:
	rm -rf $(VENV) robointel-report
