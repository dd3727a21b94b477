/*
 * table.c - the table core: a table's columns (names, units, kinds) and
 * metadata, which its format's reader declares, and chunks of rows read
 * through that reader (table_text.c for CSV, whitespace, IPAC and ECSV,
 * table_fits.c for FITS; table_open.c chooses).  See table.h for the API
 * the catalog reads through and table_build.h for what the readers use.
 */
#include <ctype.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "err.h"
#include "input.h"
#include "table_build.h"

struct table_col {
	char *name;
	char *unit;             /* the unit, then after its NUL the place it
	                           was given ("" when not known) */
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
	/* The columns by name: an open-addressing hash of column index + 1
	 * (0 an empty slot), nslot a power of two at least twice ncol, so
	 * that a header of a million names is checked for duplicates, and
	 * its columns found, in time linear in its length. */
	int *slot;
	size_t nslot;
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

/* FNV-1a, its bits then mixed (MurmurHash3's finaliser) so that the
 * low bits the slots use depend on every byte of the name. */
static uint64_t name_hash(const char *s)
{
	uint64_t h = 14695981039346656037u;

	for (; *s; s++)
		h = (h ^ (unsigned char)*s) * 1099511628211u;
	h ^= h >> 33;
	h *= 0xff51afd7ed558ccdu;
	h ^= h >> 33;
	h *= 0xc4ceb9fe1a85ec53u;
	h ^= h >> 33;
	return h;
}

/* The slot of name: the one holding it, or the empty one where it would
 * go. */
static size_t find_slot(const struct table *t, const char *name)
{
	size_t mask = t->nslot - 1, i = (size_t)name_hash(name) & mask;

	while (t->slot[i] && strcmp(t->col[t->slot[i] - 1].name, name) != 0)
		i = (i + 1) & mask;
	return i;
}

/* Room in the hash for one more column. */
static int grow_slots(struct table *t)
{
	size_t n = t->nslot ? t->nslot : 32;
	int *s;

	if (2 * ((size_t)t->ncol + 1) <= t->nslot)
		return 0;
	while (2 * ((size_t)t->ncol + 1) > n)
		n *= 2;
	if (!(s = calloc(n, sizeof(*s))))
		return -1;
	free(t->slot);
	t->slot = s;
	t->nslot = n;
	for (int c = 0; c < t->ncol; c++)
		t->slot[find_slot(t, t->col[c].name)] = c + 1;
	return 0;
}

int table_add_column(struct table *t, const char *name, size_t len,
		     struct err *e)
{
	char *lc;
	size_t k;

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
	if (grow_slots(t) < 0)
		return table_oom(e);
	lc = table_memdup0(name, len);
	if (!lc)
		return table_oom(e);
	for (char *p = lc; *p; p++)
		*p = (char)tolower((unsigned char)*p);
	k = find_slot(t, lc);
	if (t->slot[k]) {
		err_set(e, EXIT_INPUT, "%s:%ld: duplicate column '%s' (columns %d and %d)",
			t->name, t->header_line, lc, t->slot[k], t->ncol + 1);
		free(lc);
		return -1;
	}
	t->slot[k] = t->ncol + 1;
	t->col[t->ncol].name = lc;
	t->col[t->ncol].unit = NULL;
	t->col[t->ncol].kind = TABLE_TEXT;
	t->ncol++;
	return 0;
}

int table_column(const struct table *t, const char *name)
{
	return t->nslot ? t->slot[find_slot(t, name)] - 1 : -1;
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
	return table_set_unit_at(t, col, unit, len, NULL, e);
}

int table_set_unit_at(struct table *t, int col, const char *unit, size_t len,
		      const char *where, struct err *e)
{
	size_t nn = where ? strlen(t->name) : 0, wn = where ? strlen(where) : 0;
	char *u;

	table_unquote(&unit, &len);
	u = malloc(len + 1 + nn + wn + 1);
	if (!u)
		return table_oom(e);
	memcpy(u, unit, len);
	u[len] = 0;
	memcpy(u + len + 1, t->name, nn);
	memcpy(u + len + 1 + nn, where ? where : "", wn + 1);
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

const char *table_colunit_place(const struct table *t, int c)
{
	const char *u = t->col[c].unit;

	if (!u || !u[strlen(u) + 1])
		return t->name;
	return u + strlen(u) + 1;
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
	free(t->slot);
	for (int i = 0; i < t->nmeta; i++) {
		free(t->meta[i].key);
		free(t->meta[i].val);
	}
	free(t->meta);
	free(t->name);
	free(t);
}
