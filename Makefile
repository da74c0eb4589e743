# specklab - hand-written build.  `make` builds everything into bin/ and
# build/; `make test` installs missing Debian packages, builds and runs every
# test CI runs.  Other tiers: quick, asan, bench, stress, soak, fuzz, demo.
#
# Object files go under $(BUILD) so that `make asan` (BUILD=build-asan) never
# mixes sanitized and plain objects.

BUILD  ?= build
BIN    ?= bin
CC     ?= cc
PKG    ?= pkg-config

# Dependencies, each through pkg-config.  recon/ sees only RECON_PKGS.
RECON_PKGS := fftw3f fftw3 cfitsio libpng
DRV_PKGS   := aravis-0.8 libusb-1.0 libmodbus glib-2.0
CLI_PKGS   := glib-2.0 json-glib-1.0 $(DRV_PKGS)
TEST_DRV_PKGS := $(DRV_PKGS) json-glib-1.0 umockdev-1.0
SCHEMA_PKGS := sqlite3 glib-2.0 gio-2.0
DAEMON_PKGS := $(DRV_PKGS) gio-2.0 gio-unix-2.0 json-glib-1.0 sqlite3 libsystemd libsoup-3.0
FIG_PKGS   := cairo fontconfig

WARN   := -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes
ifeq ($(CI),true)
WARN   += -Werror
endif
ifneq ($(WERROR),)
WARN   += -Werror
endif
OPT    ?= -O2 -g
SAN    ?=
# -Icommon: every module includes the shared error base as "status.h".
CFLAGS_ALL := -std=c11 -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L $(OPT) \
              $(WARN) $(SAN) -MMD -MP -Icommon
LDFLAGS_ALL := $(SAN)

recon_cflags = $(shell $(PKG) --cflags $(RECON_PKGS) 2>/dev/null)
recon_libs   = $(shell $(PKG) --libs $(RECON_PKGS) 2>/dev/null) -lm
# specklabd makes FFTW's planner thread-safe (the worker and the web view
# both plan); FFTW's thread libraries have no pkg-config file.
FFTW_THREADS_LIBS := -lfftw3_threads -lfftw3f_threads
cli_cflags   = $(shell $(PKG) --cflags $(CLI_PKGS) 2>/dev/null)
cli_libs     = $(shell $(PKG) --libs $(CLI_PKGS) 2>/dev/null)
drv_cflags   = $(shell $(PKG) --cflags $(DRV_PKGS) 2>/dev/null)
drv_libs     = $(shell $(PKG) --libs $(DRV_PKGS) 2>/dev/null)
tdrv_cflags  = $(shell $(PKG) --cflags $(TEST_DRV_PKGS) 2>/dev/null)
tdrv_libs    = $(shell $(PKG) --libs $(TEST_DRV_PKGS) 2>/dev/null)
# The U3V mock camera serves its device from a umockdev testbed.
mock_cflags  = $(shell $(PKG) --cflags umockdev-1.0 2>/dev/null)
mock_libs_fake-u3v = $(shell $(PKG) --libs umockdev-1.0 2>/dev/null)
schema_cflags = $(shell $(PKG) --cflags $(SCHEMA_PKGS) 2>/dev/null)
schema_libs   = $(shell $(PKG) --libs $(SCHEMA_PKGS) 2>/dev/null)
daemon_cflags = $(shell $(PKG) --cflags $(DAEMON_PKGS) 2>/dev/null)
daemon_libs   = $(shell $(PKG) --libs $(DAEMON_PKGS) 2>/dev/null)
fig_cflags    = $(shell $(PKG) --cflags $(FIG_PKGS) 2>/dev/null)
fig_libs      = $(shell $(PKG) --libs $(FIG_PKGS) 2>/dev/null)

