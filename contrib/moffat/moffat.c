/*
 * moffat.c - a Moffat-profile star: an example wfiscene source model that
 * is not part of the core, built the way an outside author builds one (see
 * README and wfiscene-model(7)).
 *
 * The Moffat (1969) profile with FWHM f and index beta is
 *
 *   I(r) = flux (beta - 1) / (pi alpha^2) [1 + (r / alpha)^2]^-beta,
 *   alpha = f / (2 sqrt(2^(1/beta) - 1)),
 *
 * whose integral over the plane is flux for beta > 1.  It has power-law
 * wings (I ~ r^-2beta), so unlike a Gaussian it must be truncated on
 * purpose.  The light outside radius R is
 *
 *   out(R) = [1 + (R / alpha)^2]^(1 - beta),
 *
 * and the model cuts at the R where out(R) = MOFFAT_TRUNC (0.1 %), but no
 * further than MOFFAT_RMAX pixels; the profile inside R is scaled by
 * 1 / (1 - out(R)) so the pixels still add up to the row's flux.  A row
 * whose beta is so close to 1 that more than MOFFAT_LOSS_MAX (1 %) of the
 * light lies beyond MOFFAT_RMAX is refused rather than silently bent.
 *
 * Elliptical stars: ellip = 1 - b/a, and fwhm is along the major axis,
 * which points theta degrees from detector +x towards +y.  The radius above
 * is then the elliptical radius r^2 = x'^2 + (y' / q)^2 (x' along the major
 * axis, q = b/a), and the normalisation gains a factor 1/q.
 *
 * Pixels are integrated, not sampled: a star of FWHM 2 pixels changes by a
 * factor of several across its central pixel.  Each pixel is split into
 * m x m cells, each integrated with 2 x 2 Gauss-Legendre points (exact for
 * cubics), with m chosen from how fast the profile varies there: its local
 * length scale is about sqrt(alpha_minor^2 + d^2) at distance d from the
 * nearest point of the pixel, and m = ceil(6 / scale), at most 16.  Against
 * a 400 x 400 point midpoint rule the central pixels of stars with FWHM 1-3
 * pixels come out within 2e-5 to 2e-4 (2e-3 with 2 / scale, the cost of
 * which is only a few central pixels).  Pixels cut by the truncation edge
 * are less exact, but hold about 1e-3 of the light between them.  m
 * depends only on where the pixel is relative to the star, so a star split
 * across tiles gets the same pixel values.
 */
#include <math.h>
#include <stdlib.h>

#include "wfiscene/model.h"

#define MOFFAT_TRUNC 1e-3       /* light left beyond the truncation radius */
#define MOFFAT_RMAX 512.0       /* largest truncation radius, pixels */
#define MOFFAT_LOSS_MAX 0.01    /* refuse rows that would lose more than this */
#define MOFFAT_SUB 6.0          /* cells per local length scale */
#define MOFFAT_MAXSUB 16
#define MOFFAT_PI 3.14159265358979323846

/* The catalog columns, in the order render() finds them in src->param. */
enum { COL_BETA, COL_FWHM, COL_ELLIP, COL_THETA, NCOL };

/* What prepare() leaves in src->aux for footprint() and render(). */
enum {
	AUX_INV_A2,     /* 1 / alpha^2, alpha along the major axis */
	AUX_INV_Q2,     /* 1 / q^2 */
	AUX_COS,        /* cos theta */
	AUX_SIN,        /* sin theta */
	AUX_R2,         /* truncation radius squared, major-axis pixels^2 */
	AUX_AMP,        /* peak surface brightness, counts/s per pixel^2 */
	AUX_HX,         /* half-widths of the truncation ellipse's */
	AUX_HY,         /*   bounding box, pixels */
};

static const struct wfs_column moffat_columns[NCOL] = {
	{ "beta", 0, 1, "Moffat index beta (> 1; 2.5-4.765 for seeing-like stars)" },
	{ "fwhm", 0, 1, "full width at half maximum along the major axis, pixels" },
	{ "ellip", 0, 0, "ellipticity 1 - b/a, 0 <= ellip < 1 (default 0)" },
	{ "theta", 0, 0, "major axis angle from detector +x towards +y, degrees (default 0)" },
};

