# `make demo` and `make test` do all set-up on a fresh machine. Each phase prints one line:
# what it did and how long it took.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
# the project and what it imports (the demo's needs); the test extras and the cluster extras
# (Ray, RLlib, torch) are installed by `make test` only. --no-compile: Python writes a module's
# bytecode when it first imports it, not pip for every module of every package (half the install)
BASE   := $(VENV)/.installed
TESTS  := $(VENV)/.installed-test
# (in a variable: a comma written inside $(call ...) would split its arguments)
TEST_EXTRAS := .[test,ray,rllib,record,rosbag,pbr]
# Python may write each module's bytecode (into .venv and beside the sources, where numba's cache
# already lives): a machine that sets PYTHONDONTWRITEBYTECODE would otherwise compile every module
# from source in every process the demo and the tests start (about 2 s each)
unexport PYTHONDONTWRITEBYTECODE
# run a phase: $(call phase,what it does,command)
phase = @start=$$(date +%s); $(2) || exit $$?; echo "make: $(1) ($$(( $$(date +%s) - start )) s)"

.PHONY: demo test install warmup bench clean clean-kernels

$(BIN)/python:
	$(call phase,created $(VENV),$(PYTHON) -m venv $(VENV) && $(BIN)/python -m pip install --quiet 'pip>=21.3')

$(BASE): $(BIN)/python pyproject.toml
	$(call phase,installed the project into $(VENV),$(BIN)/python -m pip install --quiet --no-compile -e . && touch $(BASE))

# torch pinned first: 2.13.0 is the CPU build on disk, so the rllib extra's `torch>=2.1` is met
# (else pip fetches a multi-GB CUDA build)
$(TESTS): $(BASE)
	$(call phase,installed the test extras (pytest; Ray + RLlib + torch for the cluster tests),$(BIN)/python -m pip install --quiet --no-compile torch==2.13.0 && $(BIN)/python -m pip install --quiet --no-compile -e '$(TEST_EXTRAS)' && touch $(TESTS))

# numba compiles the kernels for this machine on their first call: done here, once, on every
# core (a second when they are already cached; after an edit it compiles what changed)
warmup: $(BASE)
	$(call phase,compiled the kernels (agvsim warmup),$(BIN)/agvsim warmup)

install: warmup

demo: warmup
	$(call phase,ran the demo (out/demo),$(BIN)/agvsim demo --out out/demo)

# -n auto: one pytest worker per core (pytest-xdist); each worker loads the compiled kernels
# once (tests/conftest.py): `warmup` compiled them before, once for all workers.
test: $(TESTS) warmup
	$(call phase,ran the test suite,$(BIN)/python -m pytest -q -p no:cacheprovider -n auto)

bench: $(BASE)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	$(BIN)/agvsim bench sim
	$(BIN)/agvsim bench localizer

clean:
	rm -rf $(VENV) out *.egg-info

# numba's cache is keyed on each kernel's own file: after editing a helper that other files'
# kernels call, drop the compiled kernels (ARCHITECTURE.md, "Stale kernels")
clean-kernels:
	find agvsim localizer envs -name '*.nbi' -delete -o -name '*.nbc' -delete
