# Two commands do all the set-up (README): `make demo` and `make test`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint bench clean linuxcnc chromium

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -e '.[test]'
	touch $@

demo: $(BIN)/.installed
	$(BIN)/camsmooth demo --out demo_out

# LinuxCNC (Debian linuxcnc-uspace) is the reference controller of the tests: installed where
# apt-get runs as root; elsewhere its tests skip and say so.
linuxcnc:
	@if command -v rs274 >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	    linuxcnc-uspace >/dev/null) || echo "camsmooth: apt-get could not install linuxcnc-uspace: LinuxCNC tests skip"; \
	else echo "camsmooth: LinuxCNC not installed (apt-get install linuxcnc-uspace as root): LinuxCNC tests skip"; fi

# Headless Chromium (Debian chromium) renders the reports in the browser tests: installed where
# apt-get runs as root; elsewhere those tests skip and say so.
chromium:
	@if command -v chromium >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	    chromium >/dev/null) || echo "camsmooth: apt-get could not install chromium: browser tests skip"; \
	else echo "camsmooth: Chromium not installed (apt-get install chromium as root): browser tests skip"; fi

test: $(BIN)/.installed linuxcnc chromium
	$(BIN)/ruff check camsmooth tests examples benchmarks surfaces
	$(BIN)/python -m pytest -n 2

bench: $(BIN)/.installed
	$(BIN)/python benchmarks/bench_pipeline.py

clean:
	rm -rf $(VENV) demo_out
