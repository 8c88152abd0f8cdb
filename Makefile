# Two commands for a new user: `make serve` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PORT   ?= 1102
OPCUA_PORT ?= 4840
HOST   ?= 127.0.0.1

.PHONY: serve test test-without-shared slow soak fuzz tshark chromium npm nodesets lint bench

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

$(VENV)/.installed: pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q -e '.[test]'
	touch $@ $(VENV)/.installed

serve: $(VENV)/.installed nodesets
	$(VENV)/bin/nckemu serve --host $(HOST) --port $(PORT) --opcua $(OPCUA_PORT)

# tshark is the independent decoder the interop tests compare against; install it when we may.
tshark:
	@if command -v tshark >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq tshark >/dev/null) \
	  || echo "tshark could not be installed: the tshark tests will skip"; \
	else echo "tshark is missing and we are not root: the tshark tests will skip"; fi

# A real headless browser for the `serve --http` page tests (Debian's chromium and its driver).
chromium:
	@if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null) \
	  || echo "chromium could not be installed: the browser tests will skip"; \
	else echo "chromium is missing and we are not root: the browser tests will skip"; fi

lint: $(VENV)/.installed-test
	$(VENV)/bin/ruff check nckemu awlsimhw_nckemu tests bench examples
	$(VENV)/bin/lint-imports --no-cache

# node-opcua-client, the outside OPC UA client of tests/emulator/faces/opcua/test_opcua_node.py (skips without npm).
npm:
	@if command -v npm >/dev/null 2>&1; then \
	  (cd tests/emulator/faces/opcua/node_opcua && npm install --no-audit --no-fund --silent >/dev/null) \
	  || echo "npm install failed: the node-opcua tests will skip"; \
	else echo "npm is missing: the node-opcua tests will skip"; fi

# The OPC Foundation NodeSets of the umati (MachineTool) and CNC models, from npm's node-opcua-nodesets,
# into the cache directory; then the face's address-space cache with them (once, ~10-50 s). Without npm
# the OPC UA face serves the SINUMERIK namespace alone and says so.
NODESETS_VERSION := 2.185.0
nodesets: $(VENV)/.installed
	@prefix=$$($(PY) -m nckemu.emulator.faces.opcua.prepare --prefix); \
	if [ -f "$$prefix/node_modules/node-opcua-nodesets/nodesets/Opc.Ua.MachineTool.NodeSet2.xml" ]; then :; \
	elif command -v npm >/dev/null 2>&1; then \
	  mkdir -p "$$prefix" && npm install --prefix "$$prefix" --no-audit --no-fund --silent \
	    node-opcua-nodesets@$(NODESETS_VERSION) >/dev/null || echo "npm install failed: the OPC UA face serves without the umati/CNC models"; \
	else echo "npm is missing: the OPC UA face serves without the umati/CNC models"; fi
	@$(PY) -m nckemu.emulator.faces.opcua.prepare

# The suite on every core (JOBS=1 for one process); a test file stays on one worker (--dist loadfile)
# so that its module-scoped servers start once. The slowest 15 are printed to see where the time goes.
JOBS ?= auto
# Bytecode compiled once first: many tests run the `nckemu` command, and where the environment sets
# PYTHONDONTWRITEBYTECODE each of them would compile ~120 modules again (~0.2-0.3 s a call).
test: $(VENV)/.installed-test tshark chromium npm nodesets lint
	$(PY) -m compileall -q nckemu >/dev/null
	$(PY) -m pytest -n $(JOBS) --dist loadfile --durations=15

# The tests that read ../shared, run as a new user's clone has them: without it. Each must skip with its
# reason, never fail (CI runs this after `make test`; the files are found by what they name).
NO_SHARED := $(CURDIR)/.no-shared-here
test-without-shared: $(VENV)/.installed-test
	NCKEMU_SHARED=$(NO_SHARED) $(PY) -m pytest -n $(JOBS) --dist loadfile \
	  $$(grep -rlE 'SHARED|shared_dir|fl_thermal_ch3_discovery|\.\./shared' tests --include='test_*.py')

# The slow suite (tests marked slow: seeds, run families, the README tour), two workers at once; a worker
# that runs out takes pending tests from the other (worksteal), and the seed matrices start first (conftest).
slow: $(VENV)/.installed-test
	$(PY) -m pytest -m slow -n 2 --dist worksteal --durations=15

# Trust under load and hostile input (docs/limits.md): SIZE=small|medium|full.
SIZE ?= small
soak: $(VENV)/.installed-test
	$(PY) bench/soak_mixed.py --size $(SIZE)

fuzz: $(VENV)/.installed-test
	$(PY) bench/fuzz_opcua.py --size $(SIZE)

bench: $(VENV)/.installed-test
	@for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done
