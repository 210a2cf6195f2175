# shadowlab quick start: `make run` then `make test` (see README.md).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test clean install experiments

# constraints.txt pins every package to the versions the test suite was run with.
$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# The default comparison: ground truth + the shadow map at two resolutions on box_on_plane.
run: $(STAMP)
	$(BIN)/shadowlab compare box_on_plane \
		--technique shadow_map \
		--technique shadow_map:resolution=256 \
		--size 800x600 --out results/quickstart

test: $(STAMP)
	$(BIN)/python -m pytest -q

# Every experiment at its small default size (a few minutes); each writes results/<name>.* and
# a .json record of the code revision, renderer, package versions, CPU and command line.
EXPERIMENTS := $(wildcard experiments/*.py)
experiments: $(STAMP)
	@set -e; for e in $(EXPERIMENTS); do echo "== $$e"; $(BIN)/python $$e; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache results/quickstart
