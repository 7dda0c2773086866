# The README's commands: `make demo` (main job) and `make test` (whole suite); `make bench`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
THREEJS := tests/io/threejs
CLIP := dataset-1_walk_happy_001.bvh

.PHONY: install test lint demo bench clean

# torch is pinned here, not in pyproject.toml: 2.13.0 is the CPU wheel on these machines, and a
# looser range would pull a multi-GB CUDA build. See the README for a GPU build.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e '.[dev,bench,eval]'
	touch $@

install: $(STAMP)

$(THREEJS)/node_modules/.package-lock.json: $(THREEJS)/package-lock.json
	@if command -v npm >/dev/null; then npm ci --prefix $(THREEJS) --no-audit --no-fund --silent; \
	else echo "npm not found: the three.js import check will be skipped"; fi

lint: install
	$(BIN)/ruff check src tests bench

test: install lint $(THREEJS)/node_modules/.package-lock.json
	$(BIN)/python -m pytest

demo: install
	mkdir -p demo_out
	for e in happy sad angry neutral; do \
		$(BIN)/emotive generate --emotion $$e --path circle --seconds 10 \
			--out demo_out/walk_$$e.bvh --preview demo_out/walk_$$e.mp4 || exit 1; \
	done
	$(BIN)/emotive generate --emotion-schedule examples/angry-to-happy.json --path figure8 \
		--seconds 20 --out demo_out/angry_to_happy.bvh --preview demo_out/angry_to_happy.mp4
	$(BIN)/emotive data fetch bandai-namco-1
	$(BIN)/emotive features "$$($(BIN)/emotive data path bandai-namco-1)/data/$(CLIP)" \
		--out demo_out/features.csv --plot demo_out/features.png
	@echo "demo outputs in $(CURDIR)/demo_out:"
	@ls -1 demo_out

bench: install
	$(BIN)/python bench/run.py

clean:
	rm -rf $(VENV) demo_out $(THREEJS)/node_modules
