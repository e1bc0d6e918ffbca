# The two entry points of a fresh Debian 12 machine that has Rust:
#   make demo  - install what is missing, build, bake and walk the animated Cornell box
#   make test  - install what is missing, build, run every test (both variants)
# Everything the project needs is installed from here, nothing by hand.

SHELL := /bin/bash
CARGO ?= cargo
VENV := .venv
PYTHON := $(VENV)/bin/python
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
DEB_PACKAGES := libembree-dev libopenimageio-dev libclang-dev pkg-config g++ cmake python3 python3-venv fonts-dejavu-core slurm-wlm munge xvfb xauth libx11-6 libxcursor1
PY_PACKAGES := mitsuba==3.9.1 flip-evaluator==1.7 numpy
DEMO_SCENE := scenes/cornell-box/scene.toml
DEMO_SIZE := 256x256
DEMO_SPP := 256
RW := target/release/rangewalk

export RANGEWALK_PYTHON := $(abspath $(PYTHON))

.PHONY: demo test deps debs venv build capi lint bench clean install capi-test fuzz

# The framework's main job on the animated Cornell box: plan and bake base
# images, walk the scene's path from them, path-trace every fifth frame of
# the walk to measure the synthesis against (contact.png shows them), and
# synthesize the `main` camera's view.
demo: deps build
	@rm -rf out/demo out/demo.partial && mkdir -p out/demo.partial
	@set -o pipefail; { \
	  $(RW) bake $(DEMO_SCENE) --quality 0.6 --frame-size $(DEMO_SIZE) --spp 8 --out out/demo.partial/bake && \
	  $(RW) walk out/demo.partial/bake --path walk --size $(DEMO_SIZE) \
	    --check-every 5 --check-spp $(DEMO_SPP) --out out/demo.partial/walk && \
	  $(RW) synth out/demo.partial/bake --camera main --time 0.5 --size $(DEMO_SIZE) \
	    --out out/demo.partial/synth-main-t0.5.exr --preview out/demo.partial/synth-main-t0.5.png; \
	} 2>&1 | tee out/demo.partial/summary.txt
	@mv out/demo.partial out/demo
	@echo "demo written to out/demo/: bake/ (base images), walk/ (frames, walk.png animation, contact.png: synthesized above path-traced above FLIP error map, summary.json), synth-main-t0.5.png, summary.txt (time of every phase, error: LRMS, bias, 8x8-block LRMS and p99, FLIP)"
	@echo "walk through it in a window: $(RW) view out/demo/bake --size $(DEMO_SIZE) (keys: docs/viewer.md; without a display: xvfb-run $(RW) view out/demo/bake --path walk --screenshot out/demo/view.png)"

# The pure-Rust variant leaves out Embree and OpenImageIO, not the command line.
PURE_RUST := --no-default-features --features cli
test: deps build lint
	$(CARGO) test --release
	$(MAKE) --no-print-directory capi-test
	$(CARGO) test --release $(PURE_RUST)

# The C ABI for C++ pipelines: the shared and static libraries, the header,
# a pkg-config file and a CMake package (find_package(rangewalk)).
PREFIX ?= /usr/local
VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -n 1)
install: build
	install -d $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/lib/cmake/rangewalk $(DESTDIR)$(PREFIX)/include
	install -m 755 target/release/librangewalk.so $(DESTDIR)$(PREFIX)/lib/
	install -m 644 target/release/librangewalk.a $(DESTDIR)$(PREFIX)/lib/
	install -m 644 include/rangewalk.h $(DESTDIR)$(PREFIX)/include/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(VERSION)|' dist/rangewalk.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/rangewalk.pc
	for f in rangewalkConfig rangewalkConfigVersion; do \
	  sed -e 's|@VERSION@|$(VERSION)|' dist/$$f.cmake.in > $(DESTDIR)$(PREFIX)/lib/cmake/rangewalk/$$f.cmake; \
	done

