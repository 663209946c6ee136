# photonmap: build, test, bench, run and install.
#
#   make                 build the library, the renderer, the benchmarks and the tests
#   make test            build everything and run the test suite (last line: N passed, N failed)
#   make run             render the default Cornell box to out/
#   make bench           run the full benchmarks, write bench/results/*.csv, plots and docs
#   make bench-quick     a small benchmark subset (also run by the test suite)
#   make results         path-traced references (if missing, ~45 min) and docs/RESULTS.md (~20 min)
#   make install PREFIX=/usr/local DESTDIR=
#   make clean
#
# Options:
#   SANITIZE=address,undefined   build with sanitizers (into build/san-*)
#   SIMD=avx2                    allow AVX2/FMA code (the default build runs on any x86-64)
#   OPENMP=0                     build without OpenMP
#   BUILD=dir                    where objects and binaries go (default build/release)
#
# Missing Debian packages are installed by scripts/install-deps.sh when pkg-config cannot
# find a dependency.

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
               -Wno-unused-parameter -fno-math-errno
ifeq ($(OPENMP),1)
  CFLAGS_BASE += -fopenmp
  OMP_LIBS := -fopenmp
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
ALL_LDFLAGS = $(SAN_FLAGS) $(OMP_LIBS) $(LDFLAGS)

