/*
 * pupil.c - the clear aperture of a WFI pupil mask: the clearance of a
 * point (the struts, the rim, the obscuration, the clipping square), the
 * clear fraction of a sample's cell, and a coarse map of the mask's
 * wholly clear and wholly dark regions, for optics.c's rasters.  The
 * shortcuts give the numbers of the plain count of every sub-sample by the
 * whole clearance test (optics_pupil_cover_plain, and the plain argument
 * of pupil_cover_affine, for the tests).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "optics.h"
#include "pupil.h"

void optics_pupil_annulus(struct optics_pupil *p, double r_out, double r_in)
{
	memset(p, 0, sizeof(*p));
	for (int k = 0; k < OPTICS_NANG; k++) {
		p->rout[k] = r_out;
		p->rin[k] = r_in;
	}
	p->rmax = p->rout_min = r_out;
	p->rin_max = r_in;
	p->half = 1e9;
}

static inline double min2(double a, double b) { return a < b ? a : b; }
static inline double max2(double a, double b) { return a > b ? a : b; }

static inline double square_gap(const struct optics_pupil *p, double x, double y)
{
	return min2(p->half - fabs(x), p->half - fabs(y));
}

static inline double strut_gap(const struct optics_strut *s, double x, double y)
{
	double u = (x - s->x0) * s->c + (y - s->y0) * s->sn;
	double v = -(x - s->x0) * s->sn + (y - s->y0) * s->c;

	return max2(max2(s->smin - u, u - s->smax),
		    max2(s->lo_a + s->lo_b * u - v, v - s->hi_a - s->hi_b * u));
}

/* the rim's and the obscuration's gap at radius r = hypot(x, y) */
static inline double rim_gap(const struct optics_pupil *p, double x, double y, double r)
{
	double a = (atan2(y, x) + M_PI) * (OPTICS_NANG / (2 * M_PI));
	int k0 = (int)a;
	double f = a - k0;
	k0 %= OPTICS_NANG;
	int k1 = (k0 + 1) % OPTICS_NANG;
	double ro = p->rout[k0] + f * (p->rout[k1] - p->rout[k0]);
	double ri = p->rin[k0] + f * (p->rin[k1] - p->rin[k0]);

	return min2(ro - r, r - ri);
}

/*
 * Signed distance-like clearance of a point: positive inside the clear
 * aperture, negative outside, in metres.  For the rim and the obscuration
 * the radial gap stands in for the distance (the edges are nearly circles,
 * so it is within a few percent of it); for the struts and the clipping
 * square it is the exact perpendicular distance.
 *
 * It is the least of its terms: the square's gap, each strut's (the
 * largest violation of its strip's four half-planes, negative inside the
 * strip) and the rim's (the least of the rim's and the obscuration's
 * radial gaps).  Each term is made by one function below, so that
 * clearance() and the cells' tests (term_bounds(), covered()) compute
 * the same numbers.
 */
static double clearance(const struct optics_pupil *p, double x, double y)
{
	double r = hypot(x, y);
	double d = square_gap(p, x, y);

	for (int i = 0; i < p->nstrut; i++)
		d = min2(d, strut_gap(&p->strut[i], x, y));
	/* The rim and the obscuration (an interpolation in angle) cannot be
	 * the minimum when the extreme radii already leave more room than d
	 * (by far more than rounding, so the minimum is the same number). */
	if (d < min2(p->rout_min - r, r - p->rin_max) - 1e-9)
		return d;
	return min2(d, rim_gap(p, x, y, r));
}

/*
 * The terms that decide a cell's sub-samples.  clearance() >= 0 exactly
 * when every term is >= 0 (the minimum of doubles is one of them; where
 * clearance() skips the rim, its gaps exceed d + 1e-9 > 0).  A term that
 * stays above 0 over a disc of radius `reach` about (x, y) need not be
 * looked at there, and one that stays below 0 leaves the whole disc dark.
 * The square's gap and a strut's change by at most their gradient's length
 * times the distance (1 for the square; for a strut its steepest
 * half-plane's, at least 1), and the radius r by at most the distance; the
 * rim's gaps are at least rout_min - r and r - rin_max, and the rim's at
 * most rmax - r.  TERM_SLACK stands for the rounding of all these.
 */
#define TERM_SLACK 1e-12        /* m: far above the terms' rounding */
#define TERM_SQUARE (-1)        /* in a list of terms: the square's gap */
#define TERM_RIM (-2)           /* the rim's gaps */

static inline double strut_slope(const struct optics_strut *s)
{
	return max2(1, max2(hypot(1, s->lo_b), hypot(1, s->hi_b))) * (1 + 1e-9);
}

