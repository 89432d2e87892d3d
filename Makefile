# The two commands a new user runs on a fresh Debian 12 machine:
#   make demo   install what is missing, build, run the plane-cylinder job
#   make test   install what is missing, build, run the whole test suite
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
# Ninja when present, chosen when cmake runs: on a fresh machine it is installed by `deps`, after make read this file.
GENERATOR ?=
CMAKE_GENERATOR_ARG = "$(if $(GENERATOR),$(GENERATOR),$$(command -v ninja >/dev/null 2>&1 && echo Ninja || echo 'Unix Makefiles'))"
VMSIM := $(BUILD)/app/vmsim

.PHONY: all deps test-deps configure build demo test bench validate asan clean

all: build

deps:
	@scripts/install-deps.sh --check 2>/dev/null || scripts/install-deps.sh

# What only the tests use (Chromium and the HTML validators for report.html); `make demo` installs none of it.
test-deps:
	@scripts/install-deps.sh --test --check 2>/dev/null || scripts/install-deps.sh --test

$(BUILD)/CMakeCache.txt:
	@$(MAKE) --no-print-directory deps
	cmake -S . -B $(BUILD) -G $(CMAKE_GENERATOR_ARG) -DCMAKE_BUILD_TYPE=Release

configure: deps $(BUILD)/CMakeCache.txt

build: configure
	cmake --build $(BUILD) -j $(JOBS)

# The demo builds only what it runs (the vmsim executable and its libraries), not the tests.
demo: configure
	cmake --build $(BUILD) -j $(JOBS) --target vmsim
	@scripts/demo.sh $(VMSIM)

test: build test-deps
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) --timeout 1200

bench: configure
	cmake --build $(BUILD) -j $(JOBS) --target benches
	@for b in $(BUILD)/bench/*_bench; do echo "== $$b"; $$b --benchmark_min_time=0.5 || exit 1; done

# Long validation runs whose figures go into the issue notes (not part of `make test`).
validate: build
	@scripts/validate.sh $(VMSIM)

# The hostile-input tests under AddressSanitizer/UBSan, in their own build tree.
asan: deps
	cmake -S . -B $(BUILD)-asan -G $(CMAKE_GENERATOR_ARG) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVMSIM_SANITIZE=ON
	cmake --build $(BUILD)-asan -j $(JOBS) --target core_tests
	cd $(BUILD)-asan && ctest --output-on-failure -L core -R 'Hostile|Fuzz'

clean:
	rm -rf $(BUILD) $(BUILD)-asan
