/*
 * catalog_units.c - the names of flux units a catalog may give (a column's
 * unit, a fluxunit keyword, a units cell), and a row's flux as the catalog
 * gave it, for messages.
 */
#include <ctype.h>
#include <stdio.h>
#include <string.h>

#include "catalog.h"

int catalog_unit_code(const char *s)
{
	char b[32];
	size_t n = 0;
	static const struct { const char *name; int code; } names[] = {
		{ "c", UNIT_COUNTS }, { "counts", UNIT_COUNTS },
		{ "count", UNIT_COUNTS }, { "counts/s", UNIT_COUNTS },
		{ "ct/s", UNIT_COUNTS }, { "e/s", UNIT_COUNTS },
		{ "e-/s", UNIT_COUNTS }, { "electron/s", UNIT_COUNTS },
		{ "electrons/s", UNIT_COUNTS }, { "cps", UNIT_COUNTS },
		{ "counts/sec", UNIT_COUNTS }, { "ct/sec", UNIT_COUNTS },
		{ "e/sec", UNIT_COUNTS }, { "e-/sec", UNIT_COUNTS },
		{ "electrons/sec", UNIT_COUNTS }, { "electron/sec", UNIT_COUNTS },
		{ "cts-1", UNIT_COUNTS }, { "electrons-1", UNIT_COUNTS },
		{ "1/s", UNIT_COUNTS }, { "s-1", UNIT_COUNTS },
		{ "m", UNIT_ABMAG }, { "abmag", UNIT_ABMAG }, { "ab", UNIT_ABMAG },
		{ "mag", UNIT_ABMAG }, { "mag(ab)", UNIT_ABMAG },
		{ "j", UNIT_JY }, { "jy", UNIT_JY }, { "jansky", UNIT_JY },
		{ "p", UNIT_PHOT }, { "e", UNIT_ERG },
		{ "maggies", UNIT_MAGGIES }, { "maggy", UNIT_MAGGIES },
		{ "nanomaggies", UNIT_NMGY }, { "nmgy", UNIT_NMGY },
	};

	for (; *s && n + 1 < sizeof(b); s++)
		if (!isspace((unsigned char)*s))
			b[n++] = (char)tolower((unsigned char)*s);
	if (*s)
		return 0;
	b[n] = 0;
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (strcmp(b, names[i].name) == 0)
			return names[i].code;
	return 0;
}

/* The name a message gives unit u (enum flux_unit). */
static const char *unit_name(int u)
{
	switch (u) {
	case UNIT_COUNTS:
		return "counts/s";
	case UNIT_ABMAG:
		return "AB mag";
	case UNIT_JY:
		return "Jy";
	case UNIT_PHOT:
		return "STIPS unit p";
	case UNIT_ERG:
		return "STIPS unit e";
	case UNIT_MAGGIES:
		return "maggies";
	case UNIT_NMGY:
		return "nanomaggies";
	}
	return "unknown unit";
}

const char *rows_flux_text(const struct rows *r, size_t i, char *buf, size_t size)
{
	const char *s, *us;
	char num[32];
	size_t n;
	int u = r->flux_unit, cu;

	if (r->flux_col < 0 || r->flux_col >= r->ncol) {
		snprintf(buf, size, "flux %.9g", r->flux[i]);
		return buf;
	}
	/* The cell as written.  A FITS double has no text until rows_text()
	 * writes it into the reader's buffer, which another thread may be
	 * reading: its text is made here, as table_fits.c makes it. */
	s = r->text[r->flux_col][i];
	if (!s) {
		snprintf(num, sizeof(num), "%.17g", r->num[r->flux_col][i]);
		s = num;
	}
	while (*s == ' ' || *s == '\t')
		s++;
	for (n = strlen(s); n && (s[n - 1] == ' ' || s[n - 1] == '\t'); n--)
		;
	/* the row's units cell, when it has one, else the column's unit
	 * (read_flux() has refused any cell that names no unit) */
	if (r->units_col >= 0 && (us = r->text[r->units_col][i]) && (cu = catalog_unit_code(us)))
		u = cu;
	snprintf(buf, size, "column '%s': %.*s (%s)", r->colname[r->flux_col],
		 (int)(n < 40 ? n : 40), s, unit_name(u));
	return buf;
}
