# shadowlab quick start: `make run` then `make test` (see README.md).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test clean install experiments

# constraints.txt pins every package to the versions the test suite was run with.
$(STAMP): pyproject.toml setup.py constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test,perceptual,viewer]'
	touch $(STAMP)

install: $(STAMP)

# The lab's headline: the quick study (shadow volumes vs shadow maps vs planar vs exact shadow
# polygons against the ray-traced truth, on a few hard cases), then where its report is.
run: $(STAMP)
	$(BIN)/shadowlab study quick --out results/study-quick

# The tests, the lab installed from its wheel into a fresh venv outside the tree (an editable
# install hides packaging mistakes), then the quick study and the soft-shadow study held against
# their committed baselines (what CI runs).
# The viewer's tests need an X server: Xvfb, installed here when missing and possible (root and
# apt-get; best effort, never failing the build — without it those tests skip with the hint).
test: $(STAMP)
	@command -v Xvfb >/dev/null || (export DEBIAN_FRONTEND=noninteractive; apt-get install -y xvfb >/dev/null 2>&1 \
	  || (apt-get update -qq >/dev/null 2>&1 && apt-get install -y xvfb >/dev/null 2>&1) || true)
	$(BIN)/python -m pytest -q
	bash tests/install_check/run.sh $(BIN)/python
	$(BIN)/shadowlab study quick --out results/study-quick
	$(BIN)/shadowlab check results/study-quick tests/baselines/quick.csv
	$(BIN)/shadowlab study soft_quick --out results/study-soft_quick
	$(BIN)/shadowlab check results/study-soft_quick tests/baselines/soft_quick.csv

# Every experiment at its small default size (a few minutes); each writes results/<name>.* and
# a .json record of the code revision, renderer, package versions, CPU and command line.
# (prepare_meshes.py, prepare_city.py, make_city_wires.py, make_sv_scenes.py and make_many_light_scenes.py are not experiments:
# they remake the shipped meshes and scenes, the first two from a downloaded package;
# volumes_vs_maps.py reads a study directory given to it.)
EXPERIMENTS := $(filter-out experiments/prepare_meshes.py experiments/prepare_city.py experiments/make_city_wires.py experiments/make_sv_scenes.py experiments/make_many_light_scenes.py experiments/make_gltf_scene.py experiments/volumes_vs_maps.py,$(wildcard experiments/*.py))
experiments: $(STAMP)
	@set -e; for e in $(EXPERIMENTS); do echo "== $$e"; $(BIN)/python $$e; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache results/quickstart results/study-quick results/study-soft_quick
