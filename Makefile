# photonmap: build, test, bench, run and install.
#
#   make                 build the libraries (static and shared), the renderer, the benchmarks
#                        and the tests
#   make test            build everything, build the example against a staged install (static
#                        and shared library), run the whole test suite
#                        (last line: N passed, N failed, N skipped)
#   make check           the quick tests only, for the edit-test loop (under 20 s on an idle
#                        machine): it leaves out the tests that took more than 0.5 CPU-second or
#                        3 s in the last `make test` (BUILD/test-times.txt) and those in
#                        CHECK_SKIP (slow renders, the quick benchmark, the staged install)
#   make run             photon mapping of cornell_spheres to out/ (45 s; SCENE=, RUNFLAGS=)
#   make bench           run the full benchmarks, write bench/results/*.csv, plots and docs
#   make bench-quick     a small benchmark subset (also run by the test suite)
#   make results         docs/RESULTS.md and docs/HARD_SCENES.md: the path-traced references
#                        when missing (128x128, make-reference.sh, ~8 min on 2 cores; the
#                        equal-time section's 96x96 ones and the survey's 32x32 ones), then
#                        make-equal-time.sh, make-survey.sh, make-results.sh (~8.5 min on 2
#                        shared cores), media-results.sh (the committed data/reference-media/)
#                        and make-hard-scenes.sh; README.md's paragraph "How it compares with
#                        path-traced references"
#   make deps            install the missing Debian packages (scripts/install-deps.sh)
#   make install PREFIX=/usr/local DESTDIR=
#                        headers, libphotonmap.a, libphotonmap.so.2, photonmap.pc, bin/render
#   make clean
#
# Options:
#   SANITIZE=address,undefined   build with sanitizers (into build/san-*)
#   SANITIZE=thread CC=clang     ThreadSanitizer; with clang's OpenMP runtime, whose Archer tool
#                                the tests load (gcc's libgomp is not TSan-aware: false races)
#   SIMD=avx2                    allow AVX2/FMA code (the default build runs on any x86-64)
#   OPENMP=0                     build without OpenMP
#   BUILD=dir                    where objects and binaries go (default build/release)
#   TESTS="pattern ..."          run only the tests whose name or file contains a pattern
#   CC, CXX, CFLAGS, LDFLAGS     as usual; CFLAGS and LDFLAGS are added after the project's
#
# Every object and program depends on $(BUILD)/flags.stamp, which holds the compilers and
# flags and is rewritten only when they change: `make OPENMP=0` after `make` rebuilds what it
# must, and a second identical `make` does nothing.
#
# Only `make deps`, `run`, `test`, `check`, `bench`, `bench-quick` and `results` install missing
# Debian packages (scripts/install-deps.sh, when pkg-config cannot find a dependency); the
# library, `lib`, `all` and `install` never call apt.

CC ?= cc
CXX ?= c++
SANITIZE ?=
SIMD ?=
OPENMP ?= 1
PREFIX ?= /usr/local
DESTDIR ?=
comma := ,

ifeq ($(SANITIZE),)
  BUILD ?= build/release
  OPT ?= -O2
else
  BUILD ?= build/san-$(subst $(comma),-,$(SANITIZE))
  OPT ?= -O1
endif
CFLAGS_BASE := -std=c11 -D_POSIX_C_SOURCE=200809L -g $(OPT) -Wall -Wextra -Wshadow \
               -fno-math-errno
ifeq ($(OPENMP),1)
  CFLAGS_BASE += -fopenmp
  OMP_LIBS := -fopenmp
else
  # Without OpenMP its pragmas are meant to be ignored: that is not worth a warning.
  CFLAGS_BASE += -Wno-unknown-pragmas
endif
ifeq ($(SIMD),avx2)
  CFLAGS_BASE += -mavx2 -mfma
endif
ifneq ($(SANITIZE),)
  SAN_FLAGS := -fsanitize=$(SANITIZE) -fno-omit-frame-pointer -fno-sanitize-recover=all
  SAN_DEFS := -DPM_SANITIZED=1
