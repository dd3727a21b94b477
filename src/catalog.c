/*
 * catalog.c - the catalog layer: gives the columns of a table (table.h)
 * their meaning, as wfiscene-catalog(5) documents; see catalog.h.
 *
 * Numbers are parsed by catalog_number.c's decimal parser
 * (catalog_parse_double), exact for the common case without strtod, since
 * parsing dominates the cost of a faint-star catalog.
 */
#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "catalog.h"
#include "catalog_number.h"
#include "err.h"
#include "instrument.h"
#include "rowpool.h"
#include "motion.h"
#include "spectrum.h"
#include "table.h"
#include "tree.h"

/* Magnitudes outside this range are surely a mistake (99 for "no data",
 * a flux in the magnitude column); an error beats a blank or blinding
 * image. */
#define CATALOG_MAG_MIN (-20.0)
#define CATALOG_MAG_MAX 50.0

enum stips_type { STIPS_NONE, STIPS_INTERNAL, STIPS_MIXED, STIPS_MULTI,
	STIPS_GENERIC };

struct catalog {
	struct table *t;
	struct catalog_opts o;
	enum stips_type stips;
	int sky;                /* 1: ra, dec; 0: x, y */
	int c_ra, c_dec, c_x, c_y, c_sca, c_flux, c_mag, c_units, c_type, c_id;
	int flux_unit;          /* unit of the flux column, per file */
	/* romanisim's convention (wfiscene-catalog(5) ROMANISIM CATALOGS):
	 * its columns are given wfiscene's meaning; half_light_radius
	 * (arcsec) becomes the extra column "re" (pixels), ncol_table + 0. */
	int roman;
	int c_hlr, c_pa, c_ba;
	int ncol_table;         /* columns of the table; rows have one more
	                           ("re") in romanisim's convention */
	double *re_num;         /* the "re" column's values */
	const char **re_text;   /* NULL (use re_num) or "" for an empty cell */
	const char ***text_ext; /* the chunk's text[] with "re" appended */
	const double **num_ext;

	/* A catalog tree (tree.h): its files are read in turn as one
	 * catalog, all with the columns of the first that has any. */
	struct tree *tree;
	size_t tree_next;       /* the next file of the tree to open */
	char **first_cols;      /* the first table's column names */
	int nfirst;
	int first_roman;
	unsigned long long bytes_done;  /* raw bytes of the tables closed */
	char *dir;              /* the tree's path, for messages */
	unsigned long long nrows;
	size_t cap;
	char **colname;

	struct table_chunk ch;  /* the last chunk read, for rows_text() */
	double *ra, *dec, *x, *y, *flux;
	int *sca;
	unsigned char *unit;
	const char **type;
	long long *id;
	/* proper motion and parallax (motion.h): the columns, or -1, and
	 * their values; motion is 1 when any of the three columns exists */
	int motion;
	int c_pmra, c_pmdec, c_plx, c_epoch;
	double *pmra, *pmdec, *plx, *epoch;
	/* the spectrum (spectrum.h): the teff, beta and color_F1_F2 columns,
	 * or -1; spectral the families they name (catalog_spectral), 0 when
	 * none exists.  A colour's filters and the
	 * factor that turns it into beta. */
	int spectral;
	int c_teff, c_beta, c_colour;
	double colour_to_beta;
	unsigned char *spec_kind;
	double *spec_value;
};

static int is_empty(const char *s)
{
	while (*s == ' ' || *s == '\t')
		s++;
	return *s == 0;
}

static int bad_number(struct err *e, const char *file, long line,
		      const char *col, const char *text, int why)
{
	if (is_empty(text))
		return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': empty value",
			       file, line, col);
	return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': %s: '%.200s'", file,
		       line, col, why == 2 ? "not a finite number" : "not a number",
		       text);
}

int rows_column(const struct rows *r, const char *name)
{
	for (int i = 0; i < r->ncol; i++)
		if (strcasecmp(r->colname[i], name) == 0)
			return i;
	return -1;
}

const char *rows_text(const struct rows *r, int col, size_t i)
{
	return table_text(r->chunk, col, i);
}

int rows_number(const struct rows *r, int col, size_t i, double fallback,
		double *out, struct err *e)
{
	const char *s = r->text[col][i];
	int rc;

	/* A FITS double: its text would read back to this value; it is
	 * written only for the message about a bad one. */
	if (!s) {
		if (isfinite(r->num[col][i])) {
			*out = r->num[col][i];
			return 0;
		}
		s = rows_text(r, col, i);
	}
	if (is_empty(s)) {
		*out = fallback;
		return 0;
	}
	rc = catalog_parse_double(s, out);
	if (rc)
		return bad_number(e, r->file, r->line[i], r->colname[col], s, rc);
	return 0;
}

/* The column named name (lower-case), or -1. */
static int col_of(const struct table *t, const char *name)
{
	return table_column(t, name);
}

static int alloc_rows(struct catalog *c, struct err *e)
{
	size_t n = c->cap;

	c->ra = malloc(n * sizeof(double));
	c->dec = malloc(n * sizeof(double));
	c->x = malloc(n * sizeof(double));
	c->y = malloc(n * sizeof(double));
	c->flux = malloc(n * sizeof(double));
	c->sca = malloc(n * sizeof(int));
	c->unit = malloc(n);
	c->type = malloc(n * sizeof(char *));
	c->id = malloc(n * sizeof(long long));
	c->re_num = malloc(n * sizeof(double));
	c->re_text = malloc(n * sizeof(char *));
	c->pmra = malloc(n * sizeof(double));
	c->pmdec = malloc(n * sizeof(double));
	c->plx = malloc(n * sizeof(double));
	c->epoch = malloc(n * sizeof(double));
	c->spec_kind = malloc(n);
	c->spec_value = malloc(n * sizeof(double));
	if (!c->spec_kind || !c->spec_value ||
	    !c->ra || !c->dec || !c->x || !c->y || !c->flux || !c->sca ||
	    !c->unit || !c->type || !c->id || !c->re_num || !c->re_text ||
	    !c->pmra || !c->pmdec || !c->plx || !c->epoch)
		return err_set(e, EXIT_SYSTEM, "out of memory");
	return 0;
}

