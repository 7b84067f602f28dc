# make demo | make test | make test-all | make bench — each creates .venv and installs the project first.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
LM     := $(VENV)/bin/lensmount
DESIGN := examples/double-gauss-360

.PHONY: install install-test demo test test-all bench clean

# The runtime alone for the demo; the test extra (pytest, CadQuery as an independent STEP reader) for tests.
$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

install: $(VENV)/.installed
install-test: $(VENV)/.installed-test

demo: install
	$(LM) regenerate $(DESIGN) --out out/double-gauss-360
	$(LM) simulate $(DESIGN) --scene $(DESIGN)/scenes/case1-diaphragm-edge.toml --out out/case1

# CI subset: everything but the tests marked slow.
test: install-test
	$(PY) -m pytest -m "not slow" -q

test-all: install-test
	$(PY) -m pytest -q

bench: install-test
	$(PY) -m pip install --quiet -e '.[test,bench]'
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) out .pytest_cache
