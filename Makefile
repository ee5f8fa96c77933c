# Two commands do all the set-up: `make run` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench clean
.PHONY: firmware

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/term --sim

test: $(STAMP)
	$(BIN)/ruff check term fcb_sim tests bench
	$(BIN)/ruff check firmware
	@command -v cc >/dev/null || echo "no C compiler (cc): the firmware tests are skipped"
	@command -v arm-none-eabi-gcc >/dev/null || echo "no arm-none-eabi-gcc: the Cortex-M0 size test is skipped"
	$(BIN)/python -m pytest

BENCHES := codec realtime flight filters profile log_compression pacing latency ui ble firmware

bench: $(STAMP)
	for b in $(BENCHES); do $(BIN)/python -m bench.$$b | tail -n 1; done

# The C protocol library and the reference board (firmware/): firmware/build/host_board, built with cc.
firmware:
	$(MAKE) -C firmware host_board

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
	rm -rf firmware/build