/* The names rows carry for the current table's columns. */
static int set_columns(struct catalog *c, struct err *e)
{
	free(c->colname);
	free(c->text_ext);
	free(c->num_ext);
	c->ncol_table = c->t ? table_ncol(c->t) : 0;
	c->colname = calloc((size_t)c->ncol_table + 2, sizeof(char *));
	c->text_ext = calloc((size_t)c->ncol_table + 2, sizeof(char **));
	c->num_ext = calloc((size_t)c->ncol_table + 2, sizeof(double *));
	if (!c->colname || !c->text_ext || !c->num_ext)
		return err_set(e, EXIT_SYSTEM, "out of memory");
	for (int i = 0; i < c->ncol_table; i++)
		c->colname[i] = (char *)table_colname(c->t, i);
	if (c->roman) {
		if (c->c_pa >= 0)
			c->colname[c->c_pa] = "phi";
		if (c->c_ba >= 0)
			c->colname[c->c_ba] = "ratio";
		if (c->c_hlr >= 0)
			c->colname[c->ncol_table] = "re";
	}
	return 0;
}

/* A tree's files after the first with columns must have the same columns
 * in the same order: the engine resolves a catalog's columns once. */
static int same_columns(struct catalog *c, struct err *e)
{
	int ok = c->nfirst == table_ncol(c->t) && c->first_roman == c->roman;

	for (int i = 0; ok && i < c->nfirst; i++)
		ok = !strcmp(c->first_cols[i], table_colname(c->t, i));
	if (!ok)
		return err_set(e, EXIT_INPUT,
			       "%s: its columns differ from those of the tree's first file, '%s'",
			       table_name(c->t), c->first_cols[c->nfirst]);
	return 0;
}

static int catalog_plan(struct catalog *c, struct err *e);

/* Open path as the current table and give its columns their meaning. */
static int open_table(struct catalog *c, const char *path, struct err *e)
{
	if (!(c->t = table_open(path, c->cap, e)))
		return -1;
	if (table_format(c->t) == TABLE_EMPTY) {
		if (!c->colname && set_columns(c, e) < 0)
			return -1;
		return 0;
	}
	if (catalog_plan(c, e) < 0)
		return -1;
	if (c->first_cols)
		return same_columns(c, e) < 0 || set_columns(c, e) < 0 ? -1 : 0;
	if (set_columns(c, e) < 0)
		return -1;
	if (!c->tree)
		return 0;
	/* the first file of a tree that has columns: remember them */
	c->nfirst = c->ncol_table;
	c->first_roman = c->roman;
	if (!(c->first_cols = calloc((size_t)c->nfirst + 1, sizeof(char *))))
		return err_set(e, EXIT_SYSTEM, "out of memory");
	for (int i = 0; i <= c->nfirst; i++)
		if (!(c->first_cols[i] = strdup(i < c->nfirst ? table_colname(c->t, i)
							      : table_name(c->t))))
			return err_set(e, EXIT_SYSTEM, "out of memory");
	return 0;
}

/* Close the current table and open the tree's next file: 1 when one
 * was opened, 0 at the end of the tree, -1. */
static int next_table(struct catalog *c, struct err *e)
{
	if (c->t) {
		c->bytes_done += table_raw_bytes(c->t);
		table_close(c->t);
		c->t = NULL;
	}
	if (!c->tree || c->tree_next >= tree_nread(c->tree))
		return 0;
	return open_table(c, tree_path(c->tree, c->tree_next++), e) < 0 ? -1 : 1;
}

/* The column a numeric meaning needs must not be a FITS string or logical
 * column. */
static int want_number(struct catalog *c, int col, struct err *e)
{
	if (col >= 0 && (table_colkind(c->t, col) == TABLE_STRING ||
			 table_colkind(c->t, col) == TABLE_LOGICAL))
		return err_set(e, EXIT_INPUT, "%s: column '%s' is a %s column, not a number",
			       table_name(c->t), table_colname(c->t, col),
			       table_colkind(c->t, col) == TABLE_LOGICAL ? "logical" : "string");
	return 0;
}

/*
 * romanisim's convention: ra, dec, type (PSF, SER), n, half_light_radius
 * (arcsec), pa (degrees east of north), ba (b/a), and one flux column per
 * filter, named by the filter, in maggies.  A table follows it when its
 * metadata says "convention=romanisim", or, without STIPS type metadata
 * and without a 'flux' or 'mag' column, when it has a column named by a
 * WFI filter or one of half_light_radius, pa, ba.  Its columns then
 * stand for wfiscene's: the filter's column is the flux (in maggies
 * unless its own unit says otherwise), ba is read as "ratio", pa as "phi"
 * (an angle on the sky, which the engine turns into one on the detector),
 * and half_light_radius / 0.11 as an extra column "re" in pixels.
 */
static int roman_plan(struct catalog *c, const char *lc, const char *where,
		      struct err *e)
{
	struct table *t = c->t;
	const char *name = table_name(t);
	const char *conv = table_meta(t, "convention");
	int any_filter = 0;
	static const char *const pairs[3][2] = {
		{ "half_light_radius", "re" }, { "pa", "phi" }, { "ba", "ratio" },
	};

