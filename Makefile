# SPDX-License-Identifier: GPL-3.0-or-later
# The README's commands. Each does its own set-up: Debian packages, configure, build.
#   make demo    the main job on the embedded default experiment (Release build)
#   make test    the whole test suite under ASan+UBSan, then the install/consumer check
#   make bench   the benchmarks (Release build), printing ratios
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
WERROR ?= OFF
DEMO_ARGS ?=
FUZZ_SECONDS ?= 30
CMAKE ?= cmake

.PHONY: all deps build build-test demo test install-check fuzz bench memcheck format lint clean

all: build

deps:
	@scripts/install-deps

build: deps
	$(CMAKE) -S . -B build -DCMAKE_BUILD_TYPE=Release -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build -j $(JOBS)

demo: build
	./build/rpiv demo --out demo-out $(DEMO_ARGS)

build-test: deps
	$(CMAKE) -S . -B build-test -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_C_FLAGS_DEBUG=-g -O1" \
	    -DRPIV_SANITIZE=address,undefined -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build-test -j $(JOBS)

test: build-test
	cd build-test && ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 \
	    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	    ctest -j $(JOBS) --output-on-failure
	$(MAKE) install-check
	$(MAKE) fuzz

# libFuzzer targets (clang, ASan+UBSan), each run FUZZ_SECONDS on its seed corpus.
fuzz: deps
	scripts/run-fuzz $(FUZZ_SECONDS)

# Install into a temporary prefix and build a consumer with pkg-config and with CMake.
install-check: deps
	scripts/check-install

bench: deps
	@scripts/install-deps --bench
	$(CMAKE) -S . -B build -DCMAKE_BUILD_TYPE=Release -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build -j $(JOBS)
	scripts/run-bench build

memcheck: deps
	$(CMAKE) -S . -B build-memcheck -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_C_FLAGS_DEBUG=-g -O1" >/dev/null
	$(CMAKE) --build build-memcheck -j $(JOBS)
	cd build-memcheck && ctest -L unit -T memcheck --output-on-failure

format:
	clang-format -i include/rpiv/*.h src/*.c src/*.h app/*.c app/*.h tests/*.c tests/*.h bench/*.c 2>/dev/null || true

lint: build
	cppcheck --project=build/compile_commands.json --enable=warning,performance,portability \
	    --suppress='*:/usr/*' --error-exitcode=1 -q

clean:
	rm -rf build build-test build-memcheck build-install build-fuzz
