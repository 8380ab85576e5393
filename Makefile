# Two commands do all the set-up on a fresh clone: `make cosim` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: venv fmu test fuzz cosim bench lint xc sweep clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $@

venv: $(STAMP)

fmu: $(STAMP)
	$(PY) -m harness build-fmus

test: fmu
	$(PY) -m pytest -q

# property tests with random seeds and many examples (about 10 min); `make test` runs the
# same suite with a fixed seed and a small budget
fuzz: fmu
	HYPOTHESIS_PROFILE=deep $(PY) -m pytest -q tests/fuzz

cosim: fmu
	$(PY) -m harness cosim --scenario all --variants all

bench: fmu
	$(PY) -m harness bench

xc: fmu
	$(PY) -m harness cross-check

sweep: fmu
	$(PY) -m harness sweep harness/sweeps/table1.toml

lint: $(STAMP)
	$(VENV)/bin/ruff check fmu_src harness tests

clean:
	rm -rf build
