/*
 * table_header.c - the headers of the text tables (table_text.h): the
 * column line of CSV and whitespace tables (and their "\key=value"
 * metadata lines), IPAC's "|name|" lines with their types, units and null
 * values, and ECSV's YAML header, read as far as wfiscene needs it.  The
 * lines come from table_lines.c's buffer; the columns, units and metadata
 * go to the table core through table_build.h.
 */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "err.h"
#include "table_text.h"

/* "\key=value" or "\key = 'value'"; "\ comment" and "\comment" are
 * ignored. */
static int meta_line(struct text_reader *t, const char *s, const char *e, struct err *ep)
{
	const char *eq;

	s++;
	eq = memchr(s, '=', (size_t)(e - s));
	if (!eq || s == e || *s == ' ')
		return 0;
	return table_add_meta(t->tab, s, (size_t)(eq - s), eq + 1, (size_t)(e - eq - 1), ep);
}

/* IPAC "|a|b|c|" lines: the first gives names and pipe positions; the
 * next up to three give types, units and null values. */
static int ipac_header(struct text_reader *t, char *ls, char *le, struct err *e)
{
	int np = 0;
	int which = 0;
	char *s, *x, where[32];

	for (char *p = ls; p < le; p++)
		if (*p == '|')
			np++;
	t->ipac_pipe = malloc((size_t)np * sizeof(int));
	if (!t->ipac_pipe)
		return table_oom(e);
	for (char *p = ls; p < le; p++)
		if (*p == '|')
			t->ipac_pipe[t->ipac_npipe++] = (int)(p - ls);
	while (le > ls && (le[-1] == ' ' || le[-1] == '\t'))
		le--;
	if (np < 2 || le[-1] != '|')
		return err_set(e, EXIT_INPUT, "%s:%ld: IPAC header needs '|name|name|' columns",
			       t->name, t->line);
	table_set_header_line(t->tab, t->line);
	for (int i = 0; i + 1 < np; i++)
		if (table_add_column(t->tab, ls + t->ipac_pipe[i] + 1,
				     (size_t)(t->ipac_pipe[i + 1] - t->ipac_pipe[i] - 1), e) < 0)
			return -1;
	t->null = calloc((size_t)np, sizeof(*t->null));
	if (!t->null)
		return table_oom(e);
	t->nnull = np;
	/* Types, units, nulls. */
	for (which = 1; which <= 3; which++) {
		int r = text_line(t, &s, &x, 0, 1, e);

		if (r < 0)
			return -1;
		if (r == 0)
			break;
		if (s == x || s[0] != '|') {
			text_unread(t, s);
			break;
		}
		if (check_text(t, s, x, t->line, e) < 0)
			return -1;
		/* Split by this line's own pipes: they should stand where the
		 * name line's do, but nothing is gained by insisting. */
		{
			int k = 0;

			for (char *p = s; p < x; p++)
				k += *p == '|';
			while (x > s && (x[-1] == ' ' || x[-1] == '\t'))
				x--;
			if (k != np || x[-1] != '|')
				return err_set(e, EXIT_INPUT,
					       "%s:%ld: IPAC header line has %d pipes, the name line has %d",
					       t->name, t->line, k, np);
		}
		snprintf(where, sizeof(where), ":%ld", t->line);
		s = memchr(s, '|', (size_t)(x - s)) + 1;
		for (int i = 0; i + 1 < np; i++) {
			const char *c = s, *b = memchr(s, '|', (size_t)(x - s));
			size_t n = (size_t)(b - c);

			s = (char *)b + 1;
			table_trim(&c, &n);
			if (which == 2 && n && table_set_unit_at(t->tab, i, c, n, where, e) < 0)
				return -1;
			if (which == 3 && n) {
				t->null[i] = table_memdup0(c, n);
				if (!t->null[i])
					return table_oom(e);
			}
		}
	}
	return 0;
}

/* ---- ECSV: the YAML header, read as far as wfiscene needs it ---- */

/* Find "key: value" pairs in a flow mapping "{a: b, c: 'd'}" and call
 * fn for each. */
static int flow_pairs(const char *s, const char *e,
		      int (*fn)(void *, const char *, size_t, const char *, size_t, struct err *),
		      void *ctx, struct err *ep)
{
	s = skip_blank(s, e);
	if (s < e && *s == '{')
		s++;
	while (e > s && (e[-1] == ' ' || e[-1] == '}'))
		e--;
	while (s < e) {
		const char *a = s, *colon = NULL;
		char q = 0;

		while (s < e) {
			if (q) {
				if (*s == q)
					q = 0;
			} else if (*s == '\'' || *s == '"') {
				q = *s;
			} else if (*s == ':' && !colon && s + 1 < e && s[1] == ' ') {
				colon = s;
			} else if (*s == ':' && !colon && s + 1 == e) {
				colon = s;
			} else if (*s == ',') {
				break;
			}
			s++;
		}
		if (colon && fn(ctx, a, (size_t)(colon - a), colon + 1,
				(size_t)(s - colon - 1), ep) < 0)
			return -1;
		if (s < e)
			s++;
	}
	return 0;
}

