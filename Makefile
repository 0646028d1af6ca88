# pathpref: the two commands a user needs are `make demo` and `make test`.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install test test-cross-cpu demo lint bench mutation clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip "setuptools>=77"
	$(BIN)/pip install --quiet -e '.[dev,ray,export,parquet,dataset,lsl,rrd,ros]'
	@# every numba kernel compiled into its cache now, not at the first decision (docs/install)
	MUJOCO_GL=egl $(BIN)/pathpref warmup --quiet
	@# the study's browser tests drive Debian's chromium (Playwright, no browser download);
	@# its viewer test opens a real MuJoCo window on a virtual screen (xvfb-run)
	(command -v chromium >/dev/null && command -v xvfb-run >/dev/null) || \
		(apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
		chromium xvfb xauth) \
		|| echo "chromium/xvfb could not be installed: the browser/viewer tests will be skipped"
	touch $(STAMP)

install: $(STAMP)

# two worker processes (pytest-xdist), each taking whole test files (module fixtures built
# once, the wheel built by one process): the suite is CPU-bound, single-threaded per test
test: $(STAMP)
	MUJOCO_GL=egl $(BIN)/python -m pytest -n 2 --dist loadfile

# The replays and pinned decisions (marker cross_cpu) once more under another CPU feature set:
# NumPy at its x86-64-v2 baseline (no AVX2/AVX-512 kernels), OpenBLAS's Sandy Bridge kernels
# (AVX, no FMA), numba compiled for a generic x86-64 with its own cache. On any x86-64 machine
# with AVX2 this differs from the first run's kernels (docs/experiments.md, "Replays exactly").
CROSS_CPU_ENV = NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR" \
	OPENBLAS_CORETYPE=Sandybridge NUMBA_CPU_NAME=generic NUMBA_CACHE_DIR=$(CURDIR)/.numba-generic
test-cross-cpu: $(STAMP)
	$(CROSS_CPU_ENV) MUJOCO_GL=egl $(BIN)/python -m pytest -m cross_cpu -p no:cacheprovider

lint: $(STAMP)
	$(BIN)/ruff check pathpref tasks tests scripts

demo: $(STAMP)
	MUJOCO_GL=egl $(BIN)/pathpref demo --out out

mutation: $(STAMP)
	rm -rf mutants
	MUJOCO_GL=egl $(BIN)/mutmut run
	$(BIN)/mutmut results

bench: $(STAMP)
	$(BIN)/python scripts/bench.py

clean:
	rm -rf $(VENV) out build *.egg-info mutants .numba-generic