/* The terms that may change sign within a cell (term_bounds), and for the
 * rim the least and largest radii of the rim's and the obscuration's
 * tables over the angles the cell spans. */
struct terms {
	int act[OPTICS_MAXSTRUT + 2], n;
	double out_lo, out_hi, in_lo, in_hi;
	double r2_clear[2], r2_dark[2]; /* covered(): r^2 bounds, below */
};

/* The terms that may change sign within reach of (x, y), into t: 1 when
 * every one of the others is positive there, 0 when one is negative
 * throughout (the cell is dark). */
static int term_bounds(const struct optics_pupil *p, double x, double y, double reach,
		       struct terms *t)
{
	double m = reach * (1 + 1e-9) + TERM_SLACK, g, r;

	/* (the rim's bounds are read only when it is a term) */
	*t = (struct terms){ .out_lo = INFINITY, .in_lo = INFINITY, .out_hi = -INFINITY,
			     .in_hi = -INFINITY };
	g = square_gap(p, x, y);
	if (g < -m)
		return 0;
	if (g <= m)
		t->act[t->n++] = TERM_SQUARE;
	for (int i = 0; i < p->nstrut; i++) {
		double ms = reach * strut_slope(&p->strut[i]) + TERM_SLACK;

		g = strut_gap(&p->strut[i], x, y);
		if (g < -ms)
			return 0;
		if (g <= ms)
			t->act[t->n++] = i;
	}
	r = hypot(x, y);
	if (p->rmax - r < -m)
		return 0;       /* beyond the rim everywhere */
	if (p->rout_min - r > m && r - p->rin_max > m)
		return 1;
	t->act[t->n++] = TERM_RIM;
	/* the table rows rim_gap() may read for a sample of the cell: those
	 * of the bins its angles span (within asin(reach / r) of the
	 * centre's, a millionth of a bin more), and the next */
	long ka = 0, kb = OPTICS_NANG;
	if (r > 2 * m) {
		double a = (atan2(y, x) + M_PI) * (OPTICS_NANG / (2 * M_PI));
		double da = asin(m / r) * (OPTICS_NANG / (2 * M_PI)) + 1e-6;

		ka = (long)floor(a - da);
		kb = (long)floor(a + da) + 1;
	}
	for (long k = ka; k <= kb && k - ka <= OPTICS_NANG; k++) {
		int q = (int)(((k % OPTICS_NANG) + OPTICS_NANG) % OPTICS_NANG);

		t->out_lo = min2(t->out_lo, p->rout[q]);
		t->out_hi = max2(t->out_hi, p->rout[q]);
		t->in_lo = min2(t->in_lo, p->rin[q]);
		t->in_hi = max2(t->in_hi, p->rin[q]);
	}
	/* the same bounds on x x + y y, a part in 10^12 inside them (the
	 * square's rounding against hypot's: three ulps and one) */
	{
		double ol = t->out_lo - TERM_SLACK, ih = t->in_hi + TERM_SLACK;
		double oh = t->out_hi + TERM_SLACK, il = t->in_lo - TERM_SLACK;

		t->r2_clear[0] = ih > 0 ? ih * ih * (1 + 1e-12) : -1;
		t->r2_clear[1] = ol > 0 ? ol * ol * (1 - 1e-12) : -1;
		t->r2_dark[0] = il > 0 ? il * il * (1 - 1e-12) : -1;
		t->r2_dark[1] = oh * oh * (1 + 1e-12);
	}
	return 1;
}

/* Whether sub-sample (x, y) is clear, by the terms t alone (the others
 * positive throughout its cell): clearance(p, x, y) >= 0.  The rim's gaps
 * from its radius alone where the tables' bounds tell (the interpolated
 * radii lie between them, to rounding). */
static inline int covered(const struct optics_pupil *p, const struct terms *t, double x,
			  double y)
{
	for (int k = 0; k < t->n; k++) {
		int a = t->act[k];

		if (a == TERM_SQUARE) {
			if (square_gap(p, x, y) < 0)
				return 0;
		} else if (a == TERM_RIM) {
			double r2 = x * x + y * y, r;

			if (r2 > t->r2_clear[0] && r2 < t->r2_clear[1])
				continue;       /* within both radii's bounds */
			if (r2 > t->r2_dark[1] || r2 < t->r2_dark[0])
				return 0;       /* beyond one */
			r = hypot(x, y);
			if (r > t->out_hi + TERM_SLACK || r < t->in_lo - TERM_SLACK)
				return 0;
			if (!(r < t->out_lo - TERM_SLACK && r > t->in_hi + TERM_SLACK) &&
			    rim_gap(p, x, y, r) < 0)
				return 0;
		} else if (strut_gap(&p->strut[a], x, y) < 0) {
			return 0;
		}
	}
	return 1;
}

