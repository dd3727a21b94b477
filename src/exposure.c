/*
 * exposure.c - the exposures of a run: one from the options, or one per
 * line of a --pointings file, each with its pointing, seed and output names.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "date.h"
#include "err.h"
#include "detector.h"
#include "exposure.h"
#include "instrument.h"
#include "names.h"
#include "scene.h"
#include "sky.h"

static int is_number(const char *s, double *v)
{
	char *end;

	*v = strtod(s, &end);
	return end != s && !*end && isfinite(*v);
}

/*
 * A header line of a pointings file that names its columns: each field one
 * of ra, dec, pa, name, seed, date (any case), each at most once, ra, dec
 * and pa among them, in another order than "ra dec pa name seed date".
 * role[k] is then field k's place in that order and the return 1; 0 for a
 * header in that order or with a word of its own, read by position as
 * before headers could name columns; -1 with the error in e for one of
 * those words alone that names one twice or leaves out ra, dec or pa (it
 * cannot be read either way: by position its data would be misread).
 */
static int pointings_header(char **field, int nf, int *role, const char *file, int lineno,
			    struct err *e)
{
	static const char *const names[6] = { "ra", "dec", "pa", "name", "seed", "date" };
	unsigned seen = 0;
	int twice = -1;

	for (int k = 0; k < nf; k++) {
		role[k] = -1;
		for (int r = 0; r < 6; r++)
			if (!strcasecmp(field[k], names[r])) {
				role[k] = r;
				if (seen >> r & 1 && twice < 0)
					twice = k;
				seen |= 1u << r;
			}
		if (role[k] < 0)
			return 0;
	}
	if (twice >= 0)
		return err_set(e, EXIT_INPUT, "%s:%d: the header names column '%s' twice", file,
			       lineno, field[twice]);
	if ((seen & 7) != 7)
		return err_set(e, EXIT_INPUT, "%s:%d: the header names columns but not %s: a "
			       "pointing needs ra, dec and pa", file, lineno,
			       !(seen & 1) ? "ra" : !(seen & 2) ? "dec" : "pa");
	/* the usual order ("ra dec pa name"): read by position, as before,
	 * so that lines may go on past the header's last name */
	for (int k = 0; k < nf; k++)
		if (role[k] != k)
			return 1;
	return 0;
}

/* Data fields in the order of a naming header (role), into std: "ra dec
 * pa name seed date" with "-" for the columns the header or the line leaves
 * out (a line may stop early, as in files whose header only described
 * them).  Returns the number of std fields, or -1 when the line has more
 * fields than the header names. */
static int pointings_reorder(char **field, int nf, const int *role, int nrole, char **std)
{
	static char dash[] = "-";
	int n = 3;

	if (nf > nrole)
		return -1;
	for (int r = 0; r < 6; r++)
		std[r] = dash;
	for (int k = 0; k < nf; k++) {
		std[role[k]] = field[k];
		if (role[k] + 1 > n)
			n = role[k] + 1;
	}
	return n;
}

/* Exposure n of p, the pointing of line lineno: its fields (nf of them in
 * the standard order, the first three the numbers v) over the defaults of
 * the options.  Returns 0, or -1 with an error naming the line. */
static int pointing_fill(const struct scene_opts *o, int lineno, char **field, int nf,
			 const double *v, struct exposure *p, int n, struct err *e)
{
	memset(&p[n], 0, sizeof(p[n]));
	p[n].ra = v[0];
	p[n].dec = v[1];
	p[n].pa = v[2];
	p[n].seed = o->seed + n;
	snprintf(p[n].name, sizeof(p[n].name), "%03d", n + 1);
	p[n].date = o->date;
	if (nf >= 4 && strcmp(field[3], "-")) {
		if (strlen(field[3]) >= sizeof(p[n].name) ||
		    strspn(field[3], "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
			   "0123456789_.-") != strlen(field[3])) {
			err_set(e, EXIT_INPUT, "%s:%d: name '%s': use letters, digits, '_', "
				"'.' and '-' (at most 63)", o->pointings, lineno, field[3]);
			return -1;
		}
		strcpy(p[n].name, field[3]);
		for (int k = 0; k < n; k++)
			if (!strcmp(p[k].name, p[n].name)) {
				err_set(e, EXIT_INPUT, "%s:%d: name '%s' is used twice",
					o->pointings, lineno, p[n].name);
				return -1;
			}
	}
	if (nf >= 5 && strcmp(field[4], "-")) {
		char *end;

		errno = 0;
		p[n].seed = strtoull(field[4], &end, 10);
		if (*end || errno || field[4][0] == '-') {
			err_set(e, EXIT_INPUT, "%s:%d: seed: not an integer: '%s'",
				o->pointings, lineno, field[4]);
			return -1;
		}
	}
	if (nf == 6 && strcmp(field[5], "-")) {
		char what[PATH_MAX + 32];

		snprintf(what, sizeof(what), "%s:%d: date", o->pointings, lineno);
		if (date_parse(field[5], what, &p[n].date, e) < 0)
			return -1;
	}
	return 0;
}

