# synthkit: make help lists the targets.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-dev
BENCH_STAMP := $(VENV)/.installed-bench

.DEFAULT_GOAL := help
.PHONY: help install browser constraints demo test test-fast fuzz bench pictures samples samples-check lint clean

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

test: $(STAMP) browser ## Install, then run the whole test suite (what CI runs)
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

clean: ## Remove outputs, benchmark results and caches (keeps .venv)
	rm -rf out bench-results .pytest_cache .ruff_cache build *.egg-info
	find . -name __pycache__ -not -path './.venv/*' -prune -exec rm -rf {} +
