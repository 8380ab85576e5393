# Two commands do all the set-up on a fresh clone: `make cosim` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# exact versions of every dependency, so a fresh clone reproduces the committed results
LOCK := constraints.txt

.PHONY: venv fmu test test-all fuzz valgrind cosim bench lint xc sweep study clean lock docs

# pyproject.toml's dependencies and its dev extra, as a requirements list: the venv installs
# them, not the project, which runs from this folder (`python -m harness`), so no package of
# ours is built or copied and nothing goes stale
REQUIREMENTS = $(PYTHON) -c "import tomllib; p = tomllib.load(open('pyproject.toml', 'rb'))['project']; \
	print(*p['dependencies'], *p['optional-dependencies']['dev'], sep='\n')"

$(STAMP): pyproject.toml $(LOCK)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip -c $(LOCK)
	$(REQUIREMENTS) > $(VENV)/requirements.txt
	$(PY) -m pip install --quiet -r $(VENV)/requirements.txt -c $(LOCK)
	touch $@

venv: $(STAMP)

fmu: $(STAMP)
	$(PY) -m harness build-fmus

# the suite less the tests marked slow (about 100 s on 2 cores, one pytest worker per core);
# test-all runs every test
test: fmu
	$(PY) -m pytest -q -n auto -m "not slow"

test-all: fmu
	$(PY) -m pytest -q -n auto

# property tests with random seeds and many examples (the ledger's alone 25 min on one core); `make test` runs the
# same suite with a fixed seed and a small budget
fuzz: fmu
	HYPOTHESIS_PROFILE=deep $(PY) -m pytest -q -n auto tests/fuzz

# the FMUs' runtime under valgrind in a C host: 50 load/instantiate/200 steps/state round
# trip/free/unload cycles of two FMUs, no error and no definite leak (about a minute)
valgrind: fmu
	$(PY) -m pytest -q -m slow tests/test_runtime.py -k valgrind

cosim: fmu
	$(PY) -m harness cosim --scenario all --variants all

bench: fmu
	$(PY) -m harness bench

xc: fmu
	$(PY) -m harness cross-check

sweep: fmu
	$(PY) -m harness sweep harness/sweeps/table1.toml
	$(PY) -m harness sweep harness/sweeps/regulation.toml

# the committed study (docs/study.md): every variant over the task models' random tasks in
# both loss sets, on 2 local Dask workers; resumes where a killed one stopped
study: fmu
	$(PY) -m harness study --scenario all --workers 2

# the generated pages: docs/variables/<Model>.md, docs/fmus.md and the mechanisms' README sections
# from the built FMUs; docs/findings.md, the README's headline table and docs/performance.md's
# figures from the committed results (tests/test_docs.py fails when one is stale)
docs: fmu
	$(PY) -m harness docs

lint: $(STAMP)
	$(VENV)/bin/ruff check fmu_src harness tests

# Re-resolve pyproject.toml's dependencies in a fresh venv (newest versions that satisfy it)
# and pin what got installed; then `make venv` installs exactly those.
lock:
	rm -rf build/lock-venv
	$(PYTHON) -m venv build/lock-venv
	build/lock-venv/bin/python -m pip install --quiet --upgrade pip
	$(REQUIREMENTS) > build/lock-venv/requirements.txt
	build/lock-venv/bin/python -m pip install --quiet -r build/lock-venv/requirements.txt
	{ echo "# Pinned by 'make lock' with $$($(PYTHON) --version) on $$(uname -sm): do not edit."; \
	  build/lock-venv/bin/python -m pip freeze --all; } > $(LOCK).tmp
	mv $(LOCK).tmp $(LOCK)
	rm -rf build/lock-venv

clean:
	rm -rf build
