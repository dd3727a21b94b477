/*
 * sersic_quick.c - the sersic-quick model: a Sérsic galaxy sampled at
 * points, with more points per pixel where the profile changes fast, then
 * convolved with the local ePSF.  The mathematics is in sersic.h.
 *
 * Cell integration: the cells within one cell of the centre (where the cusp
 * of n > 1, or a galaxy smaller than a cell, defeats any sampling) by wedges
 * from the centre (sersic_rect_rel), to 1e-4 of the cell; every other cell
 * by the midpoint rule on an N x N grid.  The midpoint rule's error on a
 * cell of side h is about (h/N)^2 / (24 ell^2) of the cell, ell the
 * profile's length scale at the cell's nearest point (sersic_scale), so
 * N = ceil(h / (QUICK_STEP ell)): with QUICK_STEP = 0.5 a cell is within
 * about 1%, and most of the light sits in cells far better than that.  A
 * cell that would need more than QUICK_NMAX points a side (a needle, q r_e
 * far below a pixel, which points would step over) goes to the wedges too,
 * to 1e-3 of its light.  The measured total-flux error is below 1% for
 * n <= 4 (BENCHMARKS.md).
 *
 * Settings: sersic-trunc (flux fraction beyond the truncation radius,
 * default 1e-3), sersic-convolve (yes/no), sersic-flux (total/ie).
 */
#include "sersic.h"

#define QUICK_TRUNC 1e-3
#define QUICK_STEP 0.5
#define QUICK_NMAX 16

struct quick {
	const struct wfs_host *host;
	double trunc;
	int convolve;
	double psf_core;
	int core_k;
};

static double quick_cell(const struct sersic_gal *g, const void *opt,
			 double x0, double x1, double y0, double y1, double h)
{
	double rmin = sersic_rho_min(g, x0, x1, y0, y1);

	if (rmin >= g->rho_t)
		return 0.0;
	if (sersic_near_centre(x0, x1, y0, y1, h))
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-4, 1e-12);
	/* More points than QUICK_NMAX even at the cell's nearest point: a
	 * needle or a galaxy far below a pixel, which points would miss. */
	if (!(ceil(h / (QUICK_STEP * sersic_cell_scale(g, rmin, x0, x1, y0, y1))) <= QUICK_NMAX))
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-3, 1e-12);
	/* The points per side from the length scale at a lower bound on rho,
	 * the cell's distance over r_e, which rounds the count up: what the
	 * errors in BENCHMARKS.md were measured with. */
	double dx = x0 > 0 ? x0 : x1 < 0 ? -x1 : 0, dy = y0 > 0 ? y0 : y1 < 0 ? -y1 : 0;
	double n = ceil(h / (QUICK_STEP * sersic_cell_scale(g, sqrt(dx * dx + dy * dy) / g->re,
							      x0, x1, y0, y1)));
	return sersic_midpoint(g, x0, x1, y0, y1, n < 1 ? 1 : n > QUICK_NMAX ? QUICK_NMAX : (int)n);
}

static int quick_init(const struct wfs_host *host, void **state)
{
	struct quick *p = calloc(1, sizeof(*p));

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	if (sersic_setting_num(host, "sersic-trunc", 1e-12, 0.5, QUICK_TRUNC, &p->trunc) ||
	    sersic_setting_num(host, "psf-core", 0, 1e3, SERSIC_PSF_CORE, &p->psf_core) ||
	    sersic_setting_core(host, &p->core_k) ||
	    sersic_setting_convolve(host, &p->convolve)) {
		free(p);
		return -1;
	}
	*state = p;
	return 0;
}

static void quick_fini(void *state)
{
	free(state);
}

static int quick_prepare(void *state, struct wfs_source *src)
{
	struct quick *p = state;

	return sersic_prepare_common(p->host, src, p->trunc);
}

static int quick_footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	struct quick *p = state;

	return sersic_footprint_common(p->host, src, box, p->convolve);
}

static int quick_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct quick *p = state;
	struct sersic_method m = { quick_cell, NULL, p->convolve, p->psf_core, p->core_k };

	return sersic_render_common(p->host, thread, src, win, &m);
}

static int quick_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct quick *p = state;

	return sersic_reach_common(p->host, src, p->trunc, p->convolve, pixels);
}

static const struct wfs_setting quick_settings[] = {
	{ "sersic-trunc", SERSIC_STR(QUICK_TRUNC), "number from 1e-12 to 0.5",
	  "fraction of the light allowed beyond the truncation radius" },
	SERSIC_SETTINGS,
};

static const struct wfs_model quick_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "sersic-quick",
	.summary = "Sérsic galaxy, sampled with a sub-sampled core, convolved with the ePSF",
	.columns = sersic_columns,
	.ncolumns = SERSIC_NCOL,
	.init = quick_init,
	.fini = quick_fini,
	.prepare = quick_prepare,
	.footprint = quick_footprint,
	.render = quick_render,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = quick_settings,
	.nsettings = (int)(sizeof(quick_settings) / sizeof(quick_settings[0])),
	.reach = quick_reach,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &quick_model : NULL;
}
