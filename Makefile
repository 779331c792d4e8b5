# Every target sets up .venv when it is missing or older than pyproject.toml.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: reproduce test bench lint docs clean

# Python keeps the bytecode it compiles (in .venv and beside the sources), even where
# PYTHONDONTWRITEBYTECODE is set: the suite starts about 130 Python processes, and each would
# otherwise compile numba's, SciPy's and the package's sources again. Only the modules a process
# imports are compiled, once, by the first process that imports them.
export PYTHONDONTWRITEBYTECODE :=

# uv (from PyPI) installs the same packages as pip, several at a time: about 8 s instead of 40 s
# for every extra. Where uv cannot be installed or cannot install (a package index that only pip's
# own settings name), pip does the same install.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	if $(BIN)/python -m pip install --quiet 'uv>=0.4' && \
		$(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[test]'; then \
		:; \
	else \
		$(BIN)/python -m pip install --quiet --upgrade pip && \
		$(BIN)/python -m pip install --quiet -e '.[test]'; \
	fi
	touch $(STAMP)

reproduce: $(STAMP)
	$(BIN)/delaytrack reproduce --out results

# One pytest process per core (pytest-xdist): the suite is mostly numba compiling. Each takes a
# whole test module at a time, in the order of tests/conftest.py.
test: $(STAMP)
	$(BIN)/python -m pytest -n auto --dist loadscope

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples scripts
	$(BIN)/ruff format --check src tests benchmarks examples scripts
	$(BIN)/mypy

# The documentation site (MkDocs + mkdocstrings) into site/; any warning fails the build.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

clean:
	rm -rf $(VENV) results site .pytest_cache
