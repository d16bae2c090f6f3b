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
# The wire's float steps (Draco's dequantization, normal codes) must round the
# same on every build: no fused multiply-add (clang contracts by default).
FP       := -ffp-contract=off
CFLAGS   += -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(OPT) $(FP) $(WARN)
# OpenMesh's headers are not -Wextra clean and trip -Wmaybe-uninitialized when
# inlined; the shims stay -Wall -Werror otherwise.
# NDEBUG: OpenMesh asserts on property type names with string compares in
# every point() access, a fifth of the decimation time.
CXXFLAGS += -std=c++17 $(OPT) $(FP) -DNDEBUG -Wall -Werror -Wno-maybe-uninitialized

# The layers (docs/architecture.md): each folder is compiled with the include
# paths of what it may use, so an include the wrong way fails the build.
#   common/    the runtime every part shares (growth, LOD runtime, model file, ...)
#   protocol/  the wire, the stream's coding, stream files, WebSocket, Draco
#                                                               uses common
#   builder/   mesh in, model or stream file out (mts-build, mts-inspect)
#                                                     uses common, protocol
#   server/    mts-server                      uses common, protocol, builder
#   client/    mts-client, its renderer and window          uses common, protocol
#   stress/    mts-stress, many simulated clients  uses common, protocol, and
#              client/webfile.c (the stream-file conversation) for URLs
#   web/       the page's decoder (WebAssembly)     uses common, protocol, client
#   tests/, bench/: the public headers of every layer
INC_common   := -Icommon
INC_protocol := -Icommon -Iprotocol
INC_builder  := -Icommon -Iprotocol -Ibuilder
INC_server   := -Icommon -Iprotocol -Ibuilder -Iserver
INC_client   := -Icommon -Iprotocol -Iclient
INC_stress   := -Icommon -Iprotocol -Iclient -Istress
INC_web      := -Icommon -Iprotocol -Iclient -Iweb
INC_all      := -Icommon -Iprotocol -Ibuilder -Iserver -Iclient -Istress
LAYERS   := common protocol builder server client stress
# Draco, EGL, GLES, libpng, libcurl and X11 (mts-client --window) ship pkg-config
# files; OpenMesh and meshoptimizer do not. --as-needed keeps each program linked
# only to what it uses.
PKGS     := draco egl glesv2 libpng libcurl x11
# A missing development package is named, with the way to get it, before a
# compiler error about a header could be. Goals that run `deps` first (and
# `clean`) skip the check: their own sub-makes run it after deps.
ifeq ($(filter deps clean test bench demo demo-serve fuzz fuzz-long,$(MAKECMDGOALS)),)
MISSING_PKGS := $(shell command -v pkg-config >/dev/null || echo pkg-config; \
                  for p in $(PKGS); do pkg-config --exists $$p 2>/dev/null || echo $$p; done; \
                  [ -f /usr/include/OpenMesh/Core/Mesh/TriMeshT.hh ] || echo OpenMesh; \
                  [ -f /usr/include/tiny_gltf.h ] || echo tinygltf)
ifneq ($(strip $(MISSING_PKGS)),)
$(error missing: $(strip $(MISSING_PKGS)). Run `make deps` (scripts/deps.sh installs the Debian packages: libdraco-dev, libegl-dev libgles-dev, libpng-dev, libcurl4-openssl-dev, libx11-dev, libopenmesh-dev, libtinygltf-dev, pkg-config))
endif
endif
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS := $(shell pkg-config --libs $(PKGS) 2>/dev/null)
CFLAGS   += $(filter-out -I/usr/include/draco%,$(PKG_CFLAGS))
LDFLAGS  += $(filter -fsanitize=%,$(OPT)) -pthread -Wl,--as-needed
# -ltinygltf before $(PKG_LIBS): Debian's libdraco exports the symbols of
# its own bundled (older) tinygltf, and the first library that defines a
# symbol wins; linked after draco, the glTF reader (gltf_read.cpp and
# gltf_draco.cpp) would call draco's copy with this header's layouts and
# corrupt memory.
LDLIBS   += -ltinygltf $(PKG_LIBS) -lOpenMeshTools -lOpenMeshCore -lm

