/*
 * data.h - the instrument tables in data/, embedded in the binary at build
 * time so that wfiscene never needs a data file at run time.
 *
 * Each table is a text file with '#' comment lines (its provenance) and
 * tab-separated rows whose first non-comment line names the columns.
 */
#ifndef WFS_DATA_H
#define WFS_DATA_H

#include <stddef.h>
#include <stdint.h>

/* The embedded text of data/<name> (e.g. "sca.tsv"), or NULL when there is
 * no such table.  *len receives its length. */
const char *data_table(const char *name, size_t *len);

/* FNV-1a 64-bit checksum of an embedded table; part of the PSF cache key. */
uint64_t data_checksum(const char *name);

/*
 * A parsed table: rows of fields, split at tabs.  Comment and empty lines are
 * dropped; row 0 is the header.  Owned by the caller; free with tsv_free().
 */
struct tsv {
	int nrow, ncol;
	char ***cell;           /* cell[row][col], NUL-terminated */
	char *text;             /* the storage cells point into */
};

int tsv_parse(struct tsv *t, const char *name);     /* 0 or -1 (no table) */
int tsv_col(const struct tsv *t, const char *colname);  /* index or -1 */
void tsv_free(struct tsv *t);

#endif
