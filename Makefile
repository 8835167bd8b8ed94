# SPDX-License-Identifier: GPL-3.0-or-later
# The README's commands. Each does its own set-up: Debian packages, configure, build.
#   make demo    the main job on the embedded default experiment (Release build)
#   make test    the whole test suite under ASan+UBSan, the install/consumer check, valgrind
#                over the quick unit programs, then the fuzz targets
#   make bench   the benchmarks (Release build), printing ratios
#   make python  the Python package (python/rpiv over build/librpiv.so)
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
WERROR ?= OFF
DEMO_ARGS ?=
FUZZ_SECONDS ?= 30
FUZZ_JOBS ?= 1
CTEST_ARGS ?=
CMAKE ?= cmake

.PHONY: all deps build build-test demo test install-check fuzz bench memcheck memcheck-quick \
	format lint clean python build-memcheck run-test-asan run-memcheck-quick

all: build

deps:
	@scripts/install-deps

build: deps
	$(CMAKE) -S . -B build -DCMAKE_BUILD_TYPE=Release -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build -j $(JOBS)

# The Python package (python/rpiv, ctypes over librpiv): the library built, then copied next to
# the package, so that `PYTHONPATH=python /usr/bin/python3 -c 'import rpiv'` works from the
# source tree and `pip install ./python` installs it (docs/python.md).
python: build
	cp -f build/librpiv.so python/rpiv/librpiv.so
	PYTHONPATH=python /usr/bin/python3 -c 'import rpiv; print("rpiv", rpiv.__version__, "for Python: ok")'

demo: build
	./build/rpiv demo --out demo-out $(DEMO_ARGS)

# -O2 under the sanitizers: the checks are inserted before the optimiser runs, and the test
# programs spend 2.7-3.6 x less CPU than at -O1 (test_uncertainty 228 -> 84 s user, test_demo
# 204 -> 56 s, session 10); same numbers printed.
build-test: deps
	$(CMAKE) -S . -B build-test -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_C_FLAGS_DEBUG=-g -O2" \
	    -DRPIV_SANITIZE=address,undefined -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build-test -j $(JOBS)

# The stages one after the other, each timed by scripts/stage (wall, user + sys CPU); the first
# that fails stops `make test` with its status. The install check installs from build-memcheck
# (the plain -O1 build valgrind needs anyway) instead of building a Release tree of its own, and
# the fuzz targets run JOBS at a time (each one single-threaded process with its own seed,
# budget and limits). docs/benchmarks.md has the stage times.
test: deps
	@scripts/stage build-test $(MAKE) --no-print-directory build-test
	@scripts/stage ctest-asan $(MAKE) --no-print-directory run-test-asan
	@scripts/stage build-memcheck $(MAKE) --no-print-directory build-memcheck
	@scripts/stage memcheck-quick $(MAKE) --no-print-directory run-memcheck-quick
	@scripts/stage install-check scripts/check-install build-memcheck
	@scripts/stage fuzz $(MAKE) --no-print-directory fuzz FUZZ_JOBS=$(JOBS)

# The test runs of `make test` alone, in trees already built (no configure, no build step):
# run-test-asan here (CTEST_ARGS are added to its ctest, e.g. CTEST_ARGS='-R test_piv'),
# run-memcheck-quick below.
run-test-asan:
	cd build-test && ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 \
	    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	    ctest -j $(JOBS) --output-on-failure $(CTEST_ARGS)

# libFuzzer targets (clang, ASan+UBSan), each run FUZZ_SECONDS on its seed corpus, FUZZ_JOBS
# at a time (default 1: the machine is shared; `make test` runs JOBS at a time).
# The library is built with clang here: with WERROR=ON (CI) its warnings fail the build too.
fuzz: deps
	RPIV_WERROR=$(WERROR) FUZZ_JOBS=$(FUZZ_JOBS) scripts/run-fuzz $(FUZZ_SECONDS)

# Install into a temporary prefix and build a consumer with pkg-config and with CMake (from a
# Release tree of its own, build-install; `make test` installs from build-memcheck instead).
install-check: deps
	scripts/check-install

bench: deps
	@scripts/install-deps --bench
	$(CMAKE) -S . -B build -DCMAKE_BUILD_TYPE=Release -DRPIV_WERROR=$(WERROR) >/dev/null
	$(CMAKE) --build build -j $(JOBS)
	scripts/run-bench build

# No benchmarks here (valgrind runs the unit label only; build-test compiles them, with WERROR).
build-memcheck: deps
	$(CMAKE) -S . -B build-memcheck -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_C_FLAGS_DEBUG=-g -O1" \
	    -DRPIV_BENCH=OFF >/dev/null
	$(CMAKE) --build build-memcheck -j $(JOBS)

# valgrind (uninitialised reads, invalid accesses, leaks; --error-exitcode fails the test) over
# every unit program: about 18 minutes here, so not part of `make test`.
memcheck: build-memcheck
	cd build-memcheck && ctest -L unit -T memcheck -j $(JOBS) --output-on-failure

# The same over the unit programs that take seconds to minutes under valgrind (all but the
# demo, the calibration, the CCM, the ensemble, the uncertainty sweep, the noise sweep, the 2.6 M
# formatted numbers of test_field_fmt (97 s under valgrind), and the CCM-heavy test_bias (over
# 600 s since session 8's measured_nodes test) and test_peak_shear (242 s), which the sanitizer
# run of `make test` covers and `make memcheck` runs), part of `make test`. test_refine (109 s
# under valgrind, the second longest) is left out too: of the library lines it runs, all but two
# (two stores of the iteration count in src/piv/refine.c) are run under valgrind by the other
# programs here (gcov per test, docs/benchmarks.md); it still runs under ASan+UBSan in
# `make test` and under valgrind in `make memcheck`. RPIV_MEMCHECK=1 makes the programs with a
# statistical sweep run a few of its cases under valgrind (tests/check.h check_memcheck; the
# ASan+UBSan run asserts the statistics): test_cbc 459 s -> about 3 min here.
MEMCHECK_QUICK_SKIP = demo|calib|ccm|ensemble|uncertainty|noise|field_fmt|bias|peak_shear|refine
memcheck-quick: build-memcheck
	@$(MAKE) --no-print-directory run-memcheck-quick
run-memcheck-quick:
	cd build-memcheck && RPIV_MEMCHECK=1 ctest -L unit -E 'test_($(MEMCHECK_QUICK_SKIP))$$' -T memcheck \
	    -j $(JOBS) --output-on-failure

format:
	clang-format -i include/rpiv/*.h src/*/*.c src/*/*.h app/*.c app/*.h tests/*.c tests/*.h bench/*.c 2>/dev/null || true

lint: build
	cppcheck --project=build/compile_commands.json --enable=warning,performance,portability \
	    --suppress='*:/usr/*' --error-exitcode=1 -q

clean:
	rm -rf build build-test build-memcheck build-install build-fuzz python/rpiv/librpiv.so
