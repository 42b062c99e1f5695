# `make demo` and `make test` do all set-up on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test install bench clean clean-kernels

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/agvsim demo --out out/demo

# -n auto: one pytest worker per core (pytest-xdist); each worker loads the localizer's
# compiled kernels once (tests/conftest.py), compiling them on a fresh clone (~80 s of numba).
test: $(STAMP)
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
