# FLISS: two commands for a new user, `make demo` and `make test`. Both set up .venv/ first.

PYTHON  ?= python3
VENV    := .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed-stamp
PYTEST_ARGS ?=

.PHONY: all demo test test-long lint verilog venv clean dist test-installed

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

test: lint
	$(PY) -m pytest $(PYTEST_ARGS)

# The full-length runs whose shorter versions `make test` runs (marker long): the link fuzz's
# 10 000 frames on each simulator, the demo twice. CI runs them too (.ci/run).
test-long: $(STAMP)
	$(PY) -m pytest -n 2 -m long $(PYTEST_ARGS)

lint: $(STAMP)
	$(PY) -m ruff check .

verilog: $(STAMP)
	$(PY) -m fliss generate -o build/verilog

clean:
	rm -rf build sim_build .pytest_cache dist

# The wheel and the sdist of what is committed (a copy made by git archive: no build/ of an
# earlier build, no untracked file), into dist/.
dist: $(STAMP)
	rm -rf build/dist-source dist && mkdir -p build/dist-source
	git archive --format=tar HEAD | tar -x -C build/dist-source
	$(PY) -m build --outdir dist build/dist-source

# The wheel as a user installs it, in fresh environments outside the checkout (.ci/installed.py):
# Python 3.10 with every dependency at its lowest claimed version, Python 3.13 with the newest,
# and the checkout's Python with the demo (the harness built into a fresh per-user cache) and a
# capture on a virtual board. INSTALLED_PYTHONS names the interpreters of the first two.
INSTALLED_PYTHONS ?= 3.10 3.13
test-installed: dist
	rm -rf build/installed-reference
	$(PY) -m fliss generate -o build/installed-reference
	@set -e; for python in $(INSTALLED_PYTHONS); do \
		if [ "$$python" = "$(firstword $(INSTALLED_PYTHONS))" ]; then min=--min-deps; else min=; fi; \
		echo "== installed wheel, Python $$python $$min"; \
		$(PY) .ci/installed.py --wheel dist/fliss-*.whl --python $$python $$min \
			--reference build/installed-reference; \
	done
	@echo "== installed wheel, $(PYTHON) (full)"
	$(PY) .ci/installed.py --wheel dist/fliss-*.whl --python $(PYTHON) --full --fresh-cache \
		--reference build/installed-reference

# Bitstreams with the YoWASP toolchain from PyPI: make bitstream BOARD=icebreaker|ulx3s
BOARD ?= icebreaker
BOARDS_STAMP := $(VENV)/.boards-stamp

.PHONY: bitstream program test-boards

$(BOARDS_STAMP): pyproject.toml $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,boards]"
	@touch $@

bitstream: $(BOARDS_STAMP)
	$(PY) -m fliss.boards.build $(BOARD)

program: $(BOARDS_STAMP)
	$(PY) -m fliss.boards.build program $(BOARD)

test-boards: $(BOARDS_STAMP)
	FLISS_BUILD_BOARDS=1 $(PY) -m pytest -n 2 tests/boards/test_boards.py tests/gateware/test_block_ram.py \
		tests/project/test_example_amaranth.py $(PYTEST_ARGS)

# Gate-level: each board's netlist, synthesized by its bitstream build's Yosys script, under the
# top level's cocotb tests with Yosys's cell models (docs/verification.md), and the Verilog of
# `fliss generate` through Yosys for Xilinx, Intel and Gowin (docs/boards.md).
# `make test-netlist` (in .ci/run, about 7.5 minutes on two cores) runs the benches sized for
# gate level; `make test-netlist NETLIST=full` adds the top level's longer benches and the
# routed netlists (tests/formal/test_netlist.py).
# `make test-vendors` (some 10 minutes, not in .ci/run) runs the other vendors' syntheses.
.PHONY: test-netlist test-vendors

NETLIST ?= 1
test-netlist: $(BOARDS_STAMP)
	@case "$(NETLIST)" in 1|full) ;; *) echo "make test-netlist: NETLIST is 1 (the CI tier)"\
		"or full, not '$(NETLIST)'" >&2; exit 2;; esac
	FLISS_NETLIST=$(NETLIST) $(PY) -m pytest -n 2 tests/formal/test_netlist.py $(PYTEST_ARGS)

test-vendors: $(BOARDS_STAMP)
	FLISS_NETLIST=1 $(PY) -m pytest -n 0 tests/formal/test_vendors.py $(PYTEST_ARGS)

# Formal proofs with SymbiYosys from PyPI: the runner's own tests (skipped by `make test`, which
# lacks the formal extra), then every proof, its covers and its mutant (docs/verification.md). FORMAL_ARGS: e.g. `-j 1`, or proof names.
FORMAL_STAMP := $(VENV)/.formal-stamp
FORMAL_ARGS ?= -j 2

.PHONY: formal

$(FORMAL_STAMP): pyproject.toml $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,formal]"
	@touch $@

formal: $(FORMAL_STAMP)
	$(PY) -m pytest -n 0 tests/formal/test_formal.py tests/formal/test_formal_link.py \
		tests/formal/test_formal_keyed.py tests/formal/test_inverted_pairs.py $(PYTEST_ARGS)
	$(PY) -m fliss.formal --mutants $(FORMAL_ARGS)
	$(PY) -m fliss.formal.equivalence --mutant -j 2 crc cobs_encoder cobs_decoder uart_tx uart_rx
	$(PY) -m fliss.formal.equivalence --mutant -j 2 delay_core
