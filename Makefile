# Two commands do all the set-up: `make run` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/term --sim

test: $(STAMP)
	$(BIN)/ruff check term fcb_sim tests bench
	$(BIN)/python -m pytest

BENCHES := codec realtime flight filters profile log_compression pacing latency ui ble

bench: $(STAMP)
	for b in $(BENCHES); do $(BIN)/python -m bench.$$b | tail -n 1; done

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
