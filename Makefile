# bsms top-level Makefile. `make demo` and `make test` work as root on a fresh Debian 12 machine.
BUILD ?= build
JOBS  ?= $(shell nproc)
RUNS  ?= runs
# The trained runs `make hardcases` examines (BSMS in MODELS/bsms, MGN in MODELS/mgn), e.g.
# `make hardcases MODELS=runs/long HARDCASES_OUT=runs/hardcases_long` after `make train-long`.
MODELS ?= $(RUNS)/demo
HARDCASES_OUT ?= $(RUNS)/hardcases
SUDO  := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

# Debian 12 packages the project needs (docs/design.md "Dependencies").
DEPS := cmake g++ make pkg-config libtorch-dev libeigen3-dev libhdf5-dev libgmsh-dev gmsh \
        nlohmann-json3-dev libprotobuf-dev libgloo-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev \
        libopenblas0-pthread libdnnl-dev libgoogle-perftools-dev gnuplot-nox jq python3-h5py ccache ninja-build \
        pybind11-dev python3-dev python3-numpy python3-pytest python3-torch python3-matplotlib

.PHONY: deps build test test-no-torch demo train-long hardcases bench fuzz sanitize sanitize-thread format clean

deps:
	@missing=$$(for p in $(DEPS); do \
	  dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:" $$missing; \
	  $(SUDO) apt-get update -q && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q --no-install-recommends $$missing; \
	fi

$(BUILD)/CMakeCache.txt: | deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) --timeout 1800

# The parts that do not use LibTorch (core, preprocess, the solver and the data formats) built and
# tested on their own, as on a machine without LibTorch: -DBSMS_TORCH=OFF in build-no-torch/, with
# the Debian packages less LibTorch and Gloo. Not part of `make test` (CI time).
NO_TORCH_DEPS := $(filter-out libtorch-dev libdnnl-dev libgloo-dev python3-torch,$(DEPS))
test-no-torch:
	$(MAKE) deps DEPS="$(NO_TORCH_DEPS)"
	cmake -S . -B build-no-torch -DCMAKE_BUILD_TYPE=Release -DBSMS_TORCH=OFF
	cmake --build build-no-torch -j $(JOBS)
	cd build-no-torch && ctest --output-on-failure -j $(JOBS) --timeout 1800

# `make demo DEMO_FAMILY=bodies3d`: the same pipeline on the 3-D family (runs/demo-bodies3d).
DEMO_FAMILY ?= disks2d
DEMO_OUT ?= $(if $(filter disks2d,$(DEMO_FAMILY)),$(RUNS)/demo,$(RUNS)/demo-$(DEMO_FAMILY))
demo: build
	DEMO_FAMILY=$(DEMO_FAMILY) ./scripts/demo.sh $(BUILD) $(DEMO_OUT)

train-long: build
	./scripts/train_long.sh $(BUILD) $(RUNS)/long

hardcases: build
	./scripts/hardcases.sh $(BUILD) $(HARDCASES_OUT) $(MODELS)

bench: build
	./scripts/bench.sh $(BUILD)

