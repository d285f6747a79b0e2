# The README's quick start: `make demo` and `make test`; `make bench` for benchmarks/.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench browser install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/cartpush demo

# Headless Chromium for tests/wholebody/test_browser.py: installed with apt-get when missing and
# possible (root or passwordless sudo); otherwise those tests skip with one line saying what to install.
browser:
	@sh .ci/install-chromium

# --dist worksteal: a worker that runs out of tests takes half of the other's queue, so a block of slow
# tests handed out together (the default `load` gives each worker its first 152 in file order: every
# diagnose module to one worker) is shared at the end.
test: $(STAMP) browser
	$(BIN)/python -m pytest -n 2 --dist worksteal tests

lint: $(STAMP)
	$(BIN)/python -m ruff check .

bench: $(STAMP)
	@for f in benchmarks/bench_*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