endif
CFLAGS ?=
LDFLAGS ?=
ALL_CFLAGS = $(CFLAGS_BASE) $(SAN_FLAGS) $(SAN_DEFS) $(CFLAGS)
# The one C++ file (bench/nanoflann_peer.cpp: nanoflann, a header-only C++ library, raced in
# bench/ only) gets the same warnings, and CFLAGS without a C -std.
CXXFLAGS_BASE := -std=c++17 -g $(OPT) -Wall -Wextra -Wshadow -fno-math-errno
ALL_CXXFLAGS = $(CXXFLAGS_BASE) $(SAN_FLAGS) $(SAN_DEFS) $(filter-out -std=%,$(CFLAGS))
ALL_LDFLAGS = $(SAN_FLAGS) $(OMP_LIBS) $(LDFLAGS)

# ---- flags stamp ---------------------------------------------------------------------------
# Written while the Makefile is read, and only when its text differs from the file's, so its
# time changes exactly when the flags do. A dry run (-n, -q) writes nothing: it treats a
# stale stamp as out of date instead, so it shows what a real run would rebuild.
FLAGS_STAMP := $(BUILD)/flags.stamp
FLAGS_TEXT := $(strip CC=$(CC) CXX=$(CXX) SIMD=$(SIMD) OPENMP=$(OPENMP) SANITIZE=$(SANITIZE) \
                CFLAGS=$(ALL_CFLAGS) CXXFLAGS=$(ALL_CXXFLAGS) LDFLAGS=$(ALL_LDFLAGS))
ifneq ($(file <$(FLAGS_STAMP)),$(FLAGS_TEXT))
  ifneq ($(findstring n,$(firstword -$(MAKEFLAGS)))$(findstring q,$(firstword -$(MAKEFLAGS))),)
    .PHONY: $(FLAGS_STAMP)
  else
    $(shell mkdir -p $(BUILD))
    $(file >$(FLAGS_STAMP),$(FLAGS_TEXT))
  endif
endif

# ---- version -------------------------------------------------------------------------------
# From the PM_VERSION_* macros of photonmap/common.h: the shared library's soname carries
# the major version.
PM_VERSION_MAJOR := $(shell sed -n 's/^\#define PM_VERSION_MAJOR \([0-9]*\).*/\1/p' photonmap/common.h)
PM_VERSION := $(PM_VERSION_MAJOR).$(shell sed -n 's/^\#define PM_VERSION_MINOR \([0-9]*\).*/\1/p' photonmap/common.h).$(shell sed -n 's/^\#define PM_VERSION_PATCH \([0-9]*\).*/\1/p' photonmap/common.h)