struct ecsv_col {
	struct text_reader *t;
	char *name, *unit;
	long unit_line;         /* the line of the unit, for messages */
};

static int ecsv_meta_pair(void *ctx, const char *k, size_t kn, const char *v,
			  size_t vn, struct err *e)
{
	struct text_reader *t = ctx;
	const char *vv = v;
	size_t n = vn;

	table_trim(&vv, &n);
	if (n == 0 || vv[0] == '{' || vv[0] == '[' || vv[0] == '!')
		return 0;       /* nested: not a scalar */
	return table_add_meta(t->tab, k, kn, v, vn, e);
}

static int ecsv_col_pair(void *ctx, const char *k, size_t kn, const char *v,
			 size_t vn, struct err *e)
{
	struct ecsv_col *c = ctx;

	table_unquote(&k, &kn);
	table_unquote(&v, &vn);
	if (kn == 4 && memcmp(k, "name", 4) == 0) {
		free(c->name);
		c->name = table_memdup0(v, vn);
		if (!c->name)
			return table_oom(e);
	} else if (kn == 4 && memcmp(k, "unit", 4) == 0) {
		free(c->unit);
		c->unit = table_memdup0(v, vn);
		if (!c->unit)
			return table_oom(e);
		c->unit_line = c->t->line;
	}
	return 0;
}

struct ecsv_state {
	char *section;          /* current top-level key */
	struct ecsv_col cur;
	char **unit_name, **unit_val;
	long *unit_line;
	int nunit, unit_cap;
};

static int ecsv_flush_col(struct ecsv_state *st, struct err *e)
{
	if (st->cur.name) {
		if (st->nunit == st->unit_cap) {
			int cap = st->unit_cap ? 2 * st->unit_cap : 16;
			char **a = realloc(st->unit_name, (size_t)cap * sizeof(*a));
			long *l;

			if (!a)
				return table_oom(e);
			st->unit_name = a;
			a = realloc(st->unit_val, (size_t)cap * sizeof(*a));
			if (!a)
				return table_oom(e);
			st->unit_val = a;
			l = realloc(st->unit_line, (size_t)cap * sizeof(*l));
			if (!l)
				return table_oom(e);
			st->unit_line = l;
			st->unit_cap = cap;
		}
		st->unit_name[st->nunit] = st->cur.name;
		st->unit_val[st->nunit] = st->cur.unit;
		st->unit_line[st->nunit] = st->cur.unit_line;
		st->nunit++;
	} else {
		free(st->cur.unit);
	}
	st->cur.name = st->cur.unit = NULL;
	return 0;
}

static int ecsv_yaml_line(struct text_reader *t, struct ecsv_state *st, const char *s,
			  const char *e, struct err *ep)
{
	const char *p = s;
	int indent;

	while (p < e && *p == ' ')
		p++;
	indent = (int)(p - s);
	if (p == e)
		return 0;
	if (indent == 0 && *p != '-') {
		/* A top-level key: "delimiter: ','", "datatype:", "meta: ..." */
		const char *colon = memchr(p, ':', (size_t)(e - p));
		const char *v;
		size_t kn, vn;

		if (ecsv_flush_col(st, ep) < 0)
			return -1;
		if (!colon)
			return 0;
		kn = (size_t)(colon - p);
		free(st->section);
		st->section = table_memdup0(p, kn);
		if (!st->section)
			return table_oom(ep);
		v = colon + 1;
		vn = (size_t)(e - v);
		table_trim(&v, &vn);
		if (vn == 3 && (v[0] == '\'' || v[0] == '"') && v[2] == v[0])
			v++, vn = 1;    /* ' ' must keep its blank */
		else
			table_unquote(&v, &vn);
		if (strcmp(st->section, "delimiter") == 0) {
			if (vn != 1 || (v[0] != ',' && v[0] != ' '))
				return err_set(ep, EXIT_INPUT,
					       "%s:%ld: ECSV delimiter must be ',' or ' '",
					       t->name, t->line);
			set_classes(t, v[0]);
		} else if (strcmp(st->section, "meta") == 0) {
			const char *w = v;
			size_t wn = vn;

			if (wn && w[0] == '!') { /* "!!omap" */
				while (wn && *w != ' ')
					w++, wn--;
				table_trim(&w, &wn);
			}
			if (wn && w[0] == '{')
				return flow_pairs(w, w + wn, ecsv_meta_pair, t, ep);
		}
		return 0;
	}
	if (!st->section)
		return 0;
	if (strcmp(st->section, "datatype") == 0) {
		if (*p == '-') {
			if (ecsv_flush_col(st, ep) < 0)
				return -1;
			p = skip_blank(p + 1, e);
			if (p < e && *p == '{')
				return flow_pairs(p, e, ecsv_col_pair, &st->cur, ep);
		}
		return flow_pairs(p, e, ecsv_col_pair, &st->cur, ep);
	}
	if (strcmp(st->section, "meta") == 0) {
		if (*p == '-')
			p = skip_blank(p + 1, e);
		/* Only the first level of meta holds the scalars wfiscene
		 * reads (type, filter, fluxunit); deeper ones are skipped. */
		if (indent > 4)
			return 0;
		return flow_pairs(p, e, ecsv_meta_pair, t, ep);
	}
	return 0;
}

