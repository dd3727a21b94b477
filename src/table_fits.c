/* table_fits.c - FITS binary tables through cfitsio; see table.h. */
#include <stdlib.h>

#include "err.h"
#include "table.h"

struct table_fits {
	int unused;
};

struct table_fits *table_fits_open(struct table *t, struct input *in,
				   size_t chunk_rows, struct err *e)
{
	err_set(e, EXIT_INPUT, "%s: FITS tables are not supported yet",
		table_name(t));
	return NULL;
}

long table_fits_read(struct table_fits *f, struct table_chunk *c,
		     struct err *e)
{
	return 0;
}

void table_fits_close(struct table_fits *f)
{
	free(f);
}
