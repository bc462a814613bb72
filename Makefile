# Thin wrapper over CMake + Ninja. Every target installs the Debian packages it needs first
# (as root, on Debian 12), so a fresh machine needs nothing but `make`.

BUILD      ?= build
BUILD_SAN  ?= build-sanitize
BUILD_TSAN ?= build-tsan
# Seconds each fuzz target runs in `make fuzz-ci` (the long campaign: fuzz/run_fuzz.sh by hand).
FUZZ_SECONDS ?= 8
DATA       ?= $(abspath ../shared/data)
JOBS       ?= $(shell nproc)
# A compiler cache speeds rebuilds when one is installed; nothing needs it.
LAUNCHER   := $(if $(shell command -v ccache 2>/dev/null),-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# nodejs and npm count as there when `node` and `npm` are on the PATH: NodeSource's nodejs package
# carries its own npm and conflicts with Debian's.
DEBS := cmake ninja-build g++ libeigen3-dev libnanoflann-dev libtbb-dev libcli11-dev \
        nlohmann-json3-dev libyaml-cpp-dev libzstd-dev liblzf-dev libxxhash-dev libpng-dev \
        liboctomap-dev libgdal-dev libgtest-dev libbenchmark-dev libfreetype-dev fonts-dejavu-core \
        librosbag-dev libsensor-msgs-dev libnav-msgs-dev libtf2-msgs-dev python3-rosbag python3-sensor-msgs \
        python3-nav-msgs python3-tf2-msgs libbz2-dev clang libclang-rt-14-dev \
        pybind11-dev python3-dev python3-numpy python3-pytest python3-pip python3-setuptools python3-wheel python3-matplotlib \
        python3-dask python3-distributed \
        liblz4-dev libsqlite3-dev nodejs npm libcpp-httplib-dev libjs-three libceres-dev
# What `make test` adds: the browser that shows the viewer's page (tests/serve/browser_test.cpp,
# driven by Node, which DEBS holds).
TEST_DEBS := chromium

.PHONY: all deps test-deps build tool demo demo-real test test-sanitize ros2-test-deps bench bench-slam bench-slam-suite bench-peers clean fuzz-ci test-tsan

all: build

deps:
	@missing=$$(for p in $(DEBS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || \
	  case $$p in nodejs|npm) command -v $${p%js} >/dev/null || echo $$p;; *) echo $$p;; esac; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:" $$missing; \
	  if [ "$$(id -u)" != 0 ]; then echo "run as root (or install: $$missing)"; exit 1; fi; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(BUILD)/build.ninja: | deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release -DHMAP_DATA_DIR=$(DATA) $(LAUNCHER)

build: deps $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS)

# The main job on the built-in default: simulate the `parking` scene with a VLP-16 along a car
# path, map it, evaluate the map against the truth, draw it (no download needed).
# Builds the hmap tool and the libraries it links, not the tests and benchmarks (`make test` does).
tool: deps $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS) --target hmap

demo: tool
	$(BUILD)/bin/hmap demo --out out/demo
	@echo "report: out/demo/report.md; pictures: out/demo/map_top.png out/demo/map_oblique.png"

# The same on real recorded scans: the Ouster OS0-64 recording of ../shared/data.
demo-real: tool
	@mkdir -p out
	$(BUILD)/bin/hmap map --kitti $(DATA)/balm_os0 --preset outdoor --cell 0.1 --out out/balm_os0.hmap
	$(BUILD)/bin/hmap info out/balm_os0.hmap
	$(BUILD)/bin/hmap render out/balm_os0.hmap --trajectory $(DATA)/balm_os0/poses.txt --out out/balm_os0_top.png
	$(BUILD)/bin/hmap render out/balm_os0.hmap --view oblique --out out/balm_os0_oblique.png
	$(BUILD)/bin/hmap export out/balm_os0.hmap --ply out/balm_os0_hvoxels.ply

# The ROS 2 test recordings are written by the ecosystem's own writers (tests/ros2: @mcap/core,
# @foxglove/rosmsg2-serialization), installed pinned from package-lock.json; the tests skip
# without them.
ros2-test-deps: deps
	npm ci --prefix tests/ros2 --no-audit --no-fund

