# FVR Workstation: the two commands of the README.
#   make run    installs what is missing, builds, starts the workstation on the built-in demo
#               study (or on STUDY=path)
#   make test   installs what is missing, builds, runs every test headless
BUILD_DIR ?= build
BUILD_TYPE ?= Release
JOBS ?= $(shell nproc)
STUDY ?=
SHARED_DATA ?= $(abspath $(CURDIR)/../shared/data)

.PHONY: all deps test-deps configure build run test bench bench-gpu gpu-kit package test-fuzz sanitize sanitize-ui format \
  format-check screenshots clean

all: build

deps:
	@bash packaging/install-deps.sh

# What only the tests need besides (Orthanc, pytest, Dask, Zarr).
test-deps:
	@bash packaging/install-deps.sh --tests

configure: deps
	@cmake -S . -B $(BUILD_DIR) -G Ninja -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) \
	  -DFVR_BUILD_GUI=ON -DFVR_BUILD_TESTS=ON -DFVR_BUILD_BENCH=ON \
	  -DFVR_SHARED_DATA_DIR=$(SHARED_DATA) > $(BUILD_DIR).configure.log 2>&1 \
	  || (cat $(BUILD_DIR).configure.log; exit 1)

build: configure
	@cmake --build $(BUILD_DIR) --parallel $(JOBS)

# Starts the workstation on the built-in phantom, or on STUDY=path (DICOM folder or volume file).
run: build
	@$(BUILD_DIR)/app/fvr-workstation $(STUDY)

test: test-deps build
	@cd $(BUILD_DIR) && xvfb-run -a -s "-screen 0 1280x1024x24" \
	  ctest --output-on-failure --parallel $(JOBS) --timeout 900

# Every fuzz target for 60 s each (the DICOM reader, the store's C-STORE handling, the dataset
# manifest; `make test` runs them for a few seconds only). FUZZ_TIME=N changes the time.
FUZZ_TIME ?= 60
test-fuzz: test-deps build
	@bash tests/fuzz/run_all.sh --build-dir $(BUILD_DIR)/tests/fuzz --time $(FUZZ_TIME) \
	  --data $(SHARED_DATA) --python /usr/bin/python3 --pythonpath $(BUILD_DIR)/python

# Debian package (fvr-workstation_VERSION_ARCH.deb in the build folder).
package: build
	@cd $(BUILD_DIR) && cpack -G DEB

bench: build
	@$(BUILD_DIR)/bench/fvr_bench

# GPU Table 1 on the machine's GPU (under a display; headless: xvfb-run gives Mesa llvmpipe).
# Headless EGL: no X server needed (FVR_EGL_DEVICE=N picks the device).
bench-gpu: build
	@$(BUILD_DIR)/bench/fvr_bench_gpu

# The hardware bench kit: build/fvr-gpu-kit.tar.gz (build/gpu-kit/fvr-gpu-kit unpacked) holding
# fvr-render, fvr_bench_gpu and the libraries a bare GPU machine lacks, and run.sh (--gpu-info,
# the GPU Table 1, GPU = CPU) writing results/ (packaging/gpu-kit/README.txt). Release build;
# fails when the tarball exceeds 48 MB.
gpu-kit: build
	@bash packaging/gpu-kit/make_kit.sh $(BUILD_DIR) $(BUILD_DIR)/gpu-kit $(BUILD_DIR)/fvr-gpu-kit.tar.gz

# Loaders and tests under AddressSanitizer + UndefinedBehaviorSanitizer.
sanitize: deps test-deps
	@cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFVR_SANITIZE=ON \
	  -DFVR_BUILD_BENCH=OFF -DFVR_BUILD_GUI=OFF -DFVR_SHARED_DATA_DIR=$(SHARED_DATA) > /dev/null
	@cmake --build build-asan --parallel $(JOBS)
	@cd build-asan && ctest --output-on-failure --parallel $(JOBS) -L "unit|pacs"

