# Two commands do all the set-up: `make run` and `make test`.
# Every install here takes the versions pinned in constraints.txt (the set the suite passed with); `make lock`
# refreshes them, `make test-lowest` runs the suite at the lowest versions pyproject.toml allows.
# PY: the Python the venv is made with (CI's .ci/run gives the distribution's: CONTRIBUTING.md, "Tests").
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP := $(BIN)/python -m pip
LOCK := constraints.txt
RUN_STAMP := $(VENV)/.installed-run
STAMP := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.installed-bench
LOWEST := .venv-lowest

.PHONY: run test test-busy test-lowest lock lint bench clean
.PHONY: firmware dist docs

# Each step says what it does in one line; the installer shows its own progress. uv installs (it downloads and
# unpacks in parallel: the test set from nothing in 20 s here, where pip took 54 s). The venv is made without pip
# (ensurepip took 8.6 s of a fresh set-up); uv goes into it by this Python's own pip (pip --python, pip >= 22.3),
# pinned, and puts pip in beside the project, so .venv/bin/pip is there as in any venv. Where this Python has no
# such pip, the venv gets its own by ensurepip first. INSTALLER=pip makes pip do it all (as when uv cannot be had:
# then pip takes over by itself). uv reads no pip.conf: a mirror is given to it as UV_DEFAULT_INDEX
# (https://docs.astral.sh/uv/reference/environment/).
INSTALLER ?= uv
UV_VERSION := 0.13.9
$(BIN)/python:
	@echo "make: making the virtual environment $(VENV) with $$($(PY) --version 2>&1)"
	@$(PY) -m venv --without-pip $(VENV) || { rm -rf $(VENV); echo "could not make $(VENV): needs Python >= 3.11 with" \
		"venv (Debian/Ubuntu: sudo apt install python3-venv)" >&2; exit 1; }

ENSURE_PIP := { test -x $(BIN)/pip || $(BIN)/python -m ensurepip --default-pip >/dev/null; }
GET_UV := { $(PY) -m pip --python $(BIN)/python install -q --disable-pip-version-check "uv==$(UV_VERSION)" \
	2>/dev/null || { $(ENSURE_PIP) && $(PIP) install -q --disable-pip-version-check "uv==$(UV_VERSION)"; }; }

# pygame-ce replaced pygame (both install the module 'pygame'): a venv from before drops pygame first.
# The install is editable (-e): the sources are used where they are, so an edit needs no reinstall.
# $(2) is compile (byte-compile every module installed, as pip does by default) or no-compile.
define install
	@if $(PIP) show -q pygame >/dev/null 2>&1; then $(PIP) uninstall -q -y pygame pygame-ce; fi
	@echo "make: installing quadrupel$(patsubst .%,%,$(1)) and its dependencies (the versions in $(LOCK)) into $(VENV)"
	@if [ "$(INSTALLER)" = uv ] && { test -x $(BIN)/uv || $(GET_UV); }; then \
		$(BIN)/uv pip install --python $(BIN)/python $(if $(filter compile,$(2)),--compile-bytecode) \
			-c $(LOCK) pip -e '$(1)'; \
	else \
		if [ "$(INSTALLER)" = uv ]; then echo "make: uv could not be installed; pip installs instead"; fi; \
		$(ENSURE_PIP) && $(PIP) install --disable-pip-version-check --progress-bar on \
			$(if $(filter no-compile,$(2)),--no-compile) -c $(LOCK) -e '$(1)'; \
	fi
	@# the editable sources' bytecode, which an environment with PYTHONDONTWRITEBYTECODE never writes: without it
	@# every start compiles them again (a quarter of a second of term params --sim list, twice)
	@$(BIN)/python -m compileall -q term fcb_sim >/dev/null
	@touch $@
endef

# pip byte-compiles every module of every dependency (46 MB here, most never imported: pygame's tests and examples,
# pygments' lexers, prompt_toolkit). The flying install skips that and compiles only the packages a flight
# imports, so the second start is as quick; anything else is compiled by Python when first imported.
FLIGHT_PACKAGES := term fcb_sim textual rich bumble bleak mcap platformdirs serial pyee pygame
define compile_flight
	@echo "make: compiling the modules a flight imports"
	@$(BIN)/python -c "import compileall, importlib.util as u, os, re, sys; skip = re.compile('/(tests|examples|docs)/'); \
		sys.exit(not all([compileall.compile_dir(os.path.dirname(u.find_spec(p).origin), quiet=1, workers=0, rx=skip) \
			for p in sys.argv[1:]]))" $(FLIGHT_PACKAGES)
