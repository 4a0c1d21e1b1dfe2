# The front door: every target creates or reuses the virtual environment it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
DEMO_STAMP := $(VENV)/.demo-stamp

.PHONY: install demo test test-fast lint docs bench evaluate models clean

# $(call venv_with,REQUIREMENT): the virtual environment, made if missing, with the project installed as asked
define venv_with
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '$(1)'
	touch $@
endef

$(STAMP): pyproject.toml
	$(call venv_with,.[test])

# the demo needs the package alone (no test, track or stats extras)
$(DEMO_STAMP): pyproject.toml
	$(call venv_with,.)

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

# the checkers pinned: a newer release's new rules must not fail a clean checkout
lint: $(STAMP)
	$(BIN)/python -m pip install --quiet 'ruff==0.17.6' 'mypy==2.4.1'
	$(BIN)/ruff check audio_features prosody tests
	$(BIN)/mypy audio_features prosody tests/typing/facade_calls.py

docs: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	$(BIN)/python -m sphinx -q -W --keep-going -b html docs out/docs
	@echo "out/docs/index.html"

bench: $(STAMP)
	$(BIN)/python -m benchmarks.bench
	$(BIN)/python -m benchmarks.live_bench
	$(BIN)/python -m benchmarks.track_bench
	$(BIN)/python -m benchmarks.head_bench
	$(BIN)/python -m benchmarks.deps_bench

evaluate: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[evaluate]'
	$(BIN)/python -m experiments.head_loco
	$(BIN)/python -m experiments.head_loso
	$(BIN)/python -m experiments.pad_fit
	$(BIN)/python -m experiments.av_offset
	$(BIN)/python -m experiments.animation_level
	$(BIN)/python -m experiments.expressivity_loso
	$(BIN)/python -m experiments.live_loco
	$(BIN)/python -m experiments.brows_heads
	$(BIN)/python -m experiments.mouth_loco
	$(BIN)/python -m experiments.phone_loop_weight
	$(BIN)/python -m experiments.viseme_fit
	$(BIN)/python -m experiments.live_mouth_loso
	$(BIN)/python -m experiments.live_mouth_videos_loso
	$(BIN)/python -m experiments.head_loop
	$(BIN)/python -m experiments.photo_loop
	$(BIN)/python -m experiments.expression_reading
	$(BIN)/python -m experiments.chin_line
	$(BIN)/python -m experiments.likeness
	$(BIN)/python -m experiments.mouth_ruler
	$(BIN)/python -m experiments.mouth_videos_loso
	$(BIN)/python -m experiments.cue_grid
	$(BIN)/python -m experiments.mouth_learners_loso
	$(BIN)/python -m experiments.phone_warp
	$(BIN)/python -m experiments.grid_transcripts $(RHUBARB)
	if [ -n "$(RHUBARB)" ]; then $(BIN)/python -m experiments.rhubarb_side_by_side $(RHUBARB); fi
	$(BIN)/python -m experiments.render

# every shipped model refitted from ../shared/data, compared with the shipped files (--write replaces them)
models: $(STAMP)
	$(BIN)/python -m scripts.retrain_models

clean:
	rm -rf $(VENV) out build *.egg-info .pytest_cache
