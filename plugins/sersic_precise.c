/*
 * sersic_precise.c - the sersic-precise model: a Sérsic galaxy whose every
 * pixel (and sub-pixel core cell) is integrated to a stated tolerance, then
 * convolved with the local ePSF.  The mathematics is in sersic.h.
 *
 * Cell integration:
 *  - cells within one cell size of the centre (the cusp for n > 1, all of a
 *    galaxy smaller than a cell) by wedges from the centre, exact up to a
 *    one-dimensional Gauss-Kronrod quadrature (sersic_rect_rel), to a
 *    tenth of the tolerance;
 *  - cells wider than twice the profile's length scale ell (sersic_scale)
 *    by adaptive Gauss-Legendre (below), which splits them until they are
 *    not, or past 8 ell (a needle, q r_e far below a pixel) takes the
 *    wedges;
 *  - cells where the profile's length scale ell is at least 10 cell sizes by
 *    the 2 x 2 Gauss-Legendre rule, whose error ~ (h/ell)^4 / 4320 is below
 *    3e-8 of the cell there;
 *  - cells (and sub-cells no wider than 2 ell) cut by the truncation
 *    ellipse by 8 x 8 midpoints (see adapt);
 *  - the rest by adaptive 2 x 2 / 3 x 3 Gauss-Legendre: a cell is accepted
 *    when the two rules agree to the tolerance (the 3 x 3 result, far more
 *    accurate than that difference, is kept), else split in four.  The
 *    rules are not asked on a cell wider than 2 ell, where both could step
 *    over a feature that narrow and agree on missing it.
 *
 * Settings: sersic-tol (relative tolerance per cell, default 1e-5),
 * sersic-trunc (flux fraction beyond the truncation radius, default 1e-4),
 * sersic-convolve (yes/no), sersic-flux (total/ie).
 */
#include "sersic.h"

#define PRECISE_TOL 1e-5
#define PRECISE_TRUNC 1e-4
#define PRECISE_DEPTH 18
/* The 2 x 2 and 3 x 3 rules are trusted on a cell no wider than
 * PRECISE_SEEN of the profile's length scales; their points are then close
 * enough to see any feature of the light.  A wider cell is split in four
 * without asking them, up to PRECISE_WEDGE length scales; wider still (a
 * needle, the middle of a galaxy far below a pixel) it goes to the
 * wedges, whose cost does not grow as the feature narrows. */
#define PRECISE_SEEN 2.0
#define PRECISE_WEDGE 8.0

struct precise {
	const struct wfs_host *host;
	double tol, trunc;
	int convolve;
	double psf_core;
	int core_k;
};

struct precise_opt {
	double tol;             /* relative, per cell */
	double atol;            /* absolute floor, fraction of the flux */
};

static const double gl3_x = 0.774596669241483377035853079956480;   /* sqrt(3/5) */
static const double gl2_x = 0.577350269189625764509148780501957;   /* 1/sqrt(3) */

static double gauss2(const struct sersic_gal *g, double x0, double x1, double y0, double y1)
{
	double mx = 0.5 * (x0 + x1), hx = 0.5 * (x1 - x0), my = 0.5 * (y0 + y1), hy = 0.5 * (y1 - y0);
	double dx = hx * gl2_x, dy = hy * gl2_x;

	return hx * hy * (sersic_sb(g, mx - dx, my - dy) + sersic_sb(g, mx + dx, my - dy)
			  + sersic_sb(g, mx - dx, my + dy) + sersic_sb(g, mx + dx, my + dy));
}

static double gauss3(const struct sersic_gal *g, double x0, double x1, double y0, double y1)
{
	static const double w[3] = { 5.0 / 9, 8.0 / 9, 5.0 / 9 };
	double mx = 0.5 * (x0 + x1), hx = 0.5 * (x1 - x0), my = 0.5 * (y0 + y1), hy = 0.5 * (y1 - y0);
	double xs[3] = { mx - hx * gl3_x, mx, mx + hx * gl3_x };
	double ys[3] = { my - hy * gl3_x, my, my + hy * gl3_x };
	double s = 0;

	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++)
			s += w[i] * w[j] * sersic_sb(g, xs[i], ys[j]);
	return hx * hy * s;
}

static double adapt(const struct sersic_gal *g, const struct precise_opt *o,
		    double x0, double x1, double y0, double y1, double atol, int depth)
{
	double rmin = sersic_rho_min(g, x0, x1, y0, y1);
	if (rmin >= g->rho_t)
		return 0.0;
	/* A cell the two rules cannot see into (a line narrower than their
	 * points' spacing, which both would step over and agree on missing):
	 * split, or if far too wide, wedges. */
	double side = fmax(x1 - x0, y1 - y0), ell = sersic_cell_scale(g, rmin, x0, x1, y0, y1);
	if (ell * PRECISE_WEDGE < side)
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 0.1 * o->tol, atol / g->flux, 0);
	int seen = ell * PRECISE_SEEN >= side || depth >= PRECISE_DEPTH;
	/* A cell cut by the truncation ellipse holds light at the eps level
	 * (about eps / (pi q rho_t^2 r_e^2) of the flux per pixel), behind a
	 * step no rule converges on quickly: 8 x 8 points resolve the step to
	 * 1/8 of the cell, an error of a few per cent of that faint light. */
	if (seen && sersic_rho2_max(g, x0, x1, y0, y1) > g->rho_t2)
		return sersic_midpoint(g, x0, x1, y0, y1, 8);
	if (seen) {
		double g3 = gauss3(g, x0, x1, y0, y1), g2 = gauss2(g, x0, x1, y0, y1);
		if (fabs(g3 - g2) <= fmax(o->tol * fabs(g3), atol) || depth >= PRECISE_DEPTH)
			return g3;
	}
	double mx = 0.5 * (x0 + x1), my = 0.5 * (y0 + y1);
	atol *= 0.25;
	return adapt(g, o, x0, mx, y0, my, atol, depth + 1) + adapt(g, o, mx, x1, y0, my, atol, depth + 1)
	       + adapt(g, o, x0, mx, my, y1, atol, depth + 1) + adapt(g, o, mx, x1, my, y1, atol, depth + 1);
}

