# wfiscene - a fast Roman WFI scene simulator.  Plain GNU make.
#
#   make            build build/wfiscene and the model plugins
#   make check      install missing packages (as root), build, run the tests
#                   (as anyone else: what the installed packages allow)
#   make demo       install missing packages, build, simulate a globular cluster
#   make help       list the targets
#
# Knobs: CC, CFLAGS, LDFLAGS, PKG_CONFIG, PREFIX, DESTDIR, V=1 (show commands),
# SANITIZE=1 (AddressSanitizer + UBSan, in build-san), SANITIZE=thread
# (ThreadSanitizer, in build-tsan), TESTS='tests/t1*.sh' (a subset).
# Local overrides go in config.mak.

-include config.mak

PREFIX     ?= /usr/local
BINDIR     ?= $(PREFIX)/bin
LIBDIR     ?= $(PREFIX)/lib
PLUGINDIR  ?= $(LIBDIR)/wfiscene
INCLUDEDIR ?= $(PREFIX)/include
PKGCONFIGDIR ?= $(LIBDIR)/pkgconfig
MANDIR     ?= $(PREFIX)/share/man
DESTDIR    ?=

VERSION    := 0.1.0
CC         ?= cc
PKG_CONFIG ?= pkg-config
CFLAGS     ?= -O2 -g
PKGS       := cfitsio wcslib fftw3 libzstd zlib libpng chealpix libfyaml libmd liblz4

Q = $(if $(filter 1,$(V)),,@)
# The plugins' inner loops are worth the vectoriser's full effort.
PLUGIN_OPT ?= -O3
B := build

ifeq ($(SANITIZE),1)
  B := build-san
  CFLAGS += -O1 -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
  LDFLAGS += -fsanitize=address,undefined
else ifeq ($(SANITIZE),thread)
  # A race report makes the program exit 66 (TSAN_OPTIONS exitcode), so a
  # test that sees one fails.
  B := build-tsan
  CFLAGS += -O1 -fsanitize=thread -fno-omit-frame-pointer
  LDFLAGS += -fsanitize=thread
else ifneq ($(SANITIZE),)
  $(error SANITIZE=$(SANITIZE): use SANITIZE=1 (address, undefined) or SANITIZE=thread)
endif

