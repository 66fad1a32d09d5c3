# FLISS: two commands for a new user, `make demo` and `make test`. Both set up .venv/ first.

PYTHON  ?= python3
VENV    := .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed-stamp
PYTEST_ARGS ?=

.PHONY: all demo test verilog venv clean

all: test

# (Re)create the virtual environment whenever pyproject.toml changes.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	@touch $@

venv: $(STAMP)

demo: $(STAMP)
	$(PY) -m fliss demo

test: $(STAMP)
	$(PY) -m pytest $(PYTEST_ARGS)

verilog: $(STAMP)
	$(PY) -m fliss generate -o build/verilog

clean:
	rm -rf build sim_build .pytest_cache