# common/: the error base every module shares (status.h: the code ranges,
# sl_strstatus).  It includes nothing of the project; every program and
# test links libcommon.a, after the archives that use it.
COMMON_SRC := $(wildcard common/*.c)
COMMON_OBJ := $(COMMON_SRC:%.c=$(BUILD)/%.o)
COMMON_LIB := $(BUILD)/libcommon.a

# recon/ in rooms (README, Layout): base, io, sim, spectra, tsm, pipeline,
# measure -> librecon.a; bench (the benchmark and its charts) -> its own
# archive, which the CLI and the tests link and specklabd never does.
RECON_SRC := $(filter-out recon/bench/%,$(wildcard recon/*/*.c))
RECON_OBJ := $(RECON_SRC:%.c=$(BUILD)/%.o)
RECON_LIB := $(BUILD)/librecon.a
BENCH_SRC := $(wildcard recon/bench/*.c)
BENCH_OBJ := $(BENCH_SRC:%.c=$(BUILD)/%.o)
BENCH_LIB := $(BUILD)/libbench.a

# figure/: figures for people drawn with cairo (reconstructions with scale
# bar, compass and colour bar; the bench chart).  Uses recon's headers;
# recon never uses it.  The CLI and specklabd link it.
FIG_SRC   := $(wildcard figure/*.c)
FIG_OBJ   := $(FIG_SRC:%.c=$(BUILD)/%.o)
FIG_LIB   := $(BUILD)/libfigure.a
# Its tests read the figures back; they run with the unit tests (quick).
TFIG_SRC  := $(wildcard tests/figure/test_*.c)
TFIG_BIN  := $(TFIG_SRC:tests/figure/%.c=$(BUILD)/tests/%)

# drivers/: cameras (Aravis, libusb) and the stage (libmodbus).  Never
# includes daemon/ and never links a mock.
DRV_SRC   := $(wildcard drivers/*.c)
DRV_OBJ   := $(DRV_SRC:%.c=$(BUILD)/%.o)
DRV_LIB   := $(BUILD)/libdrivers.a

# schema/: the SQLite catalogue; migrations are compiled in (GResource).
SCHEMA_SRC := $(wildcard schema/*.c)
SCHEMA_OBJ := $(SCHEMA_SRC:%.c=$(BUILD)/%.o) $(BUILD)/schema/catalog_res.o
SCHEMA_LIB := $(BUILD)/libschema.a
SCHEMA_RES := schema/catalog.gresource.xml

# daemon/: specklabd; its web page (daemon/webpage.html) is compiled in
# (GResource, as the catalogue's migrations).
DAEMON_SRC := $(wildcard daemon/*.c)
DAEMON_OBJ := $(DAEMON_SRC:%.c=$(BUILD)/%.o) $(BUILD)/daemon/web_res.o
WEB_RES    := daemon/webpage.gresource.xml

CLI_SRC   := $(wildcard cli/*.c)
CLI_OBJ   := $(CLI_SRC:%.c=$(BUILD)/%.o)
# Everything but main(): linked into bin/specklab and the integration tests.
CLI_LIB   := $(BUILD)/libcli.a
CLI_MAIN  := $(BUILD)/cli/main.o

# mocks/NAME/*.c -> bin/specklab-NAME: separate programs that speak the
# real protocols on loopback (tests and the demo only).
# mocks/camsrc is no program: the camera mocks' shared frame source (the
# simulator renderer, the stage poll, the model options), an archive each
# mock links (only the members it uses are pulled in).
MOCK_DIRS := $(filter-out camsrc fake-source,$(patsubst mocks/%/,%,$(sort $(dir $(wildcard mocks/*/*.c)))))
MOCK_BIN  := $(MOCK_DIRS:%=$(BIN)/specklab-%)
# Only the link rule's secondary expansion names a mock's objects, so make
# takes them for intermediates and deletes them after a fresh build; the
# next make would compile them again.  Keep them.
MOCK_OBJ  := $(patsubst %.c,$(BUILD)/%.o,$(wildcard $(MOCK_DIRS:%=mocks/%/*.c)))
.SECONDARY: $(MOCK_OBJ)
CAMSRC_OBJ := $(patsubst %.c,$(BUILD)/%.o,$(wildcard mocks/camsrc/*.c))
CAMSRC_LIB := $(BUILD)/libcamsrc.a
# mocks/fake-source -> bin/specklab-fake-source.so: camsrc's simulator
# source (fakesrc.h) for the "fake" camera backend of a process that must
# not link a mock (specklabd loads it when [camera] source names it).  A
# shared object needs position-independent code: camsrc, the recon rooms
# the simulator uses and common/ are compiled again under $(BUILD)/pic
# (an archive, so only the members used are linked); only the entry point
# is exported.  Sanitized builds leave the runtime's symbols to the host
# program, so they link without --no-undefined.
FAKESRC_SO  := $(BIN)/specklab-fake-source.so
FAKESRC_PIC := $(patsubst %.c,$(BUILD)/pic/%.o,$(wildcard mocks/fake-source/*.c mocks/camsrc/*.c))
FAKESRC_LIB_SRC := $(wildcard recon/base/*.c recon/sim/*.c recon/io/*.c common/*.c)
FAKESRC_LIB := $(BUILD)/pic/libfakesrc.a

TEST_SRC  := $(wildcard tests/unit/test_*.c)
TEST_BIN  := $(TEST_SRC:tests/unit/%.c=$(BUILD)/tests/%) $(TFIG_BIN)
# Driver and integration tests: link drivers + recon, may start mocks.
TDRV_SRC  := $(wildcard tests/drivers/test_*.c)
TDRV_BIN  := $(TDRV_SRC:tests/drivers/%.c=$(BUILD)/tests/%)
TCAT_SRC  := $(wildcard tests/catalog/test_*.c)
TCAT_BIN  := $(TCAT_SRC:tests/catalog/%.c=$(BUILD)/tests/%)
TSTR_SRC  := $(wildcard tests/stress/test_*.c)
TSTR_BIN  := $(TSTR_SRC:tests/stress/%.c=$(BUILD)/tests/%)
# Integration: daemon + mocks + CLI client; they start programs from bin/.
TINT_SRC  := $(wildcard tests/integration/test_*.c)
TINT_BIN  := $(TINT_SRC:tests/integration/%.c=$(BUILD)/tests/%)
TINT_HELP := $(filter-out $(TINT_SRC),$(wildcard tests/integration/*.c))
ALL_TESTS := $(TEST_BIN) $(TSTR_BIN) $(TDRV_BIN) $(TCAT_BIN) $(TINT_BIN)
# tests/lib: what the tests share that starts no process (the harness
# tcheck, scratch directories, synthetic data, reading results back),
# compiled once into an archive every test links; a binary pulls in only
# the members it uses.  The process, daemon and camera fixtures stay
# headers beside their tests.
TESTLIB_SRC := $(wildcard tests/lib/*.c)
TESTLIB_OBJ := $(TESTLIB_SRC:%.c=$(BUILD)/%.o)
TESTLIB     := $(BUILD)/libsltest.a

# MPI (optional): Open MPI found by pkg-config (ompi-c, else mpi) builds
# bin/specklab-mpi from mpi/ (specklab recon over MPI ranks); MPI=1 insists
# (an error without it), MPI=0 leaves it out.  Nothing else links MPI, so
# the plain build is the same with or without it.
MPI_PKG := $(firstword $(foreach p,ompi-c mpi,$(shell $(PKG) --exists $(p) 2>/dev/null && echo $(p))))
MPI ?= $(if $(MPI_PKG),1,0)
ifeq ($(MPI),1)
ifeq ($(MPI_PKG),)
$(error MPI=1 but pkg-config knows neither ompi-c nor mpi: apt-get install libopenmpi-dev openmpi-bin)
endif
endif
mpi_cflags = $(shell $(PKG) --cflags $(MPI_PKG) 2>/dev/null)
mpi_libs   = $(shell $(PKG) --libs $(MPI_PKG) 2>/dev/null)
MPI_SRC   := $(wildcard mpi/*.c)
MPI_OBJ   := $(MPI_SRC:%.c=$(BUILD)/%.o)
MPI_BIN   := $(if $(filter 1,$(MPI)),$(BIN)/specklab-mpi)

PROGS := $(BIN)/specklab $(MOCK_BIN) $(FAKESRC_SO) $(if $(DAEMON_SRC),$(BIN)/specklabd) $(MPI_BIN)

.PHONY: all deps test quick stress soak soak-web asan asan-ci-build valgrind bench fuzz demo clean
all: $(PROGS) $(ALL_TESTS)

$(BUILD)/common/%.o: common/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -c $< -o $@

$(COMMON_LIB): $(COMMON_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BUILD)/recon/%.o: recon/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon $(recon_cflags) -c $< -o $@

$(BUILD)/cli/%.o: cli/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Idrivers -Ischema -Ifigure $(recon_cflags) $(cli_cflags) $(schema_cflags) -c $< -o $@

$(BUILD)/figure/%.o: figure/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Ifigure $(recon_cflags) $(fig_cflags) -c $< -o $@

$(FIG_LIB): $(FIG_OBJ)
	rm -f $@ && ar rcs $@ $^

$(BUILD)/drivers/%.o: drivers/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) $(drv_cflags) -c $< -o $@

$(DRV_LIB): $(DRV_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BUILD)/mocks/%.o: mocks/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Idrivers -Imocks/camsrc $(recon_cflags) $(drv_cflags) $(mock_cflags) -c $< -o $@

.SECONDEXPANSION:
$(CAMSRC_LIB): $(CAMSRC_OBJ)
	rm -f $@ && ar rcs $@ $^

$(BIN)/specklab-%: $$(addprefix $(BUILD)/,$$(addsuffix .o,$$(basename $$(wildcard mocks/$$*/*.c)))) $(CAMSRC_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -o $@ $(filter %.o,$^) $(CAMSRC_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) $(drv_libs) $(mock_libs_$*)

$(BUILD)/pic/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -fPIC -fvisibility=hidden -Irecon -Idrivers -Imocks/camsrc \
	    $(recon_cflags) $(drv_cflags) -c $< -o $@

$(FAKESRC_LIB): $(patsubst %.c,$(BUILD)/pic/%.o,$(FAKESRC_LIB_SRC))
	rm -f $@ && ar rcs $@ $^

$(FAKESRC_SO): $(FAKESRC_PIC) $(FAKESRC_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -shared -Wl,-Bsymbolic $(if $(SAN),,-Wl,--no-undefined) -o $@ $(FAKESRC_PIC) \
	    $(FAKESRC_LIB) $(recon_libs) $(drv_libs)

$(BUILD)/schema/catalog_res.c: $(SCHEMA_RES) $(wildcard schema/migrations/*.sql)
	@mkdir -p $(dir $@)
	glib-compile-resources --generate-source --c-name catalog_res \
	    --sourcedir=schema --target=$@ $(SCHEMA_RES)

$(BUILD)/schema/catalog_res.o: $(BUILD)/schema/catalog_res.c
	$(CC) $(CFLAGS_ALL) -Wno-missing-prototypes $(schema_cflags) -c $< -o $@

$(BUILD)/schema/%.o: schema/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Ischema $(schema_cflags) -c $< -o $@

$(SCHEMA_LIB): $(SCHEMA_OBJ)
	rm -f $@ && ar rcs $@ $^

$(TESTLIB): $(TESTLIB_OBJ)
	rm -f $@ && ar rcs $@ $^

$(BUILD)/tests/lib/%.o: tests/lib/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Itests/lib -Irecon -Ischema $(recon_cflags) $(schema_cflags) -c $< -o $@

$(BUILD)/tests/%: tests/catalog/%.c $(TESTLIB) $(SCHEMA_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Ischema -Itests/lib $(schema_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(SCHEMA_LIB) $(COMMON_LIB) $(schema_libs) -lm

$(BUILD)/tests/%: tests/stress/%.c $(TESTLIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Itests/lib $(recon_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs)

# test_mpi* run mpirun on bin/specklab-mpi when the build has MPI.
$(BUILD)/tests/test_mpi $(BUILD)/tests/test_mpi_reprocess: $(MPI_BIN)

# Integration tests link the CLI library (client, commands) and any helper
# .c in tests/integration that is not itself a test.
$(BUILD)/tests/%: tests/integration/%.c $(TINT_HELP) $(TESTLIB) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Idrivers -Ischema -Icli -Itests/lib -Itests/unit -Itests/integration \
	    $(if $(MPI_BIN),-DSL_HAVE_MPI=1) \
	    $(recon_cflags) $(cli_cflags) $(daemon_cflags) $(tdrv_cflags) $< $(TINT_HELP) -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) \
	    $(cli_libs) $(schema_libs) $(daemon_libs) $(tdrv_libs) $(fig_libs) -lm

# The soak program (make soak only): the integration fixture plus the
# catalogue, cfitsio and json-glib; it talks to specklabd over the socket.
SOAK_SRC := $(wildcard tests/soak/*.c)
SOAK_BIN := $(BUILD)/soak/soak
$(SOAK_BIN): $(SOAK_SRC) $(wildcard tests/soak/*.h) tests/integration/daemon_fx.h \
             tests/integration/daemon_client.h $(TESTLIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Ischema -Itests/lib -Itests/unit -Itests/integration \
	    $(recon_cflags) $(schema_cflags) $(daemon_cflags) $(SOAK_SRC) -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) $(schema_libs) $(daemon_libs) -lm

$(RECON_LIB): $(RECON_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BENCH_LIB): $(BENCH_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(CLI_LIB): $(filter-out $(CLI_MAIN),$(CLI_OBJ))
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BIN)/specklab: $(CLI_MAIN) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -o $@ $(CLI_MAIN) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB) \
	    $(recon_libs) $(cli_libs) $(schema_libs) $(fig_libs)

$(BUILD)/mpi/%.o: mpi/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Icli -Ischema $(recon_cflags) $(cli_cflags) $(schema_cflags) $(mpi_cflags) -c $< -o $@

$(BIN)/specklab-mpi: $(MPI_OBJ) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -o $@ $(MPI_OBJ) $(CLI_LIB) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB) \
	    $(recon_libs) $(cli_libs) $(schema_libs) $(fig_libs) $(mpi_libs)

$(BUILD)/daemon/%.o: daemon/%.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Idrivers -Ischema -Ifigure $(recon_cflags) $(daemon_cflags) -c $< -o $@

$(BUILD)/daemon/web_res.c: $(WEB_RES) daemon/webpage.html
	@mkdir -p $(dir $@)
	glib-compile-resources --generate-source --c-name web_res \
	    --sourcedir=daemon --target=$@ $(WEB_RES)

$(BUILD)/daemon/web_res.o: $(BUILD)/daemon/web_res.c
	$(CC) $(CFLAGS_ALL) -Wno-missing-prototypes $(daemon_cflags) -c $< -o $@

$(BIN)/specklabd: $(DAEMON_OBJ) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS_ALL) -o $@ $(DAEMON_OBJ) $(FIG_LIB) $(DRV_LIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB) \
	    $(recon_libs) $(FFTW_THREADS_LIBS) $(daemon_libs) $(fig_libs) -lm

$(BUILD)/tests/%: tests/unit/%.c $(TESTLIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Itests/lib -Itests/unit $(recon_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(BENCH_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs)

$(BUILD)/tests/%: tests/figure/%.c $(TESTLIB) $(FIG_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Ifigure -Itests/lib $(recon_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(FIG_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) $(fig_libs)

# They may link camsrc (the simulator as the fake camera's source); the
# shared object is there for those that load it as specklabd does.
$(BUILD)/tests/%: tests/drivers/%.c $(TESTLIB) $(DRV_LIB) $(CAMSRC_LIB) $(RECON_LIB) $(COMMON_LIB) | $(FAKESRC_SO)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Idrivers -Imocks/camsrc -Itests/lib -Itests/unit $(recon_cflags) $(tdrv_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(DRV_LIB) $(CAMSRC_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) $(tdrv_libs)

# Install what pkg-config lacks (root) or say the exact apt-get line.
deps:
	@scripts/install-deps

# Everything CI runs: every test binary, the recon/stress/catalogue tests
# again under ASan+UBSan (asan-ci-build), and each fuzz target's corpus
# replay and short fuzz run.  One make builds all three trees, one job per
# CPU unless -j is given (CI runs plain `make test`); then one tests/run
# runs every binary, sanitized and fuzz ones too, side by side, longest
# first.  The final line is "N passed, N failed, N skipped".
NPROC := $(shell nproc 2>/dev/null || echo 1)
test: deps
	@$(MAKE) --no-print-directory $(if $(findstring -j,$(MAKEFLAGS)),,-j$(NPROC)) \
	    all fuzz-ci-build asan-ci-build
	@$(ASAN_ENV) tests/run $(ALL_TESTS) $(ASAN_CI_TESTS) $(FUZZ_CI_RUNS)

# The fast subset for the edit-compile loop: unit tests only.
quick: all
	@SL_QUICK=1 tests/run $(TEST_BIN)

# Speed and accuracy live here, never in timed tests: a quick sweep, the
# speed targets (200^2, 100 frames, median of 5) checked, then the blind
# camera-like matrix's quick subset (~20 s; the whole of it: bench --blind).
bench: all
	@mkdir -p out/bench
	@bin/specklab bench --quick --overwrite --csv out/bench/quick.csv --png out/bench/quick.png \
	    --md out/bench/quick.md \
	    && bin/specklab bench --speed --overwrite --csv out/bench/speed.csv --png out/bench/speed.png \
	    --md out/bench/speed.md \
	    && bin/specklab bench --blind --quick --overwrite --csv out/bench/blind-quick.csv

# The numerical-stability suite with its slow cases too.
stress: all
	@SL_STRESS_FULL=1 tests/run $(TSTR_BIN)

# The web page's viewers during acquisitions (make soak-web, also run by
# make soak): three 1000-frame runs, the middle one watched by ten viewers.
SOAK_WEB_BIN := $(BUILD)/soak/web-viewers
$(SOAK_WEB_BIN): tests/soak/web/viewers.c tests/integration/daemon_fx.h \
                 tests/integration/daemon_client.h tests/integration/web_fx.h $(TESTLIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS_ALL) -Irecon -Ischema -Itests/lib -Itests/unit -Itests/integration \
	    $(recon_cflags) $(schema_cflags) $(daemon_cflags) $< -o $@ \
	    $(LDFLAGS_ALL) $(TESTLIB) $(SCHEMA_LIB) $(RECON_LIB) $(COMMON_LIB) $(recon_libs) $(schema_libs) $(daemon_libs) -lm

# Daemon soak on the mocks, ~3 min, never in CI: lost frames, RSS, fds, files (tests/soak/),
# then the web page's ten viewers (~1 min).
soak: all $(SOAK_BIN) $(SOAK_WEB_BIN)
	@$(SOAK_BIN) && $(SOAK_WEB_BIN)

soak-web: all $(SOAK_WEB_BIN)
	@$(SOAK_WEB_BIN)

# The whole suite under AddressSanitizer + UndefinedBehaviorSanitizer, in a
# separate build tree.  ASAN_ENV only affects sanitized programs.
ASAN_ENV := ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
            UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
asan: deps
	@$(MAKE) --no-print-directory BUILD=build-asan BIN=build-asan/bin \
	    OPT="-O1 -g -fno-omit-frame-pointer" \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all" all
	@SPECKLABD=build-asan/bin/specklabd $(ASAN_ENV) \
	 tests/run $(patsubst $(BUILD)/%,build-asan/%,$(ALL_TESTS))

# The part of `make asan` that CI runs inside `make test`: the recon, stress
# and catalogue tests (every parser of FITS, mask, scene and SQL input and
# the numerics, the stress suite's odd sizes included) under ASan+UBSan.
# The driver and integration tests start daemons and mocks and take ~6 min
# sanitized, and five numerics tests repeat sanitized code the others cover
# at 4-5x their plain time (blind 55 s, closure 42, stress_accum 41, stress
# 33, binary 22: 190 of the 334 s): they stay in `make asan`, so that
# `make test` keeps under 7 min on 2 cores.
ASAN_CI_SLOW  := test_blind test_closure test_binary test_stress test_stress_accum
ASAN_CI_TESTS := $(patsubst $(BUILD)/%,build-asan/%,$(filter-out \
                     $(addprefix $(BUILD)/tests/,$(ASAN_CI_SLOW)),$(TEST_BIN) $(TSTR_BIN) $(TCAT_BIN)))
asan-ci-build:
	@$(MAKE) --no-print-directory BUILD=build-asan BIN=build-asan/bin \
	    OPT="-O1 -g -fno-omit-frame-pointer" \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all" $(ASAN_CI_TESTS)

# Valgrind memcheck on the recon unit tests (definite leaks and every
# memory error fail; forked "crash" children are not checked).  Slow: ~20x.
valgrind: all
	@tests/valgrind $(TEST_BIN)

# The bench experiment on the simulated bench (scripts/demo: fake stage and
# camera, specklabd, binary-bench through every screen, exports, figures).
demo: deps
	@$(MAKE) --no-print-directory all
	@scripts/demo

# ---- fuzzing (libFuzzer, clang) ------------------------------------------
# Each target links only the module it reads with; see tests/fuzz/run.
FUZZ_CC    ?= clang
FUZZ_BUILD ?= build-fuzz
FUZZ_SECS  ?= 60
# CI's smoke run per target (8 targets, each a job of make test's
# tests/run, one core each): 8 x 12 s of the 2 x 7 minutes make test may
# take on 2 cores; `make fuzz` is the deep run.
FUZZ_CI_SECS ?= 12
FUZZ_CFLAGS := -std=c11 -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L -O1 -g \
               -fno-omit-frame-pointer $(WARN) -Icommon \
               -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
FUZZ_BIN   := $(patsubst tests/fuzz/%.c,$(FUZZ_BUILD)/%,$(wildcard tests/fuzz/fuzz_*.c))
FUZZ_FITS_SRC  := recon/io/cube.c recon/io/cube_guard.c recon/io/cube_write.c \
                  recon/io/cube_meta.c recon/io/cube_header.c recon/io/datasum.c \
                  recon/base/seq.c common/status.c
FUZZ_MASK_SRC  := recon/sim/mask.c recon/sim/mask_gen.c recon/base/rng.c common/status.c
FUZZ_SCENE_SRC := recon/sim/scene.c common/status.c
FUZZ_STAGE_SRC := drivers/stage.c drivers/stage_modbus.c drivers/stage_backend.c drivers/stage_probe.c \
                  common/status.c
FUZZ_CONFIG_SRC := daemon/config.c daemon/config_defaults.c daemon/webconf.c common/status.c recon/pipeline/pipeline_names.c
# The control socket: server, dispatcher, catalogue and the stage driver
# (`devices`); the runner and the worker are stand-ins in the harness.
FUZZ_DISPATCH_SRC := daemon/dispatch.c daemon/query.c daemon/proto.c daemon/server.c \
                     daemon/runstate.c daemon/catlock.c daemon/reserve.c \
                     daemon/config.c daemon/config_defaults.c daemon/webconf.c daemon/recon_opts.c recon/pipeline/pipeline_names.c \
                     recon/pipeline/pipeline_optset.c recon/pipeline/pipeline_check.c \
                     $(SCHEMA_SRC) $(FUZZ_STAGE_SRC)
FUZZ_DISPATCH_PKGS := glib-2.0 gio-2.0 gio-unix-2.0 json-glib-1.0 sqlite3 libmodbus

$(FUZZ_BUILD)/fuzz_fits $(FUZZ_BUILD)/fuzz_fits_list: $(FUZZ_BUILD)/%: tests/fuzz/%.c $(FUZZ_FITS_SRC) recon/io/cube.h recon/io/cube_guard.h recon/io/cube_header.h recon/io/datasum.h tests/fuzz/fuzz_util.h tests/fuzz/fuzz_cube_util.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -Irecon $(shell $(PKG) --cflags cfitsio) $< $(FUZZ_FITS_SRC) -o $@ \
	    $(shell $(PKG) --libs cfitsio) -lm
$(FUZZ_BUILD)/fuzz_mask: tests/fuzz/fuzz_mask.c $(FUZZ_MASK_SRC) recon/sim/mask.h recon/sim/mask_int.h tests/fuzz/fuzz_util.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -Irecon $< $(FUZZ_MASK_SRC) -o $@ -lm
$(FUZZ_BUILD)/fuzz_scene: tests/fuzz/fuzz_scene.c $(FUZZ_SCENE_SRC) recon/sim/scene.h tests/fuzz/fuzz_util.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -Irecon $< $(FUZZ_SCENE_SRC) -o $@ -lm
$(FUZZ_BUILD)/fuzz_stage: tests/fuzz/fuzz_stage.c $(FUZZ_STAGE_SRC) drivers/stage.h drivers/stage_modbus.h drivers/stage_backend.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -pthread -Idrivers $(shell $(PKG) --cflags libmodbus) $< \
	    $(FUZZ_STAGE_SRC) -o $@ $(shell $(PKG) --libs libmodbus) -lm

$(FUZZ_BUILD)/fuzz_config: tests/fuzz/fuzz_config.c $(FUZZ_CONFIG_SRC) daemon/config.h daemon/webconf.h tests/fuzz/fuzz_util.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -Irecon -Idaemon $(shell $(PKG) --cflags glib-2.0) $< \
	    $(FUZZ_CONFIG_SRC) -o $@ $(shell $(PKG) --libs glib-2.0) -lm
# The catalogue's migrations, compiled in as in the main build (not instrumented).
$(FUZZ_BUILD)/schema/catalog_res.o: $(SCHEMA_RES) $(wildcard schema/migrations/*.sql)
	@mkdir -p $(dir $@)
	glib-compile-resources --generate-source --c-name catalog_res \
	    --sourcedir=schema --target=$(@:.o=.c) $(SCHEMA_RES)
	$(FUZZ_CC) -std=c11 -O1 $(schema_cflags) -c $(@:.o=.c) -o $@
$(FUZZ_BUILD)/fuzz_dispatch: tests/fuzz/fuzz_dispatch.c $(FUZZ_DISPATCH_SRC) \
                             $(FUZZ_BUILD)/schema/catalog_res.o $(wildcard daemon/*.h schema/*.h) \
                             tests/fuzz/fuzz_util.h tests/fuzz/fuzz_daemon_ctx.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -pthread -Irecon -Idrivers -Ischema -Idaemon \
	    $(shell $(PKG) --cflags $(FUZZ_DISPATCH_PKGS)) $< $(FUZZ_DISPATCH_SRC) \
	    $(FUZZ_BUILD)/schema/catalog_res.o -o $@ $(shell $(PKG) --libs $(FUZZ_DISPATCH_PKGS)) -lm

# The web page's server (daemon/web*.c, libsoup) from raw bytes on a
# connection; the runner and the worker are stand-ins in the harness.
FUZZ_HTTP_SRC := daemon/web.c daemon/webpeek.c daemon/webroute.c daemon/webws.c \
                 daemon/webstate.c daemon/webhist.c daemon/webview.c daemon/webtap.c \
                 daemon/webfft.c daemon/webpng.c daemon/webconf.c daemon/config.c daemon/config_defaults.c daemon/proto.c \
                 recon/pipeline/pipeline_names.c $(SCHEMA_SRC) $(FUZZ_STAGE_SRC)
FUZZ_HTTP_PKGS := glib-2.0 gio-2.0 json-glib-1.0 sqlite3 libmodbus libsoup-3.0 libpng fftw3
$(FUZZ_BUILD)/daemon/web_res.o: $(WEB_RES) daemon/webpage.html
	@mkdir -p $(dir $@)
	glib-compile-resources --generate-source --c-name web_res \
	    --sourcedir=daemon --target=$(@:.o=.c) $(WEB_RES)
	$(FUZZ_CC) -std=c11 -O1 $(shell $(PKG) --cflags gio-2.0) -c $(@:.o=.c) -o $@
$(FUZZ_BUILD)/fuzz_http: tests/fuzz/fuzz_http.c $(FUZZ_HTTP_SRC) $(FUZZ_BUILD)/schema/catalog_res.o \
                         $(FUZZ_BUILD)/daemon/web_res.o $(wildcard daemon/*.h schema/*.h) \
                         tests/fuzz/fuzz_util.h
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -pthread -Irecon -Idrivers -Ischema -Idaemon \
	    $(shell $(PKG) --cflags $(FUZZ_HTTP_PKGS)) $< $(FUZZ_HTTP_SRC) \
	    $(FUZZ_BUILD)/schema/catalog_res.o $(FUZZ_BUILD)/daemon/web_res.o -o $@ \
	    $(shell $(PKG) --libs $(FUZZ_HTTP_PKGS)) -lm

# CI's replay and short fuzz run of each target, each one more "test
# binary" for tests/run, so that the targets run beside the other tests
# (one core each) rather than one after another.  The sanitizer options of
# make test are cleared: tests/fuzz/run sets its own.
FUZZ_CI_RUNS := $(FUZZ_BIN:$(FUZZ_BUILD)/%=$(FUZZ_BUILD)/ci/%)
$(FUZZ_CI_RUNS): $(FUZZ_BUILD)/ci/%: $(FUZZ_BUILD)/% Makefile
	@mkdir -p $(dir $@)
	@printf '#!/bin/sh\n# generated by make: replay and short fuzz run of %s\nASAN_OPTIONS= UBSAN_OPTIONS= exec tests/fuzz/run $(FUZZ_BUILD) $(FUZZ_CI_SECS) %s\n' $* $* > $@
	@chmod +x $@

.PHONY: fuzz-build fuzz-ci-build
fuzz-build: $(FUZZ_BIN)
fuzz-ci-build: $(FUZZ_CI_RUNS)

# Each target for FUZZ_SECS seconds after replaying the committed corpus.
fuzz: deps
	@$(MAKE) --no-print-directory fuzz-build
	@tests/fuzz/run $(FUZZ_BUILD) $(FUZZ_SECS)

include mk/install.mk

clean:
	rm -rf build build-asan build-fuzz bin

-include $(COMMON_OBJ:.o=.d) $(RECON_OBJ:.o=.d) $(BENCH_OBJ:.o=.d) $(FIG_OBJ:.o=.d) $(DRV_OBJ:.o=.d) $(DAEMON_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(ALL_TESTS:=.d) $(TESTLIB_OBJ:.o=.d) \
         $(wildcard $(BUILD)/mocks/*/*.d) $(SCHEMA_OBJ:.o=.d) $(MPI_OBJ:.o=.d)
