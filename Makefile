# make demo | make test | make test-all | make bench — each creates .venv and installs the project first.
# make docs — the API reference from the docstrings into out/site (installs only the docs extra).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
LM     := $(VENV)/bin/lensmount
DESIGN := examples/double-gauss-360

.PHONY: install install-test install-docs browser demo test test-all test-latest lock bench docs fuzz clean

# The runtime alone for the demo; the test extra (pytest, CadQuery as an independent STEP reader) for tests.
# opticalglass declares PySide6 (673 MB, for its glass-map window) as a requirement; lensmount only reads
# its catalogues. So the Makefile installs pyproject's requirements (which list what opticalglass imports
# when it reads a catalogue) and opticalglass without its own: 1.4 GB instead of 2.1 GB (docs/performance.md).
# `pip install .` still works; it brings PySide6 along.
REQUIREMENTS = $(PY) -c "import sys, tomllib; p = tomllib.load(open('pyproject.toml', 'rb'))['project']; \
  r = p['dependencies'] + [x for e in sys.argv[1:] for x in p['optional-dependencies'][e]]; \
  print('\n'.join(x for x in r if not x.startswith('opticalglass')))"
GLASS = $(shell sed -n 's/^ *"\(opticalglass[^"]*\)".*/\1/p' pyproject.toml)
# Installs reproduce: every version comes from constraints.txt (the versions the suite passed with).
# `make test-latest` clears CONSTRAINTS to try today's newest versions in .venv-latest.
CONSTRAINTS ?= -c constraints.txt

$(VENV)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(REQUIREMENTS) > $(VENV)/requirements.txt
	$(PY) -m pip install --quiet $(CONSTRAINTS) -r $(VENV)/requirements.txt
	$(PY) -m pip install --quiet $(CONSTRAINTS) --no-deps -e . '$(GLASS)'
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	$(REQUIREMENTS) test > $(VENV)/requirements-test.txt
	$(PY) -m pip install --quiet $(CONSTRAINTS) -r $(VENV)/requirements-test.txt
	touch $@

# numba compiles the tracer's kernels once, here, not in the first run (again when their source changes).
# Their old cache goes first: numba checks only a kernel's own file, and the walk inlines kernels.py's step.
$(VENV)/.warm: $(VENV)/.installed src/lensmount/trace/kernels.py src/lensmount/trace/lens_kernel.py \
		src/lensmount/integrators/photon_mapping/radius.py
	rm -f src/lensmount/trace/__pycache__/*.nbi src/lensmount/trace/__pycache__/*.nbc
	$(PY) -m lensmount.trace.warm
	$(PY) -m lensmount.integrators.warm
	touch $@

# The docs extra alone: mkdocstrings reads src/ without importing it, so no runtime is installed.
$(VENV)/.installed-docs: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -c "import tomllib; print('\\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['docs']))" \
	  > $(VENV)/requirements-docs.txt
	$(PY) -m pip install --quiet $(CONSTRAINTS) -r $(VENV)/requirements-docs.txt
	touch $@

install: $(VENV)/.installed $(VENV)/.warm
install-test: $(VENV)/.installed-test $(VENV)/.warm
install-docs: $(VENV)/.installed-docs

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
	$(VENV)/bin/lint-imports
	$(PY) -m pytest -m "not slow" -q $(PYTEST_WORKERS)

test-all: install-test browser
	$(VENV)/bin/lint-imports
	$(PY) -m pytest -q $(PYTEST_WORKERS)

# Every reader fed 10^4 malformed inputs (the full suite feeds 2 000 each); the counts are printed.
fuzz: install-test
	LENSMOUNT_FUZZ_INPUTS=10000 $(PY) -m pytest -m slow -q -s -p no:xdist tests/inputs/test_fuzz_readers.py

# The fast suite on the newest versions the registries serve (no constraints), in a venv of its own.
test-latest:
	$(MAKE) VENV=.venv-latest CONSTRAINTS= test

# Re-resolve the newest versions and write them to constraints.txt (run test-latest first: pin what passes).
lock:
	rm -rf .venv-lock
	$(MAKE) VENV=.venv-lock CONSTRAINTS= install-test install-docs
	{ sed -n '1,/^# `make test-latest`/p' constraints.txt; .venv-lock/bin/pip freeze --exclude-editable | grep -v '^lensmount'; } > constraints.txt.new
	mv constraints.txt.new constraints.txt
	rm -rf .venv-lock

# The API reference (mkdocs.yml): --strict makes every warning, a docstring griffe cannot parse
# included, an error. The hand-written pages' lensmount names are checked by tests/docs.
docs: install-docs
	$(VENV)/bin/mkdocs build --strict

bench: install-test
	$(PY) -m pip install --quiet $(CONSTRAINTS) -e '.[test,bench]'
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) .venv-latest .venv-lock out .pytest_cache
