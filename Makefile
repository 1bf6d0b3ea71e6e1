# lucent: `make demo` runs the pipeline on the shipped data, `make test` the test suite.
CARGO ?= cargo

# The Python module and its test tools live in this project-local venv.
VENV ?= .venv-py
PYTHON3 ?= python3

.PHONY: deps build demo test bench clean python

deps:
	@bash scripts/install-deps.sh

build: deps
	$(CARGO) build --release --bin lucent

demo: build
	@bash scripts/demo.sh

test: deps
	$(CARGO) fmt --all --check
	$(CARGO) fmt --manifest-path python/Cargo.toml --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings
	$(CARGO) test --workspace
	$(MAKE) python
	$(VENV)/bin/python -m pytest -q python/tests

bench: deps
	$(CARGO) bench --workspace

# `import lucent`: builds the module (python/, PyO3) with maturin into the
# venv, with the test tools pinned in python/requirements.txt.
python: deps $(VENV)/.requirements
	VIRTUAL_ENV=$(CURDIR)/$(VENV) CARGO_TARGET_DIR=$(CURDIR)/target $(VENV)/bin/maturin develop --quiet --manifest-path python/Cargo.toml

$(VENV)/.requirements: python/requirements.txt
	$(PYTHON3) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r python/requirements.txt
	touch $@

clean:
	$(CARGO) clean
	rm -rf demo-out lucent-out $(VENV)