# ---- sources -------------------------------------------------------------------------------
PM_SRC     := $(sort $(wildcard photonmap/*.c))
PM_HDR     := $(sort $(wildcard photonmap/*.h))
# Installed headers: internal.h and *_internal.h are the library's own, not API.
PM_PUB_HDR := $(filter-out %_internal.h photonmap/internal.h,$(PM_HDR))
# render/ is one folder per pipeline stage (render/README.md); render/mpi/ is built only with MPI=1.
RENDER_SRC := $(sort $(filter-out render/app/main.c render/mpi/%,$(wildcard render/*/*.c)))
BENCH_MAIN := $(sort $(wildcard bench/bench_*.c))
BENCH_SRC  := $(sort $(filter-out $(BENCH_MAIN),$(wildcard bench/*.c)))
BENCH_CXX  := $(sort $(wildcard bench/*.cpp))
TEST_SRC   := $(sort $(wildcard tests/*.c))

PM_OBJ     := $(PM_SRC:%.c=$(BUILD)/obj/%.o)
PM_PIC_OBJ := $(PM_SRC:%.c=$(BUILD)/pic/%.o)
RENDER_OBJ := $(RENDER_SRC:%.c=$(BUILD)/obj/%.o)
BENCH_OBJ  := $(BENCH_SRC:%.c=$(BUILD)/obj/%.o) $(BENCH_CXX:%.cpp=$(BUILD)/obj/%.o)
TEST_OBJ   := $(TEST_SRC:%.c=$(BUILD)/obj/%.o)
# The octree is raced in bench/ only; its test links it from there when it lives there.
TEST_EXTRA_OBJ := $(patsubst %.c,$(BUILD)/obj/%.o,$(wildcard bench/octree.c))

LIB        := $(BUILD)/libphotonmap.a
SONAME     := libphotonmap.so.$(PM_VERSION_MAJOR)
SHLIB      := $(BUILD)/libphotonmap.so.$(PM_VERSION)
SHLIB_MAP  := $(BUILD)/libphotonmap.map
RENDER_BIN := $(BUILD)/render
BENCH_BINS := $(BENCH_MAIN:bench/%.c=$(BUILD)/%)
TEST_BIN   := $(BUILD)/run_tests

# OpenEXRCore: the C API of libopenexr-dev (render/image/exr.c), not the C++ library.
RENDER_LIBS := -lcjson -lpng -lOpenEXRCore -lz -lm
FLANN_LIBS  := -lflann -lm

.PHONY: all lib render bench-bin tests test check run bench bench-quick results install \
        uninstall clean deps example
.DEFAULT_GOAL := all

all: $(LIB) $(SHLIB) $(if $(wildcard render/app/main.c),$(RENDER_BIN)) $(BENCH_BINS) $(TEST_BIN)
lib: $(LIB) $(SHLIB)
render: $(RENDER_BIN)
bench-bin: $(BENCH_BINS)
tests: $(TEST_BIN)

# ---- dependencies --------------------------------------------------------------------------
# Only the goals below may install packages: for them every compile waits (order-only, never
# forcing a rebuild) for `deps`; for any other goal nothing calls apt.
DEPS_GOALS := deps run test check bench bench-quick results
DEPS_FIRST := $(if $(filter $(DEPS_GOALS),$(MAKECMDGOALS)),deps)
deps:
	@if ! command -v pkg-config >/dev/null 2>&1 || ! command -v $(CC) >/dev/null 2>&1 \
	    || ! pkg-config --exists libcjson libpng flann nanoflann OpenEXR 2>/dev/null \
	    || ! [ -x /usr/bin/time ]; then \
	    sh scripts/install-deps.sh; fi

# ---- compile -------------------------------------------------------------------------------
# The renderer and the tests name render's headers by stage ("scene/scene.h"): -Irender for
# them only, so photonmap/ and bench/ cannot reach into render/ by accident.
$(BUILD)/obj/render/%.o $(BUILD)/obj/tests/%.o: INC_RENDER := -Irender
$(BUILD)/obj/%.o: %.c $(FLAGS_STAMP) | $(DEPS_FIRST)
	@mkdir -p $(@D)
	$(CC) $(ALL_CFLAGS) -MMD -MP -I. -Iphotonmap $(INC_RENDER) -c $< -o $@

$(BUILD)/obj/%.o: %.cpp $(FLAGS_STAMP) | $(DEPS_FIRST)
	@mkdir -p $(@D)
	$(CXX) $(ALL_CXXFLAGS) -MMD -MP -I. -Iphotonmap -c $< -o $@

# The shared library's objects: position-independent.
$(BUILD)/pic/%.o: %.c $(FLAGS_STAMP) | $(DEPS_FIRST)
	@mkdir -p $(@D)
	$(CC) $(ALL_CFLAGS) -fPIC -MMD -MP -I. -Iphotonmap -c $< -o $@

-include $(PM_OBJ:.o=.d) $(PM_PIC_OBJ:.o=.d) $(RENDER_OBJ:.o=.d) $(BENCH_OBJ:.o=.d) \
         $(TEST_OBJ:.o=.d) $(BENCH_MAIN:bench/%.c=$(BUILD)/obj/bench/%.d) \
         $(BUILD)/obj/render/app/main.d

$(LIB): $(PM_OBJ)
	@mkdir -p $(@D)
	rm -f $@
	ar rcs $@ $^

# The shared library exports the public API only: names pm_ but not the internals' pm__.
$(SHLIB_MAP): $(FLAGS_STAMP)
	printf '{\n  global: pm_[!_]*;\n  local: *;\n};\n' > $@

$(SHLIB): $(PM_PIC_OBJ) $(SHLIB_MAP) $(FLAGS_STAMP)
	$(CC) -shared -Wl,-soname,$(SONAME) -Wl,--version-script=$(SHLIB_MAP) -o $@ \
	    $(PM_PIC_OBJ) $(ALL_LDFLAGS) -lm
	ln -sf $(notdir $@) $(BUILD)/$(SONAME)
	ln -sf $(SONAME) $(BUILD)/libphotonmap.so

$(RENDER_BIN): $(BUILD)/obj/render/app/main.o $(RENDER_OBJ) $(LIB) $(FLAGS_STAMP)
	$(CC) -o $@ $(filter %.o %.a,$^) $(ALL_LDFLAGS) $(RENDER_LIBS)

# Each bench/bench_*.c is a program; the other bench/*.c are linked into all of them.
# Their objects are reached only through the pattern rule below, which makes them
# "intermediate" to make: without this it deletes them after a fresh build and recompiles
# the benchmarks on every later `make`.
.SECONDARY: $(BENCH_MAIN:bench/%.c=$(BUILD)/obj/bench/%.o) $(BENCH_OBJ)
# FLANN is a C++ library: link with the C++ driver.
$(BUILD)/bench_%: $(BUILD)/obj/bench/bench_%.o $(BENCH_OBJ) $(LIB) $(FLAGS_STAMP)
	$(CXX) -o $@ $(filter %.o %.a,$^) $(ALL_LDFLAGS) $(FLANN_LIBS)

# One test runner holds every tests/*.c; it links the library and the renderer's objects.
$(TEST_BIN): $(TEST_OBJ) $(TEST_EXTRA_OBJ) $(RENDER_OBJ) $(LIB) $(FLAGS_STAMP)
	$(CC) -o $@ $(filter %.o %.a,$^) $(ALL_LDFLAGS) $(RENDER_LIBS)

# ---- test ----------------------------------------------------------------------------------
# The runner is the last thing run, so its "N passed, N failed, N skipped" is the last line.
# It finds the other programs (render, bench, the example) through PM_BUILD_DIR.
# The example is built the way a user would, with pkg-config on a staged `make install`:
# once against the shared library (found through an rpath) and once against the static one.
STAGE := $(abspath $(BUILD)/stage)
EXAMPLE_CC = $(CC) $(SAN_FLAGS) -std=c11 -Wall -Wextra -Werror photonmap/examples/knn_example.c
example: export PKG_CONFIG_PATH := $(STAGE)/lib/pkgconfig
example: $(LIB) $(SHLIB) $(RENDER_BIN)
	@rm -rf $(STAGE)
	@$(MAKE) --no-print-directory install PREFIX=$(STAGE) DESTDIR= BUILD=$(BUILD) >/dev/null
	@mkdir -p $(BUILD)/example
	$(EXAMPLE_CC) -o $(BUILD)/example/knn_example $$(pkg-config --cflags --libs photonmap) \
	    -Wl,-rpath,$(STAGE)/lib
	$(EXAMPLE_CC) -o $(BUILD)/example/knn_example_static $$(pkg-config --cflags photonmap) \
	    $$(pkg-config --static --libs photonmap | sed 's/-lphotonmap/-l:libphotonmap.a/')

# Under ThreadSanitizer, libomp's Archer tool tells TSan about OpenMP's synchronisation, and
# TSan ignores the uninstrumented runtime's own accesses.
ifneq ($(findstring thread,$(SANITIZE)),)
  TEST_ENV := OMP_TOOL_LIBRARIES=$(firstword $(wildcard /usr/lib/llvm-*/lib/libarcher.so)) \
              TSAN_OPTIONS="ignore_noninstrumented_modules=1 halt_on_error=1"
endif
# The runner records each test's CPU and wall time in $(BUILD)/test-times.txt.
test: all example
	$(TEST_ENV) PM_BUILD_DIR=$(abspath $(BUILD)) PM_SOURCE_DIR=$(CURDIR) $(TEST_BIN) \
	    --times $(BUILD)/test-times.txt $(TESTS)

# `make check` leaves out the tests that took more than 0.5 CPU-second or 3 s in the last
# recorded run (runner --quick), and always those that need the staged install or are known
# to be slow (CHECK_SKIP: a pattern leaves out every test whose name or file contains it).
CHECK_SKIP := bench_quick_run agrees_with_path_tracing matches_path example_ packaging_ docs_ \
              build_tracks tungsten_cornell signal_phases
check: all
	$(TEST_ENV) PM_BUILD_DIR=$(abspath $(BUILD)) PM_SOURCE_DIR=$(CURDIR) $(TEST_BIN) \
	    --times $(BUILD)/test-times.txt --quick $(addprefix -x ,$(CHECK_SKIP)) $(TESTS)

# ---- MPI (optional) ------------------------------------------------------------------------
# `make MPI=1` also builds render-mpi, the distributed renderer (render/mpi/, docs/MPI.md):
# render/mpi/*.c compiled with mpicc and linked with the renderer's objects: its main calls
# render's program, render_main (render/app/app.h), with render/mpi's hooks. The
# default build never compiles render/mpi/ nor needs mpi.h. OpenMPI is installed
# (install-deps.sh --mpi) when mpicc is missing. `make MPI=1 test-mpi` runs
# scripts/test-mpi.sh (its own "N passed, N failed" line).
MPI ?= 0
MPICC ?= mpicc
RENDER_MPI_BIN := $(BUILD)/render-mpi
MPI_OBJ := $(patsubst %.c,$(BUILD)/obj/%.o,$(wildcard render/mpi/*.c))
ifeq ($(MPI),1)
all: $(RENDER_MPI_BIN)
endif
.PHONY: render-mpi test-mpi mpi-deps
render-mpi: $(RENDER_MPI_BIN)
mpi-deps:
	@command -v $(MPICC) >/dev/null 2>&1 || sh scripts/install-deps.sh --mpi
$(BUILD)/obj/render/mpi/%.o: render/mpi/%.c $(FLAGS_STAMP) | mpi-deps
	@mkdir -p $(@D)
	$(MPICC) $(ALL_CFLAGS) -MMD -MP -I. -Iphotonmap -Irender -c $< -o $@
$(RENDER_MPI_BIN): $(MPI_OBJ) $(RENDER_OBJ) $(LIB) $(FLAGS_STAMP)
	$(MPICC) -o $@ $(filter %.o %.a,$^) $(ALL_LDFLAGS) $(RENDER_LIBS)
-include $(MPI_OBJ:.o=.d)
test-mpi: $(RENDER_MPI_BIN) $(RENDER_BIN)
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/test-mpi.sh

# ---- run -----------------------------------------------------------------------------------
# The default shows photon mapping: cornell_spheres (a glass sphere's caustic on the floor) at
# 256x256, progressive passes of 16 spp until 45 s of wall time are spent (at most about one
# pass more). SCENE=... renders another scene with the same flags; RUNFLAGS=... replaces them.
SCENE ?= data/scenes/cornell_spheres.json
RUNFLAGS ?= --mode pm --width 256 --height 256 --time 45 --pass-spp 16
run: $(RENDER_BIN)
	@mkdir -p out
	$(RENDER_BIN) $(SCENE) -o out/$(basename $(notdir $(SCENE))).png \
	    --hdr out/$(basename $(notdir $(SCENE))).pfm $(RUNFLAGS)

# ---- bench ---------------------------------------------------------------------------------
# The renderer dumps the real photon map the search bench reads; gnuplot draws the plots
# and valgrind profiles the headline (installed here when missing).
BENCH_DEPS := $(BENCH_BINS) $(if $(wildcard render/app/main.c),$(RENDER_BIN))
bench: $(BENCH_DEPS)
	@command -v gnuplot >/dev/null 2>&1 && command -v valgrind >/dev/null 2>&1 \
	    || sh scripts/install-deps.sh --bench
	PM_BENCH_CFLAGS="$(ALL_CFLAGS)" sh scripts/run-bench.sh $(BUILD) full
bench-quick: $(BENCH_DEPS)
	@command -v gnuplot >/dev/null 2>&1 || sh scripts/install-deps.sh --bench
	PM_BENCH_CFLAGS="$(ALL_CFLAGS)" sh scripts/run-bench.sh $(BUILD) quick $(BUILD)/bench-quick

# ---- results -------------------------------------------------------------------------------
# Photon mapping against long path-traced references (data/reference/, not in git).
# First photon mapping at its defaults against path tracing at equal CPU time (make-equal-time.sh;
# 96x96 references of its scenes made in data/reference/et96/ when missing: about 350, 330
# and 670 CPU-s for cornell_box, cornell_spheres and water_caustic at 32768 spp, 1,340 for
# volumetric_caustic at 16384; a quieter reference leaves fewer runs whose ratio is only a
# lower bound, gen-equal-time-md.sh), then the
# correctness and time-to-error sections at 128x128 (make-results.sh), the media section, every
# shipped scene small (make-survey.sh, its 32x32 references made when missing) and the hard
# scenes (make-hard-scenes.sh, docs/HARD_SCENES.md).
ET_SCENES ?= cornell_box cornell_spheres water_caustic volumetric_caustic
results: $(RENDER_BIN)
	@command -v gnuplot >/dev/null 2>&1 || sh scripts/install-deps.sh --bench
	@for s in $(ET_SCENES); do [ -f data/reference/et96/$$s.pfm ] || \
	    REF_RES=96 REF_OUT=data/reference/et96 REF_SPP_cornell_spheres=32768 REF_SPP_water_caustic=32768 \
	    REF_SPP_cornell_box=32768 REF_SPP_volumetric_caustic=16384 \
	    PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-reference.sh $$s || exit 1; done
	ET_SCENES="$(ET_SCENES)" PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-equal-time.sh
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-survey.sh
	@for s in cornell_spheres cornell_diffuse; do [ -f data/reference/$$s.pfm ] || \
	    PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-reference.sh $$s || exit 1; done
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-results.sh
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/media-results.sh
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-hard-scenes.sh

# ---- install -------------------------------------------------------------------------------
# photonmap.pc: -lphotonmap in Libs; what a static link also needs (libm, the OpenMP runtime
# of the compiler that built the library) in Libs.private.
LIBDIR := $(PREFIX)/lib
OMP_RUNTIME = $(if $(filter 1,$(OPENMP)),$(if $(findstring clang,$(shell $(CC) --version 2>/dev/null | head -1)),-lomp,-lgomp))
install: $(LIB) $(SHLIB) $(RENDER_BIN)
	install -d $(DESTDIR)$(PREFIX)/include/photonmap $(DESTDIR)$(LIBDIR)/pkgconfig \
	    $(DESTDIR)$(PREFIX)/bin
	install -m 644 $(PM_PUB_HDR) $(DESTDIR)$(PREFIX)/include/photonmap/
	install -m 644 $(LIB) $(DESTDIR)$(LIBDIR)/
	install -m 755 $(SHLIB) $(DESTDIR)$(LIBDIR)/
	ln -sf $(notdir $(SHLIB)) $(DESTDIR)$(LIBDIR)/$(SONAME)
	ln -sf $(SONAME) $(DESTDIR)$(LIBDIR)/libphotonmap.so
	install -m 755 $(RENDER_BIN) $(DESTDIR)$(PREFIX)/bin/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(PM_VERSION)|' \
	    -e 's|@LIBS_PRIVATE@|-lm $(OMP_RUNTIME)|' photonmap/photonmap.pc.in \
	    > $(DESTDIR)$(LIBDIR)/pkgconfig/photonmap.pc

uninstall:
	rm -rf $(DESTDIR)$(PREFIX)/include/photonmap $(DESTDIR)$(LIBDIR)/libphotonmap.a \
	       $(DESTDIR)$(LIBDIR)/libphotonmap.so* $(DESTDIR)$(LIBDIR)/pkgconfig/photonmap.pc \
	       $(DESTDIR)$(PREFIX)/bin/render

clean:
	rm -rf build
