# rvdiag: `make demo` runs the main job on the built-in default, `make test` runs the tests, `make docs` builds the
# API reference in build/docs.  Each creates .venv and installs rvdiag with its extras when needed.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.rvdiag-installed
DOCS_STAMP := $(VENV)/.rvdiag-docs-installed
OUT    ?= out

.PHONY: demo paper test docs bench clean install

install: $(STAMP)

# Exact versions from constraints.txt (pyproject.toml holds the ranges).  TORCH_INDEX installs PyTorch from
# another index first, e.g. the CPU build: make test TORCH_INDEX=https://download.pytorch.org/whl/cpu
TORCH_INDEX ?=
PIP := $(PY) -m pip install -q --disable-pip-version-check -c constraints.txt

$(STAMP): pyproject.toml constraints.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(if $(TORCH_INDEX),$(PIP) torch --index-url $(TORCH_INDEX))
	$(PIP) -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP)
	$(PY) examples/demo.py --out $(OUT)

# the same main job at the scale of the dynamics paper (6 states x 60 s, 8000-point samples)
paper: $(STAMP)
	$(PY) examples/demo.py --out $(OUT)/paper --config configs/paper.toml

# tests/services/start.sh starts PostgreSQL and installs Debian's chromium where it can (the fleet's tests)
test: $(STAMP)
	eval "$$(bash tests/services/start.sh)"; $(PY) -m pytest -q -p no:cacheprovider

$(DOCS_STAMP): $(STAMP)
	$(PIP) -e '.[test,docs]'
	@touch $(DOCS_STAMP)

# the API reference from the numpydoc docstrings (docs/api/conf.py), warnings as errors
docs: $(DOCS_STAMP)
	$(PY) -m sphinx -q -b html -W --keep-going docs/api build/docs
	@echo "API reference: build/docs/index.html"

bench: $(STAMP)
	$(PY) bench/tvms_speed.py

clean:
	rm -rf $(OUT) .pytest_cache build/docs docs/api/generated
