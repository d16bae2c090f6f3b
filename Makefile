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
LDFLAGS  += $(filter -fsanitize=%,$(OPT)) -pthread -Wl,--as-needed
LDLIBS   += $(PKG_LIBS) -lOpenMeshTools -lOpenMeshCore -lm

# Library modules; a file named mts_*.c holds a program's main().
LIB_C    := $(filter-out tools/mts_%.c server/mts_%.c client/mts_%.c,$(wildcard common/*.c protocol/*.c client/*.c server/*.c))
LIB_CXX  := $(wildcard common/*.cpp protocol/*.cpp)
LIB_OBJ  := $(patsubst %.c,$(BUILD)/obj/%.o,$(LIB_C)) $(patsubst %.cpp,$(BUILD)/obj/%.o,$(LIB_CXX))
LIB      := $(BUILD)/libmts.a

CLI_OBJ  := $(BUILD)/obj/tools/cli.o
PROGRAMS := $(BUILD)/bin/mts-build $(BUILD)/bin/mts-inspect $(BUILD)/bin/mts-server \
            $(BUILD)/bin/mts-client $(BUILD)/bin/mts-stress
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

$(BUILD)/bin/mts-stress: $(BUILD)/obj/client/mts_stress.o $(CLI_OBJ) $(LIB)
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

# ---- fuzzing (issue 4, "Hostile input") ----
# `make fuzz` builds the libFuzzer targets of tests/fuzz/ with clang (ASan +
# UBSan + coverage) into build/fuzz/, writes their seed corpora from real
# streams and files (tests/fuzz/fuzz_seeds.h, from a small torus and
# tests/data/cow.off), and runs each target for FUZZ_SECONDS on its corpus
# (build/fuzz/corpus/<target>, kept between runs) plus the seeds and the kept
# regression inputs (tests/fuzz/regressions/<target>). It prints executions per
# target and fails when a target found a crash, a hang (-timeout) or an
# out-of-memory (-rss_limit_mb, -malloc_limit_mb): the input is then in
# build/fuzz/artifacts/<target>/, reproduce it with
# `build/fuzz/bin/fuzz_<target> FILE`. tests/test_fuzz_regressions.c runs the
# same entry code in the ordinary builds.
FUZZ_SECONDS ?= 60
FUZZ_CC      ?= clang
FUZZ_CXX     ?= clang++
FUZZ_DIR     := build/fuzz
FUZZ_TARGETS := stream_client request modelfile draco
# -max_len per target: a server frame is at most 512 bytes; cow's seeds are
# the largest streams, files and Draco meshes (tens of KiB)
FUZZ_MAX_LEN_stream_client := 65536
FUZZ_MAX_LEN_request       := 1024
FUZZ_MAX_LEN_modelfile     := 65536
FUZZ_MAX_LEN_draco         := 32768
FUZZ_SAN     := -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZ_OPT     := -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer-no-link $(FUZZ_SAN)
FUZZ_CFLAGS  := -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(FUZZ_OPT) $(WARN) \
                -Icommon -Iprotocol $(filter-out -I/usr/include/draco%,$(PKG_CFLAGS))
FUZZ_CXXFLAGS := -std=c++17 $(FUZZ_OPT) -DNDEBUG -Wall -Werror -Icommon -Iprotocol
# the library modules the targets reach: common/ and protocol/
FUZZ_LIB_OBJ := $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(wildcard common/*.c protocol/*.c)) \
                $(patsubst %.cpp,$(FUZZ_DIR)/obj/%.o,$(wildcard common/*.cpp protocol/*.cpp))
FUZZ_BINS    := $(patsubst %,$(FUZZ_DIR)/bin/fuzz_%,$(FUZZ_TARGETS))
FUZZ_LDLIBS  := -Wl,--as-needed $(PKG_LIBS) -lOpenMeshTools -lOpenMeshCore -lm

.PHONY: fuzz fuzz-build

fuzz-build: $(FUZZ_BINS) $(FUZZ_DIR)/bin/fuzz-seeds

$(FUZZ_DIR)/obj/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/obj/%.o: %.cpp Makefile
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) $(FUZZ_CXXFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/bin/fuzz_%: $(FUZZ_DIR)/obj/tests/fuzz/fuzz_%.o $(FUZZ_LIB_OBJ)
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) -fsanitize=fuzzer $(FUZZ_SAN) $^ $(FUZZ_LDLIBS) -o $@

# the seed writer: the same instrumented library, a main() of its own
$(FUZZ_DIR)/bin/fuzz-seeds: $(FUZZ_DIR)/obj/tests/fuzz/fuzz_seeds.o $(FUZZ_LIB_OBJ)
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) $(FUZZ_SAN) $^ $(FUZZ_LDLIBS) -o $@

fuzz: fuzz-build
	@rm -rf $(FUZZ_DIR)/seeds
	@$(FUZZ_DIR)/bin/fuzz-seeds $(FUZZ_DIR)/seeds tests/data/cow.off
	@mkdir -p $(FUZZ_DIR)/logs; failed=""; summary=""; \
	for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_DIR)/corpus/$$t $(FUZZ_DIR)/artifacts/$$t; \
	  dirs="$(FUZZ_DIR)/corpus/$$t $(FUZZ_DIR)/seeds/$$t"; \
	  [ -d tests/fuzz/regressions/$$t ] && dirs="$$dirs tests/fuzz/regressions/$$t"; \
	  echo "fuzz: $$t for $(FUZZ_SECONDS) s (log: $(FUZZ_DIR)/logs/$$t.log)"; \
	  if $(FUZZ_DIR)/bin/fuzz_$$t -max_total_time=$(FUZZ_SECONDS) \
	       -max_len=$(FUZZ_MAX_LEN_$$t) -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
	       -print_final_stats=1 -artifact_prefix=$(FUZZ_DIR)/artifacts/$$t/ \
	       $$dirs > $(FUZZ_DIR)/logs/$$t.log 2>&1; then result=ok; \
	  else result="FAILED"; failed="$$failed $$t"; tail -n 40 $(FUZZ_DIR)/logs/$$t.log; fi; \
	  execs=$$(sed -n 's/^stat::number_of_executed_units: *//p' $(FUZZ_DIR)/logs/$$t.log); \
	  rate=$$(sed -n 's/^stat::average_exec_per_sec: *//p' $(FUZZ_DIR)/logs/$$t.log); \
	  summary="$$summary$$(printf '%-14s %12s executions %8s/s  %s' $$t "$${execs:-?}" "$${rate:-?}" $$result)\n"; \
	done; \
	printf "fuzz: %s s per target\n$$summary" $(FUZZ_SECONDS); \
	if [ -n "$$failed" ]; then \
	  echo "fuzz: failed:$$failed (inputs in $(FUZZ_DIR)/artifacts/)"; exit 1; fi

-include $(shell find $(FUZZ_DIR)/obj -name '*.d' 2>/dev/null)