	c->c_hlr = col_of(t, "half_light_radius");
	c->c_pa = col_of(t, "pa");
	c->c_ba = col_of(t, "ba");
	for (int f = 0; f < WFS_NFILTER; f++) {
		char fl[16];
		size_t k;
		const char *fn = filter_get(f)->name;

		for (k = 0; fn[k] && k + 1 < sizeof(fl); k++)
			fl[k] = (char)tolower((unsigned char)fn[k]);
		fl[k] = 0;
		any_filter |= col_of(t, fl) >= 0;
	}
	if (conv && *conv) {
		if (strcasecmp(conv, "romanisim") == 0)
			c->roman = 1;
		else if (strcasecmp(conv, "wfiscene") == 0)
			c->roman = 0;
		else
			return err_set(e, EXIT_INPUT,
				       "%s: metadata 'convention': unknown convention '%s' (want wfiscene or romanisim)",
				       name, conv);
	} else {
		c->roman = c->stips == STIPS_NONE && c->c_flux < 0 && c->c_mag < 0 &&
			(any_filter || c->c_hlr >= 0 || c->c_pa >= 0 || c->c_ba >= 0);
	}
	if (!c->roman)
		return 0;
	if (c->stips != STIPS_NONE)
		return err_set(e, EXIT_INPUT,
			       "%s: a STIPS catalog type cannot follow romanisim's convention", name);
	if (c->c_flux >= 0 || c->c_mag >= 0)
		return err_set(e, EXIT_INPUT,
			       "%s%s: column '%s' in a catalog in romanisim's convention, whose fluxes "
			       "are columns named by the filter", name, where,
			       c->c_flux >= 0 ? "flux" : "mag");
	for (int k = 0; k < 3; k++)
		if (col_of(t, pairs[k][0]) >= 0 && col_of(t, pairs[k][1]) >= 0)
			return err_set(e, EXIT_INPUT,
				       "%s%s: both '%s' (romanisim's) and '%s' (wfiscene's): keep one",
				       name, where, pairs[k][0], pairs[k][1]);
	c->c_flux = col_of(t, lc);
	if (c->c_flux < 0)
		return err_set(e, EXIT_INPUT,
			       "%s%s: catalog in romanisim's convention has no column '%s' for the "
			       "scene's filter (fluxes in maggies, one column per filter)",
			       name, where, filter_get(c->o.filter)->name);
	return 0;
}

/* The columns with numeric meanings are not FITS string columns, and
 * motion columns go with sky positions.  where: ":LINE" of the header. */
static int plan_numbers(struct catalog *c, const char *where, struct err *e)
{
	if (c->roman && (want_number(c, c->c_hlr, e) || want_number(c, c->c_pa, e) ||
			 want_number(c, c->c_ba, e)))
		return -1;
	if (want_number(c, c->c_ra, e) || want_number(c, c->c_dec, e) ||
	    want_number(c, c->c_x, e) || want_number(c, c->c_y, e) ||
	    want_number(c, c->c_sca, e) || want_number(c, c->c_flux, e) ||
	    want_number(c, c->c_mag, e) || want_number(c, c->c_pmra, e) ||
	    want_number(c, c->c_pmdec, e) || want_number(c, c->c_plx, e) ||
	    want_number(c, c->c_epoch, e))
		return -1;
	if (c->motion && !c->sky)
		return err_set(e, EXIT_INPUT, "%s%s: proper motion or parallax columns need "
			       "'ra' and 'dec' positions, not 'x' and 'y'", table_name(c->t), where);
	return 0;
}

/*
 * The spectrum's columns (wfiscene-catalog(5) SPECTRA): teff, beta, or one
 * color_F1_F2 (or colour_F1_F2), the AB colour m(F1) - m(F2) of two
 * filters (F1 != F2), which gives beta = colour / (2.5 log10(l1 / l2))
 * with l the filters' pivot wavelengths.  A column name that starts
 * "color_" but names no two known filters is an error, not a column left
 * unread; one that starts "colour_" is then the user's own.
 */
static int spectrum_plan(struct catalog *c, const char *where, struct err *e)
{
	struct table *t = c->t;

	c->c_teff = col_of(t, "teff");
	c->c_beta = col_of(t, "beta");
	c->c_colour = -1;
	for (int i = 0; i < table_ncol(t); i++) {
		const char *n = table_colname(t, i);
		char f1[8], f2[8];
		int a, b, len = 0, british = !strncmp(n, "colour_", 7), skip = british ? 7 : 6;
		int two;

		if (strncmp(n, "color_", 6) && !british)
			continue;
		two = sscanf(n + skip, "%7[^_]_%7[^_]%n", f1, f2, &len) == 2 && !n[skip + len] &&
		      (a = filter_lookup(f1)) >= 0 && (b = filter_lookup(f2)) >= 0 && a != b;
		/* the British spelling too, as the program's own settings have
		 * it, where it names two filters (a column colour_index stays
		 * a column of the user's) */
		if (british && !two)
			continue;
		if (c->c_colour >= 0)
			return err_set(e, EXIT_INPUT, "%s%s: columns '%s' and '%s': give one "
				       "colour column", table_name(t), where,
				       table_colname(t, c->c_colour), n);
		if (!two)
			return err_set(e, EXIT_INPUT, "%s%s: column '%s': want color_F1_F2 "
				       "(or colour_F1_F2) with two different filters of F062 F087 "
				       "F106 F129 F158 F184 F213 F146, e.g. color_f106_f158",
				       table_name(t), where, n);
		c->c_colour = i;
		c->colour_to_beta = 1 / (2.5 * log10(filter_get(a)->pivot /
						      filter_get(b)->pivot));
	}
	c->spectral = (c->c_teff >= 0 ? SPECTRAL_BLACKBODY : 0) |
		      (c->c_beta >= 0 || c->c_colour >= 0 ? SPECTRAL_POWER : 0);
	return 0;
}

