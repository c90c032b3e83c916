# CopperTag toolkit. The two set-up commands, on a fresh machine:
#   make test        build everything and run the whole test suite
#   make reproduce   regenerate the paper's tables and figures (reports/)
# Both install what they need (the peers' Python packages into .venv).

CARGO   ?= cargo
PYTHON  ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
BIN     := target/release/coppertag
# The gate's binary: the `ci` profile the tests are built with (Cargo.toml
# says why), so `make test` compiles every crate once.
GATE_BIN := target/ci/coppertag

QUICK   ?=
QUICKDIR := build/quick

.PHONY: all build gate-build test lint venv wheel python-test bench-python bench reproduce baseline baseline-wild baseline-system gate quick-run speed gate-slowdown calibrate-sigma build-native bench-native native-check clean

all: build

build:
	$(CARGO) build --release --locked

gate-build:
	$(CARGO) build --profile ci --locked --bin coppertag

# Python virtual environment for the peer detectors (AprilTag 3, ArUco 3,
# STag, fractal markers) and the mcap reader, pinned in eval/peers/requirements.txt.
# Also maturin and pytest for the Python package (detector/python/requirements.txt).
venv: $(VENV)/.installed
$(VENV)/.installed: eval/peers/requirements.txt detector/python/requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --quiet --disable-pip-version-check -r eval/peers/requirements.txt \
	  -r detector/python/requirements.txt
	touch $@

# The Python package (`import coppertag`, detector/python/): one abi3 wheel
# into target/wheels/, built with the `ci` profile in the workspace's target
# dir, so the coppertag crates compiled by `cargo test` are reused.
WHEELS := target/wheels
wheel: venv
	rm -f $(WHEELS)/coppertag-*.whl
	$(VPY) -m maturin build --quiet --profile ci --locked -m detector/python/Cargo.toml --out $(WHEELS)

# The wheel installed into .venv, then its pytest suite (which also installs
# it into a fresh venv, and compares with the `coppertag` binary).
python-test: wheel gate-build
	$(VPY) -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps $(WHEELS)/coppertag-*.whl
	COPPERTAG_BIN=$(GATE_BIN) $(VPY) -m pytest -q -p no:cacheprovider detector/python/tests

# Binding overhead and GIL release, measured: Python's median detect time
# against the criterion benchmark's (both `ci` profile, same 1080p frames),
# and two threads against one. Timings are noisy on a busy machine.
bench-python: python-test
	COPPERTAG_BENCH_FRAMES=$(CURDIR)/target/bench-frames $(CARGO) bench -p coppertag --bench detect --profile ci --locked -- detect_1080p
	$(VPY) detector/python/bench/bench_python.py --frames target/bench-frames --criterion target/criterion

# Clippy runs under the `ci` profile too, so build scripts and proc-macros
# are compiled once for lint and tests alike.
lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets --locked --profile ci -- -D warnings

# The peers' virtual environment is installed while clippy runs (pip waits
# on downloads and unpacking, clippy on the compiler: side by side they
# take about the time of the longer one).
test:
	$(MAKE) --no-print-directory -j2 venv lint
	COPPERTAG_REQUIRE_VENV=1 $(CARGO) test --workspace --locked --profile ci
	$(VPY) eval/peers/selftest.py
	$(MAKE) python-test
	$(MAKE) gate

