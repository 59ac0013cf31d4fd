# Two commands on a fresh machine:  make run   and   make test
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
SCENARIO ?= office

.PHONY: run test lint bench docs clean clean-kernels

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# Reinstall only when the package metadata, the pins or this file change. [bench] (pyinstrument, VMAS, MPE2)
# lets the tests run benchmarks/train_throughput.py whole, its VMAS row and profile included.
$(VENV)/.installed: pyproject.toml constraints.txt Makefile | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[dev,train,docs,bench]"
	touch $@

run: $(VENV)/.installed
	$(BIN)/parcover run $(SCENARIO)

test: $(VENV)/.installed
	$(BIN)/python -m pytest -q -n 2

lint: $(VENV)/.installed
	$(BIN)/ruff check .

# The documentation site (mkdocs.yml, sources in docs/) into site/, warnings as errors;
# `$(BIN)/mkdocs serve` serves it live at http://127.0.0.1:8000.
docs: $(VENV)/.installed
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

bench: $(VENV)/.installed
	$(BIN)/python benchmarks/throughput.py

# numba's cache=True checks only a kernel's own source file: a cached kernel that calls a kernel of another
# file keeps the old machine code after that file changes. After a pull or such an edit, drop the cache
# (the next env reset compiles again, ~20 s). A fresh clone or install starts with no cache.
clean-kernels:
	find parcover_env -name '*.nb[ic]' -delete

clean: clean-kernels
	rm -rf $(VENV) .pytest_cache site