/* STIPS's catalog types (the table's metadata 'type'): which it is, and
 * the columns and metadata each needs (wfiscene-catalog(5) STIPS CATALOG
 * TYPES).  lc is the scene's filter in lower case. */
static int stips_plan(struct catalog *c, const char *type, const char *lc,
		      const char *where, struct err *e)
{
	struct table *t = c->t;
	const char *name = table_name(t);
	const char *fname = filter_get(c->o.filter)->name;

	c->stips = STIPS_NONE;
	if (type && *type) {
		if (strcasecmp(type, "internal") == 0)
			c->stips = STIPS_INTERNAL;
		else if (strcasecmp(type, "mixed") == 0)
			c->stips = STIPS_MIXED;
		else if (strcasecmp(type, "multifilter") == 0)
			c->stips = STIPS_MULTI;
		else if (strcasecmp(type, "generic") == 0)
			c->stips = STIPS_GENERIC;
		else if (strcasecmp(type, "phoenix") == 0 ||
			 strcasecmp(type, "phoenix_realtime") == 0 ||
			 strcasecmp(type, "pandeia") == 0 ||
			 strcasecmp(type, "bc95") == 0)
			return err_set(e, EXIT_INPUT,
				       "%s: catalog type '%s' needs stellar or galaxy spectra: "
				       "convert it to an 'internal' catalog with STIPS first",
				       name, type);
		else
			return err_set(e, EXIT_INPUT,
				       "%s: unknown catalog type '%s' (want internal, mixed, multifilter or generic)",
				       name, type);
	}
	if (c->stips == STIPS_INTERNAL || c->stips == STIPS_MIXED) {
		const char *f = table_meta(t, "filter");

		if (!f || !*f)
			return err_set(e, EXIT_INPUT,
				       "%s: catalog type '%s' needs metadata 'filter'",
				       name, type);
		if (strcasecmp(f, fname) != 0)
			return err_set(e, EXIT_INPUT,
				       "%s: catalog type '%s' is for filter '%s', the scene's is '%s'",
				       name, type, f, fname);
	}
	if (c->stips == STIPS_MIXED && c->c_units < 0)
		return err_set(e, EXIT_INPUT, "%s%s: catalog type 'mixed' needs a 'units' column",
			       name, where);
	if (c->stips == STIPS_MULTI) {
		c->c_flux = col_of(t, lc);
		if (c->c_flux < 0)
			return err_set(e, EXIT_INPUT,
				       "%s%s: catalog type 'multifilter' has no column '%s' for the scene's filter",
				       name, where, fname);
		c->c_mag = -1;
	}
	if (c->stips == STIPS_GENERIC && c->c_flux < 0) {
		c->c_flux = col_of(t, lc);
		if (c->c_flux < 0)
			return err_set(e, EXIT_INPUT,
				       "%s%s: catalog type 'generic' needs a 'flux' or '%s' column",
				       name, where, lc);
	}
	return 0;
}

/* Decide what the columns mean.  The header is known; no row is read. */
static int catalog_plan(struct catalog *c, struct err *e)
{
	struct table *t = c->t;
	const char *name = table_name(t);
	long hl = table_header_line(t);
	const char *type = table_meta(t, "type");
	const char *fname = filter_get(c->o.filter)->name;
	char where[64] = "";
	char lc[16];
	size_t n;

	if (hl > 0)
		snprintf(where, sizeof(where), ":%ld", hl);
	c->c_ra = col_of(t, "ra");
	c->c_dec = col_of(t, "dec");
	c->c_x = col_of(t, "x");
	c->c_y = col_of(t, "y");
	c->c_sca = col_of(t, "sca");
	c->c_flux = col_of(t, "flux");
	c->c_mag = col_of(t, "mag");
	c->c_units = col_of(t, "units");
	c->c_type = col_of(t, "type");
	c->c_id = col_of(t, "id");
	c->c_pmra = col_of(t, "pmra");
	c->c_pmdec = col_of(t, "pmdec");
	c->c_plx = col_of(t, "parallax");
	c->c_epoch = col_of(t, "epoch");
	c->motion = c->c_pmra >= 0 || c->c_pmdec >= 0 || c->c_plx >= 0;
	if (spectrum_plan(c, where, e) < 0)
		return -1;
	for (n = 0; fname[n] && n + 1 < sizeof(lc); n++)
		lc[n] = (char)tolower((unsigned char)fname[n]);
	lc[n] = 0;

	if (stips_plan(c, type, lc, where, e) < 0)
		return -1;
	/* rows that may name their model (read_type) */
	if (c->spectral && c->c_type >= 0 && c->stips != STIPS_GENERIC)
		c->spectral |= SPECTRAL_TYPED;

	if (roman_plan(c, lc, where, e) < 0)
		return -1;

	if (c->c_ra >= 0 && c->c_dec >= 0) {
		c->sky = 1;
	} else if (c->c_x >= 0 && c->c_y >= 0) {
		c->sky = 0;
	} else if (c->c_ra >= 0 || c->c_dec >= 0) {
		return err_set(e, EXIT_INPUT, "%s%s: column '%s' without '%s'", name, where,
			       c->c_ra >= 0 ? "ra" : "dec", c->c_ra >= 0 ? "dec" : "ra");
	} else if (c->c_x >= 0 || c->c_y >= 0) {
		return err_set(e, EXIT_INPUT, "%s%s: column '%s' without '%s'", name, where,
			       c->c_x >= 0 ? "x" : "y", c->c_x >= 0 ? "y" : "x");
	} else {
		return err_set(e, EXIT_INPUT,
			       "%s%s: no position columns: need 'ra' and 'dec', or 'x' and 'y'",
			       name, where);
	}
	if (c->c_flux < 0 && c->c_mag < 0)
		return err_set(e, EXIT_INPUT, "%s%s: no flux column: need 'flux' or 'mag'",
			       name, where);

	/* The unit of the flux column: its own unit (ECSV, IPAC, FITS
	 * TUNIT), else the fluxunit metadata, else the scene's --flux-unit,
	 * else counts/s.  STIPS's own types are in counts/s by definition,
	 * so the scene's default does not apply to them. */
	c->flux_unit = c->roman ? UNIT_MAGGIES : UNIT_COUNTS;
	if (c->o.flux_unit && c->stips == STIPS_NONE && !c->roman)
		c->flux_unit = c->o.flux_unit;
	{
		const char *mu = table_meta(t, "fluxunit");

		if (mu && *mu) {
			c->flux_unit = catalog_unit_code(mu);
			if (!c->flux_unit)
				return err_set(e, EXIT_INPUT,
					       "%s: metadata 'fluxunit': unknown unit '%s' (want counts, abmag, jy or maggies)",
					       name, mu);
		}
	}
	if (c->c_flux >= 0 && *table_colunit(t, c->c_flux)) {
		const char *cu = table_colunit(t, c->c_flux);

		c->flux_unit = catalog_unit_code(cu);
		if (!c->flux_unit)
			return err_set(e, EXIT_INPUT,
				       "%s: column '%s': unknown unit '%s' (want counts/s, mag(AB), Jy or maggies)",
				       table_colunit_place(t, c->c_flux),
				       table_colname(t, c->c_flux), cu);
	}
	return plan_numbers(c, where, e);
}

