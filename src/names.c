/*
 * names.c - file names from templates; see names.h.
 *
 * One scanner reads a template for both checking and expanding, so what is
 * checked is exactly what is expanded.  Nothing here hands a user's string
 * to printf as a format: the SCA number is formatted with a literal "%0*d"
 * or "%*d" and copied in.
 */
#include <stdio.h>
#include <string.h>

#include "names.h"

/* One piece of a template: literal text (len bytes at text), or a field. */
struct piece {
	enum { PIECE_TEXT, PIECE_SCA, PIECE_EXPOSURE, PIECE_BAD } kind;
	const char *text;
	size_t len;
	int width, zero;        /* %d's */
};

/* The piece at *p, advancing *p past it. */
static struct piece next_piece(const char **p)
{
	const char *s = *p, *q;
	struct piece k = { PIECE_TEXT, s, 0, 0, 0 };

	if (*s != '%') {
		q = strchr(s, '%');
		k.len = q ? (size_t)(q - s) : strlen(s);
		*p = s + k.len;
		return k;
	}
	if (s[1] == '%') {
		k.len = 1;      /* the second '%' */
		k.text = s + 1;
		*p = s + 2;
		return k;
	}
	if (s[1] == 's') {
		k.kind = PIECE_EXPOSURE;
		*p = s + 2;
		return k;
	}
	q = s + 1;
	while (*q == '0') {
		k.zero = 1;
		q++;
	}
	while (*q >= '0' && *q <= '9' && k.width <= NAME_WIDTH_MAX)
		k.width = 10 * k.width + (*q++ - '0');
	if (*q == 'd' && k.width <= NAME_WIDTH_MAX) {
		k.kind = PIECE_SCA;
		*p = q + 1;
		return k;
	}
	/* the offending escape, for the message: '%' and what follows it up
	 * to and including the first letter (or the end) */
	k.kind = PIECE_BAD;
	while (*q && !((*q >= 'a' && *q <= 'z') || (*q >= 'A' && *q <= 'Z')) && q - s < 24)
		q++;
	k.len = (size_t)(q - s) + (*q ? 1 : 0);
	*p = s + k.len;
	return k;
}

static const char *field_help(unsigned allow)
{
	switch (allow & (NAME_SCA | NAME_EXPOSURE)) {
	case NAME_SCA:
		return "'%d' (the SCA) and '%%' (a '%')";
	case NAME_EXPOSURE:
		return "'%s' (the exposure, with --pointings) and '%%' (a '%')";
	case NAME_SCA | NAME_EXPOSURE:
		return "'%d' (the SCA), '%s' (the exposure, with --pointings) and '%%' (a '%')";
	default:
		return "'%%' (a '%')";
	}
}

int name_check(const char *what, const char *tmpl, unsigned allow, unsigned need,
	       struct err *e)
{
	int nd = 0, ns = 0;

	for (const char *p = tmpl; *p;) {
		struct piece k = next_piece(&p);

		if (k.kind == PIECE_BAD) {
			if (k.text[1] && strchr("0123456789", k.text[1]) && k.text[k.len - 1] == 'd')
				return err_set(e, EXIT_INPUT, "%s: '%s': '%.*s': a %%d is at most %d "
					       "wide", what, tmpl, (int)k.len, k.text, NAME_WIDTH_MAX);
			return err_set(e, EXIT_INPUT, "%s: '%s': '%.*s' is not a field of a file "
				       "name; only %s may follow a '%%'", what, tmpl, (int)k.len,
				       k.text, field_help(allow));
		}
		nd += k.kind == PIECE_SCA;
		ns += k.kind == PIECE_EXPOSURE;
	}
	if (nd > 1 || ns > 1)
		return err_set(e, EXIT_INPUT, "%s: '%s': only one '%%d' and one '%%s' may "
			       "appear in a name", what, tmpl);
	if (nd && !(allow & NAME_SCA))
		return err_set(e, EXIT_INPUT, "%s: '%s': one file covers every SCA; no '%%d'",
			       what, tmpl);
	if (ns && !(allow & NAME_EXPOSURE) && (allow & NAME_NEEDS_POINTINGS))
		return err_set(e, EXIT_INPUT, "%s: '%s': '%%s' stands for the exposure's name "
			       "and needs --pointings", what, tmpl);
	if (ns && !(allow & NAME_EXPOSURE))
		return err_set(e, EXIT_INPUT, "%s: '%s': no exposure's name ('%%s') here; only "
			       "%s may follow a '%%'", what, tmpl, field_help(allow));
	if (!nd && (need & NAME_SCA))
		return err_set(e, EXIT_INPUT, "%s: '%s' needs a '%%d' for the SCA", what, tmpl);
	if (!ns && (need & NAME_EXPOSURE))
		return err_set(e, EXIT_INPUT, "%s: '%s' needs a '%%s' for the exposure's name "
			       "with --pointings", what, tmpl);
	return 0;
}

unsigned name_fields(const char *tmpl)
{
	unsigned f = 0;

	for (const char *p = tmpl; *p;) {
		struct piece k = next_piece(&p);

		if (k.kind == PIECE_BAD)
			return 0;
		f |= k.kind == PIECE_SCA ? NAME_SCA : k.kind == PIECE_EXPOSURE ? NAME_EXPOSURE : 0;
	}
	return f;
}

int name_expand(char *out, size_t cap, const char *what, const char *tmpl, int sca,
		const char *expo, struct err *e)
{
	size_t n = 0;

	if (cap == 0)
		return err_set(e, EXIT_INPUT, "%s: '%s': no room for a name", what, tmpl);
	if (name_check(what, tmpl, NAME_SCA | NAME_EXPOSURE, 0, e) < 0)
		return -1;
	for (const char *p = tmpl; *p;) {
		struct piece k = next_piece(&p);
		char num[NAME_WIDTH_MAX + 16];
		const char *add = k.text;
		size_t len = k.len;

		if (k.kind == PIECE_SCA) {
			snprintf(num, sizeof(num), k.zero ? "%0*d" : "%*d", k.width, sca);
			add = num;
			len = strlen(num);
		} else if (k.kind == PIECE_EXPOSURE) {
			if (!expo)
				return err_set(e, EXIT_INPUT, "%s: '%s': '%%s' stands for the "
					       "exposure's name and needs --pointings", what, tmpl);
			add = expo;
			len = strlen(expo);
		}
		if (len >= cap - n)
			return err_set(e, EXIT_INPUT, "%s: '%s': the name is longer than %zu "
				       "bytes", what, tmpl, cap - 1);
		memcpy(out + n, add, len);
		n += len;
	}
	out[n] = 0;
	return 0;
}
