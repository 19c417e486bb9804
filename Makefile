PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint docs install bench clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,docs]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/robointel demo

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples tools
	$(BIN)/mypy

# the suite on 2 pytest-xdist workers, grouped as tests/conftest.py says (docs/design/testing.md);
# TEST_WORKERS=0 runs it in one process
TEST_WORKERS ?= 2
test: $(STAMP) lint docs
	$(BIN)/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --dist loadgroup --no-loadscope-reorder tests

# the documentation site (docs/, mkdocs.yml): a broken link or docstring reference fails
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict --quiet --site-dir $(VENV)/site

bench: $(STAMP)
	for b in benchmarks/*.py; do $(BIN)/python $$b --json || exit 1; done

clean:
	rm -rf $(VENV) robointel-report
