# `make demo` and `make test` do all set-up on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test install warmup bench clean clean-kernels

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# torch pinned first: 2.13.0 is the CPU build on disk, so the rllib extra's `torch>=2.1` is met (else pip fetches a multi-GB CUDA build)
$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e '.[test,ray,rllib]'
	touch $(STAMP)

# numba compiles the kernels for this machine on their first call: done here, once, on every
# core (seconds when they are already cached; after an edit it compiles what changed)
warmup: $(STAMP)
	$(BIN)/agvsim warmup

install: warmup

demo: warmup
	$(BIN)/agvsim demo --out out/demo

# -n auto: one pytest worker per core (pytest-xdist); each worker loads the compiled kernels
# once (tests/conftest.py): `warmup` compiled them before, once for all workers.
test: warmup
	$(BIN)/python -m pytest -q -p no:cacheprovider -n auto

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	$(BIN)/agvsim bench sim
	$(BIN)/agvsim bench localizer

clean:
	rm -rf $(VENV) out *.egg-info

# numba's cache is keyed on each kernel's own file: after editing a helper that other files'
# kernels inline or call, drop the compiled kernels (ARCHITECTURE.md, "Stale kernels")
clean-kernels:
	find agvsim localizer envs -name '*.nbi' -delete -o -name '*.nbc' -delete
