# Two commands do all the set-up: `make demo` and `make test` create .venv and install
# the project (with its extras) when it is missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench bench-peers lint format clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,plot,bench]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/jaxkin demo

test: $(STAMP)
	$(BIN)/python -m pytest -q tests

bench: $(STAMP)
	JAXKIN_WRITE_RESULTS=1 $(BIN)/python -m pytest -q benchmarks --ignore=benchmarks/test_peers.py --benchmark-only --benchmark-columns=min,median,rounds

# Installs the peer libraries into .venv (torch CPU, roboticstoolbox, pytorch_kinematics,
# PyRoki, pylinkage, visual-kinematics; jax/numpy pinned), then times them beside jaxkin.
bench-peers: $(STAMP)
	bash benchmarks/install_peers.sh $(VENV)
	$(BIN)/python -m pytest -q benchmarks/test_peers.py --benchmark-only --benchmark-columns=min,median,rounds

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks build *.egg-info
