# bsms top-level Makefile. `make demo` and `make test` work as root on a fresh Debian 12 machine.
BUILD ?= build
JOBS  ?= $(shell nproc)
RUNS  ?= runs
SUDO  := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

# Debian 12 packages the project needs (DESIGN.md, Dependencies).
DEPS := cmake g++ make pkg-config libtorch-dev libeigen3-dev libhdf5-dev libgmsh-dev gmsh \
        nlohmann-json3-dev libprotobuf-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev \
        libopenblas0-pthread gnuplot-nox

.PHONY: deps build test demo train-long hardcases bench fuzz format clean

deps:
	@missing=$$(for p in $(DEPS); do \
	  dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:" $$missing; \
	  $(SUDO) apt-get update -q && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q --no-install-recommends $$missing; \
	fi

$(BUILD)/CMakeCache.txt: | deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) --timeout 1800

demo: build
	./scripts/demo.sh $(BUILD) $(RUNS)/demo

train-long: build
	./scripts/train_long.sh $(BUILD) $(RUNS)/long

hardcases: build
	./scripts/hardcases.sh $(BUILD) $(RUNS)/hardcases $(RUNS)/demo

bench: build
	./scripts/bench.sh $(BUILD)

# libFuzzer + ASan + UBSan on the MeshGraphNets reader, FUZZ_SECONDS each, seeded with the
# fixtures; the corpus grows in $(RUNS)/fuzz-corpus. A crash leaves its input as crash-* here.
FUZZ_SECONDS ?= 120
fuzz: deps
	$(MAKE) deps DEPS="clang libclang-rt-14-dev"
	CC=clang CXX=clang++ cmake -S . -B build-fuzz -DBSMS_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo
	cmake --build build-fuzz -j $(JOBS) --target fuzz_tfrecord
	mkdir -p $(RUNS)/fuzz-corpus
	for d in tests/fixtures/meshgraphnets/*; do n=$$(basename $$d); \
	  cp $$d/meta.json $(RUNS)/fuzz-corpus/meta_$$n.json; cp $$d/test.tfrecord $(RUNS)/fuzz-corpus/$$n.tfrecord; done
	build-fuzz/fuzz/fuzz_tfrecord $(RUNS)/fuzz-corpus -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1

format:
	find src preprocess data models tests bench fuzz -name '*.cpp' -o -name '*.hpp' | xargs clang-format -i

clean:
	rm -rf $(BUILD)