struct catalog *catalog_open(const char *path, const struct catalog_opts *o,
			     struct err *e)
{
	struct catalog *c = calloc(1, sizeof(*c));

	if (!c) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		return NULL;
	}
	c->o = *o;
	if (!c->o.chunk_rows)
		c->o.chunk_rows = 65536;
	c->cap = c->o.chunk_rows;
	/* The filter's name is needed for STIPS catalog types; the tables
	 * load once, so this is free when main has loaded them. */
	if (instrument_init(e) < 0)
		goto fail;
	if (!filter_get(c->o.filter)) {
		err_set(e, EXIT_INPUT, "catalog: unknown filter %d", c->o.filter);
		goto fail;
	}
	if (alloc_rows(c, e) < 0)
		goto fail;
	if (tree_is_dir(path)) {
		struct tree_opts to = { c->o.disc, c->o.ndisc, c->o.settings };

		if (!(c->tree = tree_open(path, &to, e)) || !(c->dir = strdup(path)))
			goto fail;
		if (next_table(c, e) < 0)
			goto fail;
		if (!c->t && set_columns(c, e) < 0)
			goto fail;
	} else if (open_table(c, path, e) < 0) {
		goto fail;
	}
	return c;
fail:
	catalog_close(c);
	return NULL;
}

int catalog_spectral(const struct catalog *c)
{
	return c->spectral;
}

/* The value of numeric column col in row i: from FITS directly, else
 * parsed from text. */
static inline int cell_number(const struct table_chunk *ch, int col, size_t i,
			      const char *colname, double *v, struct err *e)
{
	int rc;

	if (ch->num[col]) {
		const char *s;

		*v = ch->num[col][i];
		if (isfinite(*v))
			return 0;
		s = table_text(ch, col, i);
		rc = isnan(*v) && !*s ? 1 : 2;
		return bad_number(e, ch->file, ch->line[i], colname, s, rc);
	}
	if (ch->padded && parse_plain(ch->text[col][i], v) == 0)
		return 0;
	rc = catalog_parse_double(ch->text[col][i], v);
	if (rc)
		return bad_number(e, ch->file, ch->line[i], colname,
				  ch->text[col][i], rc);
	return 0;
}

static int row_unit(const struct table_chunk *ch, int col, size_t i,
		    int dflt, struct err *e)
{
	const char *s = table_text(ch, col, i);
	int u;

	while (*s == ' ')
		s++;
	if (!*s)
		return dflt;
	u = catalog_unit_code(s);
	if (!u)
		return err_set(e, EXIT_INPUT,
			       "%s:%ld: column 'units': unknown unit '%.40s' (want c, j, p, e or m)",
			       ch->file, ch->line[i], s);
	return u;
}

static int integer_value(const struct table_chunk *ch, int col, size_t i,
			 const char *colname, long long *out, struct err *e)
{
	const char *s = ch->text[col][i];
	const char *p = s;
	unsigned long long v = 0;
	int neg = 0, nd = 0;
	double d;

	if (s) {
		while (*p == ' ')
			p++;
		if (*p == '-' || *p == '+')
			neg = *p++ == '-';
		for (; *p >= '0' && *p <= '9' && nd < 19; p++, nd++)
			v = v * 10 + (unsigned long long)(*p - '0');
		while (*p == ' ')
			p++;
		/* 19 digits cannot wrap 64 bits; the sign bit must stay clear. */
		if (nd && !*p && v <= (unsigned long long)LLONG_MAX) {
			*out = neg ? -(long long)v : (long long)v;
			return 0;
		}
	}
	/* "12.0", "1e3", a long number, or a FITS double (what its text would
	 * give): exact if it is an integer */
	if (cell_number(ch, col, i, colname, &d, e) < 0)
		return -1;
	if (d == floor(d) && (d >= 0x1p63 || d < -0x1p63))
		return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': %.200s is out of range "
			       "(at most %lld in magnitude)", ch->file, ch->line[i], colname,
			       table_text(ch, col, i), LLONG_MAX);
	if (d != floor(d))
		return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': not an integer: '%.200s'",
			       ch->file, ch->line[i], colname, table_text(ch, col, i));
	*out = (long long)d;
	return 0;
}

