# Every target builds .venv with the system python3 and installs the project into it.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.installed-bench

# the headless viewer test renders with software Vulkan: Debian's packages, installed by `make test` when root
SYSTEM_PACKAGES := mesa-vulkan-drivers libvulkan1

.PHONY: demo test lint fuzz fuzz-hypothesis system-packages bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/auvreplay demo --force

system-packages:
	@if command -v dpkg >/dev/null && ! dpkg -s $(SYSTEM_PACKAGES) >/dev/null 2>&1; then \
		if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
			apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $(SYSTEM_PACKAGES); \
		else \
			echo "make test: the viewer test needs Debian's $(SYSTEM_PACKAGES) (as root: apt-get install $(SYSTEM_PACKAGES))"; \
		fi; \
	fi

# the linter and the type checker first (configured in pyproject.toml), then the whole suite
test: $(STAMP) system-packages
	$(BIN)/ruff check .
	$(BIN)/mypy
	WGPU_BACKEND=vulkan $(BIN)/python -m pytest -q

# every decoder entry point, archive-damage kind, importer and live source: 3,000 cases each (live sources
# scaled by their cost), about 109,000 in all (a share runs in make test); then the hypothesis tests with
# fresh random examples
fuzz: $(STAMP) fuzz-hypothesis
	$(BIN)/python tests/fuzz/fuzz.py --cases 3000

# the hypothesis tests under the "fuzz" profile (tests/conftest.py): random, 10x the examples of make test's
# derandomized "ci" profile; pin any failing case it prints in its test with @example
fuzz-hypothesis: $(STAMP)
	HYPOTHESIS_PROFILE=fuzz $(BIN)/python -m pytest -q -m hypothesis

$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	@for script in bench/bench_*.py; do \
		echo "== $$script"; \
		$(BIN)/python $$script || exit 1; \
	done

# every tab of the sample trial at 620, 1140 and 1700 s, shot in the headless native viewer (1400x875)
SHOTS ?= screenshots
screenshots: $(STAMP) system-packages
	mkdir -p $(SHOTS)
	$(BIN)/auvreplay record samples/lake_trial/trial.toml -o $(SHOTS)/lake-trial.mcap --force --quiet
	WGPU_BACKEND=vulkan $(BIN)/python -m replay.views.screenshots $(SHOTS)/lake-trial.mcap $(SHOTS) \
		--set methods=dead_reckoning,ckf,ackf,chi_square,dual_threshold,anfis,anfis_aqpso,anfis_compensation,cusum_drift,anfis_hybrid,drift_reference
	@echo "screenshots in $(SHOTS)/"

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
