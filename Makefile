# anistar — build, test, benchmark, install.
#
#   make            build/libanistar.a, build/libanistar.so*, build/anistar, build/examples/*
#   make check      build and run every test (installs libgmp-dev/libcmocka-dev if missing
#                   and allowed; otherwise prints the exact command)
#   make sanitize   the test suite under AddressSanitizer + UndefinedBehaviorSanitizer
#   make tsan       the threaded paths' tests under ThreadSanitizer
#   make bench      build and run the benchmarks (library built with -DANISTAR_BENCH)
#   make demo       run the main job on a built-in example and write its output
#   make install    PREFIX, DESTDIR, LIBDIR, INCLUDEDIR, BINDIR;  make uninstall
#   make clean
#
# Variants live in their own trees: build/ (default), build/asan/ (sanitize),
# build/bench/ (bench). Every variant is built by this same file with BUILD= set.

VERSION_MAJOR := $(shell sed -n 's/^\#define ANISTAR_VERSION_MAJOR \([0-9]*\)/\1/p' include/anistar.h)
VERSION_MINOR := $(shell sed -n 's/^\#define ANISTAR_VERSION_MINOR \([0-9]*\)/\1/p' include/anistar.h)
VERSION_PATCH := $(shell sed -n 's/^\#define ANISTAR_VERSION_PATCH \([0-9]*\)/\1/p' include/anistar.h)
VERSION := $(VERSION_MAJOR).$(VERSION_MINOR).$(VERSION_PATCH)
SONAME := libanistar.so.$(VERSION_MAJOR)

PREFIX ?= /usr/local
DESTDIR ?=
LIBDIR ?= $(PREFIX)/lib
INCLUDEDIR ?= $(PREFIX)/include
BINDIR ?= $(PREFIX)/bin
PKGCONFIGDIR ?= $(LIBDIR)/pkgconfig

BUILD ?= build
CC ?= cc
AR ?= ar
CFLAGS ?= -O2 -g
WERROR ?= -Werror
# Flags that every variant needs: strict C11, strict IEEE arithmetic (the exact predicates
# depend on it: no fast-math style flags, ever), hidden internal symbols.
BASE_CFLAGS := -std=c11 -Wall -Wextra -Wpedantic $(WERROR) -ffp-contract=off \
               -fvisibility=hidden -fPIC -fno-strict-aliasing
VARIANT_CFLAGS ?=
ALL_CFLAGS = $(BASE_CFLAGS) $(CFLAGS) $(VARIANT_CFLAGS)
ALL_CPPFLAGS = -Iinclude -Ilib -D_POSIX_C_SOURCE=200809L $(CPPFLAGS)
VARIANT_LDFLAGS ?=
LDLIBS_LIB := -lm -lpthread

