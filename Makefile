# CopperTag toolkit. The two set-up commands, on a fresh machine:
#   make test        build everything and run the whole test suite
#   make reproduce   regenerate the paper's tables and figures (reports/)
# Both install what they need (the peers' Python packages into .venv).

CARGO   ?= cargo
PYTHON  ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
BIN     := target/release/coppertag

QUICK   ?=
QUICKDIR := build/quick

.PHONY: all build test lint venv bench reproduce baseline gate clean

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
	COPPERTAG_REQUIRE_VENV=1 $(CARGO) test --workspace --locked
	$(VPY) eval/peers/selftest.py
	$(MAKE) gate

# The regression gate: the QUICK sets (a tenth of every sweep) through all
# four detectors, compared with the committed baseline.
gate: venv build
	$(BIN) reproduce --quick --work $(QUICKDIR) --reports $(QUICKDIR)/reports --quiet
	$(BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json

# Re-make the baseline from the QUICK sets (after a deliberate change).
baseline: venv build
	$(BIN) reproduce --quick --work $(QUICKDIR) --reports $(QUICKDIR)/reports --quiet
	$(BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json --update

# The paper's tables and figures into reports/ (QUICK=1: a tenth of every
# sweep, into build/quick/reports instead).
reproduce: venv build
ifeq ($(QUICK),)
	$(BIN) reproduce --work build/full --reports reports
else
	$(BIN) reproduce --quick --work $(QUICKDIR) --reports $(QUICKDIR)/reports
endif

bench: venv
	$(CARGO) bench --workspace --locked

clean:
	$(CARGO) clean
	rm -rf $(VENV)
