# Two commands a new user needs: `make demo` and `make test`. Both build .venv on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
DEMO_OUT := demo-output

.PHONY: demo test test-slow lint bench bench-deps clean

$(STAMP): pyproject.toml setup.py scripts/system-deps.sh
	bash scripts/system-deps.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# torch first, pinned, so nothing later pulls a CUDA build.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[dev,all]'
	# splat-transform, the independent reader the format tests check our writers against
	# (best effort: without it those tests skip, saying so).
	-cd benchmarks && npm ci --no-audit --no-fund --silent
	touch $(STAMP)

demo: $(STAMP)
	bash scripts/demo.sh $(VENV) $(DEMO_OUT)

# One test process per core (files kept whole, so module fixtures are built once), each
# with one BLAS/OpenMP thread: a process per core already fills the cores, and torch's
# default of a thread per core in every process oversubscribed them (2 cores: 314 -> 221 s).
# Tests that need several threads ask for them explicitly.
test: $(STAMP)
	OMP_NUM_THREADS=1 $(PY) -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

test-slow: $(STAMP)
	OMP_NUM_THREADS=1 $(PY) -m pytest -q -n auto --dist loadfile --no-loadscope-reorder -m slow

# Peer codecs for benchmarks/ (npm splat-transform, PyPI DracoPy); not needed to test.
bench-deps: $(STAMP)
	cd benchmarks && npm ci --no-audit --no-fund
	$(PY) -m pip install --quiet -e '.[bench]'

# The rate-distortion comparison with the peers (writes bench-output/rd.json and rd.png).
bench: bench-deps
	mkdir -p bench-output
	cd benchmarks && ../$(PY) rd.py --out ../bench-output/rd.json --plot ../bench-output/rd.png

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache build *.egg-info
