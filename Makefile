# synthkit: make help lists the targets.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-dev
BENCH_STAMP := $(VENV)/.installed-bench
BLENDER_VENV := .venv-blender
BLENDER_STAMP := $(BLENDER_VENV)/.installed
VALIDATOR := tools/gltf-validator
VALIDATOR_STAMP := $(VALIDATOR)/node_modules/.installed

.DEFAULT_GOAL := help
.PHONY: help install browser clients constraints demo test test-fast fuzz bench pictures samples samples-check lint clean

help: ## List the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-14s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml setup.py constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev,dist,usd]'
	$(BIN)/python -c 'from synthkit.core.graphcut import compile_kernels; compile_kernels()'
	touch $(STAMP)

$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev,bench]'
	touch $(BENCH_STAMP)

install: $(STAMP) ## Create .venv and install synthkit with its test tools

# Blender and the validator are test clients: where one cannot be installed, its tests skip and
# say why (a note here too), except under CI=true, where a failed install fails the target.
CLIENT_FAILED = { [ "$$CI" = true ] && exit 1; echo "note: $(1) not installed; tests/clients will skip its tests"; }

$(BLENDER_STAMP): constraints-blender.txt
	@{ test -x $(BLENDER_VENV)/bin/python || $(PYTHON) -m venv $(BLENDER_VENV); } && \
	  $(BLENDER_VENV)/bin/python -m pip install --quiet --disable-pip-version-check -c constraints-blender.txt bpy && \
	  touch $(BLENDER_STAMP) || $(call CLIENT_FAILED,Blender (bpy))

$(VALIDATOR_STAMP): $(VALIDATOR)/package.json $(VALIDATOR)/package-lock.json
	@( cd $(VALIDATOR) && npm ci --no-audit --no-fund --loglevel=error ) && \
	  touch $(VALIDATOR_STAMP) || $(call CLIENT_FAILED,the glTF-Validator (npm))

clients: $(BLENDER_STAMP) $(VALIDATOR_STAMP) ## Install Blender (bpy, in .venv-blender) and the Khronos glTF-Validator (npm) for tests/clients

constraints: $(STAMP) ## Rewrite constraints.txt from the installed .venv (after a deliberate upgrade)
	{ echo "# Exact versions synthkit's tests passed with (Python 3.11, $$(date +%F)); make install uses them:"; \
	  echo "#   pip install -c constraints.txt -e '.[dev,dist,usd]'"; \
	  echo "# Regenerate after a deliberate upgrade with: make constraints"; \
	  $(BIN)/python -m pip list --format=freeze --disable-pip-version-check | \
	  grep -viE '^(synthkit|pip|setuptools|wheel)==' | sort -f; } > constraints.txt

browser: ## Install Debian's chromium for the review page's browser test (as root; the test skips without it)
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
		{ apt-get install -y -q chromium >/dev/null 2>&1 || { apt-get update -q >/dev/null 2>&1 && \
		  apt-get install -y -q chromium >/dev/null 2>&1; }; }; } || \
		echo "note: chromium not installed; the review page's browser test will skip"

demo: $(STAMP) ## Install, then run every bundled config in configs/ into out/
	$(BIN)/synthkit run configs/*/*.yaml --out-root out --overwrite --no-progress

test: $(BENCH_STAMP) browser clients ## Install (with the benchmarks' peers), then run the whole test suite (what CI runs)
	$(BIN)/python -m pytest -q

test-fast: $(STAMP) ## Run the tests not marked slow
	$(BIN)/python -m pytest -q -m "not slow"

fuzz: $(STAMP) ## Fuzz every reader longer: SYNTHKIT_FUZZ_EXAMPLES cases per format (default 400; figures in docs/performance.md)
	SYNTHKIT_FUZZ=1 $(BIN)/python -m pytest -q tests/fuzz -k "not command_line" --hypothesis-show-statistics

bench: $(BENCH_STAMP) ## Run the benchmarks; figures go to bench-results/<area>.json
	@set -e; for script in benchmarks/[a-z]*.py; do echo "== $$script"; $(BIN)/python $$script; done

pictures: $(STAMP) browser ## Regenerate docs/images/ (README and docs pictures) from the bundled samples
	$(BIN)/python docs/make_pictures.py

samples: $(STAMP) ## Regenerate data-samples/ and its SHA256SUMS
	$(BIN)/python data-samples/generate.py

samples-check: $(STAMP) ## Regenerate samples in a temporary folder and compare with SHA256SUMS
	$(BIN)/python data-samples/generate.py --check

lint: $(STAMP) ## Run ruff over the project
	$(BIN)/ruff check .

clean: ## Remove outputs, benchmark results and caches (keeps .venv, .venv-blender and the validator)
	rm -rf out bench-results .pytest_cache .ruff_cache build *.egg-info
	find . -name __pycache__ -not -path './.venv/*' -prune -exec rm -rf {} +