PKG_CFLAGS := $(shell $(PKG_CONFIG) --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   := $(shell $(PKG_CONFIG) --libs $(PKGS) 2>/dev/null)
# No string from outside ever becomes a printf format: the compiler checks.
WARN_FLAGS := -Wall -Wextra -Wno-unused-parameter -Wformat -Wformat-nonliteral -Wformat-security
# Floating point as written: no a * b + c fused unless the code says fma()
# (GCC's -std=c11 already keeps to that, clang's default does not), so a
# vector loop and the plain one beside it give the same bytes with either
# compiler; and no traps assumed (nothing here reads the FP exception
# flags), so that selects between doubles may become vector blends.
FP_FLAGS   := -ffp-contract=off -fno-trapping-math
ALL_CFLAGS  = -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE \
	$(WARN_FLAGS) $(FP_FLAGS) -pthread -Iinclude -Isrc -I$(B) \
	-DWFS_VERSION='"$(VERSION)"' -DWFS_BINDIR='"$(BINDIR)"' -DWFS_PLUGINDIR='"$(PLUGINDIR)"' \
	$(PKG_CFLAGS) $(CFLAGS)
ALL_LIBS    = $(PKG_LIBS) -lfftw3_threads -lltdl -lm -lpthread

LIB_SRC  := $(filter-out src/main.c,$(wildcard src/*.c))
LIB_OBJ  := $(patsubst src/%.c,$(B)/obj/%.o,$(LIB_SRC)) $(B)/obj/data_tables.o
# plugins/foo.c with plugins/foo_*.c is one plugin (see plugin_rule below)
plugin_units = $(filter-out $(1).c,$(wildcard $(1)_*.c))
PLUGIN_UNITS := $(foreach f,$(wildcard plugins/*.c),$(call plugin_units,$(basename $(f))))
# units several plugins link in: the Sersic code both Sersic plugins share
SERSIC_UNITS := plugins/sersic_core.c plugins/sersic_render.c
shared_units = $(if $(filter sersic_quick sersic_precise,$(1)),$(SERSIC_UNITS))
PLUGIN_MAIN  := $(filter-out $(PLUGIN_UNITS) $(SERSIC_UNITS),$(wildcard plugins/*.c))
PLUGINS  := $(patsubst plugins/%.c,$(B)/plugins/%.so,$(subst _,-,$(PLUGIN_MAIN)))
UNIT_SRC := $(wildcard tests/unit/*.c)
UNIT_BIN := $(patsubst tests/unit/%.c,$(B)/tests/%,$(UNIT_SRC))
TOOL_SRC := $(wildcard contrib/*.c)
TOOL_BIN := $(patsubst contrib/%.c,$(B)/contrib/%,$(TOOL_SRC))
DATA     := $(wildcard data/*.tsv)
# The slowest shell tests start first, longest first (as `prove --timer`
# measured them), so that prove -j2 does not end on one long test running
# alone on a core.
SLOW_TESTS := $(wildcard tests/t4403-*.sh tests/t4400-*.sh tests/t3008-*.sh \
	tests/t7100-*.sh tests/t4402-*.sh tests/t5001-*.sh tests/t9003-*.sh \
	tests/t3100-*.sh tests/t4102-*.sh tests/t5100-*.sh tests/t4101-*.sh \
	tests/t3009-*.sh tests/t1330-*.sh tests/t3005-*.sh tests/t3004-*.sh \
	tests/t4200-*.sh tests/t3002-*.sh tests/t2200-*.sh tests/t9002-*.sh \
	tests/t3007-*.sh tests/t3006-*.sh tests/t7010-*.sh tests/t3010-*.sh \
	tests/t1210-*.sh tests/t6001-*.sh tests/t5200-*.sh tests/t1220-*.sh \
	tests/t5002-*.sh)
TESTS    ?= $(SLOW_TESTS) $(filter-out $(SLOW_TESTS),$(wildcard tests/t*.sh))

## all: build wfiscene, the plugins and the contrib tools (default)
all: $(B)/wfiscene $(PLUGINS) $(TOOL_BIN)

$(B)/wfiscene: $(B)/obj/main.o $(B)/libwfs.a
	@echo "  LD      $@"
	$(Q)$(CC) $(LDFLAGS) -o $@ $^ $(ALL_LIBS)

$(B)/libwfs.a: $(LIB_OBJ)
	$(Q)rm -f $@ && ar rcs $@ $^

$(B)/obj/%.o: src/%.c $(wildcard src/*.h) include/wfiscene/model.h | $(B)/obj
	@echo "  CC      $<"
	$(Q)$(CC) $(ALL_CFLAGS) -c -o $@ $<

# The program looks for its plugins in PLUGINDIR, and relative to itself as
# BINDIR is to PLUGINDIR: both are compiled into plugin.o.  A stamp holding
# their values rebuilds it when PREFIX, BINDIR or PLUGINDIR changes (`make`,
# then `make install PREFIX=/opt/wfs`, must not install a program that looks
# in /usr/local).
$(B)/plugindir.stamp: FORCE | $(B)/obj
	$(Q)printf '%s\n' '$(BINDIR)' '$(PLUGINDIR)' | cmp -s - $@ 2>/dev/null || \
		printf '%s\n' '$(BINDIR)' '$(PLUGINDIR)' > $@
$(B)/obj/plugin.o: $(B)/plugindir.stamp
FORCE:

# The built-in PSF cache's key covers the code that computes a grid: a
# checksum of its sources, so that changed code never reads a grid that the
# old code cached.
PSF_SRC := src/optics.c src/optics.h src/pupil.c src/pupil.h src/psf.c src/psf.h src/psfbuild.c \
	src/throughput.c src/throughput.h \
	src/spectrum.c src/spectrum.h
$(B)/psf_src.h: $(PSF_SRC) | $(B)/obj
	$(Q)printf '#define PSF_SRC_SUM "%s"\n' "$$(cat $(PSF_SRC) | cksum | tr ' ' -)" > $@.tmp && \
		mv $@.tmp $@
$(B)/obj/psfbuild.o: $(B)/psf_src.h
# level 2's chisq and dumo: one loop per resultant along a row, for the
# vectoriser (src/ramp_stats.c)
$(B)/obj/ramp_stats.o: ALL_CFLAGS += -O3
# the scene's noise stages: a tile's element-wise loops, for the vectoriser
$(B)/obj/noise.o: ALL_CFLAGS += -O3

$(B)/data_tables.c: src/embed.sh $(DATA) | $(B)/obj
	@echo "  EMBED   data/*.tsv"
	$(Q)sh src/embed.sh $(DATA) > $@.tmp && mv $@.tmp $@

$(B)/obj/data_tables.o: $(B)/data_tables.c
	$(Q)$(CC) $(ALL_CFLAGS) -c -o $@ $<

# Plugins see nothing of the host but include/wfiscene/model.h (and
# src/simd.h, all static inline: the one switch of the vector code), and
# -Wl,-z,defs fails the link if one needs a symbol of the host (or any that
# libc and libm do not define).  A plugin plugins/foo_bar.c becomes
# build/plugins/foo-bar.so, the model 'foo-bar'; but a plugin of several
# files is plugins/foo.c with its units plugins/foo_*.c beside it (point.so
# is plugins/point.c and plugins/point_*.c), linked into one foo.so.
define plugin_rule
$(B)/plugins/$(subst _,-,$(1)).so: plugins/$(1).c $(call plugin_units,plugins/$(1)) $(call shared_units,$(1)) \
		include/wfiscene/model.h src/simd.h $(wildcard plugins/*.h) | $(B)/plugins
	@echo "  PLUGIN  $$@"
	$(Q)$(CC) -std=c11 -D_DEFAULT_SOURCE $(WARN_FLAGS) $(FP_FLAGS) -Iinclude \
		-fPIC -shared -fvisibility=hidden $(CFLAGS) $(PLUGIN_OPT) $(LDFLAGS) \
		-Wl,-z,defs -o $$@ plugins/$(1).c $(call plugin_units,plugins/$(1)) \
		$(call shared_units,$(1)) -lm
endef
$(foreach p,$(basename $(notdir $(PLUGIN_MAIN))),$(eval $(call plugin_rule,$(p))))

# Two unit tests compile plugin code in: its sources are theirs too.
$(B)/tests/sersic_rows: plugins/sersic_quick.c $(SERSIC_UNITS) $(wildcard plugins/*.h) src/simd.h
$(B)/tests/vmath: plugins/vmath.h
$(B)/tests/%: tests/unit/%.c tests/unit/tap.h $(B)/libwfs.a | $(B)/tests
	@echo "  CC      $@"
	$(Q)$(CC) $(ALL_CFLAGS) -Itests/unit $(LDFLAGS) -o $@ $< $(B)/libwfs.a $(ALL_LIBS)

# a unit test of a plugin's header rebuilds when the header changes
$(B)/tests/halo_amplitude: plugins/halo.h

$(B)/contrib/%: contrib/%.c | $(B)/contrib
	@echo "  CC      $@"
	$(Q)$(CC) -std=c11 -D_DEFAULT_SOURCE $(WARN_FLAGS) $(CFLAGS) $(LDFLAGS) -o $@ $< -lzstd -lm

# csv2fits writes FITS tables for the bench and so needs cfitsio.
$(B)/contrib/csv2fits: contrib/csv2fits.c | $(B)/contrib
	@echo "  CC      $@"
	$(Q)$(CC) -std=c11 -D_DEFAULT_SOURCE $(WARN_FLAGS) $(CFLAGS) \
		$$($(PKG_CONFIG) --cflags cfitsio) $(LDFLAGS) -o $@ $< \
		$$($(PKG_CONFIG) --libs cfitsio) -lm

$(B)/obj $(B)/plugins $(B)/tests $(B)/contrib:
	$(Q)mkdir -p $@

## deps: install missing Debian packages (as root), else print the command
deps:
	$(Q)sh contrib/install-deps.sh

## check: run the whole test suite (installs missing packages first as root; as
##   anyone else it runs what it can, and every skip names its reason and package)
check: deps
	$(Q)command -v prove > /dev/null 2>&1 || \
		{ echo "make check: prove is not installed (Debian package perl)" >&2; exit 1; }
	$(Q)$(MAKE) --no-print-directory all unit
	$(Q)rc=0; WFS_BUILD=$(B) prove -j2 --directives $(UNIT_BIN) \
	    > $(B)/unit-tests.log 2>&1 & upid=$$!; \
	  WFS_BUILD=$(B) prove -j2 --directives --exec sh $(TESTS) :: || rc=1; \
	  if wait $$upid; then echo "unit tests: $$(tail -n 1 $(B)/unit-tests.log)"; \
	  else rc=1; cat $(B)/unit-tests.log; echo "unit tests: FAIL (above)"; fi; exit $$rc

## unit: build the C unit tests
unit: $(UNIT_BIN)

## demo-bulge: SCA 4 of a bulge field (10^6 stars) at a 15-minute cadence, level 2 with persistence: a light curve and the afterglow
demo-bulge: all
	$(Q)WFS_BUILD=$(B) sh contrib/demo-bulge/run.sh

## demo: simulate a crowded globular cluster on several SCAs
demo: deps
	$(Q)$(MAKE) --no-print-directory all
	$(Q)WFS_BUILD=$(B) sh contrib/demo.sh

## bench: the benchmark suite (not part of check); figures go to BENCHMARKS.md
bench:
	$(Q)sh contrib/install-deps.sh bench
	$(Q)$(MAKE) --no-print-directory all unit
	$(Q)WFS_BUILD=$(B) sh contrib/bench.sh

## bench-render: the engine's render stage against the float stamp-add floor alone
bench-render:
	$(Q)$(MAKE) --no-print-directory all
	$(Q)WFS_BUILD=$(B) BENCH_RENDER_ONLY=1 sh contrib/bench.sh

## fuzz: build the catalog fuzzer (libFuzzer) and run it for FUZZ_SECONDS (60)
FUZZ_SECONDS ?= 60
fuzz: $(B)/data_tables.c
	$(Q)clang -g -O1 -fsanitize=fuzzer,address,undefined -std=c11 -D_POSIX_C_SOURCE=200809L \
		-D_DEFAULT_SOURCE -Isrc -DTABLE_BUF=512 -DTABLE_MAX_LINE=65536 \
		tests/fuzz/catalog_fuzz.c src/input.c src/table.c src/table_open.c \
		src/table_text.c src/table_lines.c src/table_header.c src/table_fits.c \
		src/catalog.c src/catalog_number.c src/catalog_units.c src/rowpool.c src/pool.c src/tree.c src/options.c \
		src/tempfile.c src/err.c src/instrument.c src/data.c $(B)/data_tables.c \
		$$($(PKG_CONFIG) --cflags --libs cfitsio libzstd zlib) -lchealpix -lm -o $(B)/catalog_fuzz
	$(Q)mkdir -p $(B)/fuzz-corpus && cp -n tests/fuzz/corpus/* $(B)/fuzz-corpus/ 2>/dev/null; \
	$(B)/catalog_fuzz -max_len=16384 -max_total_time=$(FUZZ_SECONDS) \
		-artifact_prefix=$(B)/ $(B)/fuzz-corpus tests/fuzz/corpus

## lint-man: check the man pages with mandoc -Tlint (any message, style included, fails)
lint-man:
	$(Q)command -v mandoc >/dev/null 2>&1 || \
		{ echo "lint-man: mandoc is not installed (Debian package mandoc)" >&2; exit 1; }
	$(Q)mandoc -Tlint -W style man/*

## lint-nosimd: compile every source as -DWFS_NO_SIMD builds it (no vector loops), syntax only
lint-nosimd: $(B)/psf_src.h
	$(Q)for f in $(wildcard src/*.c plugins/*.c); do \
		$(CC) $(ALL_CFLAGS) -Werror -DWFS_NO_SIMD -fsyntax-only $$f || exit 1; \
	done

## install: install the program, plugins, header, pkg-config file, man pages
install: all
	install -d $(DESTDIR)$(BINDIR) $(DESTDIR)$(PLUGINDIR) $(DESTDIR)$(INCLUDEDIR)/wfiscene \
		$(DESTDIR)$(PKGCONFIGDIR) $(DESTDIR)$(MANDIR)/man1 $(DESTDIR)$(MANDIR)/man5 $(DESTDIR)$(MANDIR)/man7
	install -m 755 $(B)/wfiscene $(DESTDIR)$(BINDIR)/wfiscene
	install -m 755 $(PLUGINS) $(DESTDIR)$(PLUGINDIR)/
	install -m 644 include/wfiscene/model.h $(DESTDIR)$(INCLUDEDIR)/wfiscene/model.h
	sed -e 's|@PREFIX@|$(PREFIX)|; s|@INCLUDEDIR@|$(INCLUDEDIR)|; s|@PLUGINDIR@|$(PLUGINDIR)|; s|@VERSION@|$(VERSION)|' \
		contrib/wfiscene-model.pc.in > $(DESTDIR)$(PKGCONFIGDIR)/wfiscene-model.pc
	for s in 1 5 7; do for m in man/*.$$s; do [ ! -f $$m ] || \
		install -m 644 $$m $(DESTDIR)$(MANDIR)/man$$s/ || exit 1; done; done

## clean: remove build outputs
clean:
	rm -rf build build-san build-tsan

## help: list the targets
help:
	@sed -n 's/^## //p' $(MAKEFILE_LIST)

.PHONY: all deps check unit demo demo-bulge bench bench-render fuzz lint-man lint-nosimd install clean help validate FORCE

## validate: the paper's 1000-star photometry test and the load tests (slow; installs python3-matplotlib for the plot)
validate:
	$(Q)sh contrib/install-deps.sh validate
	$(Q)$(MAKE) --no-print-directory all
	$(Q)WFISCENE_CACHE=$${WFISCENE_CACHE:-$(B)/test-cache} /usr/bin/python3 \
		tests/validate/photometry.py --n 1000 --seed 1 --wfs $(B)/wfiscene \
		--dir $(B)/validate --table $(B)/validate/table.md \
		--plot tests/validate/photometry.png --json $(B)/validate/summary.json
	$(Q)cat $(B)/validate/table.md
	$(Q)WFS_BUILD=$(B) sh tests/validate/load.sh
