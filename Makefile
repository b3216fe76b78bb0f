# Two commands do all set-up on a fresh machine:
#   make run    the soft-PLC daemon with the drawing-table program and its simulated table
#   make test   the whole test suite
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
PORT    ?= 5020
WEB_PORT ?= 8020
STATS   ?= 60s
# No tracked file over 1 MiB: CI refuses one (binaries and data sets belong in a registry)
MAX_FILE_BYTES := 1048576

.PHONY: run test bench lint draw clean sysdeps fuzz docs filesizes

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

# mbpoll (Debian): the independent Modbus client the end-to-end tests also use; chromium: the
# headless browser of the web monitor tests (Playwright drives it; no browser download), and
# chromium-headless-shell, the lighter headless browser they run when it is there.
sysdeps:
	@{ command -v mbpoll && command -v chromium && command -v chromium-headless-shell; } >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -qq && apt-get install -y -qq mbpoll chromium chromium-headless-shell >/dev/null; \
	  else echo "note: mbpoll/chromium not installed (needs root); the tests that use them are skipped"; fi; }

run: $(STAMP)
	@echo "web monitor: http://127.0.0.1:$(WEB_PORT)/ (the banner gives the address in use; softplc io --port $(WEB_PORT) operates it)"
	@echo "statistics every $(STATS) (make run STATS=5s); one now: kill -USR1 <the softplc pid>"
	$(BIN)/softplc run ladder_programs/drawing_table.il --config ladder_programs/drawing_table.toml --host 127.0.0.1 --port $(PORT) --web $(WEB_PORT) --stats-interval $(STATS) --trace out/trace.csv

draw: $(STAMP)
	$(BIN)/softplc draw ladder_programs/samples/star.gcode --host 127.0.0.1 --port $(PORT) --preview out/star-preview.png --trace out/trace.csv --plot out/star-drawn.png

# The three tiers (the folders tests/unit, tests/integration, tests/e2e) in one pytest-xdist
# run of TEST_WORKERS workers, one more than the cores: an end-to-end test spends much of
# its time waiting for a daemon, a browser or a client, and a unit test fills that time;
# each worker more collects every test and starts its own daemon zygote and browser (on 2
# cores: 2 workers 257 s, 3 237 s, 4 263 s, 6 278 s; docs/performance.md). Each
# test module stays on one worker (--dist loadfile), so a module's daemon fixture starts
# once, and the browser modules share one worker and its Chromium (tests/conftest.py);
# the modules are handed out in the order given (--no-loadscope-reorder: xdist would
# sort them by test count), the end-to-end ones, the longest, first and the unit tier's
# small ones last, so that no long module is left alone at the end. The tests wait for
# conditions, never for the machine's speed. PYTHONDONTWRITEBYTECODE, if the shell sets
# it, would make each worker rewrite and compile every test module and plugin again (the
# daemons and commands the tests start lose it too: tests/conftest.py).
TEST_WORKERS ?= 3
test: $(STAMP) sysdeps filesizes docs
	$(BIN)/ruff check softplc tests tools
	env -u PYTHONDONTWRITEBYTECODE $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder tests/e2e tests/integration tests/unit

# The documentation site (mkdocs.yml, docs/) into site/: --strict fails on a broken link or
# anchor, and its hook on a generated reference page that differs from the code
# (tools/gen_docs.py writes them).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

filesizes:
	@big=$$(git ls-files -z | xargs -0 -r stat -c '%s %n' 2>/dev/null | awk -v max=$(MAX_FILE_BYTES) '$$1 > max'); \
	  if [ -n "$$big" ]; then echo "tracked files over $(MAX_FILE_BYTES) bytes:"; echo "$$big"; exit 1; fi

# libmodbus-dev (Debian): the C library the benchmark's "C ceiling" row compiles against.
bench: $(STAMP)
	@dpkg -s libmodbus-dev >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && \
	  echo "make bench: installing the Debian package libmodbus-dev (apt-get) for the C ceiling row (a C Modbus server to compare with)" && \
	  apt-get update -qq && apt-get install -y -qq libmodbus-dev >/dev/null; } || \
	  echo "note: no libmodbus-dev (installing it needs root): the C ceiling row is skipped"
	$(BIN)/pip install -q -e '.[test,bench]'
	# --no-deps: pyrung's pyclickplc pins pymodbus<3.13 (pyrung's core runs with ours)
	$(BIN)/pip install -q --no-deps 'pyrung==0.15.2' 'pyclickplc==0.4.1'
	$(BIN)/python tools/bench.py
	$(BIN)/python tools/bench_web.py --duration 2
	$(BIN)/python tools/bench_compile.py
	-$(BIN)/python tools/bench_modbus_c.py  # needs gcc and libmodbus-dev

lint: $(STAMP)
	$(BIN)/ruff check softplc tests tools

clean:
	rm -rf $(VENV) *.egg-info .pytest_cache .ruff_cache results out site

# The fuzzers and slow property tests with their full example counts (the suite runs a
# quarter: tests/fuzz_budget.py), then the mutation fuzzers at full size with a progress
# line: 4,000 mutated programs and 1,559 mutated configs, 0 tracebacks and 0 crashes expected.
fuzz: $(STAMP)
	SOFTPLC_FUZZ=1 $(BIN)/python -m pytest -q tests/unit/test_fuzz.py tests/unit/test_properties.py tests/unit/test_config_fuzz.py tests/unit/test_il_recovery.py tests/unit/test_input_fuzz.py tests/integration/test_examples.py
	$(BIN)/python tools/fuzz_mutations.py