test-deps:
	@missing=$$(for p in $(TEST_DEBS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages for the tests:" $$missing; \
	  if [ "$$(id -u)" != 0 ]; then echo "run as root (or install: $$missing)"; exit 1; fi; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi

test: build test-deps ros2-test-deps
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# hmap slam with its defaults beside Debian's Open3D ICP and KISS-ICP (built from ../shared/peers
# when it is there) on the same sequences: ATE / RPE and timings per system (bench/slam_peers.py).
PEER_DEBS := python3-open3d python3-numpy robin-map-dev
bench-slam: build
	@missing=$$(for p in $(PEER_DEBS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; fi
	/usr/bin/python3 bench/slam_peers.py --hmap $(BUILD)/bin/hmap --data $(DATA) --peers $(abspath ../shared/peers)

# hmap slam with its defaults on the simulator's routes, over sensors and eight noise seeds, and on
# the real sets with a reference (bench/slam_suite.py, the standard library only; about 15 minutes
# on two cores, the simulations kept in out/slam_suite for the next run). kitti_hdl64_seq16 is
# scored against the Open3D ICP trajectory that `make bench-slam` writes.
bench-slam-suite: tool
	python3 bench/slam_suite.py --hmap $(BUILD)/bin/hmap --data $(DATA) --seeds 8 --json out/slam_suite/defaults.json

# The same suite under AddressSanitizer and UndefinedBehaviorSanitizer, and every reader and loader
# fuzzed (fuzz/), from one clang build: the libraries carry libFuzzer's coverage as well, so the
# tests and the libFuzzer programs share every object file (CI builds the libraries once for both).
# -O1 -g1: what ASan recommends, with line tables enough for its stack traces and a third of the
# compile time of -O2 -g.
SAN_CONFIGURE = CC=clang CXX=clang++ cmake -S . -B $(BUILD_SAN) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DHMAP_SANITIZE=ON -DHMAP_FUZZ=ON -DHMAP_BUILD_BENCH=OFF -DHMAP_DATA_DIR=$(DATA) $(LAUNCHER)
# Tests left out under the sanitizers: they time the tool's refusal of a 1 GiB file and SIGKILL it
# mid-save, which the Release run checks; under ASan they cost minutes and test no memory access
# the other tests do not. readme_commands runs every command of the README and docs on the real
# data to keep the documents true (49 s in Release, the longest test under ASan, alone on its core
# at the end of the run); the code it runs is run under ASan by the CLI tests and fuzzed.
# Browser.FollowsALiveSlamRun simulates 280 sweeps and follows their SLAM run in Chromium under an
# 80 s cap: under ASan that run alone takes minutes; the server's live updates it watches are run
# under ASan by ServerTest, the SLAM by slam_tests. bench.slam_suite tests a Python script's
# figures and arguments (144 s under ASan in session 29's CI, the longest test there); the `hmap
# slam` runs it drives are the CLI and SLAM tests' code.
SAN_EXCLUDE := ^(BoundedTest.AGibibyteOfRandomBytesIsRejected|TornFileTest\..*|readme_commands|Browser.FollowsALiveSlamRun|bench.slam_suite)$$

test-sanitize: deps test-deps ros2-test-deps
	$(SAN_CONFIGURE)
	cmake --build $(BUILD_SAN) -j $(JOBS)
	cd $(BUILD_SAN) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS) -E '$(SAN_EXCLUDE)'

# Every reader and loader fuzzed: libFuzzer programs built with clang, ASan and UBSan (the build of
# test-sanitize), seeds cut from $(DATA) plus fuzz/corpus and fuzz/regressions, each run for
# FUZZ_SECONDS; fails on any crash, leak, hang or memory blow-up.
fuzz-ci: deps
	$(SAN_CONFIGURE)
	cmake --build $(BUILD_SAN) -j $(JOBS) --target fuzz_all
	fuzz/run_fuzz.sh $(BUILD_SAN) $(FUZZ_SECONDS)

# The tests of the code that runs in parallel (TBB: scan binning, ray tracing, merging, the
# occupancy update, the elevation baseline, the map metrics, the SLAM matcher) under ThreadSanitizer, with TBB
# replaced by std::thread (tests/reliability/tsan_tbb: Debian's libtbb is not instrumented).
TSAN_TESTS := maps_tests occupancy_tests baseline_tests eval_tests slam_tests
test-tsan: deps
	cmake -S . -B $(BUILD_TSAN) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHMAP_TSAN=ON \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
	  -DHMAP_BUILD_BENCH=OFF -DHMAP_DATA_DIR=$(DATA) $(LAUNCHER)
	cmake --build $(BUILD_TSAN) -j $(JOBS) --target $(TSAN_TESTS)
	cd $(BUILD_TSAN) && TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" \
	  ctest --output-on-failure -j $(JOBS) -L '^(maps|occupancy|baseline|eval|slam)$$'

bench: build
	$(BUILD)/bin/hmap bench --kitti $(DATA)/kitti_hdl64_seq16 --cell 0.2 --max-range 50
	$(BUILD)/bin/hmap_bench

# hmap beside Bonxai (compiled into $(BUILD) from ../shared/peers/bonxai when it is there; CMake's
# HMAP_BONXAI_DIR) and OctoMap, on the same scans and poses in one process (bench/peers_main.cpp):
# the figures of BENCHMARKS.md's first table. OctoMap takes about a minute per balm_os0 run at 0.1 m.
bench-peers: deps $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS) --target hmap_peers_bench
	$(BUILD)/bin/hmap_peers_bench --kitti $(DATA)/kitti_hdl64_seq16 --cell 0.2 --max-range 50 --rounds 4 --octomap-rounds 2
	$(BUILD)/bin/hmap_peers_bench --kitti $(DATA)/balm_os0 --cell 0.1 --max-range 25 --rounds 4 --octomap-rounds 1
	$(BUILD)/bin/hmap_peers_bench --kitti $(DATA)/balm_os0 --cell 0.2 --max-range 25 --rounds 4 --octomap-rounds 1

clean:
	rm -rf $(BUILD) $(BUILD_SAN) $(BUILD_TSAN) out
