# pathpref: the two commands a user needs are `make demo` and `make test`.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install test demo lint bench mutation clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip "setuptools>=77"
	$(BIN)/pip install --quiet -e '.[dev,ray]'
	@# the study's browser tests drive Debian's chromium (Playwright, no browser download);
	@# its viewer test opens a real MuJoCo window on a virtual screen (xvfb-run)
	(command -v chromium >/dev/null && command -v xvfb-run >/dev/null) || \
		(apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
		chromium xvfb xauth) \
		|| echo "chromium/xvfb could not be installed: the browser/viewer tests will be skipped"
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	MUJOCO_GL=egl $(BIN)/python -m pytest

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
	rm -rf $(VENV) out build *.egg-info mutants
