# make demo | make test | make test-all | make bench — each creates .venv and installs the project first.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
LM     := $(VENV)/bin/lensmount
DESIGN := examples/double-gauss-360

.PHONY: install install-test browser demo test test-all bench clean

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
	$(LM) simulate $(DESIGN) --scene $(DESIGN)/scenes/case1-diaphragm-edge.toml --geometry out/double-gauss-360 \
	    --out out/case1 --store out/runs.sqlite

# Headless Chromium for the report test (tests/report), from Debian, only when missing.
# CI runs as root on a fresh Debian machine: there it installs (about a minute); elsewhere
# it says what to do, and the test skips (or fails when CI=true).
browser:
	@if [ ! -x /usr/bin/chromium ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing chromium for the report test (apt-get)"; \
	    apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium; \
	  else \
	    echo "note: /usr/bin/chromium is missing; as root on Debian: apt-get install -y chromium"; \
	  fi; \
	fi

# Two pytest workers, one per core; a test file stays on one worker (its module fixtures are built once).
# PYTEST_WORKERS= (empty) runs in one process.
PYTEST_WORKERS ?= -n 2 --dist loadfile

# CI subset: everything but the tests marked slow.
test: install-test browser
	$(PY) -m pytest -m "not slow" -q $(PYTEST_WORKERS)

test-all: install-test browser
	$(PY) -m pytest -q $(PYTEST_WORKERS)

bench: install-test
	$(PY) -m pip install --quiet -e '.[test,bench]'
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) out .pytest_cache