# ---- sources -------------------------------------------------------------------------------
PM_SRC     := $(sort $(wildcard photonmap/*.c))
PM_HDR     := $(sort $(wildcard photonmap/*.h))
# Installed headers: *_internal.h are the library's own, not API.
PM_PUB_HDR := $(filter-out %_internal.h,$(PM_HDR))
RENDER_SRC := $(sort $(filter-out render/main.c,$(wildcard render/*.c)))
BENCH_MAIN := $(sort $(wildcard bench/bench_*.c))
BENCH_SRC  := $(sort $(filter-out $(BENCH_MAIN),$(wildcard bench/*.c)))
TEST_SRC   := $(sort $(wildcard tests/*.c))

PM_OBJ     := $(PM_SRC:%.c=$(BUILD)/obj/%.o)
RENDER_OBJ := $(RENDER_SRC:%.c=$(BUILD)/obj/%.o)
BENCH_OBJ  := $(BENCH_SRC:%.c=$(BUILD)/obj/%.o)
TEST_OBJ   := $(TEST_SRC:%.c=$(BUILD)/obj/%.o)

LIB        := $(BUILD)/libphotonmap.a
RENDER_BIN := $(BUILD)/render
BENCH_BINS := $(BENCH_MAIN:bench/%.c=$(BUILD)/%)
TEST_BIN   := $(BUILD)/run_tests

RENDER_LIBS := -lcjson -lpng -lz -lm
FLANN_LIBS  := -lflann -lm

.PHONY: all lib render bench-bin tests test run bench bench-quick results install uninstall clean deps example
.DEFAULT_GOAL := all

all: $(LIB) $(if $(wildcard render/main.c),$(RENDER_BIN)) $(BENCH_BINS) $(TEST_BIN)
lib: $(LIB)
render: $(RENDER_BIN)
bench-bin: $(BENCH_BINS)
tests: $(TEST_BIN)

# ---- dependencies --------------------------------------------------------------------------
# Order-only: runs before compiling, never forces a rebuild.
deps:
	@if ! command -v pkg-config >/dev/null 2>&1 || ! command -v $(CC) >/dev/null 2>&1 \
	    || ! pkg-config --exists libcjson libpng flann 2>/dev/null; then \
	    sh scripts/install-deps.sh; fi

# ---- compile -------------------------------------------------------------------------------
$(BUILD)/obj/%.o: %.c | deps
	@mkdir -p $(@D)
	$(CC) $(ALL_CFLAGS) -MMD -MP -Iphotonmap -c $< -o $@

-include $(PM_OBJ:.o=.d) $(RENDER_OBJ:.o=.d) $(BENCH_OBJ:.o=.d) $(TEST_OBJ:.o=.d) \
         $(BENCH_MAIN:bench/%.c=$(BUILD)/obj/bench/%.d) $(BUILD)/obj/render/main.d

$(LIB): $(PM_OBJ)
	@mkdir -p $(@D)
	rm -f $@
	ar rcs $@ $^

$(RENDER_BIN): $(BUILD)/obj/render/main.o $(RENDER_OBJ) $(LIB)
	$(CC) -o $@ $^ $(ALL_LDFLAGS) $(RENDER_LIBS)

# Each bench/bench_*.c is a program; the other bench/*.c are linked into all of them.
# Their objects are reached only through the pattern rule below, which makes them
# "intermediate" to make: without this it deletes them after a fresh build and recompiles
# the benchmarks on every later `make`.
.SECONDARY: $(BENCH_MAIN:bench/%.c=$(BUILD)/obj/bench/%.o) $(BENCH_OBJ)
# FLANN is a C++ library: link with the C++ driver.
$(BUILD)/bench_%: $(BUILD)/obj/bench/bench_%.o $(BENCH_OBJ) $(LIB)
	$(CXX) -o $@ $^ $(ALL_LDFLAGS) $(FLANN_LIBS)

# One test runner holds every tests/*.c; it links the library and the renderer's objects.
$(TEST_BIN): $(TEST_OBJ) $(RENDER_OBJ) $(LIB)
	$(CC) -o $@ $^ $(ALL_LDFLAGS) $(RENDER_LIBS)

# ---- test ----------------------------------------------------------------------------------
# The runner is the last thing run, so its "N passed, N failed" is the last line printed.
# It finds the other programs (render, bench, the example) through PM_BUILD_DIR.
STAGE := $(abspath $(BUILD)/stage)
example: $(LIB)
	@$(MAKE) --no-print-directory install PREFIX=$(STAGE) DESTDIR= BUILD=$(BUILD) >/dev/null
	@mkdir -p $(BUILD)/example
	PKG_CONFIG_PATH=$(STAGE)/lib/pkgconfig sh -c '$(CC) $(SAN_FLAGS) -std=c11 -Wall -Wextra \
	    -o $(BUILD)/example/knn_example photonmap/examples/knn_example.c \
	    $$(pkg-config --cflags --libs photonmap)'

test: all example
	PM_BUILD_DIR=$(abspath $(BUILD)) PM_SOURCE_DIR=$(CURDIR) $(TEST_BIN) $(TESTS)

# ---- run -----------------------------------------------------------------------------------
SCENE ?= data/scenes/cornell_box.json
run: $(RENDER_BIN)
	@mkdir -p out
	$(RENDER_BIN) $(SCENE) -o out/$(basename $(notdir $(SCENE))).png \
	    --hdr out/$(basename $(notdir $(SCENE))).pfm $(RUNFLAGS)

# ---- bench ---------------------------------------------------------------------------------
# The renderer dumps the real photon map the search bench reads; gnuplot draws the plots
# and valgrind profiles the headline (installed here when missing).
BENCH_DEPS := $(BENCH_BINS) $(if $(wildcard render/main.c),$(RENDER_BIN))
bench: $(BENCH_DEPS)
	@command -v gnuplot >/dev/null 2>&1 && command -v valgrind >/dev/null 2>&1 \
	    || sh scripts/install-deps.sh --bench
	PM_BENCH_CFLAGS="$(ALL_CFLAGS)" sh scripts/run-bench.sh $(BUILD) full
bench-quick: $(BENCH_DEPS)
	@command -v gnuplot >/dev/null 2>&1 || sh scripts/install-deps.sh --bench
	PM_BENCH_CFLAGS="$(ALL_CFLAGS)" sh scripts/run-bench.sh $(BUILD) quick $(BUILD)/bench-quick

# ---- results -------------------------------------------------------------------------------
# Photon mapping against long path-traced references (data/reference/, not in git).
results: $(RENDER_BIN)
	@command -v gnuplot >/dev/null 2>&1 || sh scripts/install-deps.sh --bench
	@for s in cornell_spheres cornell_diffuse; do [ -f data/reference/$$s.pfm ] || \
	    PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-reference.sh $$s || exit 1; done
	PM_BUILD_DIR=$(abspath $(BUILD)) sh scripts/make-results.sh

# ---- install -------------------------------------------------------------------------------
install: $(LIB)
	install -d $(DESTDIR)$(PREFIX)/include/photonmap $(DESTDIR)$(PREFIX)/lib/pkgconfig
	install -m 644 $(PM_PUB_HDR) $(DESTDIR)$(PREFIX)/include/photonmap/
	install -m 644 $(LIB) $(DESTDIR)$(PREFIX)/lib/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(shell sed -n 's/.*PM_VERSION_STRING "\(.*\)"/\1/p' photonmap/common.h)|' \
	    -e 's|@LIBS@|-lm $(OMP_LIBS)|' photonmap/photonmap.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/photonmap.pc

uninstall:
	rm -rf $(DESTDIR)$(PREFIX)/include/photonmap $(DESTDIR)$(PREFIX)/lib/libphotonmap.a \
	       $(DESTDIR)$(PREFIX)/lib/pkgconfig/photonmap.pc

clean:
	rm -rf build
