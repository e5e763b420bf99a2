# rvdiag: `make demo` runs the main job on the built-in default, `make test` runs the tests.
# Both create .venv and install rvdiag with its test extras when needed.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.rvdiag-installed
OUT    ?= out

.PHONY: demo paper test bench clean install

install: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP)
	$(PY) examples/demo.py --out $(OUT)

# the same main job at the scale of the dynamics paper (6 states x 60 s, 8000-point samples)
paper: $(STAMP)
	$(PY) examples/demo.py --out $(OUT)/paper --config configs/paper.toml

test: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider

bench: $(STAMP)
	$(PY) bench/tvms_speed.py

clean:
	rm -rf $(OUT) .pytest_cache
