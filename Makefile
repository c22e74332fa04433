# Two commands do all the set-up: `make demo` and `make test` create .venv and install
# the project (with its extras) when it is missing, with uv (parallel downloads; pip if it fails).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow docs docs-serve bench bench-goals bench-peers lint lint-imports format clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	{ $(BIN)/python -m pip install --quiet uv \
	  && $(BIN)/python -m uv pip install --quiet --python $(BIN)/python -e '.[test,cli,plot,bench,urdf,viewer]'; } \
	  || $(BIN)/python -m pip install --quiet -e '.[test,cli,plot,bench,urdf,viewer]'
	touch $(STAMP)

# The demo's files go to examples/output/ (ignored by git), never the repository's root.
DEMO_OUTPUT := examples/output

demo: $(STAMP)
	mkdir -p $(DEMO_OUTPUT)
	$(BIN)/jaxkin demo --output-dir $(DEMO_OUTPUT)

# Two worker processes (pytest-xdist), one file per worker at a time so that a file's tests
# share their compilations. The slow tests (`@pytest.mark.slow`) run with `make test-slow`.
# Python's bytecode caches are written even where the environment turns them off, so that
# later processes (workers, the command-line tests' subprocesses) load modules compiled once.
PYTEST := PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q -n 2 --dist loadfile

# lint-imports checks the import layers and cycles of pyproject.toml's [tool.importlinter];
# mypy type-checks the package ([tool.mypy]; a second run reads its cache, .mypy_cache).
test: $(STAMP)
	$(PYTEST) -m "not slow" tests
	$(BIN)/lint-imports
	$(BIN)/mypy

test-slow: $(STAMP)
	$(PYTEST) -m slow tests

DOCS_STAMP := $(VENV)/.installed-docs

$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m uv pip install --quiet --python $(BIN)/python -e '.[docs]' \
	  || $(BIN)/python -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

docs-serve: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve

bench: $(STAMP)
	JAXKIN_WRITE_RESULTS=1 $(BIN)/python -m pytest -q benchmarks --ignore=benchmarks/test_peers.py --benchmark-only --benchmark-columns=min,median,rounds

# The goal ratios alone (benchmarks/test_goals.py, about a minute): fails when a kernel's
# ratio to its reference falls below the floor recorded there. `make bench` runs it too.
bench-goals: $(STAMP)
	$(BIN)/python -m pytest -q -s benchmarks/test_goals.py --benchmark-only --benchmark-columns=rounds

# Installs the peer libraries into .venv (torch CPU, roboticstoolbox, pytorch_kinematics,
# PyRoki, pylinkage, visual-kinematics; jax/numpy pinned), then times them beside jaxkin.
bench-peers: $(STAMP)
	bash benchmarks/install_peers.sh $(VENV)
	$(BIN)/python -m pytest -q benchmarks/test_peers.py --benchmark-only --benchmark-columns=min,median,rounds

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/mypy

lint-imports: $(STAMP)
	$(BIN)/lint-imports

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .benchmarks build site *.egg-info
