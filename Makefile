# Thin wrapper over CMake: the README's two commands are `make demo` and `make test`.
BUILD    ?= build
JOBS     ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=

.PHONY: all deps build demo test asan fuzz bench bench-latency install clean

all: build

deps:
	@sh scripts/deps.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS)

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

# The main job: project the shipped body mesh from the default camera into an RGB-D EXR + PNG.
demo: build
	@mkdir -p out
	./$(BUILD)/smplpix project --mesh data/body/human_woman.obj --camera data/cameras/default.json \
	    --out out/demo.exr --png out/demo.png --npy out/demo.npy

# All tests (warnings are errors here, as in CI).
test: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DSPX_WERROR=ON $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS)
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer.
asan: deps
	cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DSPX_SANITIZE=ON -DSPX_WERROR=ON -DSPX_BUILD_BENCHMARKS=OFF
	cmake --build build-asan -j $(JOBS)
	cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  LSAN_OPTIONS=suppressions=$(CURDIR)/scripts/lsan.supp:print_suppressions=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS)

# libFuzzer harnesses (clang); FUZZ_SECONDS per parser.
FUZZ_SECONDS ?= 30
fuzz: deps
	CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=Debug -DSPX_FUZZ=ON \
	  -DSPX_BUILD_TESTS=OFF -DSPX_BUILD_BENCHMARKS=OFF
	cmake --build build-fuzz -j $(JOBS)
	sh fuzz/run.sh build-fuzz $(FUZZ_SECONDS)

bench: build
	sh benchmarks/run.sh $(BUILD)

# Renderer latency vs vertex count (also part of `make bench`): table on stdout,
# out/bench/latency.{csv,json,png}.
bench-latency: build
	$(BUILD)/benchmarks/bench_latency

PREFIX ?= /usr/local
install: build
	cmake --install $(BUILD) --prefix $(PREFIX)

clean:
	rm -rf $(BUILD) build-asan build-fuzz out
