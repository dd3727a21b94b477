/*
 * table.c - the table core: a table's columns (names, units, kinds) and
 * metadata, which its format's reader declares, and chunks of rows read
 * through that reader (table_text.c for CSV, whitespace, IPAC and ECSV,
 * table_fits.c for FITS; table_open.c chooses).  See table.h for the API
 * the catalog reads through and table_build.h for what the readers use.
 */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "err.h"
#include "input.h"
#include "table_build.h"

struct table_col {
	char *name;
	char *unit;
	enum table_kind kind;
};

struct table_kv {
	char *key, *val;
};

struct table {
	struct input *in;
	char *name;
	enum table_format fmt;
	struct table_col *col;
	int ncol, col_cap;
	struct table_kv *meta;
	int nmeta, meta_cap;
	long header_line;
	const struct table_reader *reader;
	void *rd;               /* the reader's state */
};

int table_oom(struct err *e)
{
	return err_set(e, EXIT_SYSTEM, "out of memory");
}

char *table_memdup0(const char *s, size_t n)
{
	char *d = malloc(n + 1);

	if (d) {
		memcpy(d, s, n);
		d[n] = 0;
	}
	return d;
}

void table_trim(const char **s, size_t *n)
{
	while (*n && isspace((unsigned char)**s))
		(*s)++, (*n)--;
	while (*n && isspace((unsigned char)(*s)[*n - 1]))
		(*n)--;
}

void table_unquote(const char **s, size_t *n)
{
	table_trim(s, n);
	if (*n >= 2 && ((*s)[0] == '\'' || (*s)[0] == '"') &&
	    (*s)[*n - 1] == (*s)[0]) {
		(*s)++;
		*n -= 2;
		table_trim(s, n);
	}
}

int table_add_column(struct table *t, const char *name, size_t len,
		     struct err *e)
{
	char *lc;
	int i;

	table_trim(&name, &len);
	if (len >= 2 && name[0] == '"' && name[len - 1] == '"')
		name++, len -= 2;
	if (len == 0)
		return err_set(e, EXIT_INPUT, "%s:%ld: empty column name (column %d)",
			       t->name, t->header_line, t->ncol + 1);
	if (t->ncol == t->col_cap) {
		int cap = t->col_cap ? 2 * t->col_cap : 16;
		struct table_col *c = realloc(t->col, (size_t)cap * sizeof(*c));

		if (!c)
			return table_oom(e);
		t->col = c;
		t->col_cap = cap;
	}
	lc = table_memdup0(name, len);
	if (!lc)
		return table_oom(e);
	for (char *p = lc; *p; p++)
		*p = (char)tolower((unsigned char)*p);
	for (i = 0; i < t->ncol; i++)
		if (strcmp(t->col[i].name, lc) == 0) {
			err_set(e, EXIT_INPUT, "%s:%ld: duplicate column '%s' (columns %d and %d)",
				t->name, t->header_line, lc, i + 1, t->ncol + 1);
			free(lc);
			return -1;
		}
	t->col[t->ncol].name = lc;
	t->col[t->ncol].unit = NULL;
	t->col[t->ncol].kind = TABLE_TEXT;
	t->ncol++;
	return 0;
}

int table_add_meta(struct table *t, const char *key, size_t klen,
		   const char *val, size_t vlen, struct err *e)
{
	char *k, *v;

	table_unquote(&key, &klen);
	table_unquote(&val, &vlen);
	if (klen == 0)
		return 0;
	/* The first value of a key wins, as a later HDU's header must not
	 * override the file's. */
	for (int i = 0; i < t->nmeta; i++)
		if (strlen(t->meta[i].key) == klen &&
		    strncasecmp(t->meta[i].key, key, klen) == 0)
			return 0;
	if (t->nmeta == t->meta_cap) {
		int cap = t->meta_cap ? 2 * t->meta_cap : 16;
		struct table_kv *m = realloc(t->meta, (size_t)cap * sizeof(*m));

		if (!m)
			return table_oom(e);
		t->meta = m;
		t->meta_cap = cap;
	}
	k = table_memdup0(key, klen);
	v = table_memdup0(val, vlen);
	if (!k || !v) {
		free(k);
		free(v);
		return table_oom(e);
	}
	t->meta[t->nmeta].key = k;
	t->meta[t->nmeta].val = v;
	t->nmeta++;
	return 0;
}

int table_set_unit(struct table *t, int col, const char *unit, size_t len,
		   struct err *e)
{
	char *u;

	table_unquote(&unit, &len);
	u = table_memdup0(unit, len);
	if (!u)
		return table_oom(e);
	free(t->col[col].unit);
	t->col[col].unit = u;
	return 0;
}

void table_set_kind(struct table *t, int col, enum table_kind kind)
{
	t->col[col].kind = kind;
}

void table_set_format(struct table *t, enum table_format fmt)
{
	t->fmt = fmt;
}

void table_set_header_line(struct table *t, long line)
{
	t->header_line = line;
}

void table_set_reader(struct table *t, const struct table_reader *reader, void *rd)
{
	t->reader = reader;
	t->rd = rd;
}

enum table_format table_format(const struct table *t) { return t->fmt; }
const char *table_name(const struct table *t) { return t->name; }
int table_ncol(const struct table *t) { return t->ncol; }
const char *table_colname(const struct table *t, int c) { return t->col[c].name; }
enum table_kind table_colkind(const struct table *t, int c) { return t->col[c].kind; }
long table_header_line(const struct table *t) { return t->header_line; }

const char *table_colunit(const struct table *t, int c)
{
	return t->col[c].unit ? t->col[c].unit : "";
}

const char *table_meta(const struct table *t, const char *key)
{
	for (int i = 0; i < t->nmeta; i++)
		if (strcasecmp(t->meta[i].key, key) == 0)
			return t->meta[i].val;
	return NULL;
}

unsigned long long table_raw_bytes(const struct table *t)
{
	return t->in ? input_raw_bytes(t->in) : 0;
}
struct table *table_new(struct input *in, struct err *e)
{
	struct table *t = calloc(1, sizeof(*t));

	if (!t) {
		input_close(in);
		table_oom(e);
		return NULL;
	}
	t->in = in;
	if (!(t->name = strdup(input_name(in)))) {
		table_close(t);
		table_oom(e);
		return NULL;
	}
	return t;
}

long table_read(struct table *t, struct table_chunk *c, struct err *e)
{
	memset(c, 0, sizeof(*c));
	c->file = t->name;
	return t->reader->read(t->rd, c, e);
}

const char *table_text(const struct table_chunk *c, int col, size_t row)
{
	const char *s = c->text[col][row];

	return s ? s : c->cell_text(c->src, col, row);
}

void table_close(struct table *t)
{
	if (!t)
		return;
	if (t->reader)
		t->reader->close(t->rd);
	input_close(t->in);
	for (int i = 0; i < t->ncol; i++) {
		free(t->col[i].name);
		free(t->col[i].unit);
	}
	free(t->col);
	for (int i = 0; i < t->nmeta; i++) {
		free(t->meta[i].key);
		free(t->meta[i].val);
	}
	free(t->meta);
	free(t->name);
	free(t);
}