/* The only state: the host, for error messages in prepare(). */
struct moffat {
	const struct wfs_host *host;
};

static int moffat_init(const struct wfs_host *host, void **state)
{
	struct moffat *m = malloc(sizeof(*m));

	if (!m)
		return host->error(host->ctx, "out of memory");
	m->host = host;
	*state = m;
	return 0;
}

static void moffat_fini(void *state)
{
	free(state);
}

/* Validate a row and precompute everything render() needs. */
static int moffat_prepare(void *state, struct wfs_source *src)
{
	const struct wfs_host *h = ((struct moffat *)state)->host;
	double beta = src->param[COL_BETA], fwhm = src->param[COL_FWHM];
	double ellip = src->param[COL_ELLIP], theta = src->param[COL_THETA];
	double alpha, q, r, loss, rx, ry, c, s;

	if (!(beta > 1) || !isfinite(beta))
		return h->error(h->ctx, "beta must be above 1 (its flux is infinite at 1 "
				"and below): %g", beta);
	if (!(fwhm > 0) || !isfinite(fwhm))
		return h->error(h->ctx, "fwhm must be a positive number of pixels: %g", fwhm);
	if (!(ellip >= 0 && ellip < 1))
		return h->error(h->ctx, "ellip must be at least 0 and below 1: %g", ellip);
	if (!isfinite(theta))
		return h->error(h->ctx, "theta must be a number of degrees: %g", theta);
	if (!isfinite(src->flux))
		return h->error(h->ctx, "flux must be finite: %g", src->flux);

	alpha = fwhm / (2 * sqrt(pow(2, 1 / beta) - 1));
	q = 1 - ellip;
	/* out(R) = MOFFAT_TRUNC solved for R; pow() overflows to inf for
	 * beta near 1, which the cap handles. */
	r = alpha * sqrt(pow(MOFFAT_TRUNC, 1 / (1 - beta)) - 1);
	if (!(r <= MOFFAT_RMAX))
		r = MOFFAT_RMAX;
	loss = pow(1 + r * r / (alpha * alpha), 1 - beta);
	if (loss > MOFFAT_LOSS_MAX)
		return h->error(h->ctx, "beta %g with fwhm %g puts %.1f%% of the light "
				"beyond %g pixels; use a larger beta", beta, fwhm,
				100 * loss, MOFFAT_RMAX);

	c = cos(theta * MOFFAT_PI / 180);
	s = sin(theta * MOFFAT_PI / 180);
	rx = r;
	ry = q * r;
	src->aux[AUX_INV_A2] = 1 / (alpha * alpha);
	src->aux[AUX_INV_Q2] = 1 / (q * q);
	src->aux[AUX_COS] = c;
	src->aux[AUX_SIN] = s;
	src->aux[AUX_R2] = r * r;
	src->aux[AUX_AMP] = src->flux * (beta - 1) / (MOFFAT_PI * alpha * alpha * q) /
			    (1 - loss);
	/* The bounding box of an ellipse with semi-axes rx, ry turned by theta. */
	src->aux[AUX_HX] = sqrt(rx * rx * c * c + ry * ry * s * s);
	src->aux[AUX_HY] = sqrt(rx * rx * s * s + ry * ry * c * c);
	return 0;
}

/* Pixels whose square [i - 1/2, i + 1/2) overlaps [x - h, x + h]. */
static void moffat_range(double x, double h, int *i0, int *i1)
{
	double lo = floor(x - h - 0.5) + 1, hi = ceil(x + h + 0.5);

	/* A source far off the detector must not overflow an int; the host
	 * clips the box to the detector anyway. */
	*i0 = (int)fmax(-1e9, fmin(1e9, lo));
	*i1 = (int)fmax(-1e9, fmin(1e9, hi));
}

static int moffat_footprint(void *state, const struct wfs_source *src,
			    struct wfs_box *box)
{
	(void)state;
	moffat_range(src->x, src->aux[AUX_HX], &box->x0, &box->x1);
	moffat_range(src->y, src->aux[AUX_HY], &box->y0, &box->y1);
	return 0;
}

