# specklab - hand-written build.  `make` builds everything into bin/ and
# build/; `make test` installs missing Debian packages, builds and runs every
# test CI runs.  Other tiers: quick, asan, bench, fuzz, demo.
#
# Object files go under $(BUILD) so that `make asan` (BUILD=build-asan) never
# mixes sanitized and plain objects.

BUILD  ?= build
BIN    ?= bin
CC     ?= cc
PKG    ?= pkg-config

# Dependencies, each through pkg-config.  recon/ sees only RECON_PKGS.
RECON_PKGS := fftw3f fftw3 cfitsio libpng
CLI_PKGS   := glib-2.0 json-glib-1.0

WARN   := -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes
ifeq ($(CI),true)
WARN   += -Werror
endif
ifneq ($(WERROR),)
WARN   += -Werror
endif
OPT    ?= -O2 -g
SAN    ?=
CFLAGS_ALL := -std=c11 -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L $(OPT) \
              $(WARN) $(SAN) -MMD -MP
LDFLAGS_ALL := $(SAN)

recon_cflags = $(shell $(PKG) --cflags $(RECON_PKGS) 2>/dev/null)
recon_libs   = $(shell $(PKG) --libs $(RECON_PKGS) 2>/dev/null) -lm
cli_cflags   = $(shell $(PKG) --cflags $(CLI_PKGS) 2>/dev/null)
cli_libs     = $(shell $(PKG) --libs $(CLI_PKGS) 2>/dev/null)

RECON_SRC := $(wildcard recon/*.c)
RECON_OBJ := $(RECON_SRC:%.c=$(BUILD)/%.o)
RECON_LIB := $(BUILD)/librecon.a

CLI_SRC   := $(wildcard cli/*.c)
CLI_OBJ   := $(CLI_SRC:%.c=$(BUILD)/%.o)

TEST_SRC  := $(wildcard tests/unit/test_*.c)
TEST_BIN  := $(TEST_SRC:tests/unit/%.c=$(BUILD)/tests/%)

PROGS := $(BIN)/specklab

.PHONY: all deps test quick asan bench fuzz demo clean
all: $(PROGS) $(TEST_BIN)

$(BUILD)/recon/%.o: recon/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) $(recon_cflags) -c $< -o $@

$(BUILD)/cli/%.o: cli/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon $(recon_cflags) $(cli_cflags) -c $< -o $@

$(RECON_LIB): $(RECON_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BIN)/specklab: $(CLI_OBJ) $(RECON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -o $@ $(CLI_OBJ) $(RECON_LIB) $(recon_libs) $(cli_libs)

$(BUILD)/tests/%: tests/unit/%.c $(RECON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Itests/unit $(recon_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(RECON_LIB) $(recon_libs)

# Install what pkg-config lacks (root) or say the exact apt-get line.
deps:
	@scripts/install-deps

# Everything CI runs.  The final line is "N passed, N failed".
test: deps
	@$(MAKE) --no-print-directory all
	@tests/run $(TEST_BIN)

# The fast subset for the edit-compile loop: unit tests only.
quick: all
	@SL_QUICK=1 tests/run $(TEST_BIN)

# The whole suite under AddressSanitizer + UndefinedBehaviorSanitizer, in a
# separate build tree.
asan: deps
	@$(MAKE) --no-print-directory BUILD=build-asan BIN=build-asan/bin \
	    OPT="-O1 -g -fno-omit-frame-pointer" \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all" all
	@ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	 tests/run $(patsubst $(BUILD)/%,build-asan/%,$(TEST_BIN))

# The main job.  Until the daemon exists: simulate a binary and reconstruct.
demo: deps
	@$(MAKE) --no-print-directory all
	@scripts/demo

clean:
	rm -rf build build-asan bin

-include $(RECON_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(TEST_BIN:=.d)