/*
 * A pointings file: one exposure a line, "ra dec pa [name [seed [date]]]",
 * fields separated by blanks or commas; '#' starts a comment; a first line
 * whose first field is not a number is a header, which may name the columns
 * in any order (pointings_header).  Exposure k (from 1) is
 * named k with three digits unless named, and has seed --seed + k - 1 unless
 * given, so that a single run of that pointing with that seed gives the same
 * image; a '-' for the name or the seed keeps that default.  The date (as
 * --date takes it, without blanks) is --date's unless given.
 */
static int read_pointings(const struct scene_opts *o, struct exposure **out, int *nout,
			  struct err *e)
{
	FILE *f = fopen(o->pointings, "r");
	char line[4096];
	struct exposure *p = NULL;
	int n = 0, cap = 0, lineno = 0, seen_data = 0, role[7], nrole = 0;

	if (!f)
		return err_sys(e, "%s", o->pointings);
	while (fgets(line, sizeof(line), f)) {
		char *field[7], *save = NULL, *tok, *hash = strchr(line, '#');
		int nf = 0;
		double v[3];

		lineno++;
		if (!strchr(line, '\n') && !feof(f)) {
			err_set(e, EXIT_INPUT, "%s:%d: line too long", o->pointings, lineno);
			goto fail;
		}
		if (hash)
			*hash = 0;
		for (tok = strtok_r(line, " \t\r\n,", &save); tok && nf < 7;
		     tok = strtok_r(NULL, " \t\r\n,", &save))
			field[nf++] = tok;
		if (nf == 0)
			continue;
		if (!seen_data++ && !is_number(field[0], &v[0])) {
			/* a header line, which may name the columns */
			int h = tok ? 0 : pointings_header(field, nf, role, o->pointings, lineno, e);

			if (h < 0)
				goto fail;
			nrole = h ? nf : 0;
			continue;
		}
		if (nrole) {
			char *std[6];

			if ((nf = pointings_reorder(field, tok ? 7 : nf, role, nrole, std)) < 0) {
				err_set(e, EXIT_INPUT, "%s:%d: the header names %d columns, this "
					"line has more fields", o->pointings, lineno, nrole);
				goto fail;
			}
			memcpy(field, std, sizeof(std));
		}
		if (nf < 3 || nf > 6) {
			err_set(e, EXIT_INPUT, "%s:%d: expected 'ra dec pa [name [seed [date]]]', "
				"got %d field%s", o->pointings, lineno, nf, nf == 1 ? "" : "s");
			goto fail;
		}
		for (int k = 0; k < 3; k++)
			if (!is_number(field[k], &v[k])) {
				err_set(e, EXIT_INPUT, "%s:%d: %s: not a number: '%s'", o->pointings,
					lineno, k == 0 ? "ra" : k == 1 ? "dec" : "pa", field[k]);
				goto fail;
			}
		if (v[1] < -90 || v[1] > 90) {
			err_set(e, EXIT_INPUT, "%s:%d: dec %g is outside [-90, 90]", o->pointings,
				lineno, v[1]);
			goto fail;
		}
		if (n == MAX_EXPOSURES) {
			err_set(e, EXIT_INPUT, "%s:%d: more than %d pointings", o->pointings, lineno,
				MAX_EXPOSURES);
			goto fail;
		}
		if (n == cap) {
			struct exposure *q;

			cap = cap ? 2 * cap : 64;
			if (!(q = realloc(p, cap * sizeof(*p)))) {
				err_sys(e, "pointings");
				goto fail;
			}
			p = q;
		}
		if (pointing_fill(o, lineno, field, nf, v, p, n, e) < 0)
			goto fail;
		n++;
	}
	if (ferror(f)) {
		err_sys(e, "%s", o->pointings);
		goto fail;
	}
	if (n == 0) {
		err_set(e, EXIT_INPUT, "%s: no pointings", o->pointings);
		goto fail;
	}
	fclose(f);
	*out = p;
	*nout = n;
	return 0;
fail:
	fclose(f);
	free(p);
	return -1;
}