/* The truncated profile at offset (dx, dy) from the centre, per pixel^2. */
static double moffat_at(const double *a, double beta, double dx, double dy)
{
	double xm = dx * a[AUX_COS] + dy * a[AUX_SIN];
	double ym = -dx * a[AUX_SIN] + dy * a[AUX_COS];
	double r2 = xm * xm + ym * ym * a[AUX_INV_Q2];

	if (r2 > a[AUX_R2])
		return 0;
	return a[AUX_AMP] * exp(-beta * log1p(r2 * a[AUX_INV_A2]));
}

/* The integral over the pixel centred at (dx, dy) from the star: m x m
 * cells, 2 x 2 Gauss-Legendre points each (at +-1/sqrt(3) of the half
 * cell, equal weights). */
static double moffat_pixel(const double *a, double beta, double dx, double dy,
			   int m)
{
	double cell = 1.0 / m, g = 0.5 * cell / sqrt(3.0), sum = 0;
	int u, v;

	for (v = 0; v < m; v++) {
		double cy = dy - 0.5 + (v + 0.5) * cell;

		for (u = 0; u < m; u++) {
			double cx = dx - 0.5 + (u + 0.5) * cell;

			sum += moffat_at(a, beta, cx - g, cy - g) +
			       moffat_at(a, beta, cx + g, cy - g) +
			       moffat_at(a, beta, cx - g, cy + g) +
			       moffat_at(a, beta, cx + g, cy + g);
		}
	}
	return sum * 0.25 * cell * cell;
}

/*
 * Adds the star into the part of its box inside win, and nothing else: the
 * loops run over the intersection only.  Reads only src and its own
 * constants, writes only win, allocates nothing: safe to call from any
 * number of threads at once.
 */
static int moffat_render(void *state, void *tstate, void *thread,
			 const struct wfs_source *src, const struct wfs_window *win)
{
	const double *a = src->aux;
	double beta = src->param[COL_BETA];
	/* The profile's narrowest scale: alpha along the minor axis. */
	double amin2 = 1 / (a[AUX_INV_A2] * a[AUX_INV_Q2]);
	int x0, x1, y0, y1, i, j;

	(void)state;
	(void)tstate;
	(void)thread;
	moffat_range(src->x, a[AUX_HX], &x0, &x1);
	moffat_range(src->y, a[AUX_HY], &y0, &y1);
	if (x0 < win->x0)
		x0 = win->x0;
	if (y0 < win->y0)
		y0 = win->y0;
	if (x1 > win->x0 + win->nx)
		x1 = win->x0 + win->nx;
	if (y1 > win->y0 + win->ny)
		y1 = win->y0 + win->ny;
	for (j = y0; j < y1; j++) {
		double *row = win->pix + (ptrdiff_t)(j - win->y0) * win->stride - win->x0;
		double dy = j - src->y;

		for (i = x0; i < x1; i++) {
			double dx = i - src->x;
			/* Distance to the pixel's nearest point (its centre less
			 * half a diagonal), as the star may sit inside it. */
			double d = fmax(0, sqrt(dx * dx + dy * dy) - 0.7072);
			double m = ceil(MOFFAT_SUB / sqrt(amin2 + d * d));
			int mi = m < 1 ? 1 : m > MOFFAT_MAXSUB ? MOFFAT_MAXSUB : (int)m;

			row[i] += moffat_pixel(a, beta, dx, dy, mi);
		}
	}
	return 0;
}

/* How far the star's light goes (model.h, reach()): its truncation
 * ellipse's larger half-width, plus the half pixel its edge pixels reach
 * beyond it and a pixel of rounding.  prepare() works on a copy. */
static int moffat_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct wfs_source at = *src;

	if (moffat_prepare(state, &at) < 0)
		return -1;
	*pixels = fmax(at.aux[AUX_HX], at.aux[AUX_HY]) + 1.5;
	return 0;
}

static const struct wfs_model moffat_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "moffat",
	.summary = "Moffat-profile star (beta, fwhm; optional ellip, theta), truncated at 99.9% of its light",
	.columns = moffat_columns,
	.ncolumns = NCOL,
	.init = moffat_init,
	.fini = moffat_fini,
	.prepare = moffat_prepare,
	.footprint = moffat_footprint,
	.render = moffat_render,
	.column_size = sizeof(struct wfs_column),
	.reach = moffat_reach,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &moffat_model : NULL;
}
