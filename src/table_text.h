/*
 * table_text.h - between the three files of the text table reader:
 * table_text.c (opening a text table, IPAC rows, chunks), table_lines.c
 * (the buffer, lines, the CSV/whitespace tokenizer) and table_header.c
 * (the headers: the column line of CSV and whitespace tables, IPAC's pipe
 * lines, ECSV's YAML).  Nothing else includes it.
 */
#ifndef WFS_TABLE_TEXT_H
#define WFS_TABLE_TEXT_H

#include <stddef.h>

#include "table_build.h"

struct err;
struct input;

#define TEXT_NONE ((size_t)-1)

enum cls { C_PLAIN, C_DELIM, C_QUOTE, C_BAD, C_HIGH, C_CR };

/* One text table being read; the core's struct table holds its columns
 * and metadata. */
struct text_reader {
	struct table *tab;
	struct input *in;
	const char *name;       /* the table's, for messages */
	enum table_format fmt;
	size_t chunk_rows;
	int ncol;               /* once the header is read */
	char **null;            /* IPAC null value of each column, or NULL */
	int nnull;

	/* Text: unparsed data is buf[pos, len); buf[len] is kept free for a
	 * terminating NUL.  nl is the offset of the next '\n' at or after pos
	 * when known, else TEXT_NONE. */
	char *buf;
	size_t cap, len, pos, nl;
	/* The first '"' at or after qfrom, found by searching buf[qfrom,
	 * qscan), or TEXT_NONE when there is none there: one search serves many
	 * quote-free lines.  qscan = 0 when unknown. */
	size_t qt, qfrom, qscan;
	int eof;
	long line;              /* lines consumed before pos */
	int consumed;           /* lines the last text_line() consumed */
	char delim;
	unsigned char cls[256];
	int *ipac_pipe;         /* pipe offsets of the IPAC name line */
	int ipac_npipe;
	char *arena;            /* IPAC cells of the current chunk */
	size_t arena_cap, arena_len;
	char **fields;
	int fields_cap;

	/* The current chunk. */
	const char **cells;
	const char ***text;
	const double **num;
	long *line_of;
};

/* table_lines.c: the next complete line [*ls, *le) (see there for quotes
 * and can_move; 1 a line, 0 the end, 2 the buffer is full, -1 an error);
 * text_unread() gives it back. */
int text_line(struct text_reader *t, char **ls, char **le, int quotes,
	      int can_move, struct err *e);
void text_unread(struct text_reader *t, char *ls);
/* Refuse control bytes and invalid UTF-8 in s[0, e), naming the line. */
int check_text(struct text_reader *t, const char *s, const char *e, long line,
	       struct err *ep);
/* Split a line into t->fields by t->delim; the field count, or -1. */
int split_line(struct text_reader *t, char *s, char *end, long line,
	       struct err *e);
/* Make delim (',' or ' ' for blanks) the tokenizer's delimiter. */
void set_classes(struct text_reader *t, char delim);

/* table_header.c: read the header of a text table, declaring its columns,
 * units and metadata; t->fmt becomes the format found.  0, or -1. */
int text_header(struct text_reader *t, struct err *e);

static inline int is_blank(const char *s, const char *e)
{
	while (s < e && (*s == ' ' || *s == '\t'))
		s++;
	return s == e;
}

static inline const char *skip_blank(const char *s, const char *e)
{
	while (s < e && (*s == ' ' || *s == '\t'))
		s++;
	return s;
}

#endif
