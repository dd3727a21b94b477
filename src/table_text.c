/*
 * table_text.c - the text table readers: CSV, whitespace separated, IPAC and
 * ECSV, recognised from their header (see table.h); table_open.c hands them
 * every input that is not FITS.
 *
 * Text is read into one buffer and cells point into it: a delimiter is
 * overwritten with NUL and quoted cells are unquoted in place, so a row
 * costs no allocation.  Because cells of the current chunk point into the
 * buffer, the buffer is only compacted or grown at the start of a chunk; a
 * chunk simply ends early when the buffer is full.  The buffer grows only
 * for a single line longer than it, up to TABLE_MAX_LINE.  Memory is thus
 * bounded by max(TABLE_BUF, TABLE_MAX_LINE) for text plus chunk_rows x
 * (ncol + 1) words for the cell pointers and line numbers.
 *
 * This file opens a text table and reads its rows in chunks (IPAC rows
 * here); the buffer, its lines and the CSV/whitespace tokenizer are
 * table_lines.c's, the headers table_header.c's, and the reader's state
 * (struct text_reader) is shared through table_text.h.
 */
#include <ctype.h>
#include <stdint.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "err.h"
#include "input.h"
#include "table_text.h"

/* Initial text buffer.  Overridable at build time so that the fuzzer
 * reaches the buffer-full and line-growth paths with small inputs. */
#ifndef TABLE_BUF
#define TABLE_BUF (8u << 20)
#endif
/* Bytes after the text buffer and the IPAC arena, kept zero (defined), so
 * that a cell may be read 8 bytes at a time past its NUL (table.h,
 * TABLE_PAD). */
#define PAD TABLE_PAD
#define TABLE_MAX_CELLS (8u << 20)

/* Copy a cell into the arena; ipac_row() has made room. */
static char *arena_put(struct text_reader *t, const char *s, size_t n)
{
	char *p = t->arena + t->arena_len;

	memcpy(p, s, n);
	p[n] = 0;
	t->arena_len += n + 1;
	return p;
}

static int ipac_row(struct text_reader *t, size_t row, char *s, char *x, struct err *e)
{
	long line = t->line;
	int len = (int)(x - s);

	size_t need = (size_t)len + (size_t)t->ncol + 1;

	if (check_text(t, s, x, line, e) < 0)
		return -1;
	/* The cells are disjoint slices of the line, so the line's length
	 * plus a NUL each is enough.  Cells of this chunk point into the
	 * arena: it may only move before the chunk's first row. */
	if (t->arena_len + need > t->arena_cap) {
		char *p;

		if (row > 0)
			return 2;
		p = realloc(t->arena, need + PAD);
		if (!p)
			return table_oom(e);
		memset(p + t->arena_cap, 0, need + PAD - t->arena_cap);
		t->arena = p;
		t->arena_cap = need;
	}
	for (int i = 0; i < t->ncol; i++) {
		int a = i == 0 ? 0 : t->ipac_pipe[i] + 1;
		int b = t->ipac_pipe[i + 1] + 1;
		const char *c;
		size_t n;
		char *cell;

		if (a > len)
			a = len;
		if (b > len)
			b = len;
		c = s + a;
		n = (size_t)(b - a);
		table_trim(&c, &n);
		if (t->null[i] && strlen(t->null[i]) == n && memcmp(t->null[i], c, n) == 0)
			n = 0;
		cell = arena_put(t, c, n);
		t->text[i][row] = cell;
	}
	{
		const char *rest = s + t->ipac_pipe[t->ipac_npipe - 1] + 1;

		if (rest < x && !is_blank(rest, x))
			return err_set(e, EXIT_INPUT,
				       "%s:%ld: data beyond the last column (after byte %d)",
				       t->name, line, t->ipac_pipe[t->ipac_npipe - 1] + 1);
	}
	return 0;
}

