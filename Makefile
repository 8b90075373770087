# sphnl — every target builds what it needs; `make deps` runs first and installs
# missing Debian packages (as root) or prints the exact apt-get command.
#
#   make test                      build and run every test (what CI runs)
#   make reproduce [FULL=1] [MAX_N=n]  benchmarks -> results/<run-id>/ -> figures + REPRODUCTION.md
#                  [FORCE_MERGE=reason]  add a part made by other code to an existing run (recorded)
#   make ablations [FULL=1]        the ablation studies (experiments/ablation_*.json, beyond_loops, beyond_thread_updates)
#   make figures RESULTS=dir       redraw figures and report from stored JSON only
#   make bench ARGS="..."          run the benchmark binary with ARGS passed through
#   make compare [BASE=ref] [THRESHOLD=2]   compare performance against another git ref
#   make counters-build            the build valgrind runs (build-counters/: x86-64-v3, -g) for the counters kind
#   make test-sanitize             C++ tests under AddressSanitizer + UBSan (build-sanitize/)
#   make test-portable             -march=x86-64-v2 build: no AVX-512, same results (build-portable/)
#   make run ARGS="..."            run `sphnl run ARGS`
#   make replicate A=results/x B=results/y   compare two runs claim by claim -> B/replication.md|json
#   make resume RUN=results/<run-id> [ONLY=ids] [MAX_N=n]   finish a run with the revision that began it

# Debian's interpreter: it can import python3-numpy/pandas/matplotlib/scipy,
# while the first python3 on PATH may be a pyenv one that cannot.
PYTHON ?= /usr/bin/python3
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=
SIZE := $(if $(filter 1 yes true,$(FULL)),full,default)
# One folder per size and revision: re-running resumes, a new commit starts afresh.
RUN_ID ?= $(SIZE)-$(shell git rev-parse --short=12 HEAD 2>/dev/null || echo norev)
RESULTS ?= results/full
BASE ?=
THRESHOLD ?= 2
REPS ?= 5
# MAX_N=n leaves out sweep points above n particles (a FULL run in parts).
MAX_N ?=
# FORCE_MERGE=reason merges into a run folder whose earlier parts were made by
# other code (experiments/run.py refuses otherwise); the reason is shown in the report.
FORCE_MERGE ?=
COMPARE_OUT ?= .compare/out
export MPLBACKEND := Agg

SANITIZE_BUILD ?= build-sanitize
PORTABLE_BUILD ?= build-portable
# The counters kind runs sphnl_bench under valgrind 3.19, which cannot execute
# AVX-512: an x86-64-v3 Release build with debug symbols (harness/valgrind.py).
COUNTERS_BUILD ?= build-counters
# The two physics validations (hydrostatic tank, Martin & Moyce front) run
# minutes of simulated flow; under the sanitizers' ~3x slowdown they would
# double CI time while exercising the same code the other tests cover.
SANITIZE_SKIP ?= ^Precision/Validation\.

.PHONY: all deps configure build test test-cpp test-python test-sanitize test-portable reproduce resume ablations figures bench compare run replicate clean counters-build

all: build

deps:
	@bash tools/deps.sh
	@$(PYTHON) -c "import numpy, pandas, matplotlib, scipy" 2>/dev/null || { \
	  echo "sphnl: $(PYTHON) cannot import numpy/pandas/matplotlib/scipy; install python3-numpy python3-pandas python3-matplotlib python3-scipy or set PYTHON=" >&2; exit 1; }

$(BUILD)/CMakeCache.txt: CMakeLists.txt | deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=$(PYTHON) $(CMAKE_FLAGS)

configure: deps $(BUILD)/CMakeCache.txt

build: configure
	cmake --build $(BUILD) -j $(JOBS)

# The Python test classes run $(JOBS) at a time (tools/run_python_tests.py:
# one process each, longest first); `$(PYTHON) -m unittest discover -s
# tests/python -v` with SPHNL_BUILD_DIR set runs the same tests serially.
test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)
	SPHNL_BUILD_DIR=$(abspath $(BUILD)) $(PYTHON) tools/run_python_tests.py --jobs $(JOBS)

