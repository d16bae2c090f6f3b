# mtstream build. `make` builds the library, programs and tests into build/;
# `make SAN=1` builds the same with AddressSanitizer + UBSan into build/asan/.
# `make test` runs `make deps`, then the tests in both builds.

PREFIX  ?= /usr/local
DESTDIR ?=

CC  ?= cc
CXX ?= c++

ifeq ($(SAN),1)
BUILD    ?= build/asan
OPT      := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
else
BUILD    ?= build
OPT      := -O2 -g
endif

WARN     := -Wall -Wextra -Werror
CFLAGS   += -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(OPT) $(WARN) -Icommon -Iprotocol -Iclient -Iserver -Itools
# OpenMesh's headers are not -Wextra clean and trip -Wmaybe-uninitialized when
# inlined; the shims stay -Wall -Werror otherwise.
# NDEBUG: OpenMesh asserts on property type names with string compares in
# every point() access, a fifth of the decimation time.
CXXFLAGS += -std=c++17 $(OPT) -DNDEBUG -Wall -Werror -Wno-maybe-uninitialized -Icommon -Iprotocol
# Draco, EGL, GLES, libpng and libcurl ship pkg-config files; OpenMesh and meshoptimizer
# do not. --as-needed keeps each program linked only to what it uses.
PKGS     := draco egl glesv2 libpng libcurl
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS := $(shell pkg-config --libs $(PKGS) 2>/dev/null)
CFLAGS   += $(filter-out -I/usr/include/draco%,$(PKG_CFLAGS))
LDFLAGS  += $(filter -fsanitize=%,$(OPT)) -Wl,--as-needed
LDLIBS   += $(PKG_LIBS) -lOpenMeshTools -lOpenMeshCore -lm

# Library modules; a file named mts_*.c holds a program's main().
LIB_C    := $(filter-out tools/mts_%.c server/mts_%.c client/mts_%.c,$(wildcard common/*.c protocol/*.c client/*.c server/*.c))
LIB_CXX  := $(wildcard common/*.cpp protocol/*.cpp)
LIB_OBJ  := $(patsubst %.c,$(BUILD)/obj/%.o,$(LIB_C)) $(patsubst %.cpp,$(BUILD)/obj/%.o,$(LIB_CXX))
LIB      := $(BUILD)/libmts.a

CLI_OBJ  := $(BUILD)/obj/tools/cli.o
PROGRAMS := $(BUILD)/bin/mts-build $(BUILD)/bin/mts-inspect $(BUILD)/bin/mts-server \
            $(BUILD)/bin/mts-client
TESTS    := $(patsubst tests/%.c,$(BUILD)/tests/%,$(wildcard tests/test_*.c))
BENCH    := $(BUILD)/bin/mts-bench

.PHONY: all programs tests test test-release test-asan bench demo deps install clean
# keep object files of programs and tests between builds
.SECONDARY:
all: programs tests

programs: $(PROGRAMS)
tests: $(TESTS)

$(BUILD)/obj/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/obj/%.o: %.cpp Makefile
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) -MMD -MP -c $< -o $@

$(LIB): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@
	ar rcs $@ $^

$(BUILD)/bin/mts-%: $(BUILD)/obj/tools/mts_%.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-server: $(BUILD)/obj/server/mts_server.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-client: $(BUILD)/obj/client/mts_client.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/tests/%: $(BUILD)/obj/tests/%.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BENCH): $(BUILD)/obj/bench/mts_bench.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -lmeshoptimizer -o $@

$(BUILD)/bin/mts-bench-stream: $(BUILD)/obj/bench/mts_bench_stream.o $(CLI_OBJ) $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -lmeshoptimizer -o $@

deps:
	@scripts/deps.sh

# The README's test command. Both builds run every test program; the last
# line is the total ("N passed, N failed, N skipped").
test: deps
	@$(MAKE) --no-print-directory all
	@$(MAKE) --no-print-directory SAN=1 all
	@tests/run.sh build build/asan

test-release: all
	@tests/run.sh build

test-asan:
	@$(MAKE) --no-print-directory SAN=1 all
	@tests/run.sh build/asan

bench: deps
	@$(MAKE) --no-print-directory programs $(BENCH) $(BUILD)/bin/mts-bench-stream
	@bench/run.sh

demo: deps
	@$(MAKE) --no-print-directory programs
	@scripts/demo.sh

install: programs
	install -d $(DESTDIR)$(PREFIX)/bin
	install -m 755 $(PROGRAMS) $(DESTDIR)$(PREFIX)/bin/

clean:
	rm -rf build bench/out

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)
