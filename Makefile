# The README's commands. Each target installs what it needs into .venv first.
# Debian's own CPython 3.11 when it is there: built with PGO and LTO, it runs the simulator ~7 % faster than a plain
# build such as pyenv's (the same results, bit for bit); otherwise whatever python3 is on the PATH.
PY ?= $(firstword $(wildcard /usr/bin/python3.11) python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
RUN_DIR ?= runs/demo

.PHONY: setup native demo circle test lint eval bench clean mosquitto

$(STAMP): pyproject.toml
	@# A bare Debian has python3 but may lack venv/ensurepip: install it with apt-get (as root or via sudo).
	$(PY) -m venv $(VENV) || { rm -rf $(VENV); \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -q && $$SUDO apt-get install -y -q python3-venv python3-pip && $(PY) -m venv $(VENV); }
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

setup: $(STAMP)

native: $(STAMP)  ## the simulator's hot modules compiled with mypyc (when their sources changed): same results, less CPU
	$(BIN)/python -m sim.native_build

mosquitto:  ## the MQTT broker, its clients (mosquitto_pub/sub) and openssl (the test CA) for the ground-station tests
	@# Debian puts the broker in /usr/sbin, off a normal user's PATH: look there too. Same apt-get/sudo as above.
	@missing=""; \
	  { command -v mosquitto || [ -x /usr/sbin/mosquitto ]; } >/dev/null 2>&1 || missing="mosquitto"; \
	  command -v mosquitto_pub >/dev/null 2>&1 || missing="$$missing mosquitto-clients"; \
	  command -v openssl >/dev/null 2>&1 || missing="$$missing openssl"; \
	  if [ -n "$$missing" ]; then \
	    SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	    $$SUDO apt-get update -q && $$SUDO apt-get install -y -q $$missing; \
	  fi

demo: $(STAMP) native   ## fly the default simulated mission (the pickup, sea state 2) and print its summary
	$(BIN)/python -m app.main --mission pickup.yaml --sim --seed 1 --run-dir $(RUN_DIR); \
	  status=$$?; cat $(RUN_DIR)/summary.json; echo "report: $(RUN_DIR)/report.png"; exit $$status

circle: $(STAMP) native  ## the circle-tracking mission (thesis §5.2)
	$(BIN)/python -m app.main --mission circle.yaml --sim --run-dir runs/circle
	@cat runs/circle/summary.json

test: $(STAMP) native mosquitto   ## the whole test suite (unit, simulator, end-to-end through the real CLI)
	$(BIN)/python -m pytest -q

eval: $(STAMP) native   ## target filters against ground truth, sea states 0–4
	$(BIN)/python -m sim.evaluate filters

bench: $(STAMP) native  ## the benchmarks: perception, triangulation, radar, an evaluation run's cost, orbit tracking (figures printed; --json for machines)
	$(BIN)/python -m app.bench perception
	$(BIN)/python -m app.bench triangulation
	$(BIN)/python -m app.bench radar
	$(BIN)/python -m sim.bench_runs
	$(BIN)/python -m sim.bench_orbit

lint: $(STAMP)
	$(BIN)/ruff check app sim tests
	$(BIN)/mypy

clean:
	rm -rf runs build .pytest_cache .mypy_cache .ruff_cache