static long text_read(struct text_reader *t, struct table_chunk *c, struct err *e)
{
	size_t rows = 0;
	int quotes = t->fmt != TABLE_IPAC;

	if (t->fmt == TABLE_EMPTY)
		return 0;
	/* Move the unparsed rest to the front only when the free space at
	 * the end runs low: moving it every chunk would copy the buffer
	 * over and over. */
	if (t->pos > 0 && (t->pos == t->len || t->cap - t->len < t->cap / 4)) {
		memmove(t->buf, t->buf + t->pos, t->len - t->pos);
		t->len -= t->pos;
		t->pos = 0;
		t->nl = TEXT_NONE;
		t->qscan = 0;
	}
	t->arena_len = 0;
	while (rows < t->chunk_rows) {
		char *s, *x;
		int r = text_line(t, &s, &x, quotes, rows == 0, e);

		if (r < 0)
			return -1;
		if (r == 0 || r == 2)
			break;
		/* Blank and comment lines; a quick test first, as nearly
		 * every line starts with a digit or sign. */
		if (s == x || *s == '#' || *s == ' ' || *s == '\t' ||
		    (t->fmt == TABLE_IPAC && (*s == '\\' || *s == '|'))) {
			const char *p = skip_blank(s, x);

			if (p == x || *p == '#')
				continue;
			if (t->fmt == TABLE_IPAC && (*p == '\\' || *p == '|')) {
				/* A header repeated by a chunked writer. */
				continue;
			}
		}
		if (t->fmt == TABLE_IPAC) {
			r = ipac_row(t, rows, s, x, e);
			if (r < 0)
				return -1;
			if (r == 2) {
				text_unread(t, s);
				break;
			}
		} else {
			int nf = split_line(t, s, x, t->line - t->consumed + 1, e);

			if (nf < 0)
				return -1;
			if (nf != t->ncol)
				return err_set(e, EXIT_INPUT,
					       "%s:%ld: row has %d field%s, the header has %d",
					       t->name, t->line - t->consumed + 1, nf,
					       nf == 1 ? "" : "s", t->ncol);
			for (int i = 0; i < nf; i++)
				t->text[i][rows] = t->fields[i];
		}
		t->line_of[rows] = t->line - t->consumed + 1;
		rows++;
	}
	c->n = rows;
	c->padded = 1;
	c->file = t->name;
	c->line = t->line_of;
	c->text = t->text;
	c->num = t->num;
	return (long)rows;
}

static int alloc_chunk(struct text_reader *t, struct err *e)
{
	size_t nc = (size_t)(t->ncol ? t->ncol : 1), n;

	/* A very wide table is read in fewer rows per chunk, so the cell
	 * pointers stay under TABLE_MAX_CELLS x 8 bytes. */
	if (t->chunk_rows > TABLE_MAX_CELLS / nc)
		t->chunk_rows = TABLE_MAX_CELLS / nc > 0 ? TABLE_MAX_CELLS / nc : 1;
	n = t->chunk_rows;

	t->cells = calloc(nc * n, sizeof(*t->cells));
	t->text = calloc(nc, sizeof(*t->text));
	t->num = calloc(nc, sizeof(*t->num));
	t->line_of = calloc(n, sizeof(*t->line_of));
	if (!t->cells || !t->text || !t->num || !t->line_of)
		return table_oom(e);
	for (size_t i = 0; i < (size_t)t->ncol; i++)
		t->text[i] = t->cells + i * n;
	if (t->fmt == TABLE_IPAC) {
		/* IPAC cells are copied (a value may touch the next column's
		 * slice): room for the whole text buffer is enough. */
		t->arena_cap = t->cap + (size_t)t->ncol * 64;
		t->arena = calloc(t->arena_cap + PAD, 1);
		if (!t->arena)
			return table_oom(e);
	}
	return 0;
}

static void text_close(void *rd)
{
	struct text_reader *t = rd;

	if (!t)
		return;
	for (int i = 0; i < t->nnull; i++)
		free(t->null[i]);
	free(t->null);
	free(t->buf);
	free(t->ipac_pipe);
	free(t->arena);
	free(t->fields);
	free(t->cells);
	free(t->text);
	free(t->num);
	free(t->line_of);
	free(t);
}

static long text_read_chunk(void *rd, struct table_chunk *c, struct err *e)
{
	return text_read(rd, c, e);
}

static const struct table_reader text_ops = { text_read_chunk, text_close };

int table_text_open(struct table *tab, struct input *in, size_t chunk_rows,
		    struct err *e)
{
	struct text_reader *t = calloc(1, sizeof(*t));
	const void *pk;
	ssize_t n;

	if (!t)
		return table_oom(e);
	t->tab = tab;
	t->in = in;
	t->name = table_name(tab);
	t->chunk_rows = chunk_rows;
	t->nl = TEXT_NONE;
	table_set_reader(tab, &text_ops, t);
	t->cap = TABLE_BUF;
	t->buf = calloc(t->cap + PAD, 1);
	if (!t->buf)
		return table_oom(e);
	n = input_peek(in, &pk, 3, e);
	if (n < 0)
		return -1;
	/* A UTF-8 byte order mark is not part of the first column's name. */
	if (n >= 3 && memcmp(pk, "\xef\xbb\xbf", 3) == 0) {
		char bom[3];

		if (input_read(in, bom, 3, e) != 3)
			return -1;
	}
	n = input_peek(in, &pk, 7, e);
	if (n < 0)
		return -1;
	t->fmt = n == 7 && memcmp(pk, "# %ECSV", 7) == 0 ? TABLE_ECSV : TABLE_CSV;
	if (text_header(t, e) < 0)
		return -1;
	t->ncol = table_ncol(tab);
	table_set_format(tab, t->fmt);
	return alloc_chunk(t, e);
}
