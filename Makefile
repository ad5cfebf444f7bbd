# Antumbra: the two commands of the README.
#   make demo   the main job: render the demo pictures with built-in data
#   make test   every check: fmt, clippy, API docs, cargo tests, Miri over the
#               unsafe code, no_std build, header,
#               C examples (static, shared, valgrind, sanitizers), the bare-metal
#               library as Cortex-M4 firmware under QEMU, install with CMake and
#               pkg-config consumers, Embree cross-checks, the C ABI from Python
#               (ctypes) against Embree
# Each `test` step is also a target of its own (make clippy, make c-examples, ...).
# Also: make install PREFIX=/usr/local [DESTDIR=...]   make docs   make perf

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
CARGO ?= cargo
NO_STD_TARGET := thumbv7em-none-eabihf
# A 64-bit target without x86's vector paths: clippy checks that the library
# builds without warnings where only the portable code exists.
OTHER_ARCH_TARGET := aarch64-unknown-linux-gnu
PYENV := $(CURDIR)/target/pyenv
# Where cargo puts its builds (CARGO_TARGET_DIR when set).
TARGET_DIR := $(or $(CARGO_TARGET_DIR),$(CURDIR)/target)
export ANTUMBRA_ORACLE_PYTHON := $(PYENV)/bin/python
# Property tests draw from a fixed seed here so a CI run is reproducible; plain
# `cargo test` keeps proptest's random seeds for exploring.
export PROPTEST_RNG_SEED ?= 20261122
# Root installs system packages directly; anyone else goes through sudo.
SUDO := $(if $(filter 0,$(shell id -u)),,sudo)

TEST_STEPS := fmt clippy docs no-std cargo-test miri header oracle-selfcheck embree c-examples \
              avx-encoding embedded install-check python-abi
PREFIX ?= /usr/local
DESTDIR ?=

.PHONY: demo test deps toolchain system-packages pyenv install doc c-docs perf $(TEST_STEPS) clean

demo:
	$(CARGO) run --release -p antumbra-cli -- demo

test: deps
	@start=$$(date +%s); \
	for step in $(TEST_STEPS); do \
	  echo "==> make $$step"; t0=$$(date +%s); \
	  $(MAKE) --no-print-directory $$step || { echo "make test: step '$$step' FAILED"; exit 1; }; \
	  echo "<== $$step: ok ($$(( $$(date +%s) - t0 )) s)"; \
	done; \
	echo "make test: every step passed in $$(( $$(date +%s) - start )) s"; \
	echo "$(words $(TEST_STEPS)) passed, 0 failed"

# --- dependencies: everything the checks need, installed by the project itself ---
deps: toolchain system-packages pyenv

toolchain:
	rustup component add rustfmt clippy >/dev/null
	rustup target list --installed | grep -qx $(NO_STD_TARGET) || rustup target add $(NO_STD_TARGET)
	rustup target list --installed | grep -qx $(OTHER_ARCH_TARGET) || rustup target add $(OTHER_ARCH_TARGET)

system-packages:
	@missing=""; \
	for tool in valgrind gcc g++ python3 cmake doxygen pkg-config; do \
	  command -v $$tool >/dev/null || missing="$$missing $$tool"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing:$$missing"; \
	  $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq \
	    $$(echo $$missing | sed -e 's/python3/python3 python3-venv/' -e 's/pkg-config/pkgconf/'); \
	fi
	@# The bare-metal check: the Arm cross compiler with newlib, and QEMU.
	@missing=""; \
	command -v arm-none-eabi-gcc >/dev/null || missing="$$missing gcc-arm-none-eabi"; \
	[ -e /usr/lib/arm-none-eabi/newlib/thumb/v7e-m+fp/hard/libc_nano.a ] || \
	  missing="$$missing libnewlib-arm-none-eabi"; \
	command -v qemu-system-arm >/dev/null || missing="$$missing qemu-system-arm"; \
	if [ -n "$$missing" ]; then \
	  echo "installing:$$missing"; \
	  $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi

pyenv:
	tests/oracle/setup_venv.sh $(PYENV)

# --- the checks ---
fmt:
	$(CARGO) fmt --all -- --check

clippy:
	$(CARGO) clippy --workspace --all-targets -- -D warnings
	$(CARGO) clippy -p antumbra-core --no-default-features -- -D warnings
	$(CARGO) clippy -p antumbra-core --all-features --all-targets -- -D warnings
	$(CARGO) clippy -p antumbra-ffi --no-default-features --target $(NO_STD_TARGET) -- -D warnings
	$(CARGO) clippy -p antumbra-core --all-features --all-targets --target $(OTHER_ARCH_TARGET) -- -D warnings
	$(CARGO) clippy -p antumbra-ffi --target $(OTHER_ARCH_TARGET) -- -D warnings

# The API references, warnings as errors: rustdoc for the crates (every public item
# documented, no broken intra-doc links) into target/doc, and Doxygen for the C
# header (whose comments come from the ffi crate's docs) into target/doc/c/html.
docs: doc c-docs

# Core's private items first (their links are checked too), then the public
# documentation, which overwrites it.
doc:
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc -p antumbra-core --all-features --no-deps --document-private-items
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --workspace --no-deps --exclude antumbra-cli

c-docs:
	mkdir -p $(TARGET_DIR)/doc/c
	( cat docs/api/Doxyfile; echo "OUTPUT_DIRECTORY = $(TARGET_DIR)/doc/c" ) | doxygen -
	@echo "C API reference: $(TARGET_DIR)/doc/c/html/index.html"

# Installs the C library, header, pkg-config and CMake package under $(DESTDIR)$(PREFIX).
install:
	PREFIX="$(PREFIX)" DESTDIR="$(DESTDIR)" CARGO="$(CARGO)" tools/install.sh

# Installs into a temporary prefix and builds and runs the CMake and pkg-config consumers.
install-check:
	CARGO="$(CARGO)" tools/check_install.sh

no-std:
	$(CARGO) build -p antumbra-core --no-default-features --target $(NO_STD_TARGET)
	@# One glam in the tree: obvhs and core must share it (architecture.md).
	@if $(CARGO) tree --workspace -d -e normal,build --prefix depth | grep -q '^0glam '; then \
	  $(CARGO) tree --workspace -d -i glam; echo "more than one glam in the tree"; exit 1; fi

# Everything but the Embree comparison, which `embree` runs with its figures shown.
# The workspace run already tests core with every feature on (the cli and the
# ffi ask for std, bvh and parallel); the second run tests it without std.
cargo-test:
	$(CARGO) test --workspace --exclude antumbra-tests
	$(CARGO) test -p antumbra-core --no-default-features

# Miri, the undefined-behaviour checker, over the tests that reach core's unsafe
# code: the AVX lanes of the BVH and of the edge bounds, prefetching, the
# silhouette record's uninitialised slots, fallible allocation and the calls of
# the rasterizer's AVX2 and AVX-512 builds. Soft floats, since libm's x86 `asm!`
# stops Miri; every feature of those builds on, so the vector paths and the
# builds run. Miri interprets on one thread, so the tests are dealt out in turn
# to MIRI_JOBS processes run side by side (one per core), each with its log.
MIRI_TESTS := miri_ avx_octants_equal_the_portable_ones
MIRI_JOBS ?= 2
AVX512 := +avx512f,+avx512vl,+avx512bw,+avx512dq,+avx512cd
MIRI := MIRIFLAGS="-Zmiri-disable-isolation" \
  RUSTFLAGS="-C target-feature=+avx2,+fma,+bmi1,+bmi2,+lzcnt,+popcnt,$(AVX512)" \
  $(CARGO) +nightly miri test -p antumbra-core --features "std bvh libm/force-soft-floats"