LIB_SRC := $(sort $(wildcard lib/*.c lib/*/*.c))
LIB_OBJ := $(LIB_SRC:%.c=$(BUILD)/obj/%.o)
TOOL_SRC := examples/anistar.c
EXAMPLE_SRC := $(filter-out $(TOOL_SRC),$(sort $(wildcard examples/*.c)))
EXAMPLES := $(EXAMPLE_SRC:examples/%.c=$(BUILD)/examples/%)
TEST_SRC := $(sort $(wildcard test/test_*.c))
TESTS := $(TEST_SRC:test/%.c=$(BUILD)/test/%)
TEST_COMMON_SRC := $(sort $(wildcard test/common/*.c))
TEST_COMMON_OBJ := $(TEST_COMMON_SRC:%.c=$(BUILD)/obj/%.o)
BENCH_SRC := $(sort $(wildcard bench/bench_*.c))
BENCHES := $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
BENCH_COMMON_SRC := $(sort $(wildcard bench/common/*.c))
BENCH_COMMON_OBJ := $(BENCH_COMMON_SRC:%.c=$(BUILD)/obj/%.o)

STATIC_LIB := $(BUILD)/libanistar.a
SHARED_REAL := $(BUILD)/libanistar.so.$(VERSION)
SHARED_LIBS := $(SHARED_REAL) $(BUILD)/$(SONAME) $(BUILD)/libanistar.so
TOOL := $(BUILD)/anistar

# Test and bench programs use GMP (exact oracle) and cmocka (runner); the library never.
TEST_LDLIBS := -lcmocka -lgmp -lm -lpthread

.PHONY: all lib tools examples tests benches check check-deps check-run sanitize tsan bench \
        demo install uninstall clean
.DEFAULT_GOAL := all
# Keep object files of chained rules (examples, tests, benches): no rebuild on every make.
.SECONDARY:

all: lib tools examples

lib: $(STATIC_LIB) $(SHARED_LIBS)
tools: $(TOOL)
examples: $(EXAMPLES)
tests: $(TESTS)
benches: $(BENCHES)

$(BUILD)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CPPFLAGS) $(ALL_CFLAGS) -MMD -MP -c $< -o $@

$(STATIC_LIB): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@
	$(AR) rcs $@ $(LIB_OBJ)

$(SHARED_REAL): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	$(CC) -shared -Wl,-soname,$(SONAME) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) \
	    -o $@ $(LIB_OBJ) $(LDLIBS_LIB)

$(BUILD)/$(SONAME): $(SHARED_REAL)
	ln -sf $(notdir $<) $@

$(BUILD)/libanistar.so: $(BUILD)/$(SONAME)
	ln -sf $(notdir $<) $@

$(TOOL): $(BUILD)/obj/examples/anistar.o $(STATIC_LIB)
	$(CC) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) -o $@ $< $(STATIC_LIB) $(LDLIBS_LIB)

$(BUILD)/examples/%: $(BUILD)/obj/examples/%.o $(STATIC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) -o $@ $< $(STATIC_LIB) $(LDLIBS_LIB)

# Tests see the internal headers and link the static library (all symbols visible).
$(BUILD)/test/%: $(BUILD)/obj/test/%.o $(TEST_COMMON_OBJ) $(STATIC_LIB) | $(SHARED_LIBS) $(TOOL) $(EXAMPLES)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) -o $@ $< $(TEST_COMMON_OBJ) \
	    $(STATIC_LIB) $(TEST_LDLIBS)

$(BUILD)/bench/%: $(BUILD)/obj/bench/%.o $(BENCH_COMMON_OBJ) $(STATIC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) -o $@ $< $(BENCH_COMMON_OBJ) \
	    $(STATIC_LIB) $(TEST_LDLIBS)

$(BUILD)/obj/bench/%.o: ALL_CPPFLAGS += -Ibench/common -Itest/common

# Tests find the shared library and the tool of their own variant through these.
$(BUILD)/obj/test/%.o: ALL_CPPFLAGS += -Itest/common -DAS_TEST_BUILD_DIR='"$(BUILD)"' -DAS_TEST_DATA_DIR='"test/data"'

# del3's debug mode (del3.h "Debug:"): test_del3_debug links a copy of lib/geom/del3.c built
# with -DAS_DEL3_DEBUG (validators after every insertion). That object defines every
# as_del3_* symbol, so the archive's own del3.o is never pulled into this program.
DEL3_DEBUG_OBJ := $(BUILD)/obj/test/del3_debug.o
$(DEL3_DEBUG_OBJ): lib/geom/del3.c
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CPPFLAGS) $(ALL_CFLAGS) -DAS_DEL3_DEBUG -MMD -MP -c $< -o $@
$(BUILD)/test/test_del3_debug: $(BUILD)/obj/test/test_del3_debug.o $(DEL3_DEBUG_OBJ) \
                               $(TEST_COMMON_OBJ) $(STATIC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) $(VARIANT_LDFLAGS) $(LDFLAGS) -o $@ $< $(DEL3_DEBUG_OBJ) \
	    $(TEST_COMMON_OBJ) $(STATIC_LIB) $(TEST_LDLIBS)
-include $(DEL3_DEBUG_OBJ:.o=.d)

# ---- check ----------------------------------------------------------------------------

check-deps:
	@sh test/deps.sh

check: check-deps
	@$(MAKE) --no-print-directory all tests
	@sh test/run.sh $(BUILD)

check-run: all tests
	@sh test/run.sh $(BUILD)

SAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
sanitize: check-deps
	@$(MAKE) --no-print-directory BUILD=build/asan CFLAGS="-O2 -g" \
	    VARIANT_CFLAGS="$(SAN_FLAGS)" VARIANT_LDFLAGS="$(SAN_FLAGS)" all tests
	@ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	    sh test/run.sh build/asan

# ThreadSanitizer on the threaded paths (issue 15): the thread-count test (three surfaces
# on 1, 2, 3 and 8 threads, two contexts at once), the partition simulation (its parts are
# threads meeting at barriers), the tool's suites (the CLI runs on every online core) and
# the out-of-memory sweep (a user allocator called from the pool's threads, every error
# path of a batch). About 12 minutes on 2 cores.
TSAN_FLAGS := -fsanitize=thread -fno-omit-frame-pointer
TSAN_TESTS := test_threads test_partition test_cli_mesh test_cli test_oom
tsan: check-deps
	@$(MAKE) --no-print-directory BUILD=build/tsan CFLAGS="-O2 -g" \
	    VARIANT_CFLAGS="$(TSAN_FLAGS)" VARIANT_LDFLAGS="$(TSAN_FLAGS)" all \
	    $(TSAN_TESTS:%=build/tsan/test/%)
	@TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" sh test/run.sh build/tsan

# ---- bench ----------------------------------------------------------------------------

bench: check-deps
	@$(MAKE) --no-print-directory BUILD=build/bench CFLAGS="-O2 -g" \
	    VARIANT_CFLAGS="-DANISTAR_BENCH" benches
	@sh bench/run.sh build/bench

# ---- demo -----------------------------------------------------------------------------

DEMO_OUT := build/demo
demo: all
	@mkdir -p $(DEMO_OUT)
	@sh examples/demo.sh $(BUILD) $(DEMO_OUT)

# ---- install --------------------------------------------------------------------------

# anistar.pc is written at install time from this install's own PREFIX, LIBDIR and
# INCLUDEDIR (never a file left in build/ by an earlier make with another PREFIX).
install: all
	install -d $(DESTDIR)$(INCLUDEDIR) $(DESTDIR)$(LIBDIR) $(DESTDIR)$(BINDIR) \
	    $(DESTDIR)$(PKGCONFIGDIR)
	install -m 644 include/anistar.h $(DESTDIR)$(INCLUDEDIR)/anistar.h
	install -m 644 $(STATIC_LIB) $(DESTDIR)$(LIBDIR)/libanistar.a
	install -m 755 $(SHARED_REAL) $(DESTDIR)$(LIBDIR)/libanistar.so.$(VERSION)
	ln -sf libanistar.so.$(VERSION) $(DESTDIR)$(LIBDIR)/$(SONAME)
	ln -sf $(SONAME) $(DESTDIR)$(LIBDIR)/libanistar.so
	printf '%s\n' 'prefix=$(PREFIX)' 'libdir=$(LIBDIR)' 'includedir=$(INCLUDEDIR)' '' \
	    'Name: anistar' 'Description: anisotropic Delaunay meshes of surfaces' \
	    'Version: $(VERSION)' 'Libs: -L$${libdir} -lanistar' 'Libs.private: -lm -lpthread' \
	    'Cflags: -I$${includedir}' > $(DESTDIR)$(PKGCONFIGDIR)/anistar.pc
	chmod 644 $(DESTDIR)$(PKGCONFIGDIR)/anistar.pc
	install -m 755 $(TOOL) $(DESTDIR)$(BINDIR)/anistar

uninstall:
	rm -f $(DESTDIR)$(INCLUDEDIR)/anistar.h $(DESTDIR)$(LIBDIR)/libanistar.a \
	    $(DESTDIR)$(LIBDIR)/libanistar.so.$(VERSION) $(DESTDIR)$(LIBDIR)/$(SONAME) \
	    $(DESTDIR)$(LIBDIR)/libanistar.so $(DESTDIR)$(PKGCONFIGDIR)/anistar.pc \
	    $(DESTDIR)$(BINDIR)/anistar

clean:
	rm -rf build

-include $(LIB_OBJ:.o=.d) $(TEST_SRC:%.c=$(BUILD)/obj/%.d) $(TEST_COMMON_OBJ:.o=.d) \
         $(BENCH_SRC:%.c=$(BUILD)/obj/%.d) $(BENCH_COMMON_OBJ:.o=.d) \
         $(EXAMPLE_SRC:%.c=$(BUILD)/obj/%.d) $(BUILD)/obj/examples/anistar.d