# The workstation's UI tests under the same sanitizers (sanitize builds no GUI): the same
# build-asan with the GUI on. Leaks off: D-Bus and fontconfig keep allocations to the end.
sanitize-ui: deps test-deps
	@cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFVR_SANITIZE=ON \
	  -DFVR_BUILD_BENCH=OFF -DFVR_BUILD_GUI=ON -DFVR_SHARED_DATA_DIR=$(SHARED_DATA) > /dev/null
	@cmake --build build-asan --parallel $(JOBS) --target fvr_ui_tests
	@cd build-asan && ASAN_OPTIONS=detect_leaks=0 xvfb-run -a -s "-screen 0 1280x1024x24" \
	  ctest --output-on-failure -L ui --timeout 900

# Formats the C++ sources in place with .clang-format (STYLE.md: 100 columns, 4 spaces);
# format-check lists the files it would change and fails if there are any.
FORMAT_FILES = $(shell git ls-files --cached --others --exclude-standard '*.cpp' '*.h')
format: deps
	@clang-format -i $(FORMAT_FILES)

format-check: deps
	@clang-format --dry-run -Werror $(FORMAT_FILES)

# The README's screenshots (resources/screenshots), regenerated headless under Xvfb at a fixed
# window size by the workstation itself (--screenshot … --quit), each run with settings of its
# own (XDG_CONFIG_HOME: no user's saved settings; the file is "<organization>/<application>.conf"
# of ui/src/app_info.cpp). Studies from ../shared/data, the built-in phantom where missing.
SCREENSHOT_DIR ?= resources/screenshots
SCREENSHOT_SIZE ?= 1400x1000
SHOT_CONFIG = $(abspath $(BUILD_DIR))/screenshots-config
SHOT_SETTINGS = $(SHOT_CONFIG)/fvr-workstation/FVR Workstation.conf
HEAD_PHANTOM = $(SHARED_DATA)/dicom/ct_phantom_philips_512x512x140
BODY_CT = $(SHARED_DATA)/volumes/body_ct_hu_3mm/example_ct.mhd
SHOT = xvfb-run -a -s "-screen 0 1600x1200x24" env XDG_CONFIG_HOME="$(SHOT_CONFIG)" \
  QT_QPA_PLATFORM=xcb $(BUILD_DIR)/app/fvr-workstation --window-size $(SCREENSHOT_SIZE) --quit