/*
 * The exposure's background on all 18 SCAs, requested or not, so that runs
 * split by SCA agree on it (the models' noise level is the least of the 18).
 * The SCA centres come from the layout of the pointing; the Sun angle is
 * the boresight's: with the WFI01 reference, the boresight is where the WFI
 * centre falls in WFI01's focal plane.  Done before anything is drawn or
 * opened, so a refused pointing leaves no file behind.
 */
static int exposure_background(struct exposure *x, const struct scene_opts *o, struct err *e)
{
	const struct sca_info *s1 = sca_get(1);
	double ra[WFS_NSCA], dec[WFS_NSCA], bra, bdec;
	struct sky sky;

	/* The layout of all 18 SCAs, for their centres as the run places them. */
	if (sky_init(&sky, x->ra, x->dec, x->pa, x->boresight, o->geometry,
		     (1u << WFS_NSCA) - 1, e) < 0)
		return -1;
	for (int s = 0; s < WFS_NSCA; s++) {
		ra[s] = sky.sca[s].ra;
		dec[s] = sky.sca[s].dec;
	}
	bra = sky.ra0;
	bdec = sky.dec0;
	if (!x->boresight)
		sky_from_focal(&sky, s1->x_idl - s1->x_bore, s1->y_idl - s1->y_bore, &bra, &bdec);
	sky_free(&sky);
	return background_exposure(&x->bkg, o->bkg_model, x->background, o->filter, x->date,
				   o->zodi_norm, o->allow_sun, ra, dec, bra, bdec, e);
}

/* *out: template tmpl of option what expanded for exposure x (names.h), or
 * NULL for a NULL tmpl.  Returns 0 or -1 with the message in e. */
static int expand_side(const char *what, const char *tmpl, const struct exposure *x,
		       char **out, struct err *e)
{
	char buf[PATH_MAX];

	*out = NULL;
	if (!tmpl)
		return 0;
	if (name_expand(buf, sizeof(buf), what, tmpl, 0, x->name[0] ? x->name : NULL, e) < 0)
		return -1;
	if (!(*out = strdup(buf)))
		return err_sys(e, "%s", what);
	return 0;
}


int exposures_make(const struct scene_opts *o, struct exposure **out, int *n, struct err *e)
{
	struct exposure *x;

	*n = 1;
	if (o->pointings) {
		if (read_pointings(o, &x, n, e) < 0)
			return -1;
	} else {
		if (!(x = calloc(1, sizeof(*x))))
			return err_sys(e, "memory");
		x->ra = o->ra;
		x->dec = o->dec;
		x->pa = o->pa;
		x->seed = o->seed;
		x->date = o->date;
	}
	for (int i = 0; i < *n; i++) {
		x[i].index = i;
		x[i].boresight = o->boresight;
		x[i].sca_mask = o->sca_mask;
		x[i].level = o->level;
		x[i].background = o->background;
		if (exposure_background(&x[i], o, e) < 0) {
			if (o->pointings)
				err_prefix(e, "%s: exposure %s", o->pointings, x[i].name);
			exposures_free(x, *n);
			return -1;
		}
		x[i].output = o->output;
		if (expand_side("--placed", o->placed, &x[i], &x[i].placed, e) < 0 ||
		    expand_side("--report", o->report, &x[i], &x[i].report, e) < 0) {
			exposures_free(x, *n);
			return -1;
		}
	}
	*out = x;
	return 0;
}

void exposures_free(struct exposure *x, int n)
{
	for (int i = 0; x && i < n; i++) {
		free(x[i].placed);
		free(x[i].report);
	}
	free(x);
}
