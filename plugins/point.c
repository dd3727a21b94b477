/*
 * point.c - point sources drawn with the effective PSF (ePSF).
 *
 * The host lends the ePSF near the source: four grid nodes, each an n x n
 * array sampled `over` (4) times per pixel, and their bilinear weights in
 * position.  A sample's value is the fraction of the flux that lands in a
 * detector pixel centred at that offset, so drawing a source is sampling the
 * ePSF at the pixel centres around it (the paper's section 2.2):
 *
 *   pixel(i, j) += flux * ePSF(c + over (i - x), c + over (j - y)).
 *
 * Because over * i is an integer, every pixel of a source sits at the same
 * sub-sample phase: the interpolation weights are computed once per source
 * and each pixel reads a fixed set of taps (the hoisting that makes the hot
 * loop cheap).  Within `core` pixels of the centre the ePSF is interpolated
 * with Keys' cubic convolution kernel (a = -1/2, 4 x 4 taps): it reproduces
 * quadratics, so the sharp core is not flattened as bilinear interpolation
 * does (the STIPS paper's Figures 3-4: about 3% error in the core).  Further
 * out the ePSF is smooth on the sample scale and bilinear interpolation
 * (2 x 2 taps) is accurate to well under 1%.  Both kernels' weights sum to 1
 * at every phase, so the total placed does not depend on the phase beyond
 * the ePSF's own sampling.  STIPS blends four local quadratics in the core;
 * this is a standard interpolating cubic instead.
 *
 * The box is the set of pixels within half = centre / over pixels of the
 * source in x and in y (44 x 44 for the 177-sample ePSF), symmetric about
 * the source; the ePSF array covers exactly that range.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"

struct point {
	const struct wfs_host *host;
	double core;            /* radius of the bicubic core, pixels */
};

static int point_init(const struct wfs_host *host, void **state)
{
	struct point *p = calloc(1, sizeof(*p));
	const char *s;

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	p->core = 4.0;
	if ((s = host->setting(host->ctx, "psf-core")) && *s) {
		char *end;

		p->core = strtod(s, &end);
		if (*end || !(p->core >= 0)) {
			free(p);
			return host->error(host->ctx, "psf-core: bad radius '%s'", s);
		}
	}
	*state = p;
	return 0;
}

static void point_fini(void *state)
{
	free(state);
}

static int point_footprint(void *state, const struct wfs_source *src,
			   struct wfs_box *box)
{
	struct point *p = state;
	struct wfs_epsf e;
	double half;

	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	half = (double)e.centre / e.over;
	/* pixels i with x - half < i < x + half */
	box->x0 = (int)floor(src->x - half) + 1;
	box->x1 = (int)ceil(src->x + half);
	box->y0 = (int)floor(src->y - half) + 1;
	box->y1 = (int)ceil(src->y + half);
	return 0;
}

/* Keys' cubic convolution weights for taps -1, 0, 1, 2 at phase t in [0, 1). */
static void keys_weights(double t, double w[4])
{
	double t2 = t * t, t3 = t2 * t;

	w[0] = -0.5 * t3 + t2 - 0.5 * t;
	w[1] = 1.5 * t3 - 2.5 * t2 + 1.0;
	w[2] = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
	w[3] = 0.5 * t3 - 0.5 * t2;
}

static int point_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct point *p = state;
	struct wfs_epsf e;
	const float *node[4];
	double wn[4], bx[2], by[2], cx[4], cy[4];
	int nn = 0, n, o, basex, basey;
	double tx, ty, fx, fy, core2;

	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	for (int k = 0; k < 4; k++)
		if (e.weight[k] != 0) {
			node[nn] = e.node[k];
			wn[nn++] = e.weight[k] * src->flux;
		}
	n = e.n;
	o = e.over;
	/* sample index of pixel i: centre + o i + base, plus the phase f */
	tx = -o * src->x;
	ty = -o * src->y;
	basex = (int)floor(tx);
	basey = (int)floor(ty);
	fx = tx - basex;
	fy = ty - basey;
	bx[0] = 1 - fx; bx[1] = fx;
	by[0] = 1 - fy; by[1] = fy;
	keys_weights(fx, cx);
	keys_weights(fy, cy);
	/* the cubic's taps must stay inside the array */
	core2 = p->core * o + 2 < e.centre ? p->core * p->core : 0;

	for (int j = win->y0; j < win->y0 + win->ny; j++) {
		double *row = win->pix + (ptrdiff_t)(j - win->y0) * win->stride - win->x0;
		long iy = e.centre + (long)o * j + basey;
		double dy = j - src->y;

		for (int i = win->x0; i < win->x0 + win->nx; i++) {
			long ix = e.centre + (long)o * i + basex;
			double dx = i - src->x, v = 0;

			if (ix < 0 || iy < 0 || ix > n - 2 || iy > n - 2)
				continue;       /* only outside the footprint */
			if (dx * dx + dy * dy <= core2) {
				for (int k = 0; k < nn; k++) {
					const float *a = node[k] + (iy - 1) * n + (ix - 1);
					double s = 0;

					for (int b = 0; b < 4; b++, a += n)
						s += cy[b] * (cx[0] * a[0] + cx[1] * a[1] +
							      cx[2] * a[2] + cx[3] * a[3]);
					v += wn[k] * s;
				}
			} else {
				for (int k = 0; k < nn; k++) {
					const float *a = node[k] + iy * n + ix;

					v += wn[k] * (by[0] * (bx[0] * a[0] + bx[1] * a[1]) +
						      by[1] * (bx[0] * a[n] + bx[1] * a[n + 1]));
				}
			}
			row[i] += v;
		}
	}
	return 0;
}

static const struct wfs_model point_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "point",
	.summary = "point source drawn with the Roman effective PSF",
	.columns = NULL,
	.ncolumns = 0,
	.init = point_init,
	.fini = point_fini,
	.footprint = point_footprint,
	.render = point_render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &point_model : NULL;
}
