/*
 * table_open.c - a catalog file opened as a table: its bytes recognised
 * (a FITS file by its first card, anything else as text) and handed to the
 * format's reader, table_fits.c or table_text.c, which reads the header
 * into the table core (table.c).  See table.h.
 */
#include <string.h>
#include <sys/types.h>

#include "err.h"
#include "input.h"
#include "table_build.h"

struct table *table_open(const char *path, size_t chunk_rows, struct err *e)
{
	struct input *in;
	struct table *t;
	const void *p;
	ssize_t n;

	if (!chunk_rows)
		chunk_rows = 65536;
	if (!(in = input_open(path, e)) || !(t = table_new(in, e)))
		return NULL;
	n = input_peek(in, &p, 80, e);
	if (n < 0)
		goto fail;
	if (n >= 9 && memcmp(p, "SIMPLE  =", 9) == 0) {
		table_set_format(t, TABLE_FITS);
		if (table_fits_open(t, in, chunk_rows, e) < 0)
			goto fail;
	} else if (table_text_open(t, in, chunk_rows, e) < 0) {
		goto fail;
	}
	return t;
fail:
	table_close(t);
	return NULL;
}
