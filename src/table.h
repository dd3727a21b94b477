/*
 * table.h - the table layer under catalog.h (internal to the catalog
 * module): any supported format, plain or compressed, read as chunks of
 * rows whose cells are text, plus the file's metadata and column units.
 * The core is table.c; the readers are table_text.c and table_header.c (CSV,
 * whitespace, IPAC, ECSV) and table_fits.c (FITS), built on table_build.h.
 *
 * Formats are recognised from the content (table_open):
 *   FITS        "SIMPLE  =" at byte 0; binary (and ASCII) table HDUs in turn
 *   ECSV        a first line "# %ECSV"
 *   IPAC        a "|name|name|" header line, optionally after "\key=value"
 *   CSV         a header line containing a comma
 *   whitespace  anything else: fields separated by blanks or tabs
 * "\key=value" metadata lines are accepted before the header of every text
 * format, not only IPAC.
 */
#ifndef WFS_TABLE_H
#define WFS_TABLE_H

#include <stddef.h>

struct err;

enum table_format { TABLE_CSV, TABLE_WS, TABLE_IPAC, TABLE_ECSV, TABLE_FITS,
	TABLE_EMPTY };

/* What a column holds: text formats say nothing (TEXT); FITS tables say
 * whether the column is numeric or a string. */
enum table_kind { TABLE_TEXT, TABLE_NUMBER, TABLE_STRING, TABLE_LOGICAL };

/* The longest line (or quoted row) a text table may have. */
#ifndef TABLE_MAX_LINE
#define TABLE_MAX_LINE (16u << 20)
#endif

struct table_chunk {
	size_t n;
	const char *file;       /* name for messages, e.g. "cat.fits[2]" */
	long *line;             /* per row: file line (text) or table row (FITS) */
	const char ***text;     /* text[col][row], NUL-terminated, trimmed;
	                           NULL for a FITS double not written as text
	                           yet: table_text() writes it */
	const double **num;     /* num[col][row] for TABLE_NUMBER columns, else
	                           num[col] == NULL */
	/* Writes the text of a cell whose text[col][row] is NULL (a FITS
	 * double), for table_text(); src is the reader. */
	const char *(*cell_text)(void *src, int col, size_t row);
	void *src;
	int padded;             /* text tables: TABLE_PAD defined bytes follow
	                           every cell's NUL, so a cell may be read a
	                           word at a time past its end */
};

#define TABLE_PAD 16

/* The text of cell (col, row) of chunk c: text[col][row], or a FITS
 * double (D) cell written now as "%.17g", which reads back to its value.
 * Reading a FITS table, most numbers are only ever used as numbers, so
 * their text is written only for messages and for columns read as text.
 * Valid as long as the chunk. */
const char *table_text(const struct table_chunk *c, int col, size_t row);

struct table;

/* Open path ("-" for stdin), decompress, recognise the format and read the
 * header: column names, units, metadata.  chunk_rows > 0. */
struct table *table_open(const char *path, size_t chunk_rows, struct err *e);

/* Next chunk: > 0 rows, 0 at the end, -1 with a message.  The chunk's
 * memory belongs to the table and lasts until the next table_read(). */
long table_read(struct table *t, struct table_chunk *c, struct err *e);

enum table_format table_format(const struct table *t);
const char *table_name(const struct table *t);
int table_ncol(const struct table *t);
/* Lower-case column name; its unit ("" when none); its kind. */
const char *table_colname(const struct table *t, int col);
const char *table_colunit(const struct table *t, int col);
enum table_kind table_colkind(const struct table *t, int col);
/* Where the column's unit was given, to begin a message about it:
 * "cat.ecsv:5", "cat.fits[1] TUNIT3", or the table's name when the reader
 * did not say.  Valid as long as the table. */
const char *table_colunit_place(const struct table *t, int col);
/* The index of the column named name (lower-case, as table_colname()
 * gives), or -1; a hash look-up, not a scan of the columns. */
int table_column(const struct table *t, const char *name);
/* Line of the header (for messages about columns), 0 for FITS. */
long table_header_line(const struct table *t);
/* Metadata value of key (case-insensitive), or NULL. */
const char *table_meta(const struct table *t, const char *key);
unsigned long long table_raw_bytes(const struct table *t);
void table_close(struct table *t);

#endif