# The regression gate: the QUICK sets (a tenth of every sweep) through all
# five detectors, then our speed against each peer's on the same frames
# (interleaved, with a noise band), compared with the committed baseline.
# Detection, wrong ids, false positives, duplicates and corner error are
# exact checks; speed fails only when, over the peers, the median growth of
# our ratio at the low end of its noise band exceeds the allowed 1.25x (one
# peer drifting alone cannot fail it; eval/src/gate.rs, SpeedCheck, says why).
# The quick slice of the wild sets (datasets/wild) is gated for CopperTag:
# detection rate, rough detections, wrong ids, false positives per MP.
gate: quick-run speed
	$(GATE_BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json \
	  --speed $(QUICKDIR)/results/speed.json --wild $(QUICKDIR)/results/wild.json

# The quick run scores detection only (--no-times): its detector sessions
# run side by side, one per core, each on a shard of the images, and put
# back together exactly as one run; the speed check below times our
# detector and the peers itself.
quick-run: venv gate-build
	$(GATE_BIN) reproduce --quick --no-times --work $(QUICKDIR) --reports $(QUICKDIR)/reports --quiet

# The speed baseline was measured on the paper's sweeps and the robustness
# sets; the sampled wild and jitter sets (other frame sizes, other tags) are
# left out so the gate compares the same frames it was made on.
SPEED_SWEEPS := challenge-defocus,challenge-lighting,distance-z,occlusion,robust,rotated-x,rotated-y,rotated-z
# A peer whose whole band lies above the baseline's limit is measured a
# second time (--confirm-against), and the gate checks that second
# measurement: one burst of load cannot fail it, a real slowdown fails both.
CONFIRM := --confirm-against reports/baseline.json
speed: venv gate-build
	$(GATE_BIN) speed --work $(QUICKDIR) -o $(QUICKDIR)/results/speed.json --quiet --sweeps $(SPEED_SWEEPS) $(CONFIRM)

# Proof that the speed check catches a real slowdown: our detector made
# 1.4x slower (it burns CPU after each detection) must fail the gate with
# exit code 1. Uses the QUICK datasets of a `make gate` run.
gate-slowdown: venv gate-build
	test -d $(QUICKDIR)/datasets || $(MAKE) quick-run
	$(GATE_BIN) speed --work $(QUICKDIR) -o $(QUICKDIR)/results/speed-slowed.json --quiet --slowdown 1.4 --sweeps $(SPEED_SWEEPS) $(CONFIRM)
	$(GATE_BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json \
	  --speed $(QUICKDIR)/results/speed-slowed.json --wild $(QUICKDIR)/results/wild.json; \
	  code=$$?; if [ $$code -eq 1 ]; then echo "gate-slowdown: the 1.4x slowdown was caught"; \
	  else echo "gate-slowdown: the 1.4x slowdown was NOT caught (gate exit $$code)"; exit 1; fi

# Re-make the baseline from the QUICK sets (after a deliberate change),
# with the same profile and measurement as the gate.
baseline: quick-run speed
	$(GATE_BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json \
	  --speed $(QUICKDIR)/results/speed.json --wild $(QUICKDIR)/results/wild.json --update

# Re-make only what the wild slice decides (after a deliberate change to
# the wild specs): the wild entries and every system's entries of the wild
# datasets (*-wild, *-jitter, *-dense, fp-*), leaving every other entry,
# and the speed ratios, as they are.
baseline-wild: quick-run
	$(GATE_BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json \
	  --wild $(QUICKDIR)/results/wild.json --update-wild

# Add (or re-make) one system's entries and its speed ratio (make
# baseline-system SYSTEM=fractal, after adding a peer), leaving every other
# entry of the baseline as it is.
SYSTEM ?=
baseline-system: quick-run
	test -n "$(SYSTEM)" || { echo "give SYSTEM=name"; exit 2; }
	$(GATE_BIN) speed --work $(QUICKDIR) -o $(QUICKDIR)/results/speed-$(SYSTEM).json --quiet \
	  --sweeps $(SPEED_SWEEPS) --only $(SYSTEM)
	$(GATE_BIN) gate --baseline reports/baseline.json --summary $(QUICKDIR)/results/summary.json \
	  --speed $(QUICKDIR)/results/speed-$(SYSTEM).json --update-system $(SYSTEM)

# The paper's tables and figures into reports/ (QUICK=1: a tenth of every
# sweep, into build/quick/reports instead).
reproduce: venv build
ifeq ($(QUICK),)
	$(BIN) reproduce --work build/full --reports reports
else
	$(BIN) reproduce --quick --work $(QUICKDIR) --reports $(QUICKDIR)/reports
endif

# The calibration of the detector's corner sigma (BLUR_BIAS and
# SMEAR_SPREAD_PX in detector/src/detect/verify.rs, LIKELIHOOD_SIGMA_FACTOR
# in detector/src/detect/decoding.rs): the wild set's ranges with another
# seed and 1000 scenes (datasets/wild/calibration/coppertag-calib.toml),
# and the dense frames' with another seed (coppertag-dense-calib.toml, the
# blurs of 1080p pixels that the VGA set never reaches), so the constants
# are chosen apart from the benchmark they are reported on. Renders both,
# runs CopperTag over them and prints, for each, the share of corners
# within 2 sigma of the truth: all, read by code or by likelihood, observed
# or estimated, on tags drawn with a heavy motion blur. Their figures
# choose constants; they are never reported. Built with the gate's `ci`
# profile, like quick-run: the crates `make test` already compiled, rather
# than a release build with LTO.
CALIB_SETS := coppertag-calib coppertag-dense-calib
CALIBDIR   := build/calibrate-sigma
calibrate-sigma: gate-build
	set -e; for s in $(CALIB_SETS); do \
	  $(GATE_BIN) synth datasets/wild/calibration/$$s.toml -o $(CALIBDIR)/$$s --force --quiet; \
	  $(GATE_BIN) run --dataset $(CALIBDIR)/$$s --detector coppertag -o $(CALIBDIR)/$$s.mcap --quiet; \
	  $(GATE_BIN) eval --wild $(CALIBDIR)/$$s.mcap -o $(CALIBDIR)/results-$$s; \
	done

bench: venv
	$(CARGO) bench --workspace --locked

# A build for this machine's own CPU (make build-native, bench-native): the
# compiler may then use every instruction set the CPU has (AVX2, FMA and
# POPCNT on a recent x86-64), where the default build targets any x86-64.
# Such a binary runs on this CPU and those like it only, so nothing shipped
# (the wheel, the binary `make reproduce` and the gate use) is built so.
# Detections are the same to the bit: Rust neither fuses nor reorders
# floating-point operations by itself, so the same IEEE operations run
# either way; `make native-check` compares the two builds' detections.
# Kept in target/native, so that the two builds do not rebuild each other.
NATIVE_BIN := target/native/release/coppertag
NATIVE_ENV := RUSTFLAGS="$(RUSTFLAGS) -C target-cpu=native" CARGO_TARGET_DIR=$(CURDIR)/target/native
build-native:
	$(NATIVE_ENV) $(CARGO) build --release --locked

bench-native: venv
	$(NATIVE_ENV) $(CARGO) bench --workspace --locked

# Both builds over a tenth of the wild set's scenes, with ct14 tags and
# again with ct8 ones (each set's truth must show its family, in case the
# spec's wording changes): the detections must be the same to the bit.
NATIVE_CHECK := build/native-check
native-check: build build-native
	rm -rf $(NATIVE_CHECK) && mkdir -p $(NATIVE_CHECK)
	set -e; for fam in ct14 ct8; do \
	  set_=$(NATIVE_CHECK)/wild-$$fam; \
	  sed "s/\"ct14\"/\"$$fam\"/g" datasets/wild/coppertag-wild.toml > $$set_.toml; \
	  $(BIN) synth $$set_.toml --every 10 -o $$set_ --quiet; \
	  grep -q ",$$fam," $$set_/truth.csv; \
	  $(BIN) detect --json $$set_/images/*.png > $$set_-default.jsonl; \
	  $(NATIVE_BIN) detect --json $$set_/images/*.png > $$set_-native.jsonl; \
	  $(PYTHON) eval/tools/same_detections.py $$set_-default.jsonl $$set_-native.jsonl; \
	done

clean:
	$(CARGO) clean
	rm -rf $(VENV)