static int ecsv_header(struct text_reader *t, struct ecsv_state *st, struct err *e)
{
	char *s, *x;
	int r, yaml = 0;

	for (;;) {
		r = text_line(t, &s, &x, 0, 1, e);
		if (r <= 0)
			return r;
		if (check_text(t, s, x, t->line, e) < 0)
			return -1;
		if (s == x || s[0] != '#') {
			text_unread(t, s);
			return ecsv_flush_col(st, e) < 0 ? -1 : 1;
		}
		s++;
		if (s < x && *s == ' ')
			s++;
		if (!yaml) {
			if (x - s >= 3 && memcmp(s, "---", 3) == 0)
				yaml = 1;
			continue;
		}
		if (ecsv_yaml_line(t, st, s, x, e) < 0)
			return -1;
	}
}

/* Read the header of a text table.  Returns 0, or -1. */
int text_header(struct text_reader *t, struct err *e)
{
	struct ecsv_state st = { .cur.t = t };
	char *s, *x;
	int r, rc = -1;

	if (t->fmt == TABLE_ECSV) {
		set_classes(t, ' ');
		r = ecsv_header(t, &st, e);
		if (r < 0)
			goto out;
		if (r == 0) {
			t->fmt = TABLE_EMPTY;
			rc = 0;
			goto out;
		}
	}
	for (;;) {
		r = text_line(t, &s, &x, 0, 1, e);
		if (r < 0)
			goto out;
		if (r == 0) {
			/* Nothing but comments: an empty catalog. */
			if (t->fmt != TABLE_ECSV)
				t->fmt = TABLE_EMPTY;
			rc = 0;
			goto out;
		}
		if (check_text(t, s, x, t->line, e) < 0)
			goto out;
		if (is_blank(s, x))
			continue;
		if (t->fmt == TABLE_ECSV)
			break;
		{
			const char *p = skip_blank(s, x);

			if (*p == '#')
				continue;
			if (*p == '\\') {
				if (meta_line(t, p, x, e) < 0)
					goto out;
				continue;
			}
			if (*p == '|') {
				t->fmt = TABLE_IPAC;
				rc = ipac_header(t, s, x, e);
				goto out;
			}
			if (memchr(s, ',', (size_t)(x - s))) {
				t->fmt = TABLE_CSV;
				set_classes(t, ',');
			} else {
				t->fmt = TABLE_WS;
				set_classes(t, ' ');
			}
		}
		break;
	}
	table_set_header_line(t->tab, t->line);
	{
		char save = *x;
		int nf = split_line(t, s, x, t->line, e);

		if (nf < 0)
			goto out;
		for (int i = 0; i < nf; i++)
			if (table_add_column(t->tab, t->fields[i], strlen(t->fields[i]), e) < 0)
				goto out;
		(void)save;
	}
	/* The datatype entries' units, each to its column (names match
	 * case-insensitively; the columns' are lower-case). */
	for (int i = 0; i < st.nunit; i++) {
		char where[32];
		int c;

		if (!st.unit_val[i])
			continue;
		for (char *p = st.unit_name[i]; *p; p++)
			*p = (char)tolower((unsigned char)*p);
		if ((c = table_column(t->tab, st.unit_name[i])) < 0)
			continue;
		snprintf(where, sizeof(where), ":%ld", st.unit_line[i]);
		if (table_set_unit_at(t->tab, c, st.unit_val[i], strlen(st.unit_val[i]),
				      where, e) < 0)
			goto out;
	}
	rc = 0;
out:
	for (int i = 0; i < st.nunit; i++) {
		free(st.unit_name[i]);
		free(st.unit_val[i]);
	}
	free(st.unit_name);
	free(st.unit_val);
	free(st.unit_line);
	free(st.section);
	free(st.cur.name);
	free(st.cur.unit);
	return rc;
}