static void lower_trim(char **s)
{
	char *p = *s, *q;

	while (*p == ' ' || *p == '\t')
		p++;
	for (q = p; *q; q++)
		if (*q >= 'A' && *q <= 'Z')
			*q = (char)(*q + 32);
	while (q > p && (q[-1] == ' ' || q[-1] == '\t'))
		*--q = 0;
	*s = p;
}

/* Row i's position: ra, dec, or pixel x, y (1-based in the file) and sca. */
static int read_position(struct catalog *c, const struct table_chunk *ch, size_t i,
			 struct err *e)
{
	double v;

	if (c->sky) {
		if (cell_number(ch, c->c_ra, i, "ra", &v, e) < 0)
			return -1;
		c->ra[i] = v;
		if (cell_number(ch, c->c_dec, i, "dec", &v, e) < 0)
			return -1;
		if (v < -90 || v > 90)
			return err_set(e, EXIT_INPUT,
				       "%s:%ld: column 'dec': out of range [-90, 90]: '%.40s'",
				       ch->file, ch->line[i], table_text(ch, c->c_dec, i));
		c->dec[i] = v;
		c->x[i] = c->y[i] = NAN;
		c->sca[i] = 0;
		return 0;
	}
	c->ra[i] = c->dec[i] = NAN;
	if (cell_number(ch, c->c_x, i, "x", &v, e) < 0)
		return -1;
	c->x[i] = v - 1;
	if (cell_number(ch, c->c_y, i, "y", &v, e) < 0)
		return -1;
	c->y[i] = v - 1;
	c->sca[i] = 0;
	if (c->c_sca >= 0) {
		long long s;

		if (integer_value(ch, c->c_sca, i, "sca", &s, e) < 0)
			return -1;
		if (s < 1 || s > WFS_NSCA)
			return err_set(e, EXIT_INPUT,
				       "%s:%ld: column 'sca': not an SCA (1 to %d): '%.40s'",
				       ch->file, ch->line[i], WFS_NSCA, table_text(ch, c->c_sca, i));
		c->sca[i] = (int)s;
	}
	return 0;
}

/* Row i's flux and its unit (maggies and nanomaggies become AB mag). */
static int read_flux(struct catalog *c, const struct table_chunk *ch, size_t i,
		     struct err *e)
{
	const char *fn = ch->file;
	double f;
	int u;

	if (c->c_flux >= 0) {
		const char *cn = table_colname(c->t, c->c_flux);

		if (cell_number(ch, c->c_flux, i, cn, &f, e) < 0)
			return -1;
		u = c->flux_unit;
		if (c->c_units >= 0 && c->stips != STIPS_INTERNAL) {
			u = row_unit(ch, c->c_units, i, u, e);
			if (u < 0)
				return -1;
		}
		if (u == UNIT_MAGGIES || u == UNIT_NMGY) {
			const char *un = u == UNIT_NMGY ? "nanomaggies" : "maggies";

			if (!(f > 0))
				return err_set(e, EXIT_INPUT,
					       "%s:%ld: column '%s': flux must be positive: '%.40s'",
					       fn, ch->line[i], cn, table_text(ch, c->c_flux, i));
			f = (u == UNIT_NMGY ? 22.5 : 0.0) - 2.5 * log10(f);
			u = UNIT_ABMAG;
			/* the message says what the cell holds, not only the
			 * magnitude it became */
			if (f < CATALOG_MAG_MIN || f > CATALOG_MAG_MAX)
				return err_set(e, EXIT_INPUT,
					       "%s:%ld: column '%s': %.40s %s is AB %g, out of the "
					       "magnitude range [%g, %g]", fn, ch->line[i], cn,
					       table_text(ch, c->c_flux, i), un, f,
					       CATALOG_MAG_MIN, CATALOG_MAG_MAX);
		}
		if (u == UNIT_ABMAG) {
			if (f < CATALOG_MAG_MIN || f > CATALOG_MAG_MAX)
				return err_set(e, EXIT_INPUT,
					       "%s:%ld: column '%s': magnitude out of range [%g, %g]: '%.40s'",
					       fn, ch->line[i], cn, CATALOG_MAG_MIN,
					       CATALOG_MAG_MAX, table_text(ch, c->c_flux, i));
		} else if (!(f > 0)) {
			return err_set(e, EXIT_INPUT,
				       "%s:%ld: column '%s': flux must be positive: '%.40s'",
				       fn, ch->line[i], cn, table_text(ch, c->c_flux, i));
		}
	} else {
		if (cell_number(ch, c->c_mag, i, "mag", &f, e) < 0)
			return -1;
		if (f < CATALOG_MAG_MIN || f > CATALOG_MAG_MAX)
			return err_set(e, EXIT_INPUT,
				       "%s:%ld: column 'mag': magnitude out of range [%g, %g]: '%.40s'",
				       fn, ch->line[i], CATALOG_MAG_MIN, CATALOG_MAG_MAX,
				       table_text(ch, c->c_mag, i));
		u = UNIT_ABMAG;
	}
	c->flux[i] = f;
	c->unit[i] = (unsigned char)u;
	return 0;
}

const char *catalog_roman_type(const char *t)
{
	return !strcasecmp(t, "psf") ? "point" : !strcasecmp(t, "ser") ? "sersic" : NULL;
}