# ASan + UBSan (any report fails the test: -fno-sanitize-recover, halt_on_error).
test-sanitize: deps
	cmake -S . -B $(SANITIZE_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSPHNL_SANITIZE=ON \
	  -DSPHNL_BUILD_BENCHMARKS=OFF -DPython3_EXECUTABLE=$(PYTHON) $(CMAKE_FLAGS)
	cmake --build $(SANITIZE_BUILD) -j $(JOBS)
	ASAN_OPTIONS=halt_on_error=1:detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
	  ctest --test-dir $(SANITIZE_BUILD) --output-on-failure -j $(JOBS) -E '$(SANITIZE_SKIP)'

# The user's CMAKE_CXX_FLAGS -march must win over SPHNL_MARCH=native; the
# binary must hold no AVX-512 instruction and give the native build's results.
test-portable: build
	cmake -S . -B $(PORTABLE_BUILD) -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS=-march=x86-64-v2 \
	  -DSPHNL_BUILD_TESTS=OFF -DSPHNL_BUILD_BENCHMARKS=OFF -DPython3_EXECUTABLE=$(PYTHON)
	cmake --build $(PORTABLE_BUILD) --target sphnl -j $(JOBS)
	$(PYTHON) tools/check_portable.py --native $(BUILD)/sphnl --portable $(PORTABLE_BUILD)/sphnl

counters-build: deps
	cmake -S . -B $(COUNTERS_BUILD) $$($(PYTHON) -m harness.valgrind --cmake-options)
	cmake --build $(COUNTERS_BUILD) --target sphnl_bench -j $(JOBS)

reproduce: build counters-build
	$(PYTHON) -m experiments.run --size $(SIZE) --run-id $(RUN_ID) --bench $(BUILD)/benchmarks/sphnl_bench --counters-bench $(COUNTERS_BUILD)/benchmarks/sphnl_bench $(if $(MAX_N),--max-n $(MAX_N)) $(if $(FORCE_MERGE),--force-merge "$(FORCE_MERGE)")
	$(PYTHON) -m plots.report results/$(RUN_ID)
	@echo "sphnl: report: results/$(RUN_ID)/REPRODUCTION.md"

# The ablation studies (README.md, "Ablations"): not part of `make reproduce`
# (its default size must stay within 30 min); run into the same folder.
ABLATIONS := ablation_window_start,ablation_freed_memory,ablation_freed_pages,peers_first_call,ablation_pair_loop,ablation_simd,ablation_boundary_pairs,ablation_gridder_a,ablation_initial_order,beyond_loops,beyond_thread_updates,beyond_scaling,beyond_dynamic,beyond_precision,beyond_pair_loop,beyond_vl_loop,beyond_inner_order

ablations: build
	$(PYTHON) -m experiments.run --size $(SIZE) --run-id $(RUN_ID) --only $(ABLATIONS) --bench $(BUILD)/benchmarks/sphnl_bench $(if $(MAX_N),--max-n $(MAX_N)) $(if $(FORCE_MERGE),--force-merge "$(FORCE_MERGE)")
	$(PYTHON) -m plots.report results/$(RUN_ID)
	@echo "sphnl: report: results/$(RUN_ID)/REPRODUCTION.md"

figures: deps
	$(PYTHON) -m plots.report $(RESULTS)

# A run made in parts, resumed after this checkout moved on: that revision is
# checked out and built in build-rev-<rev>/, measures, and today's plots draw.
resume: deps
	@test -n "$(RUN)" || { echo "sphnl: make resume needs the run folder: make resume RUN=results/<run-id> [ONLY=fig14,fig16] [MAX_N=n]" >&2; exit 2; }
	$(PYTHON) -m experiments.resume_run "$(RUN)" --python $(PYTHON) --jobs $(JOBS) $(if $(ONLY),--only $(ONLY)) $(if $(MAX_N),--max-n $(MAX_N))
	$(PYTHON) -m plots.report "$(RUN)"

replicate: deps
	@test -n "$(A)" -a -n "$(B)" || { echo "sphnl: make replicate needs two run folders: make replicate A=results/<run> B=results/<other run>" >&2; exit 2; }
	$(PYTHON) -m plots.replicate "$(A)" "$(B)" $(if $(OUT),--out "$(OUT)")

bench: build
	$(BUILD)/benchmarks/sphnl_bench $(ARGS)

compare: deps
	$(PYTHON) tools/compare.py --base "$(BASE)" --threshold "$(THRESHOLD)" --reps "$(REPS)" --out "$(COMPARE_OUT)"

run: build
	$(BUILD)/sphnl run $(ARGS)

clean:
	rm -rf $(BUILD) $(SANITIZE_BUILD) $(PORTABLE_BUILD) $(COUNTERS_BUILD) .compare
