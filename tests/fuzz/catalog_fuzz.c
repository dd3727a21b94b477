/*
 * catalog_fuzz.c - libFuzzer harness for catalog reading: decompression,
 * format recognition, every text format, FITS tables, column meanings.
 *
 * Each input is written to one temporary file and read to the end through
 * catalog_open/catalog_read, exactly as the program reads a catalog.  The
 * last input byte picks the scene filter, the flux unit default and the
 * chunk size, so chunk boundaries move around.  Build (the Makefile's
 * "make fuzz" does the same):
 *
 *   clang -g -O1 -fsanitize=fuzzer,address,undefined -std=c11 \
 *     -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -Isrc \
 *     -DTABLE_BUF=512 -DTABLE_MAX_LINE=65536 \
 *     tests/fuzz/catalog_fuzz.c src/input.c src/table.c src/table_open.c \
 *     src/table_text.c src/table_lines.c src/table_header.c src/table_fits.c \
 *     src/catalog.c src/tree.c src/err.c src/instrument.c src/data.c build/data_tables.c \
 *     $(pkg-config --cflags --libs cfitsio libzstd zlib) -lchealpix -lm -o build/catalog_fuzz
 *   build/catalog_fuzz -max_len=65536 tests/fuzz/corpus
 *
 * TABLE_BUF and TABLE_MAX_LINE shrink the text buffer so that small inputs
 * reach the buffer-full, compaction and line-too-long paths.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "catalog.h"
#include "err.h"
#include "instrument.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static char path[64];
	static const int units[] = { 0, UNIT_COUNTS, UNIT_ABMAG, UNIT_JY };
	struct catalog_opts o = { F129, 0, 0 };
	struct catalog *c;
	struct rows r;
	struct err e = { 0 };
	unsigned knob = size ? data[size - 1] : 0;
	FILE *f;
	long n;

	if (!path[0]) {
		const char *d = getenv("TMPDIR");
		int fd;

		snprintf(path, sizeof(path), "%s/catfuzz-XXXXXX", d && *d ? d : "/tmp");
		fd = mkstemp(path);
		if (fd < 0)
			abort();
		close(fd);
	}
	f = fopen(path, "wb");
	if (!f || fwrite(data, 1, size, f) != size || fclose(f) != 0)
		abort();
	o.filter = (int)(knob % WFS_NFILTER);
	o.flux_unit = units[(knob >> 3) % 4];
	o.chunk_rows = 1 + (knob >> 5);
	c = catalog_open(path, &o, &e);
	if (!c) {
		if (!e.code || !e.msg[0])
			abort();        /* a failure must say why */
		return 0;
	}
	while ((n = catalog_read(c, &r, &e)) > 0) {
		/* Touch what the host reads. */
		for (long i = 0; i < n; i++) {
			volatile double v = r.ra[i] + r.x[i] + r.flux[i];
			volatile size_t k = strlen(r.type[i]);

			(void)v;
			(void)k;
			if (!(r.flux[i] == r.flux[i]))
				abort();
			/* as the host reads a cell: a FITS double's text is
			 * formatted when first asked for (table_text) */
			for (int j = 0; j < r.ncol; j++)
				k = strlen(rows_text(&r, j, i));
		}
	}
	if (n < 0 && (!e.code || !e.msg[0]))
		abort();
	catalog_close(c);
	return 0;
}