# The C++ example (CMake, find_package) and the C test of every error path
# (CMake, pkg-config), built against an installed copy with AddressSanitizer
# and UndefinedBehaviorSanitizer; any report fails the run. The C test's
# full-disk case writes onto a 64 KiB tmpfs mounted here: that needs root,
# as the tests and CI run; without it the test fails rather than skip.
CAPI := out/capi
CAPI_PREFIX := $(abspath $(CAPI)/prefix)
SANITIZERS := ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# The library carries only what its API needs: no crate of the command
# line, and no function but the rw_ calls and the glue cxx generates for
# the OpenImageIO shim's vectors (rustc exports it; it cannot be hidden).
CLI_CRATES := clap indicatif plotters minifb font8x8
capi-test: build
	@linked=$$($(CARGO) tree -e normal $(CAPI_FEATURES) --prefix none | cut -d' ' -f1 | sort -u | grep -xF $(CLI_CRATES:%=-e %) || true); \
	  if [ -n "$$linked" ]; then echo "the C library links" $$linked; exit 1; fi
	@others=$$(nm -D --defined-only target/release/librangewalk.so | awk '$$2 == "T" && $$3 !~ /^(rw_|cxxbridge1[$$]rust_vec[$$]rangewalk[$$]oiio[$$])/ { print $$3 }'); \
	  if [ -n "$$others" ]; then echo "the C library exports" $$others; exit 1; fi
	if mountpoint -q $(CAPI)/full; then umount $(CAPI)/full; fi
	rm -rf $(CAPI)
	$(MAKE) --no-print-directory install PREFIX=$(CAPI_PREFIX)
	cmake -S examples/cpp -B $(CAPI)/pipeline -DSANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_PREFIX_PATH=$(CAPI_PREFIX) > /dev/null
	cmake --build $(CAPI)/pipeline
	PKG_CONFIG_PATH=$(CAPI_PREFIX)/lib/pkgconfig cmake -S tests/capi -B $(CAPI)/errors -DSANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo > /dev/null
	cmake --build $(CAPI)/errors
	$(SANITIZERS) $(CAPI)/pipeline/pipeline $(DEMO_SCENE) $(CAPI)/run $(abspath $(RW))
	mkdir -p $(CAPI)/full && mount -t tmpfs -o size=64k rangewalk-full $(CAPI)/full
	RW_FULL_DIR=$(abspath $(CAPI)/full) $(SANITIZERS) $(CAPI)/errors/error_paths $(DEMO_SCENE) scenes/furnace/scene.toml $(CAPI)/run/bake $(CAPI)/errors/work; \
	  status=$$?; umount $(CAPI)/full; exit $$status

# Fuzzing (docs/fuzzing.md): each target for FUZZ_SECONDS on one core,
# from the committed inputs (tests/fuzz-regressions/<target>/, which
# `cargo test --test fuzz_regressions` replays on stable). New inputs go to
# fuzz/corpus/<target>, a crash to fuzz/artifacts/<target>/ and fails the run.
FUZZ_SECONDS ?= 60
FUZZ_TARGETS := scene exr bake
fuzz:
	@command -v cargo-fuzz > /dev/null || $(CARGO) install cargo-fuzz
	@rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
	cd fuzz && for t in $(FUZZ_TARGETS); do \
	  mkdir -p corpus/$$t && \
	  $(CARGO) +nightly fuzz run -a $$t corpus/$$t $$(ls -d ../tests/fuzz-regressions/$$t/*/) -- \
	    -max_total_time=$(FUZZ_SECONDS) -timeout=10 -rss_limit_mb=2048 || exit 1; \
	done

deps: debs venv

# Debian packages, installed only when missing (sudo only when not root).
debs:
	@missing=""; \
	for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi

# Mitsuba 3, the independent renderer the validation tests compare against,
# and NVIDIA FLIP, the perceptual error of the experiment reports.
venv: $(VENV)/.installed
$(VENV)/.installed: Makefile
	python3 -m venv $(VENV)
	$(PYTHON) -m pip install -q --disable-pip-version-check $(PY_PACKAGES)
	$(PYTHON) -c "import mitsuba, flip_evaluator; mitsuba.set_variant('scalar_rgb')"
	touch $@

build: capi
	$(CARGO) build --release

# The shared and static C libraries, without the `cli` feature's crates.
# The shared one names itself, so that programs linked against an installed
# copy find it by name, and exports only the rw_ calls: the symbols of the
# Rust and C++ archives it is made of (cxx's among them) stay inside.
CAPI_FEATURES := --no-default-features --features embree,oiio
capi:
	$(CARGO) rustc --release --lib $(CAPI_FEATURES) --crate-type cdylib,staticlib -- \
	  -C link-arg=-Wl,-soname,librangewalk.so -C link-arg=-Wl,--exclude-libs,ALL

lint:
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings
	$(CARGO) clippy --release --all-targets $(PURE_RUST) -- -D warnings
	$(CARGO) clippy --release --lib $(CAPI_FEATURES) -- -D warnings

bench: deps
	$(CARGO) bench

clean:
	$(CARGO) clean
	rm -rf out $(VENV)
