# Two entry points that work on a fresh machine with only python3 (3.11+) and make.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP_RUN := $(VENV)/.installed-run
STAMP_TEST := $(VENV)/.installed-test
# pytest-xdist workers for make test (0: one process), each given whole modules; tests/conftest.py puts the long ones first.
TEST_WORKERS ?= 2
PYTEST_PARALLEL := -n $(TEST_WORKERS) --dist loadscope --no-loadscope-reorder

.PHONY: demo test test-fast clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP_RUN): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(STAMP_TEST): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@ $(STAMP_RUN)

demo: $(STAMP_RUN)
	$(BIN)/aerostereo-mission --demo --out demo/mission.csv --kml demo/mission.kml \
		--geojson demo/mission.geojson --plot demo/mission.png --summary-json demo/summary.json
	$(BIN)/python -m sim --out demo/dataset --frames 20 --width 640 --height 360 \
		--contact-sheet demo/contact_sheet.png --overwrite

# The whole pipeline on the demo world, measured against the truth (report in closed_loop/report.md).
closed-loop: $(STAMP_RUN)
	$(BIN)/python tools/loops/closed_loop.py --out closed_loop

# The same over demo:large's 150,732 m2, 1000 dataset frames (report in area_loop/report.md; a rerun continues).
area-loop: $(STAMP_RUN)
	$(BIN)/python tools/loops/area_loop.py --out area_loop

test: $(STAMP_TEST)
	$(BIN)/python -m pytest $(PYTEST_PARALLEL)

# Skips the slow end-to-end tests (CI runs everything).
test-fast: $(STAMP_TEST)
	$(BIN)/python -m pytest $(PYTEST_PARALLEL) -m "not slow"

clean:
	rm -rf $(VENV) demo .pytest_cache