# libFuzzer + ASan + UBSan on every parser bsms owns (fuzz/*.cpp): config JSON with --set
# overrides as train config, scene and scene family (fuzz_config), the multilevel graph file
# (fuzz_multilevel) and the HDF5 dataset layouts (fuzz_dataset) through HDF5 structure programs,
# the mesh intake after gmsh (fuzz_mesh), the direct MSH 2.2 / 4.1 reader (fuzz_msh) and the
# MeshGraphNets TFRecord / meta.json reader (fuzz_tfrecord), one after the other on
# $(RUNS)/fuzz-corpus/<target>/, seeded from the shipped configs, the fixtures and the targets'
# built-in seeds; the corpus grows there. A crash, leak, timeout or out-of-memory leaves its input
# in $(RUNS)/fuzz-crashes/<target>/ and makes `make fuzz` fail once every target has run (UBSan
# reports included). Each target runs FUZZ_SECONDS, or its own FUZZ_SECONDS_<target>, sized to
# reach about 1M inputs (rates seen on a loaded 2-core machine: msh ~50k/s, mesh ~13k/s, config
# ~3.4k/s, tfrecord ~3.1k/s, multilevel ~0.4-1.2k/s and dataset ~0.4-0.95k/s, as these two write
# and read HDF5 files per input). FUZZ_SECONDS=N on the command line sets every target's time.
# build-fuzz/fuzz/fuzz_gmsh_mesh (extract_mesh through a gmsh model) is built but not run here:
# libgmsh 4.8 itself crashes after a few thousand models in one process (fuzz/fuzz_mesh.cpp).
FUZZ_SECONDS ?= 120
FUZZ_TARGETS := fuzz_config fuzz_multilevel fuzz_dataset fuzz_mesh fuzz_msh fuzz_tfrecord fuzz_json fuzz_geo
# datasets: real files damaged byte-wise (fuzz/fuzz_dataset_bytes.cpp), ~0.47k/s on that machine.
FUZZ_TARGETS += fuzz_dataset_bytes
ifneq ($(origin FUZZ_SECONDS),command line)
FUZZ_SECONDS_fuzz_config ?= 360
FUZZ_SECONDS_fuzz_multilevel ?= 3000
FUZZ_SECONDS_fuzz_dataset ?= 3000
FUZZ_SECONDS_fuzz_tfrecord ?= 480
FUZZ_SECONDS_fuzz_msh ?= 60
FUZZ_SECONDS_fuzz_json ?= 360
# gmsh scripts: fuzz_geo, the check of .geo scripts before they run (~0.5-1.2k/s), seeded from
# configs/geometry and its own seeds
FUZZ_SECONDS_fuzz_geo ?= 900
FUZZ_SECONDS_fuzz_dataset_bytes ?= 2400
endif
FUZZ_MAX_LEN_fuzz_config := 8192
FUZZ_MAX_LEN_fuzz_multilevel := 4096
FUZZ_MAX_LEN_fuzz_dataset := 4096
FUZZ_MAX_LEN_fuzz_mesh := 2048
FUZZ_MAX_LEN_fuzz_msh := 8192
FUZZ_MAX_LEN_fuzz_tfrecord := 262144
FUZZ_MAX_LEN_fuzz_json := 65536
FUZZ_MAX_LEN_fuzz_geo := 4096
# --- checkpoints --- fuzz_checkpoint: the checkpoint loader on damaged file images of real
# small checkpoints (~20 KB) and on structurally mutated contents (models/checkpoint.cpp).
FUZZ_TARGETS += fuzz_checkpoint
FUZZ_SEED_TARGETS += fuzz_checkpoint
ifneq ($(origin FUZZ_SECONDS),command line)
FUZZ_SECONDS_fuzz_checkpoint ?= 900
endif
FUZZ_MAX_LEN_fuzz_checkpoint := 16384
FUZZ_MAX_LEN_fuzz_dataset_bytes := 64
FUZZ_CORPUS = $(RUNS)/fuzz-corpus
fuzz: deps
	$(MAKE) deps DEPS="clang libclang-rt-14-dev"
	CC=clang CXX=clang++ cmake -S . -B build-fuzz -DBSMS_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo
	cmake --build build-fuzz -j $(JOBS) --target $(FUZZ_TARGETS) fuzz_gmsh_mesh
	for t in $(FUZZ_TARGETS); do mkdir -p $(FUZZ_CORPUS)/$$t $(RUNS)/fuzz-crashes/$$t; done
	cp configs/train/*.json configs/scenes/*.json configs/families/*.json tests/data/mpm/scenes/*.json $(FUZZ_CORPUS)/fuzz_config/
	{ cat configs/train/disks2d-bsms.json; printf '\0model.latent=64\0features.strain=off\0optimizer.lr=0.5'; } \
	  > $(FUZZ_CORPUS)/fuzz_config/set_train.json
	{ cat configs/scenes/colliding_disks.json; printf '\0bodies.0.spacing=0.05\0solver.kernel=bspline'; } \
	  > $(FUZZ_CORPUS)/fuzz_config/set_scene.json
	{ cat configs/families/disks2d.json; printf '\0sample.count=[1,3]\0scene.background.min=[0]'; } \
	  > $(FUZZ_CORPUS)/fuzz_config/set_family.json
	cp configs/train/*.json configs/families/*.json $(FUZZ_CORPUS)/fuzz_json/
	for d in tests/fixtures/meshgraphnets/*; do \
	  cp $$d/meta.json $(FUZZ_CORPUS)/fuzz_json/meta_$$(basename $$d).json; done
	for t in fuzz_multilevel fuzz_dataset fuzz_mesh fuzz_msh fuzz_json fuzz_dataset_bytes $(FUZZ_SEED_TARGETS); do \
	  BSMS_FUZZ_WRITE_SEEDS=$(FUZZ_CORPUS)/$$t build-fuzz/fuzz/$$t || exit 1; done
	BSMS_FUZZ_WRITE_SEEDS=$(FUZZ_CORPUS)/fuzz_geo build-fuzz/fuzz/fuzz_geo && \
	  cp configs/geometry/*.geo $(FUZZ_CORPUS)/fuzz_geo/
	for d in tests/fixtures/meshgraphnets/*; do n=$$(basename $$d); \
	  cp $$d/meta.json $(FUZZ_CORPUS)/fuzz_tfrecord/meta_$$n.json; \
	  cp $$d/test.tfrecord $(FUZZ_CORPUS)/fuzz_tfrecord/$$n.tfrecord; done
	status=0; $(foreach t,$(FUZZ_TARGETS),echo "== $(t)"; \
	  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 build-fuzz/fuzz/$(t) $(FUZZ_CORPUS)/$(t) \
	  -max_total_time=$(or $(FUZZ_SECONDS_$(t)),$(FUZZ_SECONDS)) -max_len=$(FUZZ_MAX_LEN_$(t)) \
	  -rss_limit_mb=2048 -timeout=30 -print_final_stats=1 -artifact_prefix=$(RUNS)/fuzz-crashes/$(t)/ \
	  || { echo "$(t): FAILED (input in $(RUNS)/fuzz-crashes/$(t)/)"; status=1; };) exit $$status

# The whole ctest suite under AddressSanitizer + UndefinedBehaviorSanitizer (-O1, build-sanitize/).
# Any report fails the test that caused it. Leaks inside libgmsh are suppressed
# (tests/sanitizers/lsan.supp); nothing else is.
SAN_ENV := ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1 \
           LSAN_OPTIONS=suppressions=$(CURDIR)/tests/sanitizers/lsan.supp:print_suppressions=0 \
           UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
sanitize: deps
	cmake -S . -B build-sanitize -DBSMS_SANITIZE=address -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g"
	cmake --build build-sanitize -j $(JOBS)
	cd build-sanitize && $(SAN_ENV) ctest --output-on-failure -j $(JOBS) --timeout 3600

# ThreadSanitizer on the OpenMP kernels (core, preprocess, solver tests; clang + LLVM's OpenMP with
# its Archer tool, so that OpenMP's own synchronisation is visible to TSan: GCC's libgomp is not).
TSAN_TESTS ?= test_core test_preprocess test_mpm
sanitize-thread: deps
	$(MAKE) deps DEPS="clang libclang-rt-14-dev libomp-14-dev"
	CC=clang CXX=clang++ cmake -S . -B build-tsan -DBSMS_SANITIZE=thread -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g"
	cmake --build build-tsan -j $(JOBS) --target $(TSAN_TESTS)
	./scripts/tsan.sh build-tsan $(TSAN_TESTS)

format:
	find src preprocess data models tests bench fuzz -name '*.cpp' -o -name '*.hpp' | xargs clang-format -i

clean:
	rm -rf $(BUILD)
