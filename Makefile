# lucent: `make demo` runs the pipeline on the shipped data, `make test` the test suite.
CARGO ?= cargo

# The Python module and its test tools live in this project-local venv.
VENV ?= .venv-py
PYTHON3 ?= python3
# Cargo's build folder (the workspace's target/ unless CARGO_TARGET_DIR says otherwise).
TARGET_DIR ?= $(or $(CARGO_TARGET_DIR),target)

.PHONY: deps build demo test bench clean python

deps:
	@bash scripts/install-deps.sh

build: deps
	$(CARGO) build --release --bin lucent

demo: build
	@bash scripts/demo.sh

# The Python module's tests import the extension `cargo test --workspace`
# has just built (python/ is a workspace member): its library copied as
# lucent.abi3.so, with its type hints, into $(TARGET_DIR)/python-test/,
# which PYTHONPATH puts first. No maturin here: its own build of the module
# would compile dozens of dependencies again with other features.
test: deps $(VENV)/.requirements
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --workspace --no-deps
	$(CARGO) test --workspace
	rm -rf $(TARGET_DIR)/python-test
	mkdir -p $(TARGET_DIR)/python-test
	cp $(TARGET_DIR)/debug/deps/liblucent_py.so $(TARGET_DIR)/python-test/lucent.abi3.so
	cp python/lucent.pyi $(TARGET_DIR)/python-test/lucent.pyi
	PYTHONPATH=$(abspath $(TARGET_DIR))/python-test $(VENV)/bin/python -m pytest -q python/tests

bench: deps
	$(CARGO) bench --workspace

# `import lucent`: builds the module (python/, PyO3) with maturin in the
# release profile (as `make build` builds the command: the simulations run
# at full speed) and installs it in the venv, with the test tools pinned in
# python/requirements.txt. Several minutes on 2 cores (docs/benchmarks.md,
# "The Python module").
python: deps $(VENV)/.requirements
	VIRTUAL_ENV=$(CURDIR)/$(VENV) $(VENV)/bin/maturin develop --release --quiet --manifest-path python/Cargo.toml

$(VENV)/.requirements: python/requirements.txt
	$(PYTHON3) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r python/requirements.txt
	touch $@

clean:
	$(CARGO) clean
	rm -rf demo-out lucent-out $(VENV)