endef

# make run: only what flying needs (term plot's matplotlib is the plot extra: .venv/bin/pip install -e '.[plot]')
$(RUN_STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(call install,.,no-compile)
	$(call compile_flight)

# The test set is not byte-compiled at install (that took 14 s of uv's 20, for 3,954 modules): the suite runs with
# PYTHONDONTWRITEBYTECODE unset (PYTEST below), so Python writes the bytecode of the 1,235 it imports as it goes.
$(STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(call install,.[test],no-compile)

DOCS_STAMP := $(VENV)/.installed-docs
$(DOCS_STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(call install,.[docs],compile)

# docs/ as a site (mkdocs.yml) in site/, strict: a link to a missing page or anchor, or a page out of the nav, fails
# it. $(BIN)/mkdocs serve shows it live while writing.
docs: $(DOCS_STAMP)
	$(BIN)/mkdocs build --strict

BENCH_EXTRAS := .[test,bench]
$(BENCH_STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(call install,$(BENCH_EXTRAS),compile)

run: $(RUN_STAMP)
	@echo "make: starting term --sim (the simulated board, its radio and the terminal; Ctrl+Q quits)"
	@$(BIN)/term --sim

# The autopilot's tour of the features (term --sim --demo) in a 120x40 tmux session: Ctrl+Q quits, Ctrl+B D
# detaches. Without a terminal (CI) it runs detached, waits for the tour's end, prints the last screen, and fails
# if the tour did not finish within DEMO_TIMEOUT seconds.
.PHONY: demo
DEMO_TIMEOUT ?= 240
demo: $(RUN_STAMP)
	@command -v tmux >/dev/null || { echo "make demo needs tmux (Debian/Ubuntu: sudo apt install tmux)" >&2; exit 1; }
	@tmux kill-session -t quadrupel-demo 2>/dev/null || true
	@if [ -t 0 ] && [ -t 1 ]; then \
		tmux new-session -s quadrupel-demo -x 120 -y 40 '$(BIN)/term --sim --demo --no-record'; \
	else \
		tmux new-session -d -s quadrupel-demo -x 120 -y 40 '$(BIN)/term --sim --demo --no-record; sleep 600'; \
		ok=; for i in $$(seq 1 $(DEMO_TIMEOUT)); do sleep 1; \
			if tmux capture-pane -p -t quadrupel-demo | grep -q 'demo: done'; then ok=1; break; fi; done; \
		tmux capture-pane -p -t quadrupel-demo; \
		tmux send-keys -t quadrupel-demo C-q; sleep 2; tmux kill-session -t quadrupel-demo 2>/dev/null; \
		if [ -z "$$ok" ]; then echo "make demo: the tour did not finish within $(DEMO_TIMEOUT) s" >&2; exit 1; fi; \
		echo "make demo: the tour flew to its end"; \
	fi

# The suite on three workers (pytest-xdist): many tests wait on a real-time link, so a third fills the cores while
# the others wait (here, on two cores: 5 min 36 s against 5 min 54 s on two workers, and it held beside four busy
# processes, as make test-busy runs it); the tests hold on a busy machine, which is what each worker is to the
# others. TEST_WORKERS=0: one process.
# worksteal: a worker that runs out takes tests queued for the other, so the run does not end on one long tail.
# The plugins are named, not found by their entry points: pytest rewrites the asserts of every module of a plugin
# it finds (all of hypothesis, on each worker: 1.4 s of its 5 s of collection here). A plugin the suite needs goes
# into TEST_PLUGINS. Bytecode is written (in .venv and the checkout's __pycache__, both ignored by git) even where
# the environment says PYTHONDONTWRITEBYTECODE: the test set is installed without it.
TEST_WORKERS ?= 3
TEST_PLUGINS := xdist.plugin xdist.looponfail pytest_asyncio.plugin _hypothesis_pytestplugin syrupy pytest_textual_snapshot
PYTEST := env -u PYTHONDONTWRITEBYTECODE PYTEST_DISABLE_PLUGIN_AUTOLOAD=1 $(BIN)/python -m pytest \
	$(addprefix -p ,$(TEST_PLUGINS)) -n $(TEST_WORKERS) --dist worksteal

test: $(STAMP)
	$(BIN)/ruff check term fcb_sim tests bench
	$(BIN)/ruff check firmware
	@command -v cc >/dev/null || echo "no C compiler (cc): the firmware tests are skipped"
	@command -v arm-none-eabi-gcc >/dev/null || echo "no arm-none-eabi-gcc: the Cortex-M0 size and boot tests are skipped"
	$(PYTEST)

# The suite on a busy machine, as a pilot's laptop is (issue 21): BUSY_PER_CORE processes per core beside it doing
# bursts of 5-50 ms of work with short sleeps. ../shared/tools/busy when it is there (CI has a copy of shared/ beside
# the clone), else the same loop here.
BUSY_PER_CORE ?= 2
BUSY_TOOL := $(wildcard ../shared/tools/busy)
BUSY_LOOP := import random, time; exec("while 1:\n e = time.perf_counter() + random.uniform(0.005, 0.05)\n while \
time.perf_counter() < e: pass\n time.sleep(random.uniform(0.0005, 0.003))")
test-busy: $(STAMP)
	@if [ -n "$(BUSY_TOOL)" ]; then $(BUSY_TOOL) -n $(BUSY_PER_CORE) -- $(PYTEST); else \
		n=$$(( $(BUSY_PER_CORE) * $$(nproc) )); pids=; \
		for i in $$(seq 1 $$n); do $(BIN)/python -c '$(BUSY_LOOP)' & pids="$$pids $$!"; done; \
		echo "test-busy: $$n busy processes beside the suite" >&2; \
		$(PYTEST); rc=$$?; kill $$pids; exit $$rc; fi

BENCHES := codec realtime flight filters profile log_compression pacing latency ui plots ble firmware download soak lessons keyboard foxglove long_work \
	contention first_minute

# Every benchmark runs (its last line, the JSON, is printed); make bench fails if any of them failed.
bench: $(BENCH_STAMP)
	@failed=; for b in $(BENCHES); do \
		out=$$($(BIN)/python -m bench.$$b) || failed="$$failed $$b"; \
		printf '%s\n' "$$out" | tail -n 1; \
	done; \
	if [ -n "$$failed" ]; then echo "make bench: failed:$$failed" >&2; exit 1; fi

# The suite at the floors (constraints-lowest.txt) in its own venv: slow (it installs them), not part of make test.
# The pixel snapshots are left out: they pin the locked Textual's drawing, not behaviour.
test-lowest:
	test -x $(LOWEST)/bin/python || $(PY) -m venv $(LOWEST)
	$(LOWEST)/bin/python -m pip install -q --upgrade pip
	$(LOWEST)/bin/python -m pip install -q -c constraints-lowest.txt -e '.[test]'
	QUADRUPEL_EXPECT_FLOORS=1 $(LOWEST)/bin/python -m pytest -p no:cacheprovider -k "not snapshot"

# constraints.txt from today's newest releases; then run make test, and commit it if the suite passes.
lock:
	rm -rf .venv-lock && $(PY) -m venv .venv-lock
	.venv-lock/bin/python -m pip install -q --upgrade pip
	.venv-lock/bin/python -m pip install -q '.[plot,analysis,test,bench,docs]'
	{ sed -n '1,2p' $(LOCK); .venv-lock/bin/python -m pip freeze --all --exclude-editable \
		| grep -v -i '^pip==\|^quadrupel' | sort -f; } > $(LOCK).new && mv $(LOCK).new $(LOCK)
	rm -rf .venv-lock

# The C protocol library, the reference board and the C board (firmware/): firmware/build/host_board and
# firmware/build/libqb_host.so, built with cc. (fcb-sim and term --board c build what they load on first use into
# the user's cache directory, one folder per version of the sources: fcb_sim/cbuild.py.)
firmware:
	$(MAKE) -C firmware host_board board

# The sdist and the wheel (dist/): what users install (pip install dist/quadrupel-*.whl). The wheel carries the C
# sources --board c and the native filter build from (into the user's cache, never the installation) and docs/;
# tests/packaging/test_wheel.py installs it into a fresh venv and flies it.
dist: $(STAMP)
	rm -rf dist
	$(BIN)/python -m build --no-isolation --outdir dist .

clean:
	rm -rf $(VENV) $(LOWEST) .pytest_cache .hypothesis dist build site
	rm -rf firmware/build
