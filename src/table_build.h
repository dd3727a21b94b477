/*
 * table_build.h - between the table core (table.c), the opening of a table
 * (table_open.c) and the format readers (table_text.c with table_lines.c
 * and table_header.c, table_fits.c); nothing else includes it but tests.
 *
 * table_open.c makes the table (table_new), recognises the format and calls
 * the reader's open function, which reads the header: it declares the
 * columns, their units and kinds and the metadata through the table_add_*
 * and table_set_* calls below, and registers itself with
 * table_set_reader().  table_read() and table_close() then go to the
 * reader's callbacks.  Messages name the file with table_name(); the core's
 * strings live as long as the table.  The core calls no reader by name.
 */
#ifndef WFS_TABLE_BUILD_H
#define WFS_TABLE_BUILD_H

#include <stddef.h>

#include "table.h"

struct err;
struct input;

/* A format reader: read fills c (memset to 0, c->file set to the table's
 * name) with the next chunk and returns its rows, 0 at the end, -1 with a
 * message; close frees the reader's state. */
struct table_reader {
	long (*read)(void *rd, struct table_chunk *c, struct err *e);
	void (*close)(void *rd);
};

/* The readers.  in is the opened input, its first bytes not consumed;
 * chunk_rows > 0.  Each returns 0 with its reader registered, or -1 with a
 * message (the core then closes what was registered). */
int table_text_open(struct table *t, struct input *in, size_t chunk_rows,
		    struct err *e);
/* A plain file is opened again by path, anything else is spooled to an
 * unlinked temporary file first, because cfitsio needs to seek. */
int table_fits_open(struct table *t, struct input *in, size_t chunk_rows,
		    struct err *e);

/* An empty table reading in, named after it; it owns in from now on (also
 * on failure: NULL with a message, in closed). */
struct table *table_new(struct input *in, struct err *e);

void table_set_reader(struct table *t, const struct table_reader *reader, void *rd);
void table_set_format(struct table *t, enum table_format fmt);
/* The line of the header, for messages about columns (0 for FITS). */
void table_set_header_line(struct table *t, long line);

/* A column named name[0, len) (trimmed, one pair of double quotes removed,
 * lower-cased); an empty or duplicate name is an error naming the header
 * line. */
int table_add_column(struct table *t, const char *name, size_t len,
		     struct err *e);
/* Metadata key=value (trimmed and unquoted); the first value of a key
 * wins. */
int table_add_meta(struct table *t, const char *key, size_t klen,
		   const char *val, size_t vlen, struct err *e);
int table_set_unit(struct table *t, int col, const char *unit, size_t len,
		   struct err *e);
/* table_set_unit(), and where the unit was given, what follows the
 * table's name in table_colunit_place(): ":5" for line 5, "[1] TUNIT3"
 * for a FITS keyword; NULL when not known. */
int table_set_unit_at(struct table *t, int col, const char *unit, size_t len,
		      const char *where, struct err *e);
void table_set_kind(struct table *t, int col, enum table_kind kind);

/* Helpers of the core the readers share. */
int table_oom(struct err *e);                   /* "out of memory", -1 */
char *table_memdup0(const char *s, size_t n);   /* s[0, n) and a NUL */
void table_trim(const char **s, size_t *n);     /* blanks off both ends */
void table_unquote(const char **s, size_t *n);  /* and one pair of quotes */

/* Write v as snprintf(buf, size, "%.*g", digits, v) does, faster
 * (table_fits.c).  Needs size >= 26 for its fast path. */
int table_format_double(char *buf, size_t size, double v, int digits);

#endif
