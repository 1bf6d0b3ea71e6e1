# lucent: `make demo` runs the pipeline on the shipped data, `make test` the test suite.
CARGO ?= cargo

.PHONY: deps build demo test bench clean

deps:
	@bash scripts/install-deps.sh

build: deps
	$(CARGO) build --release --bin lucent

demo: build
	@bash scripts/demo.sh

test: deps
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings
	$(CARGO) test --workspace

bench: deps
	$(CARGO) bench --workspace

clean:
	$(CARGO) clean
	rm -rf demo-out lucent-out
