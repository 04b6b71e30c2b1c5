# refspatial-gen: `make shards` and `make test` set everything up on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
HASH := $(shell cat pyproject.toml | sha1sum | cut -c1-12)
STAMP := $(VENV)/.installed-$(HASH)
TEST_STAMP := $(VENV)/.installed-test-$(HASH)
RECIPE ?= recipes/default.yaml
OUT ?= out/shards/default
SCENES ?=
WORKERS ?= 2
PYTEST_ARGS ?=
BENCH_ARGS ?=
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: setup setup-test shards test test-slow test-all bench preview lint clean

$(STAMP): pyproject.toml
	@bash scripts/ensure-system-libs.sh
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@echo "installing refspatial-gen and its pinned dependencies into $(VENV) (first use only)"
	@$(BIN)/python -m pip install -q --upgrade pip
	@$(BIN)/python -m pip install -q -e .
	@rm -f $(VENV)/.installed-[0-9a-f]*
	@touch $@

# the tests also need the optional extras: Ray (scale-out), torch + transformers + onnxruntime (depth models),
# sentencepiece (SigLIP tokenizers, perception)
$(TEST_STAMP): $(STAMP)
	@echo "installing test extras (pytest, hypothesis, ray, torch CPU, transformers, onnxruntime, sentencepiece)"
	@$(BIN)/python -m pip install -q -e '.[test,ray,depth,dev,perception]'
	@rm -f $(VENV)/.installed-test-*
	@touch $@

setup: $(STAMP)
setup-test: $(TEST_STAMP)

shards: setup
	$(BIN)/refspatial-gen shards --recipe $(RECIPE) --out $(OUT) $(if $(SCENES),--scenes $(SCENES)) --workers $(WORKERS)

test: setup-test
	$(BIN)/python -m pytest -q -m "not slow" $(PYTEST_ARGS)

test-slow: setup-test
	$(BIN)/python -m pytest -q -m slow $(PYTEST_ARGS); rc=$$?; [ $$rc -eq 5 ] && rc=0; exit $$rc

test-all: setup-test
	$(BIN)/python -m pytest -q $(PYTEST_ARGS)

bench: setup-test
	$(BIN)/python -m refspatial_gen.bench $(BENCH_ARGS)

preview: setup
	$(BIN)/refspatial-gen preview $(OUT) --out out/preview

lint: setup
	$(BIN)/refspatial-gen recipes lint recipes/*.yaml recipes/templates/*.yaml

clean:
	rm -rf out