/* Row i's model name, lower-case ("point" by default). */
static void read_type(struct catalog *c, const struct table_chunk *ch, size_t i)
{
	if (c->c_type >= 0 && c->stips != STIPS_GENERIC) {
		/* Cells live in the table's own buffers, which are
		 * writable: lower-case them in place. */
		char *s = (char *)table_text(ch, c->c_type, i);

		lower_trim(&s);
		c->type[i] = *s ? s : "point";
		if (c->roman && catalog_roman_type(s))
			c->type[i] = catalog_roman_type(s);
	} else {
		c->type[i] = "point";
	}
}

/* Row i's "re" (pixels) from romanisim's half_light_radius (arcsec). */
static int read_roman_re(struct catalog *c, const struct table_chunk *ch, size_t i,
			 struct err *e)
{
	const char *h = ch->text[c->c_hlr][i];
	double v;

	if (h && is_empty(h)) {
		c->re_text[i] = "";
		return 0;
	}
	if (cell_number(ch, c->c_hlr, i, "half_light_radius", &v, e) < 0)
		return -1;
	c->re_text[i] = NULL;
	c->re_num[i] = v / WFS_PIXSCALE;
	/* romanisim's radius is the circularised one, sqrt(a b) (GalSim's
	 * shear keeps the area), where re is along the major axis: re = hlr /
	 * sqrt(ba).  A ba out of (0, 1] is left for the model to refuse. */
	if (c->c_ba >= 0 && (!ch->text[c->c_ba][i] || !is_empty(ch->text[c->c_ba][i]))) {
		double ba;

		if (cell_number(ch, c->c_ba, i, "ba", &ba, e) < 0)
			return -1;
		if (ba > 0 && ba <= 1)
			c->re_num[i] /= sqrt(ba);
	}
	return 0;
}

/* Optional numeric cell (col, i) into *out, fallback when the column is
 * absent or the cell empty, refused outside [lo, hi]. */
static int optional_number(const struct table_chunk *ch, int col, size_t i, const char *name,
			   double fallback, double lo, double hi, double *out, struct err *e)
{
	*out = fallback;
	if (col < 0 || (ch->text[col][i] && is_empty(ch->text[col][i])))
		return 0;
	if (cell_number(ch, col, i, name, out, e) < 0)
		return -1;
	if (*out < lo || *out > hi)
		return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': out of range [%g, %g]: '%.40s'",
			       ch->file, ch->line[i], name, lo, hi, table_text(ch, col, i));
	return 0;
}

/* Row i's proper motion, parallax and epoch (empty cells: 0, --epoch). */
static int read_motion(struct catalog *c, const struct table_chunk *ch, size_t i,
		       struct err *e)
{
	double ep = c->o.epoch ? c->o.epoch : MOTION_EPOCH_DEFAULT;

	if (optional_number(ch, c->c_pmra, i, "pmra", 0, -MOTION_PM_MAX, MOTION_PM_MAX,
			    &c->pmra[i], e) < 0 ||
	    optional_number(ch, c->c_pmdec, i, "pmdec", 0, -MOTION_PM_MAX, MOTION_PM_MAX,
			    &c->pmdec[i], e) < 0 ||
	    optional_number(ch, c->c_plx, i, "parallax", 0, -MOTION_PLX_MAX, MOTION_PLX_MAX,
			    &c->plx[i], e) < 0 ||
	    optional_number(ch, c->c_epoch, i, "epoch", ep, MOTION_EPOCH_MIN, MOTION_EPOCH_MAX,
			    &c->epoch[i], e) < 0)
		return -1;
	return 0;
}

/* Row i's spectrum: at most one of its teff, beta and colour cells. */
static int read_spectrum(struct catalog *c, const struct table_chunk *ch, size_t i,
			 struct err *e)
{
	const int col[3] = { c->c_teff, c->c_beta, c->c_colour };
	int given = -1;

	c->spec_kind[i] = SPEC_DEFAULT;
	c->spec_value[i] = 0;
	for (int k = 0; k < 3; k++) {
		const char *name = col[k] >= 0 ? table_colname(c->t, col[k]) : "";
		double v;

		if (col[k] < 0 || (ch->text[col[k]][i] && is_empty(ch->text[col[k]][i])))
			continue;
		if (given >= 0)
			return err_set(e, EXIT_INPUT, "%s:%ld: columns '%s' and '%s': give one "
				       "spectrum per row", ch->file, ch->line[i],
				       table_colname(c->t, col[given]), name);
		given = k;
		if (cell_number(ch, col[k], i, name, &v, e) < 0)
			return -1;
		if (k == 0 && !(v >= SPEC_TEFF_MIN && v <= SPEC_TEFF_MAX))
			return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': %.40s K is outside "
				       "%g to %g K", ch->file, ch->line[i], name,
				       table_text(ch, col[k], i), SPEC_TEFF_MIN, SPEC_TEFF_MAX);
		c->spec_kind[i] = k == 0 ? SPEC_BLACKBODY : SPEC_POWER;
		c->spec_value[i] = k == 2 ? v * c->colour_to_beta : v;
		if (!isfinite(c->spec_value[i]))
			return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': not a finite "
				       "slope: '%.40s'", ch->file, ch->line[i], name,
				       table_text(ch, col[k], i));
		if (k > 0 && fabs(c->spec_value[i]) > SPEC_BETA_MAX)
			return err_set(e, EXIT_INPUT, "%s:%ld: column '%s': '%.40s' gives "
				       "the slope beta = %.9g, steeper than +-%g", ch->file,
				       ch->line[i], name, table_text(ch, col[k], i),
				       c->spec_value[i], SPEC_BETA_MAX);
	}
	return 0;
}

