# CopperTag toolkit. The two set-up commands, on a fresh machine:
#   make test        build everything and run the whole test suite
#   make reproduce   regenerate the paper's tables and figures (reports/)
# Both install what they need (the peers' Python packages into .venv).

CARGO   ?= cargo
PYTHON  ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
BIN     := target/release/coppertag

.PHONY: all build test lint venv bench reproduce clean

all: build

build:
	$(CARGO) build --release --locked

# Python virtual environment for the peer detectors (AprilTag 3, ArUco 3,
# STag) and the mcap reader, pinned in eval/peers/requirements.txt.
venv: $(VENV)/.installed
$(VENV)/.installed: eval/peers/requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --quiet --disable-pip-version-check -r eval/peers/requirements.txt
	touch $@

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings

test: venv lint
	$(CARGO) test --workspace --locked
	$(VPY) eval/peers/selftest.py

bench: venv
	$(CARGO) bench --workspace --locked

clean:
	$(CARGO) clean
	rm -rf $(VENV)