screenshots: build
	@mkdir -p $(SCREENSHOT_DIR)
	@# The first image: no study named, the built-in chest phantom at the default window.
	@rm -rf "$(SHOT_CONFIG)"
	@$(SHOT) --screenshot $(SCREENSHOT_DIR)/first-image.png
	@# Four kernels side by side (view 1 Kaiser-Bessel 4, linear, nearest, sinc4), AP.
	@rm -rf "$(SHOT_CONFIG)"
	@study="$(HEAD_PHANTOM)"; [ -d "$$study" ] || study=phantom:shepp-logan:128; \
	 $(SHOT) "$$study" --compare 4 --view AP --screenshot $(SCREENSHOT_DIR)/workstation.png
	@# Beer-Lambert film look: transmitted intensity at 70 keV, exposure 2, edge enhancement
	@# (amount 1, sigma 2 mm), inverted (bone white), through the X-ray and Display panels' keys.
	@rm -rf "$(SHOT_CONFIG)" && mkdir -p "$(SHOT_CONFIG)/fvr-workstation"
	@printf '[xray]\noutput=1\nenergyKeV=70\nexposure=2\nsharpen=1\nsharpenRadius=2\n[display]\ninvert=true\n' \
	  > "$(SHOT_SETTINGS)"
	@study="$(BODY_CT)"; [ -f "$$study" ] || study=phantom:shepp-logan:128; \
	 $(SHOT) "$$study" --view AP --screenshot $(SCREENSHOT_DIR)/xray-film.png
	@# Voxel models side by side: band-limited (view 1) and trilinear (view 2), the same kernel
	@# (Kaiser-Bessel 4 deapodized), body CT, AP, 70 keV film, one window for both; the
	@# two views' PNG exports (what they display, without the overlay), cropped alike.
	@command -v convert >/dev/null || { echo "make screenshots: needs imagemagick (convert)"; exit 1; }
	@rm -rf "$(SHOT_CONFIG)" && mkdir -p "$(SHOT_CONFIG)/fvr-workstation"
	@printf '[xray]\noutput=1\nenergyKeV=70\n[display]\ninvert=true\n' > "$(SHOT_SETTINGS)"
	@study="$(BODY_CT)"; [ -f "$$study" ] || study=phantom:chest; \
	 $(SHOT) "$$study" --view AP --compare 2 --kernel kaiser-bessel4,kaiser-bessel4 \
	   --voxel-model bandlimited,trilinear --export-views "$(SHOT_CONFIG)/voxel-models"
	@cd "$(SHOT_CONFIG)/voxel-models" && crop=$$(convert view1.png -trim -format '%wx%h%X%Y' info:) && \
	 convert view1.png view2.png -crop "$$crop" +repage -bordercolor black -border 24 +append \
	   "$(abspath $(SCREENSHOT_DIR))/voxel-models.png"
	@rm -rf "$(SHOT_CONFIG)"
	@# Cone beam beside parallel: the chest phantom at LAO 30 CRAN 15, a cardiac C-arm's SID and
	@# SOD, view 1 the Fourier renderer's parallel image, view 2 the ray-cast cone beam.
	@rm -rf "$(SHOT_CONFIG)"
	@$(SHOT) phantom:chest --compare 2 --projection parallel,cone --carm 30,15 --sid 1020 \
	   --sod 750 --size 256 --screenshot $(SCREENSHOT_DIR)/cone-beam.png
	@# resources/screenshots/xray-match.png (File > Open X-ray to match...) is a capture of the
	@# dialog (not the main window, which --screenshot grabs): a simulated XA of the chest phantom
	@# (256^3 box model, 640x560, 0.6 mm, LAO 20 CRAN 10, SID 1100, SOD 800, Poisson noise) opened
	@# with `fvr-workstation --match-xray FILE`, the screen grabbed with `import -window root`.
	@# Polychromatic: the chest phantom AP at 70 and 120 kVp (TASMIP + 1.5 mm Al, CsI-free ideal
	@# energy-integrating detector), -ln(I/I0) each at its own auto window, bone white.
	@for k in 70 120; do $(BUILD_DIR)/app/fvr-render phantom:chest --view AP --kvp $$k \
	   --filtration-al 1.5 --size 512 --out $(BUILD_DIR)/kvp-$$k.png 2>/dev/null || exit 1; done
	@convert $(BUILD_DIR)/kvp-70.png $(BUILD_DIR)/kvp-120.png -trim +repage -bordercolor black \
	   -border 16 +append $(SCREENSHOT_DIR)/kvp-70-120.png
	@# The PACS dialog after a search and a retrieve from a real Orthanc (the UI test grabs it).
	@rm -f $(BUILD_DIR)/tests/tmp/pacs-dialog.png
	@cd $(BUILD_DIR) && QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1280x1024x24" \
	  ./tests/fvr_ui_tests --gtest_filter='PacsWorkstation.FindRetrieveOpenAndSendBack' >/dev/null
	@cp $(BUILD_DIR)/tests/tmp/pacs-dialog.png $(SCREENSHOT_DIR)/pacs.png
	@ls -l $(SCREENSHOT_DIR)/pacs.png $(SCREENSHOT_DIR)/kvp-70-120.png $(SCREENSHOT_DIR)/voxel-models.png $(SCREENSHOT_DIR)/first-image.png $(SCREENSHOT_DIR)/workstation.png \
	  $(SCREENSHOT_DIR)/xray-film.png

clean:
	@rm -rf $(BUILD_DIR) build-asan out