# Library modules; a file named mts_*.c holds a program's main().
LIB_C    := $(filter-out $(foreach l,$(LAYERS),$(l)/mts_%.c),$(wildcard $(foreach l,$(LAYERS),$(l)/*.c)))
LIB_CXX  := $(wildcard $(foreach l,$(LAYERS),$(l)/*.cpp))
LIB_OBJ  := $(patsubst %.c,$(BUILD)/obj/%.o,$(LIB_C)) $(patsubst %.cpp,$(BUILD)/obj/%.o,$(LIB_CXX))
LIB      := $(BUILD)/libmts.a

PROGRAMS := $(BUILD)/bin/mts-build $(BUILD)/bin/mts-inspect $(BUILD)/bin/mts-server \
            $(BUILD)/bin/mts-client $(BUILD)/bin/mts-stress
TESTS    := $(patsubst tests/%.c,$(BUILD)/tests/%,$(wildcard tests/test_*.c))
BENCH    := $(BUILD)/bin/mts-bench

.PHONY: all programs tests test test-release test-asan bench soak demo demo-serve demo-web deps install clean
# keep object files of programs and tests between builds
.SECONDARY:
all: programs tests

programs: $(PROGRAMS)
tests: $(TESTS)

# each object gets its layer's include paths
$(foreach l,$(LAYERS),$(eval $(BUILD)/obj/$(l)/%.o: LAYER_INC := $(INC_$(l))))
$(BUILD)/obj/tests/%.o: LAYER_INC := $(INC_all)
$(BUILD)/obj/bench/%.o: LAYER_INC := $(INC_all)

$(BUILD)/obj/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(LAYER_INC) -MMD -MP -c $< -o $@

$(BUILD)/obj/%.o: %.cpp Makefile
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) $(LAYER_INC) -MMD -MP -c $< -o $@

$(LIB): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@
	ar rcs $@ $^

$(BUILD)/bin/mts-build: $(BUILD)/obj/builder/mts_build.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-inspect: $(BUILD)/obj/builder/mts_inspect.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-server: $(BUILD)/obj/server/mts_server.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

# mts_client_window.c is mts-client's window run, beside its main()
$(BUILD)/bin/mts-client: $(BUILD)/obj/client/mts_client.o $(BUILD)/obj/client/mts_client_window.o \
		$(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-stress: $(BUILD)/obj/stress/mts_stress.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/tests/%: $(BUILD)/obj/tests/%.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BENCH): $(BUILD)/obj/bench/mts_bench.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -lmeshoptimizer -o $@

$(BUILD)/bin/mts-bench-stream: $(BUILD)/obj/bench/mts_bench_stream.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -lmeshoptimizer -o $@

$(BUILD)/bin/mts-bench-apply: $(BUILD)/obj/bench/mts_bench_apply.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

# where the splits form's apply time goes, by key interval (docs/threads.md)
$(BUILD)/bin/mts-bench-phases: $(BUILD)/obj/bench/mts_bench_phases.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

# the browser client's figures (bench/web.sh): drives Chromium with tests/cdp.h
$(BUILD)/bin/mts-bench-web: $(BUILD)/obj/bench/mts_bench_web.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

$(BUILD)/bin/mts-bench-walk: $(BUILD)/obj/bench/mts_bench_walk.o $(LIB)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@

deps:
	@scripts/deps.sh

# The README's test command. Both builds run every test program; the last
# line is the total ("N passed, N failed, N skipped").
test: deps
	@$(MAKE) --no-print-directory all
	@$(MAKE) --no-print-directory SAN=1 all
	@$(MAKE) --no-print-directory web-if-emcc
	@tests/run.sh build build/asan

# the browser client for tests/test_web.c, where emscripten is (it skips,
# saying so, where build/web is missing)
web-if-emcc:
	@if command -v $(EMCC) >/dev/null; then $(MAKE) --no-print-directory web; \
	else echo "make test: no $(EMCC) (scripts/deps.sh installs emscripten): the browser client is not built"; fi

test-release: all
	@tests/run.sh build

test-asan:
	@$(MAKE) --no-print-directory SAN=1 all
	@tests/run.sh build/asan

# A long run of good and hostile clients against one server (not part of
# make test): scripts/soak.py, figures in bench/out/soak.json.
SOAK_SECONDS ?= 1800
soak: all
	@mkdir -p bench/out
	@scripts/soak.py --seconds $(SOAK_SECONDS) --json bench/out/soak.json

bench: deps
	@$(MAKE) --no-print-directory programs $(BENCH) $(BUILD)/bin/mts-bench-stream $(BUILD)/bin/mts-bench-walk \
		$(BUILD)/bin/mts-bench-apply $(BUILD)/bin/mts-bench-web
	@$(MAKE) --no-print-directory web-if-emcc
	@bench/run.sh

demo: deps
	@$(MAKE) --no-print-directory programs
	@scripts/demo.sh

# the demo, then the server stays up for `mts-client cow --window` (Ctrl-C ends it)
demo-serve: deps
	@$(MAKE) --no-print-directory programs
	@MTS_DEMO_SERVE=1 scripts/demo.sh

# the browser client: the page and the models served on 127.0.0.1:7448 (Ctrl-C ends it)
demo-web: deps
	@$(MAKE) --no-print-directory programs web
	@scripts/demo-web.sh

# docker/'s files run under podman (scripts/deploy-test.sh): base images by
# debootstrap where absent, both images built, compose up, 1,000 clients
# through the lb, a restarted replica, a stop with streams in flight, k8s.yaml
# played; a table, non-zero on any failure (docker/README.md). Not part of
# `make test`; CI runs it after.
.PHONY: deploy-test
deploy-test: deps
	@$(MAKE) --no-print-directory programs
	@MTS_DEPLOY_BIN=$(BUILD)/bin scripts/deploy-test.sh

install: programs
	install -d $(DESTDIR)$(PREFIX)/bin
	install -m 755 $(PROGRAMS) $(DESTDIR)$(PREFIX)/bin/

clean:
	rm -rf build bench/out

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)

# ---- the browser client ----
# `make web` builds the page into build/web/: the stream decoder (common/,
# protocol/) and web/mts_web.c compiled with emscripten, Draco's own
# WebAssembly decoder (npm draco3d, scripts/web-deps.sh), and web/'s page.
# build/web/ holds the page's files and nothing else (objects and the
# archive go to build/web-obj/), so a web server may hand out all of it:
# web/nginx.conf serves it and proxies the stream (make demo-web).
EMCC     ?= emcc
EMAR     ?= emar
WEB_ENV  := NODE_PATH=/usr/share/nodejs
WEB_DIR  := build/web
WEB_OBJ_DIR := build/web-obj
WEB_CFLAGS := -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -O2 $(FP) $(WARN) $(INC_web)
# the runtime and the protocol, and the client's GL-free camera, geomorphs
# and follower (client/follow.c: the level, slots and packing the page draws)
# (the command-line helpers, the sockets and libcurl are the programs')
WEB_LIB_OBJ := $(patsubst %.c,$(WEB_OBJ_DIR)/%.o,$(filter-out common/cli.c common/net.c common/fetch.c common/http.c common/tls.c,\
               $(wildcard common/*.c protocol/*.c)) client/camera.c client/morph.c client/follow.c)
WEB_OBJ  := $(WEB_OBJ_DIR)/web/mts_web.o $(WEB_OBJ_DIR)/web/draco_web.o
WEB_LINK := -sMODULARIZE=1 -sEXPORT_NAME=createMtsWeb -sALLOW_MEMORY_GROWTH=1 \
            -sENVIRONMENT=web,node -sEXPORTED_FUNCTIONS=_malloc,_free \
            -sEXPORTED_RUNTIME_METHODS=UTF8ToString,stringToUTF8,lengthBytesUTF8
WEB_PAGE := $(patsubst web/%,$(WEB_DIR)/%,$(wildcard web/*.html web/*.js web/*.css))

# The threaded variant beside it (mts_web_mt.js, .wasm, .worker.js): the
# same sources built with -pthread (shared memory, atomics), the decoder's
# pool thread a Web Worker made ready before the module resolves
# (PTHREAD_POOL_SIZE), so pthread_create never waits for the browser; with
# no worker free it fails (POOL_SIZE_STRICT=2) and the decoder runs on one
# thread. A page may load it only where it is cross-origin isolated
# (SharedArrayBuffer): web/mts.js picks.
WEB_MT_OBJ_DIR := build/web-mt-obj
WEB_MT_LIB_OBJ := $(patsubst $(WEB_OBJ_DIR)/%,$(WEB_MT_OBJ_DIR)/%,$(WEB_LIB_OBJ))
WEB_MT_OBJ := $(patsubst $(WEB_OBJ_DIR)/%,$(WEB_MT_OBJ_DIR)/%,$(WEB_OBJ))
WEB_MT_LINK := $(filter-out -sEXPORT_NAME=% -sENVIRONMENT=%,$(WEB_LINK)) -pthread \
            -sEXPORT_NAME=createMtsWebMt -sENVIRONMENT=web,worker,node \
            -sPTHREAD_POOL_SIZE=1 -sPTHREAD_POOL_SIZE_STRICT=2 -Wno-pthreads-mem-growth

.PHONY: web web-if-emcc
web: $(WEB_DIR)/mts_web.js $(WEB_DIR)/mts_web_mt.js $(WEB_PAGE) $(WEB_DIR)/draco_decoder_nodejs.js

$(WEB_OBJ_DIR)/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(WEB_ENV) $(EMCC) $(WEB_CFLAGS) -MMD -MP -c $< -o $@

$(WEB_OBJ_DIR)/libmts_web.a: $(WEB_LIB_OBJ)
	@rm -f $@
	$(WEB_ENV) $(EMAR) rcs $@ $^

$(WEB_DIR)/mts_web.js: $(WEB_OBJ) $(WEB_OBJ_DIR)/libmts_web.a
	@mkdir -p $(dir $@)
	$(WEB_ENV) $(EMCC) -O2 $(WEB_LINK) $^ -o $@

$(WEB_MT_OBJ_DIR)/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(WEB_ENV) $(EMCC) $(WEB_CFLAGS) -pthread -MMD -MP -c $< -o $@

$(WEB_MT_OBJ_DIR)/libmts_web.a: $(WEB_MT_LIB_OBJ)
	@rm -f $@
	$(WEB_ENV) $(EMAR) rcs $@ $^

$(WEB_DIR)/mts_web_mt.js: $(WEB_MT_OBJ) $(WEB_MT_OBJ_DIR)/libmts_web.a
	@mkdir -p $(dir $@)
	$(WEB_ENV) $(EMCC) -O2 $(WEB_MT_LINK) $^ -o $@

$(WEB_DIR)/%: web/%
	@mkdir -p $(dir $@)
	cp $< $@

$(WEB_DIR)/draco_decoder_nodejs.js:
	@scripts/web-deps.sh $(WEB_DIR)

-include $(shell find $(WEB_OBJ_DIR) $(WEB_MT_OBJ_DIR) -name '*.d' 2>/dev/null)

# ---- fuzzing ----
# `make fuzz` builds the libFuzzer targets of tests/fuzz/ with clang (ASan +
# UBSan + coverage) into build/fuzz/, writes their seed corpora from real
# streams and files (tests/fuzz/fuzz_seeds.h: a small torus and
# tests/data/cow.off), and runs each target (scripts/fuzz.sh) for FUZZ_SECONDS,
# then on while it has run fewer than FUZZ_MIN_RUNS executions, up to
# FUZZ_MAX_SECONDS in all (the stream decoder derives every record, about 3k
# executions a second under the sanitizers: a million takes some 6 minutes),
# on build/fuzz/corpus/<target> (kept between runs), the seeds and
# the kept regression inputs (tests/fuzz/regressions/<target>). It prints the
# executions per target and fails when a target found a crash, a hang or an
# out-of-memory; the input is then in build/fuzz/artifacts/<target>/:
# reproduce with `build/fuzz/bin/fuzz_<target> FILE`. The ordinary builds run
# the same entry code on the seeds and regressions (tests/test_fuzz_regressions.c).
FUZZ_SECONDS  ?= 60
FUZZ_MIN_RUNS ?= 1000000
FUZZ_MAX_SECONDS ?= 480
FUZZ_CC       ?= clang
FUZZ_CXX      ?= clang++
FUZZ_DIR      := build/fuzz
# target:-max_len. A server reads a first frame of at most 512 bytes; the
# other targets' largest seeds are 1 to 9 KiB (cow's streams, the torus's
# model file and stream files, a textured box GLB), and room to grow a few
# times that.
FUZZ_TARGETS  := stream_client:32768 request:1024 modelfile:16384 draco:8192 ws:8192 \
                 stream_file:16384 gltf:16384
FUZZ_NAMES    := $(foreach t,$(FUZZ_TARGETS),$(firstword $(subst :, ,$(t))))
FUZZ_SAN      := -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZ_OPT      := -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer-no-link $(FUZZ_SAN)
FUZZ_CFLAGS   := -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(FUZZ_OPT) $(FP) $(WARN) \
                 $(filter-out -I/usr/include/draco%,$(PKG_CFLAGS))
FUZZ_CXXFLAGS := -std=c++17 $(FUZZ_OPT) $(FP) -DNDEBUG -Wall -Werror
# the library modules the targets reach: common/, protocol/, and builder/
# (the seeds are built from meshes)
FUZZ_LAYERS   := common protocol builder
FUZZ_LIB_OBJ  := $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(filter-out common/cli.c common/fetch.c common/http.c common/tls.c \
                 $(foreach l,$(FUZZ_LAYERS),$(l)/mts_%.c),$(wildcard $(foreach l,$(FUZZ_LAYERS),$(l)/*.c)))) \
                 $(patsubst %.cpp,$(FUZZ_DIR)/obj/%.o,$(wildcard $(foreach l,$(FUZZ_LAYERS),$(l)/*.cpp)))
$(foreach l,$(FUZZ_LAYERS),$(eval $(FUZZ_DIR)/obj/$(l)/%.o: FUZZ_INC := $(INC_$(l))))
$(FUZZ_DIR)/obj/tests/%.o: FUZZ_INC := $(INC_all)
FUZZ_BINS     := $(patsubst %,$(FUZZ_DIR)/bin/fuzz_%,$(FUZZ_NAMES))
FUZZ_LDLIBS   := -Wl,--as-needed -ltinygltf $(PKG_LIBS) -lOpenMeshTools -lOpenMeshCore -lm

.PHONY: fuzz fuzz-long fuzz-build

fuzz: deps
	@$(MAKE) --no-print-directory fuzz-build
	@rm -rf $(FUZZ_DIR)/seeds
	@$(FUZZ_DIR)/bin/fuzz-seeds $(FUZZ_DIR)/seeds tests/data/cow.off
	@scripts/fuzz.sh $(FUZZ_DIR) $(FUZZ_SECONDS) $(FUZZ_MIN_RUNS) $(FUZZ_MAX_SECONDS) $(FUZZ_TARGETS)

# Fuzzing that reaches depth: each target to FUZZ_LONG_RUNS
# executions or FUZZ_LONG_SECONDS, whichever comes first, FUZZ_JOBS targets
# at once (one a core), the slowest first; what they grew is merged into
# tests/fuzz/corpus/<target> (only inputs that add coverage), which every
# later `make fuzz` starts from. Figures in bench/fuzz-long.json.
FUZZ_LONG_RUNS    ?= 10000000
FUZZ_LONG_SECONDS ?= 3600
FUZZ_JOBS         ?= $(shell nproc 2>/dev/null || echo 1)
fuzz-long: deps
	@$(MAKE) --no-print-directory fuzz-build
	@rm -rf $(FUZZ_DIR)/seeds
	@$(FUZZ_DIR)/bin/fuzz-seeds $(FUZZ_DIR)/seeds tests/data/cow.off
	@scripts/fuzz.sh --jobs $(FUZZ_JOBS) --keep --json bench/fuzz-long.json \
		$(FUZZ_DIR) 1 $(FUZZ_LONG_RUNS) $(FUZZ_LONG_SECONDS) $(FUZZ_TARGETS)

fuzz-build: $(FUZZ_BINS) $(FUZZ_DIR)/bin/fuzz-seeds

$(FUZZ_DIR)/obj/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) $(FUZZ_INC) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/obj/%.o: %.cpp Makefile
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) $(FUZZ_CXXFLAGS) $(FUZZ_INC) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/bin/fuzz_%: $(FUZZ_DIR)/obj/tests/fuzz/fuzz_%.o $(FUZZ_LIB_OBJ)
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) -fsanitize=fuzzer $(FUZZ_SAN) $^ $(FUZZ_LDLIBS) -o $@

# the seed writer: the same instrumented library, a main() of its own
$(FUZZ_DIR)/bin/fuzz-seeds: $(FUZZ_DIR)/obj/tests/fuzz/fuzz_seeds.o $(FUZZ_LIB_OBJ)
	@mkdir -p $(dir $@)
	$(FUZZ_CXX) $(FUZZ_SAN) $^ $(FUZZ_LDLIBS) -o $@

-include $(shell find $(FUZZ_DIR)/obj -name '*.d' 2>/dev/null)
