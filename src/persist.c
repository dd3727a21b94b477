/*
 * persist.c - persistence from earlier exposures of a series; see persist.h.
 *
 * The model.  A pixel that collected a fluence x (e-) in an exposure that
 * ended at time T releases, at time t > T, an extra current
 *
 *   I(t) = s(x) g(t - T),   g(u) = a e^(-b u) + d e^(-e u) + c  (e-/s),
 *
 * g the Roman Project's fit to the median persistence of the SCA's sensor
 * control unit after its stimulus (WFI_Persistence_exp_fits.ecsv), taken
 * here as the response to a full well (100,000 e-, the table's
 * 'reference'), and released only while the fit is positive and within the
 * times it was measured at (to 1770.72 s: beyond, the trapped charge is
 * taken as gone).  Before 177 s, the first time measured, the fit is
 * extrapolated.  The amplitude s(x) scales it with the stimulus by the
 * fermi model of GalSim's roman module and romanisim (H4RG-lo):
 *
 *   f(x) = (x / x0)^alpha / (1 + e^(-(x - x0) / dx))  for x >= half well,
 *   f(x) = f(hw) x / hw                               below,
 *   s(x) = f(x) / f(reference),
 *
 * with x0 = 6e4, dx = 5e4, alpha = 0.045 and a half well of 5e4 e-.  A
 * pixel's trapped charge is that of one stimulus: when a later exposure
 * brings a new one, the pixel keeps whichever gives the larger current 30 s
 * after that exposure's end (a full well again refills the traps; a faint
 * exposure leaves the older, brighter stimulus's charge to decay).
 *
 * What is kept: pixels whose current 30 s after the latest exposure's end
 * is at least the floor (--set persistence-floor, 0.01 e-/s by default,
 * the current at which romanisim stops tracking a pixel), so the state
 * holds the cores of bright stars, not the sky.
 */
#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "data.h"
#include "date.h"
#include "err.h"
#include "exposure.h"
#include "options.h"
#include "persist.h"
#include "scene.h"
#include "tempfile.h"

#define PERSIST_MAGIC "wfiscene-persistence 1"
#define LAG_KEEP 30.0           /* s after an exposure's end: the keep rule */
#define GAP_MAX 1e9             /* s: --set persistence-gap's upper bound */
#define REFERENCE_MIN 1e3       /* e-: --set persistence-reference's lower bound */
#define DATE_SLACK 1e-6         /* s an exposure may begin before the last ends */

static double curve_at(const struct persist_curve *c, double u)
{
	double g;

	if (!(u >= 0) || u > c->tmax)
		return 0;
	g = c->a * exp(-c->b * u) + c->d * exp(-c->e * u) + c->c;
	return g > 0 ? g : 0;
}

/* The antiderivative's difference over [u0, u1], without the clamp. */
static double curve_integral(const struct persist_curve *c, double u0, double u1)
{
	double w = u1 - u0;

	return c->a / c->b * exp(-c->b * u0) * -expm1(-c->b * w) +
	       c->d / c->e * exp(-c->e * u0) * -expm1(-c->e * w) + c->c * w;
}

double persist_charge(const struct persist_curve *c, double scale, double t0, double t1)
{
	double q;

	if (t0 < 0)
		t0 = 0;
	if (t1 > c->tmax)
		t1 = c->tmax;
	if (!(t1 > t0) || !(scale > 0))
		return 0;
	/* tmax is where the fit ends or turns negative: it is positive (and
	 * falling) over [t0, t1] */
	q = scale * curve_integral(c, t0, t1);
	return q > 0 ? q : 0;
}