/*
 * The clear fraction of the cell about (x, y) of the Zernike plane whose
 * 8 x 8 sub-samples are (x, y) + b (u, v), u, v = (i - 3.5) d / 8, the
 * mask seen at (x, fy y): whole (1 or 0) when the centre's clearance is
 * beyond edge either way, else the sub-samples counted, with plain by the
 * whole clearance test, else by the terms that can change sign within
 * reach of the centre (term_bounds(), covered()): the same count.
 */
static double cover_cell(const struct optics_pupil *p, double x, double y, const double b[4],
			 double d, double fy, double edge, double reach, int plain)
{
	double c = clearance(p, x, fy * y), sx[64], sy[64];
	struct terms t;
	int hit = 0;

	if (c > edge)
		return 1;
	if (c < -edge)
		return 0;
	for (int j = 0, k = 0; j < 8; j++)
		for (int i = 0; i < 8; i++, k++) {
			double u = (i - 3.5) * d / 8, v = (j - 3.5) * d / 8;

			sx[k] = x + b[0] * u + b[1] * v;
			sy[k] = fy * (y + b[2] * u + b[3] * v);
		}
	if (plain) {
		for (int k = 0; k < 64; k++)
			hit += clearance(p, sx[k], sy[k]) >= 0;
	} else if (term_bounds(p, x, fy * y, reach, &t)) {
		for (int k = 0; k < 64; k++)
			hit += covered(p, &t, sx[k], sy[k]);
	}
	return hit / 64.0;
}

/* the square cell: b the identity (x + 1 u + 0 v is x + u to the bit),
 * whole beyond 0.75 d, its sub-samples within 0.62 d of the centre */
static const double unit_map[4] = { 1, 0, 0, 1 };

double optics_pupil_cover_plain(const struct optics_pupil *p, double x, double y, double d)
{
	return cover_cell(p, x, y, unit_map, d, 1, 0.75 * d, 0.75 * d, 1);
}

double optics_pupil_cover(const struct optics_pupil *p, double x, double y,
			  double d)
{
	return cover_cell(p, x, y, unit_map, d, 1, 0.75 * d, 0.75 * d, 0);
}

/* the parallelogram: whole beyond 1.01 reach, its sub-samples within
 * reach (its half diagonal) */
double pupil_cover_affine(const struct optics_pupil *p, double x, double y, const double b[4],
			  double d, int flip, double reach, int plain)
{
	return cover_cell(p, x, y, b, d, flip ? -1 : 1, 1.01 * reach, reach, plain);
}

int pupil_coarse_make(struct pupil_coarse *co, const struct optics_pupil *p, double reach)
{
	double e = fmax(p->rmax, p->half * M_SQRT2) + 4 * reach;
	double hd, t;

	co->g = PUPIL_COARSE_SIDE;
	co->org = -e;
	co->cs = 2 * e / co->g;
	co->inv = 1 / co->cs;
	/* a sample's distance from its cell's centre, and the margin */
	hd = 0.5 * co->cs * M_SQRT2 * (1 + 1e-9) + TERM_SLACK;
	t = 1.01 * reach * (1 + 1e-9) + TERM_SLACK;
	if (!(co->cl = malloc((size_t)co->g * co->g)))
		return -1;
	for (int b = 0; b < co->g; b++)
		for (int a = 0; a < co->g; a++) {
			double x = co->org + (a + 0.5) * co->cs, y = co->org + (b + 0.5) * co->cs;
			double g = square_gap(p, x, y), r = hypot(x, y);
			int clear = g - hd > t, dark = g + hd < -t;

			for (int i = 0; i < p->nstrut && !dark; i++) {
				double l = hd * strut_slope(&p->strut[i]);

				g = strut_gap(&p->strut[i], x, y);
				clear &= g - l > t;
				dark |= g + l < -t;
			}
			clear &= p->rout_min - r - hd > t && r - hd - p->rin_max > t;
			dark |= p->rmax - r + hd < -t;
			co->cl[(size_t)b * co->g + a] = dark ? PUPIL_DARK :
							clear ? PUPIL_CLEAR : PUPIL_UNKNOWN;
		}
	return 0;
}

void pupil_coarse_free(struct pupil_coarse *co)
{
	free(co->cl);
	co->cl = NULL;
}
