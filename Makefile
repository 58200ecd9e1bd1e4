# FVR Workstation: the two commands of the README.
#   make run    installs what is missing, builds, starts the workstation on the demo study
#               (or on STUDY=path)
#   make test   installs what is missing, builds, runs every test headless
BUILD_DIR ?= build
BUILD_TYPE ?= Release
JOBS ?= $(shell nproc)
STUDY ?=
SHARED_DATA ?= $(abspath $(CURDIR)/../shared/data)

.PHONY: all deps configure build run test bench sanitize clean

all: build

deps:
	@bash packaging/install-deps.sh

configure: deps
	@cmake -S . -B $(BUILD_DIR) -G Ninja -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) \
	  -DFVR_SHARED_DATA_DIR=$(SHARED_DATA) > $(BUILD_DIR).configure.log 2>&1 \
	  || (cat $(BUILD_DIR).configure.log; exit 1)

build: configure
	@cmake --build $(BUILD_DIR) --parallel $(JOBS)

# Until the Qt workstation lands (issue 5), `make run` renders the study with fvr-render and
# writes out/projection.png (and the float line integrals in out/projection.npy).
run: build
	@mkdir -p out
	@$(BUILD_DIR)/app/fvr-render $(if $(STUDY),$(STUDY),phantom:shepp-logan:128) \
	  --dir 0.35,0.2,0.92 --up 0,-1,0 --kernel catmull-rom --oversampling 2 --values mu \
	  --size 512 --out out/projection.npy
	@$(BUILD_DIR)/app/fvr-render $(if $(STUDY),$(STUDY),phantom:shepp-logan:128) \
	  --dir 0.35,0.2,0.92 --up 0,-1,0 --kernel catmull-rom --oversampling 2 --values mu \
	  --size 512 --out out/projection.png
	@echo "Open out/projection.png (display-mapped) or out/projection.npy (line integrals, mm)."

test: build
	@cd $(BUILD_DIR) && xvfb-run -a -s "-screen 0 1280x1024x24" \
	  ctest --output-on-failure --parallel $(JOBS) --timeout 900

bench: build
	@$(BUILD_DIR)/bench/fvr_bench

# Loaders and tests under AddressSanitizer + UndefinedBehaviorSanitizer.
sanitize: deps
	@cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFVR_SANITIZE=ON \
	  -DFVR_BUILD_BENCH=OFF -DFVR_BUILD_GUI=OFF -DFVR_SHARED_DATA_DIR=$(SHARED_DATA) > /dev/null
	@cmake --build build-asan --parallel $(JOBS)
	@cd build-asan && ctest --output-on-failure --parallel $(JOBS) -L unit

clean:
	@rm -rf $(BUILD_DIR) build-asan out
