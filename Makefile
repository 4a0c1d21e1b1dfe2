# The front door: every target creates or reuses the virtual environment it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
DEMO_STAMP := $(VENV)/.demo-stamp

.PHONY: install demo test test-fast lint docs bench evaluate clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# the demo needs the package alone (no test, track or stats extras)
$(DEMO_STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	touch $(DEMO_STAMP)

install: $(STAMP)

demo: $(DEMO_STAMP)
	mkdir -p out
	$(BIN)/prosody convert samples/arctic_a0009.wav -o out/arctic_a0009.fap
	$(BIN)/prosody inspect out/arctic_a0009.fap
	$(BIN)/prosody preview samples/arctic_a0009.wav -o out/arctic_a0009.gif
	$(BIN)/prosody stream samples/arctic_a0009.wav -o out/arctic_a0009.live.fap

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

lint: $(STAMP)
	$(BIN)/python -m pip install --quiet ruff mypy
	$(BIN)/ruff check audio_features prosody tests
	$(BIN)/mypy audio_features prosody

docs: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	$(BIN)/python -m sphinx -q -W --keep-going -b html docs out/docs
	@echo "out/docs/index.html"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench.py
	$(BIN)/python benchmarks/live_bench.py
	$(BIN)/python benchmarks/track_bench.py
	$(BIN)/python benchmarks/head_bench.py
	$(BIN)/python benchmarks/deps_bench.py

evaluate: $(STAMP)
	$(BIN)/python benchmarks/head_loco.py
	$(BIN)/python benchmarks/head_loso.py
	$(BIN)/python benchmarks/pad_fit.py
	$(BIN)/python benchmarks/av_offset.py
	$(BIN)/python benchmarks/animation_level.py
	$(BIN)/python benchmarks/expressivity_loso.py
	$(BIN)/python benchmarks/live_loco.py
	$(BIN)/python benchmarks/mouth_loco.py
	$(BIN)/python benchmarks/train_live_mouth.py
	$(BIN)/python benchmarks/head_loop.py
	$(BIN)/python benchmarks/mouth_videos_loso.py

clean:
	rm -rf $(VENV) out build *.egg-info .pytest_cache