miri:
	rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
	rustup component add --toolchain nightly miri rust-src >/dev/null
	$(MIRI) --no-run
	@tests=$$($(MIRI) -- $(MIRI_TESTS) --list --format terse | sed -n 's/: test$$//p'); \
	test -n "$$tests" || { echo "make miri: no test matches '$(MIRI_TESTS)'"; exit 1; }; \
	rm -f $(TARGET_DIR)/miri-job-*.log; pids=""; \
	for job in $$(seq 0 $$(( $(MIRI_JOBS) - 1 ))); do \
	  share=$$(echo "$$tests" | awk -v n=$(MIRI_JOBS) -v j=$$job '(NR - 1) % n == j'); \
	  if [ -z "$$share" ]; then continue; fi; \
	  echo "make miri: job $$job:" $$share; \
	  ( $(MIRI) -- --exact $$share > $(TARGET_DIR)/miri-job-$$job.log 2>&1 ) & pids="$$pids $$!"; \
	done; \
	failed=0; for pid in $$pids; do wait $$pid || failed=1; done; \
	cat $(TARGET_DIR)/miri-job-*.log; \
	if [ $$failed != 0 ]; then echo "make miri: a job failed (its log is above)"; fi; \
	exit $$failed

# The same package selection as `cargo-test`, so the build it made is reused
# (`-p antumbra-ffi` alone would unify features differently and rebuild).
header:
	$(CARGO) test --workspace --exclude antumbra-tests --test header

oracle-selfcheck:
	$(ANTUMBRA_ORACLE_PYTHON) tests/oracle/test_oracle_selfcheck.py

embree:
	$(CARGO) test -p antumbra-tests -- --nocapture --test-threads=1

c-examples:
	$(CARGO) build --release -p antumbra-ffi
	$(MAKE) -C c_examples check

# No function of the release library that runs 256-bit AVX code runs legacy SSE
# instructions too (each would make the processor save or merge the vector
# registers' upper halves), and, in the library built with AVX throughout (as
# `-C target-cpu=native` engines build it), none of the rasterizer's functions.
AVX_TARGET_DIR := $(TARGET_DIR)/avx-encoding
avx-encoding:
	$(CARGO) build --release -p antumbra-ffi
	python3 tools/check_avx_encoding.py $(TARGET_DIR)/release/libantumbra.so
	RUSTFLAGS="-C target-feature=+avx2,+fma" CARGO_TARGET_DIR=$(AVX_TARGET_DIR) \
	  $(CARGO) build --release -p antumbra-ffi
	python3 tools/check_avx_encoding.py --all-avx antumbra_core::hemi:: \
	  $(AVX_TARGET_DIR)/release/libantumbra.so

# The C library without std, as Cortex-M4 firmware under QEMU, against the host.
embedded:
	CARGO="$(CARGO)" tools/check_embedded.sh

# libantumbra.so through ctypes, against Embree directly: the ABI as a foreign caller sees it.
python-abi:
	$(CARGO) build --release -p antumbra-ffi
	$(ANTUMBRA_ORACLE_PYTHON) tests/oracle/test_ctypes_abi.py $(TARGET_DIR)/release/libantumbra.so

# Every table of docs/performance.md (minutes; one core per figure, ratios against
# baselines in the same run). Not part of `test`: timings are not assertions.
ANTUMBRA := $(TARGET_DIR)/release/antumbra
perf: pyenv
	$(CARGO) build --release -p antumbra-cli
	$(ANTUMBRA) bench raycast
	$(ANTUMBRA) bench hemi
	$(ANTUMBRA) bench hemi --mesh tests/data/armadillo.obj
	$(ANTUMBRA) bench hemi --scaling --receivers 300 --min-time 300
	$(ANTUMBRA) bench ssv --frame --passes 2
	$(ANTUMBRA) bench transfer --bands 4,5,6,7
	$(ANTUMBRA) bench transfer --mesh tests/data/armadillo.obj --bands 4 --clusters 1

clean:
	$(CARGO) clean
	$(MAKE) -C c_examples clean