int persist_curve_get(int sca, struct persist_curve *c, struct err *e)
{
	struct tsv t;
	char name[16];
	double tmax = 0;
	int have = 0;

	snprintf(name, sizeof(name), "WFI%02d", sca);
	if (tsv_parse(&t, "persistence.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "persistence.tsv: table missing from the build");
	for (int r = 1; r < t.nrow; r++) {
		if (t.ncol < 7)
			continue;
		if (!strcmp(t.cell[r][0], "const") && !strcmp(t.cell[r][1], "tmax"))
			tmax = strtod(t.cell[r][2], NULL);
		if (!strcmp(t.cell[r][0], "decay") && !strcmp(t.cell[r][1], name)) {
			c->a = strtod(t.cell[r][2], NULL);
			c->b = strtod(t.cell[r][3], NULL);
			c->c = strtod(t.cell[r][4], NULL);
			c->d = strtod(t.cell[r][5], NULL);
			c->e = strtod(t.cell[r][6], NULL);
			have = 1;
		}
	}
	tsv_free(&t);
	if (!have || !(tmax > 0) || !(c->b > 0) || !(c->e > 0) || c->a < 0 || c->d < 0)
		return err_set(e, EXIT_SYSTEM, "persistence.tsv: incomplete or bad for %s", name);
	c->tmax = tmax;
	/* a negative c: the fit crosses zero, after which it releases
	 * nothing; find the crossing by bisection (g falls monotonically) */
	if (curve_at(c, tmax) <= 0) {
		double lo = 0, hi = tmax;

		for (int i = 0; i < 200 && hi - lo > 1e-9; i++) {
			double mid = 0.5 * (lo + hi);

			if (c->a * exp(-c->b * mid) + c->d * exp(-c->e * mid) + c->c > 0)
				lo = mid;
			else
				hi = mid;
		}
		c->tmax = lo;
	}
	return 0;
}

static double fermi(const struct persist *p, double x)
{
	double hw = p->half_well;

	if (!(x > 0))
		return 0;
	if (x < hw)
		return fermi(p, hw) * x / hw;
	return pow(x / p->x0, p->alpha) / (1 + exp(-(x - p->x0) / p->dx));
}

double persist_scale(const struct persist *p, double x)
{
	return fermi(p, x) / p->ref_response;
}

/* --set key=value as a number within [lo, hi]: *v, or -1 with a message. */
static int knob(const char *const *settings, const char *key, double lo, double hi, double *v,
		struct err *e)
{
	const char *s = setting_last(settings, key);
	char *end;
	double x;

	if (!s)
		return 0;
	x = strtod(s, &end);
	if (end == s || *end || !(x >= lo && x <= hi))
		return err_set(e, EXIT_INPUT, "--set %s=%s: expected a number from %g "
			       "to %g", key, s, lo, hi);
	*v = x;
	return 0;
}

struct persist *persist_new(unsigned sca_mask, int ylo, int yhi,
			    const char *const *settings, struct err *e)
{
	struct persist *p = calloc(1, sizeof(*p));
	struct tsv t;
	double ref = 0;

	if (!p) {
		err_sys(e, "persistence state");
		return NULL;
	}
	p->sca_mask = sca_mask;
	p->ylo = ylo;
	p->yhi = yhi;
	p->floor = 0.01;
	p->flag = 0.5;
	p->gap = 60;
	if (tsv_parse(&t, "persistence.tsv") < 0) {
		err_set(e, EXIT_SYSTEM, "persistence.tsv: table missing from the build");
		goto fail;
	}
	for (int r = 1; r < t.nrow; r++) {
		if (t.ncol < 7 || strcmp(t.cell[r][0], "const"))
			continue;
		if (!strcmp(t.cell[r][1], "fermi")) {
			p->x0 = strtod(t.cell[r][3], NULL);
			p->dx = strtod(t.cell[r][4], NULL);
			p->alpha = strtod(t.cell[r][5], NULL);
			p->half_well = strtod(t.cell[r][6], NULL);
		} else if (!strcmp(t.cell[r][1], "reference")) {
			ref = strtod(t.cell[r][2], NULL);
		}
	}
	tsv_free(&t);
	if (!(p->x0 > 0) || !(p->dx > 0) || !(p->half_well > 0) || !(ref > 0)) {
		err_set(e, EXIT_SYSTEM, "persistence.tsv: the fermi constants are missing");
		goto fail;
	}
	if (knob(settings, "persistence-floor", 1e-6, 1e3, &p->floor, e) < 0 ||
	    knob(settings, "persistence-flag", 0, 1e6, &p->flag, e) < 0 ||
	    knob(settings, "persistence-gap", 0, GAP_MAX, &p->gap, e) < 0 ||
	    knob(settings, "persistence-reference", REFERENCE_MIN, 1e7, &ref, e) < 0)
		goto fail;
	p->ref_response = fermi(p, ref);
	for (int s = 1; s <= WFS_NSCA; s++) {
		double g, lo = 0, hi = 1e12;

		if (!(sca_mask >> (s - 1) & 1))
			continue;
		if (persist_curve_get(s, &p->curve[s - 1], e) < 0)
			goto fail;
		/* the fluence at the floor, by bisection (the amplitude rises
		 * with the fluence), a little low so that the exact test of
		 * persist_add() decides at the edge */
		g = curve_at(&p->curve[s - 1], LAG_KEEP);
		for (int i = 0; i < 200 && hi - lo > 1e-6 * hi; i++) {
			double mid = 0.5 * (lo + hi);

			if (persist_scale(p, mid) * g < p->floor)
				lo = mid;
			else
				hi = mid;
		}
		p->x_keep[s - 1] = 0.999 * lo;
	}
	return p;
fail:
	free(p);
	return NULL;
}

static void list_free(struct persist_list *l)
{
	free(l->pix);
	free(l->scale);
	free(l->tend);
	memset(l, 0, sizeof(*l));
}

void persist_free(struct persist *p)
{
	if (!p)
		return;
	for (int s = 0; s < WFS_NSCA; s++) {
		list_free(&p->now[s]);
		list_free(&p->next[s]);
	}
	free(p);
}

static int list_reserve(struct persist_list *l, size_t n)
{
	size_t cap = l->cap ? l->cap : 1024;
	uint32_t *pix;
	float *scale;
	double *tend;

	if (n <= l->cap)
		return 0;
	while (cap < n)
		cap *= 2;
	pix = realloc(l->pix, cap * sizeof(*pix));
	if (pix)
		l->pix = pix;
	scale = realloc(l->scale, cap * sizeof(*scale));
	if (scale)
		l->scale = scale;
	tend = realloc(l->tend, cap * sizeof(*tend));
	if (tend)
		l->tend = tend;
	if (!pix || !scale || !tend)
		return -1;
	l->cap = cap;
	return 0;
}

static int list_push(struct persist_list *l, uint32_t pix, float scale, double tend)
{
	if (l->n == l->cap && list_reserve(l, l->n + 1) < 0)
		return -1;
	l->pix[l->n] = pix;
	l->scale[l->n] = scale;
	l->tend[l->n] = tend;
	l->n++;
	return 0;
}

int persist_begin(struct persist *p, const char *name, double mjd, double exptime,
		  struct err *e)
{
	double t0 = isnan(mjd) ? (p->have_last ? p->last_end + p->gap : 0) : mjd * 86400.0;

	if (p->have_last && t0 < p->last_end - DATE_SLACK)
		return err_set(e, EXIT_INPUT, "persistence: exposure%s%s begins %.3f s before "
			       "the previous one ends: the exposures of a series must be in "
			       "date order, each after the one before (or leave persistence "
			       "out: --detector none)", name && *name ? " " : "",
			       name ? name : "", p->last_end - t0);
	p->t0 = t0;
	p->t1 = t0 + exptime;
	for (int s = 0; s < WFS_NSCA; s++)
		p->next[s].n = 0;
	return 0;
}

int persist_check_dates(struct persist *p, const struct exposure *x, int n, double exptime,
			struct err *e)
{
	double last = p->last_end, t0 = p->t0, t1 = p->t1;
	int have = p->have_last, rc = 0;

	for (int i = 0; i < n && rc == 0; i++) {
		rc = persist_begin(p, x[i].name, x[i].date, exptime, e);
		p->last_end = p->t1;
		p->have_last = 1;
	}
	p->last_end = last;
	p->have_last = have;
	p->t0 = t0;
	p->t1 = t1;
	return rc;
}

size_t persist_row(const struct persist *p, int sca, int y, size_t *first)
{
	const struct persist_list *l = &p->now[sca - 1];
	uint32_t a = (uint32_t)y * WFS_NPIX, b = a + WFS_NPIX;
	size_t lo = 0, hi = l->n, i;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;

		if (l->pix[mid] < a)
			lo = mid + 1;
		else
			hi = mid;
	}
	*first = lo;
	for (i = lo; i < l->n && l->pix[i] < b; i++)
		;
	return i - lo;
}

int persist_add(struct persist *p, int sca, int y, int x0, int n, const double *fluence)
{
	struct persist_list *l = &p->next[sca - 1];
	double g = curve_at(&p->curve[sca - 1], LAG_KEEP), xk = p->x_keep[sca - 1];

	for (int i = 0; i < n; i++) {
		double s;

		if (!(fluence[i] >= xk))
			continue;
		/* an infinite fluence (an image that overflowed) as the largest
		 * finite one: the state holds only finite amplitudes, which
		 * persist_load() takes back */
		s = persist_scale(p, fluence[i] < DBL_MAX ? fluence[i] : DBL_MAX);
		if (s * g < p->floor)
			continue;
		if (list_push(l, (uint32_t)y * WFS_NPIX + (uint32_t)(x0 + i), (float)s, p->t1) < 0)
			return -1;
	}
	return 0;
}

int persist_end(struct persist *p, struct err *e)
{
	double tk = p->t1 + LAG_KEEP;

	for (int s = 0; s < WFS_NSCA; s++) {
		struct persist_list *a = &p->now[s], *b = &p->next[s], m = { 0 };
		const struct persist_curve *c = &p->curve[s];
		size_t i = 0, j = 0;

		if (!(p->sca_mask >> s & 1))
			continue;
		if (list_reserve(&m, a->n + b->n + 1) < 0) {
			list_free(&m);
			return err_sys(e, "persistence state");
		}
		while (i < a->n || j < b->n) {
			int take_a = j >= b->n || (i < a->n && a->pix[i] < b->pix[j]);
			int take_b = i >= a->n || (j < b->n && b->pix[j] < a->pix[i]);
			double ca, cb;

			if (take_a) {
				ca = a->scale[i] * curve_at(c, tk - a->tend[i]);
				if (ca >= p->floor)
					list_push(&m, a->pix[i], a->scale[i], a->tend[i]);
				i++;
			} else if (take_b) {
				list_push(&m, b->pix[j], b->scale[j], b->tend[j]);
				j++;
			} else {
				/* both: the one whose current is the larger */
				ca = a->scale[i] * curve_at(c, tk - a->tend[i]);
				cb = b->scale[j] * curve_at(c, tk - b->tend[j]);
				if (ca > cb)
					list_push(&m, a->pix[i], a->scale[i], a->tend[i]);
				else
					list_push(&m, b->pix[j], b->scale[j], b->tend[j]);
				i++;
				j++;
			}
		}
		list_free(a);
		*a = m;
		b->n = 0;
	}
	p->last_end = p->t1;
	p->have_last = 1;
	p->exposures++;
	return 0;
}

/* ---- the state file ----
 *
 * Text lines, then binary arrays:
 *
 *   wfiscene-persistence 1
 *   scas 1 2 ...          the SCAs of the state
 *   rows FIRST LAST       the science rows it covers, 1-based
 *   exposures N           exposures taken into it
 *   end T                 the end of the last one (s, %.17g)
 *   sca S N               then N uint32 pixels (y * 4088 + x, 0-based,
 *                         ascending), N float32 amplitudes, N float64
 *                         end times, little-endian; one such block per SCA
 */

static int little_endian(void)
{
	const uint16_t one = 1;

	return *(const uint8_t *)&one == 1;
}

int persist_save(const struct persist *p, const char *path, struct err *e)
{
	char tmp[4096];
	FILE *f;
	int fd;

	if (!little_endian())
		return err_set(e, EXIT_SYSTEM, "%s: the persistence state is written on "
			       "little-endian machines only", path);
	if ((fd = tempfile_open_output(path, tmp, sizeof(tmp), e)) < 0)
		return -1;
	if (!(f = fdopen(fd, "wb"))) {
		err_sys(e, "%s", path);
		close(fd);
		goto fail;
	}
	fprintf(f, "%s\nscas", PERSIST_MAGIC);
	for (int s = 1; s <= WFS_NSCA; s++)
		if (p->sca_mask >> (s - 1) & 1)
			fprintf(f, " %d", s);
	fprintf(f, "\nrows %d %d\nexposures %d\nend %.17g\n", p->ylo + 1, p->yhi, p->exposures,
		p->have_last ? p->last_end : NAN);
	for (int s = 1; s <= WFS_NSCA; s++) {
		const struct persist_list *l = &p->now[s - 1];

		if (!(p->sca_mask >> (s - 1) & 1))
			continue;
		fprintf(f, "sca %d %zu\n", s, l->n);
		if (l->n && (fwrite(l->pix, sizeof(*l->pix), l->n, f) != l->n ||
			     fwrite(l->scale, sizeof(*l->scale), l->n, f) != l->n ||
			     fwrite(l->tend, sizeof(*l->tend), l->n, f) != l->n))
			break;
	}
	if (fflush(f) || ferror(f) || (tmp[0] && fsync(fileno(f)) < 0)) {
		err_sys(e, "%s", path);
		fclose(f);
		goto fail;
	}
	if (fclose(f)) {
		err_sys(e, "%s", path);
		goto fail;
	}
	if (tmp[0] && tempfile_commit(tmp, path, e) < 0)
		return -1;
	return 0;
fail:
	tempfile_discard(tmp);
	return -1;
}

/* The next header line of f into buf, its newline taken off.  0 or -1. */
static int line(FILE *f, char *buf, size_t cap)
{
	size_t n;

	if (!fgets(buf, (int)cap, f))
		return -1;
	n = strlen(buf);
	if (!n || buf[n - 1] != '\n')
		return -1;
	buf[n - 1] = 0;
	return 0;
}

static void mask_text(unsigned mask, char *buf, size_t cap)
{
	size_t len = 0;

	buf[0] = 0;
	for (int s = 1; s <= WFS_NSCA && len + 4 < cap; s++)
		if (mask >> (s - 1) & 1)
			len += (size_t)snprintf(buf + len, cap - len, "%s%d", len ? "," : "", s);
}

/* The reader of a state file: its name and the line it is at, for the
 * messages. */
struct state_in {
	FILE *f;
	const char *path;
	int lineno;
	char buf[256];
};

/* A file that ends too soon (or a line too long to be the program's),
 * where the reader is: -1 with a message, exit 1, or 2 if it could not be
 * read. */
static int state_short(const struct state_in *in, const char *want, struct err *e)
{
	if (ferror(in->f))
		return err_sys(e, "%s: persistence state", in->path);
	return err_set(e, EXIT_INPUT, "%s:%d: persistence state damaged or truncated: "
		       "expected '%s'", in->path, in->lineno, want);
}

/* The next header line, which must be form's key and a blank (form is
 * "key WHAT ...", for the message): the rest in *val.  0 or -1 with a
 * message. */
static int state_line(struct state_in *in, const char *form, const char **val, struct err *e)
{
	size_t k = strcspn(form, " ");

	in->lineno++;
	if (line(in->f, in->buf, sizeof(in->buf)) < 0)
		return state_short(in, form, e);
	if (strncmp(in->buf, form, k) || in->buf[k] != ' ')
		return err_set(e, EXIT_INPUT, "%s:%d: expected '%s': '%s'", in->path, in->lineno,
			       form, in->buf);
	*val = in->buf + k + 1;
	return 0;
}

/* A decimal integer at s, nothing before it, into *v: the character after
 * it, or NULL when s holds none or one beyond a long. */
static const char *int_at(const char *s, long *v)
{
	char *end;

	if (*s != '-' && !(*s >= '0' && *s <= '9'))
		return NULL;
	errno = 0;
	*v = strtol(s, &end, 10);
	return end == s || errno ? NULL : end;
}

/*
 * What persist_save() can write, which persist_load() takes and nothing
 * else.  Times are s on the clock of MJD x 86400 (persist_begin): an
 * exposure with a date begins within date_parse()'s years 1800-2200, one
 * without 60 s (the gap, at most GAP_MAX) after the one before, or at 0,
 * and lasts at most --exptime's SCENE_EXPTIME_MAX; so the end of the
 * last of N exposures is at most the start of 2201 plus N (GAP_MAX +
 * SCENE_EXPTIME_MAX).
 * A pixel's stimulus ended at an exposure's end: not after the state's
 * end, but for persist_begin's DATE_SLACK (with the rounding of the times
 * it compares) that each exposure may take the end back by.  Amplitudes
 * are above 0 (the floor is) and at most that of the largest fluence
 * (persist_add takes an infinite one as that) against the least reference
 * allowed.
 */
static double time_min(void)
{
	return date_mjd(1800, 1, 1, 0, 0, 0) * 86400.0;
}

static double time_max(long exposures)
{
	return date_mjd(2201, 1, 1, 0, 0, 0) * 86400.0 +
	       (double)exposures * (GAP_MAX + SCENE_EXPTIME_MAX);
}

static double time_late(double end, long exposures)
{
	return end + (double)exposures * (DATE_SLACK + 8 * DBL_EPSILON * fabs(end));
}

static double scale_max(const struct persist *p)
{
	return fermi(p, DBL_MAX) / fermi(p, REFERENCE_MIN);
}

/* The header after the magic line into *mask, *first, *last (1-based),
 * *exposures and *end (NaN: none).  0 or -1 with a message. */
static int state_header(struct state_in *in, const struct persist *p, unsigned *mask,
			long *first, long *last, long *exposures, double *end, struct err *e)
{
	char want[64], got[64];
	const char *v, *s;
	char *stop;
	long sca, prev = 0;

	if (state_line(in, "scas S ...", &v, e) < 0)
		return -1;
	for (s = v;; s++) {
		if (!(s = int_at(s, &sca)) || sca <= prev || sca > WFS_NSCA || (*s && *s != ' '))
			return err_set(e, EXIT_INPUT, "%s:%d: scas '%s': expected SCA numbers "
				       "from 1 to %d, ascending, each once", in->path, in->lineno,
				       v, WFS_NSCA);
		*mask |= 1u << (sca - 1);
		prev = sca;
		if (!*s)
			break;
	}
	if (state_line(in, "rows FIRST LAST", &v, e) < 0)
		return -1;
	if (!(s = int_at(v, first)) || *s != ' ' || !(s = int_at(s + 1, last)) || *s ||
	    *first < 1 || *last < *first || *last > WFS_NPIX)
		return err_set(e, EXIT_INPUT, "%s:%d: rows '%s': expected the first and last "
			       "science rows, from 1 to %d, the first not after the last",
			       in->path, in->lineno, v, WFS_NPIX);
	if (*mask != p->sca_mask || *first != p->ylo + 1 || *last != p->yhi) {
		mask_text(*mask, got, sizeof(got));
		mask_text(p->sca_mask, want, sizeof(want));
		return err_set(e, EXIT_INPUT, "%s: a persistence state of SCAs %s, rows %ld-%ld; "
			       "this run is of SCAs %s, rows %d-%d (--sca and --rows must be "
			       "those of the run that wrote it)", in->path, got, *first, *last,
			       want, p->ylo + 1, p->yhi);
	}
	if (state_line(in, "exposures N", &v, e) < 0)
		return -1;
	if (!(s = int_at(v, exposures)) || *s || *exposures < 0 || *exposures > INT_MAX)
		return err_set(e, EXIT_INPUT, "%s:%d: exposures '%s': expected the count of "
			       "exposures taken into the state, from 0 to %d", in->path,
			       in->lineno, v, INT_MAX);
	if (state_line(in, "end T", &v, e) < 0)
		return -1;
	*end = strtod(v, &stop);
	if (stop == v || *stop || isspace((unsigned char)*v))
		return err_set(e, EXIT_INPUT, "%s:%d: end '%s': not a number", in->path,
			       in->lineno, v);
	if (*exposures == 0 && !isnan(*end))
		return err_set(e, EXIT_INPUT, "%s:%d: end '%s': expected 'nan' (the state has "
			       "no exposures)", in->path, in->lineno, v);
	if (*exposures > 0 && !(*end >= time_min() && *end <= time_max(*exposures)))
		return err_set(e, EXIT_INPUT, "%s:%d: end '%s': expected the end of the last "
			       "of its %ld exposures, a time in s (MJD x 86400) from %.15g to "
			       "%.15g", in->path, in->lineno, v, *exposures, time_min(),
			       time_max(*exposures));
	return 0;
}

/* The block of SCA s into l: its line, then its pixels, amplitudes and
 * end times, each checked against what persist_save() writes for a state
 * of that many exposures ending at end.  0 or -1 with a message. */
static int state_block(struct state_in *in, const struct persist *p, int s, long exposures,
		       double end, struct persist_list *l, struct err *e)
{
	/* the state's rows and, at levels 1 and 2, the row either side
	 * (persist.h), within the SCA */
	long y0 = p->ylo > 0 ? p->ylo - 1 : 0, y1 = p->yhi < WFS_NPIX ? p->yhi : WFS_NPIX - 1;
	uint32_t pix_lo = (uint32_t)y0 * WFS_NPIX, pix_hi = (uint32_t)(y1 + 1) * WFS_NPIX - 1;
	long cap = exposures ? (y1 - y0 + 1) * WFS_NPIX : 0, sca, n;
	float smax = (float)scale_max(p);
	double late = time_late(end, exposures), tmin = time_min();
	char form[32];
	const char *v, *t;

	snprintf(form, sizeof(form), "sca %d N", s);
	if (state_line(in, form, &v, e) < 0)
		return -1;
	if (!(t = int_at(v, &sca)) || sca != s || *t != ' ' || !(t = int_at(t + 1, &n)) || *t)
		return err_set(e, EXIT_INPUT, "%s:%d: sca '%s': expected '%d N', the block of "
			       "SCA %d and its count of pixels", in->path, in->lineno, v, s, s);
	if (n < 0 || n > cap) {
		if (!cap)
			return err_set(e, EXIT_INPUT, "%s:%d: sca '%s': expected no pixels (the "
				       "state has no exposures)", in->path, in->lineno, v);
		return err_set(e, EXIT_INPUT, "%s:%d: sca '%s': expected from 0 to %ld pixels "
			       "(rows %ld-%ld of the SCA)", in->path, in->lineno, v, cap, y0 + 1,
			       y1 + 1);
	}
	list_free(l);
	if (!n)
		return 0;
	if (list_reserve(l, (size_t)n) < 0)
		return err_sys(e, "%s: persistence state", in->path);
	if (fread(l->pix, sizeof(*l->pix), (size_t)n, in->f) != (size_t)n ||
	    fread(l->scale, sizeof(*l->scale), (size_t)n, in->f) != (size_t)n ||
	    fread(l->tend, sizeof(*l->tend), (size_t)n, in->f) != (size_t)n) {
		if (ferror(in->f))
			return err_sys(e, "%s: persistence state", in->path);
		return err_set(e, EXIT_INPUT, "%s: persistence state damaged or truncated: the "
			       "block of sca %d (line %d) ends before its %ld pixels", in->path,
			       s, in->lineno, n);
	}
	l->n = (size_t)n;
	for (size_t i = 0; i < l->n; i++) {
		uint32_t pix = l->pix[i];

		if (pix < pix_lo || pix > pix_hi)
			return err_set(e, EXIT_INPUT, "%s: sca %d pixel %zu of %zu: number %lu: "
				       "expected y * %d + x from %lu to %lu (rows %ld-%ld of the "
				       "SCA)", in->path, s, i + 1, l->n, (unsigned long)pix,
				       WFS_NPIX, (unsigned long)pix_lo, (unsigned long)pix_hi,
				       y0 + 1, y1 + 1);
		if (i && pix <= l->pix[i - 1])
			return err_set(e, EXIT_INPUT, "%s: sca %d pixel %zu of %zu: number %lu "
				       "after %lu: expected ascending numbers, each once", in->path,
				       s, i + 1, l->n, (unsigned long)pix,
				       (unsigned long)l->pix[i - 1]);
		if (!(l->scale[i] > 0 && l->scale[i] <= smax))
			return err_set(e, EXIT_INPUT, "%s: sca %d pixel %zu of %zu (number %lu): "
				       "amplitude %g: expected a number above 0, at most %g (that "
				       "of the largest fluence)", in->path, s, i + 1, l->n,
				       (unsigned long)pix, (double)l->scale[i], (double)smax);
		if (!(l->tend[i] >= tmin && l->tend[i] <= late))
			return err_set(e, EXIT_INPUT, "%s: sca %d pixel %zu of %zu (number %lu): "
				       "end time %.15g: expected a time in s (MJD x 86400) from "
				       "%.15g to the state's end, %.15g", in->path, s, i + 1, l->n,
				       (unsigned long)pix, l->tend[i], tmin, end);
	}
	return 0;
}

int persist_load(struct persist *p, const char *path, struct err *e)
{
	struct state_in in = { .f = fopen(path, "rb"), .path = path };
	unsigned mask = 0;
	long first = 0, last = 0, exposures = 0;
	double end = NAN;
	struct stat st;

	if (!in.f) {
		if (errno == ENOENT)
			return 0;
		return err_sys(e, "%s: persistence state", path);
	}
	/* a directory opens, and fails only as it is read: bad input, as a
	 * directory given to --into is */
	if (fstat(fileno(in.f), &st) == 0 && S_ISDIR(st.st_mode)) {
		fclose(in.f);
		return err_set(e, EXIT_INPUT, "%s: a directory, not a wfiscene persistence state",
			       path);
	}
	in.lineno = 1;
	if (line(in.f, in.buf, sizeof(in.buf)) < 0 || strcmp(in.buf, PERSIST_MAGIC)) {
		if (ferror(in.f))
			err_sys(e, "%s: persistence state", path);
		else
			err_set(e, EXIT_INPUT, "%s:1: not a wfiscene persistence state (expected "
				"'%s')", path, PERSIST_MAGIC);
		goto fail;
	}
	if (state_header(&in, p, &mask, &first, &last, &exposures, &end, e) < 0)
		goto fail;
	for (int s = 1; s <= WFS_NSCA; s++)
		if ((mask >> (s - 1) & 1) &&
		    state_block(&in, p, s, exposures, end, &p->now[s - 1], e) < 0)
			goto fail;
	if (fgetc(in.f) != EOF) {
		err_set(e, EXIT_INPUT, "%s: persistence state damaged: more after the block of "
			"the last SCA (line %d), expected the end of the file", path, in.lineno);
		goto fail;
	}
	if (ferror(in.f)) {
		err_sys(e, "%s: persistence state", path);
		goto fail;
	}
	fclose(in.f);
	p->exposures = (int)exposures;
	p->have_last = exposures > 0;
	p->last_end = p->have_last ? end : 0;
	return 0;
fail:
	fclose(in.f);
	for (int s = 0; s < WFS_NSCA; s++)
		list_free(&p->now[s]);
	return -1;
}