/* Hand the chunk's n rows to r. */
static void rows_fill(struct catalog *c, struct rows *r, const struct table_chunk *ch,
		      long n)
{
	r->n = (size_t)n;
	r->file = ch->file;
	r->line = ch->line;
	r->ra = c->ra;
	r->dec = c->dec;
	r->x = c->x;
	r->y = c->y;
	r->sca = c->sca;
	r->flux = c->flux;
	r->unit = c->unit;
	/* as read_flux() reads them */
	r->flux_col = c->c_flux >= 0 ? c->c_flux : c->c_mag;
	r->units_col = c->c_flux >= 0 && c->c_units >= 0 && c->stips != STIPS_INTERNAL ?
		c->c_units : -1;
	r->flux_unit = c->c_flux >= 0 ? c->flux_unit : UNIT_ABMAG;
	r->type = c->type;
	r->id = c->id;
	if (c->motion) {
		r->pmra = c->pmra;
		r->pmdec = c->pmdec;
		r->parallax = c->plx;
		r->epoch = c->epoch;
	}
	if (c->spectral) {
		r->spec_kind = c->spec_kind;
		r->spec_value = c->spec_value;
	}
	r->sersic_ie = c->stips == STIPS_INTERNAL || c->stips == STIPS_MIXED ||
		c->stips == STIPS_MULTI;
	r->ncol = c->ncol_table;
	r->colname = c->colname;
	r->text = ch->text;
	r->num = ch->num;
	r->roman = c->roman;
	r->sky_angle_col = c->roman ? c->c_pa : -1;
	if (c->roman && c->c_hlr >= 0) {
		/* the chunk's columns and "re" after them */
		memcpy(c->text_ext, ch->text, (size_t)c->ncol_table * sizeof(char **));
		memcpy(c->num_ext, ch->num, (size_t)c->ncol_table * sizeof(double *));
		c->text_ext[c->ncol_table] = c->re_text;
		c->num_ext[c->ncol_table] = c->re_num;
		r->text = c->text_ext;
		r->num = c->num_ext;
		r->ncol++;
	}
	c->ch = *ch;
	r->chunk = &c->ch;
}

/* Row i's cells into the chunk's arrays; each row writes only its own
 * entries, so rows may be read on several threads. */
static int read_row(struct catalog *c, const struct table_chunk *ch, size_t i, struct err *e)
{
	if (read_position(c, ch, i, e) < 0 || read_flux(c, ch, i, e) < 0)
		return -1;
	read_type(c, ch, i);
	if (c->roman && c->c_hlr >= 0 && read_roman_re(c, ch, i, e) < 0)
		return -1;
	if (c->c_id >= 0 && (!ch->text[c->c_id][i] || !is_empty(ch->text[c->c_id][i]))) {
		if (integer_value(ch, c->c_id, i, "id", &c->id[i], e) < 0)
			return -1;
	} else {
		c->id[i] = (long long)(c->nrows + i + 1);
	}
	if (c->motion && read_motion(c, ch, i, e) < 0)
		return -1;
	if (c->spectral && read_spectrum(c, ch, i, e) < 0)
		return -1;
	return 0;
}

/* rowpool_run()'s step: row i of the chunk being read. */
struct cell_job {
	struct catalog *c;
	const struct table_chunk *ch;
};

static int cell_row(void *arg, size_t i, struct err *e)
{
	struct cell_job *j = arg;

	return read_row(j->c, j->ch, i, e);
}

/* The chunk's n rows read, 8192 rows a task on the catalog's pool for a
 * text table (a FITS cell's text for a message is formatted in the
 * reader's own buffer); the first failing row in order is reported. */
static int read_cells(struct catalog *c, const struct table_chunk *ch, size_t n,
		      struct err *e)
{
	struct cell_job j = { c, ch };

	return rowpool_run(ch->padded ? c->o.pool : NULL, n, 8192, cell_row, &j, e);
}

long catalog_read(struct catalog *c, struct rows *r, struct err *e)
{
	struct table_chunk ch;
	long n;

	memset(r, 0, sizeof(*r));
	r->sky_angle_col = -1;
	r->flux_col = r->units_col = -1;
	for (;;) {
		n = c->t ? table_read(c->t, &ch, e) : 0;
		if (n != 0)
			break;
		/* the end of a table: a tree goes on with its next file */
		if (!c->tree || (n = next_table(c, e)) <= 0)
			break;
	}
	if (n <= 0) {
		r->file = c->t ? table_name(c->t) : c->dir ? c->dir : "";
		return n;
	}
	if (read_cells(c, &ch, (size_t)n, e) < 0)
		return -1;
	c->nrows += (unsigned long long)n;
	rows_fill(c, r, &ch, n);
	return n;
}

unsigned long long catalog_rows(const struct catalog *c)
{
	return c->nrows;
}

unsigned long long catalog_bytes(const struct catalog *c)
{
	return c->bytes_done + (c->t ? table_raw_bytes(c->t) : 0);
}

int catalog_tree_counts(const struct catalog *c, struct tree_counts *out)
{
	if (!c->tree)
		return 0;
	tree_get_counts(c->tree, out);
	return 1;
}

void catalog_close(struct catalog *c)
{
	if (!c)
		return;
	table_close(c->t);
	tree_free(c->tree);
	free(c->dir);
	if (c->first_cols)
		for (int i = 0; i <= c->nfirst; i++)
			free(c->first_cols[i]);
	free(c->first_cols);
	free(c->ra);
	free(c->dec);
	free(c->x);
	free(c->y);
	free(c->flux);
	free(c->sca);
	free(c->unit);
	free(c->type);
	free(c->id);
	free(c->colname);
	free(c->text_ext);
	free(c->num_ext);
	free(c->re_num);
	free(c->re_text);
	free(c->pmra);
	free(c->pmdec);
	free(c->plx);
	free(c->epoch);
	free(c->spec_kind);
	free(c->spec_value);
	free(c);
}