static double precise_cell(const struct sersic_gal *g, const void *opt,
			   double x0, double x1, double y0, double y1, double h)
{
	const struct precise_opt *o = opt;
	double rmin = sersic_rho_min(g, x0, x1, y0, y1);

	if (rmin >= g->rho_t)
		return 0.0;
	/* Light below the absolute floor even at the cell's brightest point:
	 * one point is as good as any rule. */
	double area = (x1 - x0) * (y1 - y0);
	if (exp(g->lni0 - g->b * pow(rmin, g->inv_n)) * area <= o->atol * g->flux)
		return sersic_sb(g, 0.5 * (x0 + x1), 0.5 * (y0 + y1)) * area;
	/* Near the centre: exact wedges, to the tolerance of the cell's own
	 * light. */
	if (sersic_near_centre(x0, x1, y0, y1, h))
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 0.1 * o->tol, o->atol, 0);
	/* Smooth light well inside the cut: 2 x 2 points. */
	double ell = sersic_cell_scale(g, rmin, x0, x1, y0, y1);
	if (ell >= 10.0 * h && sersic_rho2_max(g, x0, x1, y0, y1) <= g->rho_t2)
		return gauss2(g, x0, x1, y0, y1);
	return adapt(g, o, x0, x1, y0, y1, o->atol * g->flux, 0);
}

static int precise_init(const struct wfs_host *host, void **state)
{
	struct precise *p = calloc(1, sizeof(*p));

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	if (sersic_setting_num(host, "sersic-tol", 1e-12, 1e-1, PRECISE_TOL, &p->tol) ||
	    sersic_setting_num(host, "sersic-trunc", 1e-12, 0.5, PRECISE_TRUNC, &p->trunc) ||
	    sersic_setting_num(host, "psf-core", 0, 1e3, SERSIC_PSF_CORE, &p->psf_core) ||
	    sersic_setting_core(host, &p->core_k) ||
	    sersic_setting_convolve(host, &p->convolve)) {
		free(p);
		return -1;
	}
	*state = p;
	return 0;
}

static void precise_fini(void *state)
{
	free(state);
}

static int precise_prepare(void *state, struct wfs_source *src)
{
	struct precise *p = state;

	if (sersic_prepare_common(p->host, src, p->trunc, 0, 0) < 0)
		return -1;
	sersic_keep_sca_light(src);
	return 0;
}

static int precise_footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	struct precise *p = state;

	return sersic_footprint_common(p->host, src, box, p->convolve, p->core_k);
}

static int precise_render(void *state, void *tstate, void *thread,
			  const struct wfs_source *src, const struct wfs_window *win)
{
	struct precise *p = state;
	/* Cells far out whose light is below 1e-3 of the tolerance of the
	 * whole flux are not refined further. */
	struct precise_opt o = { p->tol, 1e-3 * p->tol * 1e-4 };
	struct sersic_method m = { .cell = precise_cell, .opt = &o, .convolve = p->convolve,
				   .psf_core = p->psf_core, .core_k = p->core_k, .block = 1 };

	return sersic_render_common(p->host, thread, src, win, &m);
}

static int precise_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct precise *p = state;

	return sersic_reach_common(p->host, src, p->trunc, p->convolve, p->core_k, pixels);
}

static const struct wfs_setting precise_settings[] = {
	{ "sersic-tol", SERSIC_STR(PRECISE_TOL), "number from 1e-12 to 0.1",
	  "relative tolerance of each pixel's integral" },
	{ "sersic-trunc", SERSIC_STR(PRECISE_TRUNC), "number from 1e-12 to 0.5",
	  "fraction of the light allowed beyond the truncation radius" },
	SERSIC_SETTINGS,
};

static const struct wfs_model precise_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "sersic-precise",
	.summary = "Sérsic galaxy, each pixel integrated to a stated tolerance, convolved with the ePSF",
	.columns = sersic_columns,
	.ncolumns = SERSIC_NCOL,
	.init = precise_init,
	.fini = precise_fini,
	.prepare = precise_prepare,
	.footprint = precise_footprint,
	.render = precise_render,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = precise_settings,
	.nsettings = (int)(sizeof(precise_settings) / sizeof(precise_settings[0])),
	.reach = precise_reach,
	.flags = WFS_PARALLEL_PREPARE,
	.roman_type = "SER",
	.column_roles = sersic_roles,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &precise_model : NULL;
}
