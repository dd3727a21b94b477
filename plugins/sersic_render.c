/*
 * sersic_render.c - rendering a Sérsic galaxy through the ePSF, linked
 * into both Sérsic plugins: the wings integrated per pixel and convolved
 * by FFT with second-order corrections, the core drawn on sub-pixel cells
 * at the galaxy's own phase.  The profile and its integrals are sersic.h's
 * and sersic_core.c's; a plugin's own cell integral comes in through
 * struct sersic_method.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "sersic.h"
#include "../src/simd.h"

/* The ePSF samples at the galaxy: blend of four nodes at sample (ix, iy),
 * zero outside the array. */
static inline double epsf_at(const struct wfs_epsf *e, int ix, int iy)
{
	if (ix < 0 || iy < 0 || ix >= e->n || iy >= e->n)
		return 0.0;
	size_t k = (size_t)iy * e->n + ix;
	return e->weight[0] * e->node[0][k] + e->weight[1] * e->node[1][k]
	       + e->weight[2] * e->node[2][k] + e->weight[3] * e->node[3][k];
}

/* Keys' cubic convolution weights (a = -1/2) for taps -1, 0, 1, 2 at
 * phase t in [0, 1): the interpolating cubic that reproduces quadratics. */
static void sersic_keys(double t, double w[4])
{
	double t2 = t * t, t3 = t2 * t;

	w[0] = -0.5 * t3 + t2 - 0.5 * t;
	w[1] = 1.5 * t3 - 2.5 * t2 + 1.0;
	w[2] = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
	w[3] = 0.5 * t3 - 0.5 * t2;
}

/*
 * The ePSF at a fixed fractional sample offset (phx, phy) in [0, 1), as the
 * point model evaluates it between samples: within `core` pixels of the
 * centre in x and in y (setting psf-core, default 4) Keys' cubic on 4 x 4
 * samples, so the sharp core is not flattened; farther out bilinear, where
 * the ePSF is smooth on the sample scale (the point model's psf-wing=44,
 * without its nearest samples beyond 8 pixels).  ep[k] = E(k + ph).  A galaxy much smaller
 * than a cell is therefore drawn exactly as a point source of its flux.
 * The four nodes are blended once into eb first (n x n scratch), both only
 * over the samples [lo_x, hi_x] x [lo_y, hi_y] (and the blend's taps
 * around them): the rest of ep is left as it was.
 */
/* eb[k] for k in [k0, k1): the four nodes blended (sersic_phase_epsf). */
SIMD_CLONES("avx512f", "avx2", "default")
static void sersic_blend_run(const struct wfs_epsf *e, double *restrict eb, size_t k0, size_t k1)
{
	const float *n0 = e->node[0], *n1 = e->node[1], *n2 = e->node[2], *n3 = e->node[3];
	double w0 = e->weight[0], w1 = e->weight[1], w2 = e->weight[2], w3 = e->weight[3];

	for (size_t k = k0; k < k1; k++)
		eb[k] = w0 * n0[k] + w1 * n1[k] + w2 * n2[k] + w3 * n3[k];
}

/* ep[k] for k in [k0, k1) of one row, bilinear between the samples
 * (sersic_phase_epsf), all four taps inside the array. */
SIMD_CLONES("avx512f", "avx2", "default")
static void sersic_bilinear_run(const double *restrict eb, double *restrict ep, size_t k0, size_t k1,
				int n, double b00, double b01, double b10, double b11)
{
	for (size_t k = k0; k < k1; k++)
		ep[k] = b00 * eb[k] + b01 * eb[k + 1] + b10 * eb[k + n] + b11 * eb[k + n + 1];
}

static void sersic_phase_epsf(const struct wfs_epsf *e, double phx, double phy, double core,
			      double *eb, double *ep, int lo_x, int hi_x, int lo_y, int hi_y)
{
	int n = e->n;
	double wx[4], wy[4];

	/* only the samples [lo, hi] on each axis are asked for; the blend
	 * reaches 1 before and 2 after them */
	lo_x = lo_x < 0 ? 0 : lo_x;
	lo_y = lo_y < 0 ? 0 : lo_y;
	hi_x = hi_x >= n ? n - 1 : hi_x;
	hi_y = hi_y >= n ? n - 1 : hi_y;
	if (lo_x > hi_x || lo_y > hi_y)
		return;
	int bx0 = lo_x > 0 ? lo_x - 1 : 0, bx1 = hi_x + 2 < n ? hi_x + 2 : n - 1;
	int by0 = lo_y > 0 ? lo_y - 1 : 0, by1 = hi_y + 2 < n ? hi_y + 2 : n - 1;
	for (int ky = by0; ky <= by1; ky++)
		sersic_blend_run(e, eb, (size_t)ky * n + bx0, (size_t)ky * n + bx1 + 1);
	sersic_keys(phx, wx);
	sersic_keys(phy, wy);
	double b00 = (1 - phx) * (1 - phy), b01 = phx * (1 - phy), b10 = (1 - phx) * phy, b11 = phx * phy;
	/* the samples bilinear with all four taps inside: kx + 1 < n */
	int bl1 = hi_x < n - 2 ? hi_x : n - 2;
	for (int ky = lo_y; ky <= hi_y; ky++) {
		double dy = (ky + phy - e->centre) / e->over;
		int keys_row = fabs(dy) < core && ky >= 1 && ky + 2 < n;

		int inner = ky + 1 < n && lo_x <= bl1;

		if (inner)
			sersic_bilinear_run(eb, ep, (size_t)ky * n + lo_x, (size_t)ky * n + bl1 + 1, n,
					    b00, b01, b10, b11);
		/* Keys' cubic within core of the centre: a window of samples
		 * about it, each tested as before */
		int ka = (int)floor(e->centre - phx - core * e->over) - 1;
		int kb = (int)ceil(e->centre - phx + core * e->over) + 1;
		ka = ka > lo_x ? ka : lo_x;
		kb = kb < hi_x ? kb : hi_x;
		for (int kx = ka; keys_row && kx <= kb; kx++) {
			double dx = (kx + phx - e->centre) / e->over, v = 0;
			const double *r = eb + (size_t)ky * n + kx - n - 1;

			if (!(fabs(dx) < core && kx >= 1 && kx + 2 < n))
				continue;
			for (int bb = 0; bb < 4; bb++, r += n)
				v += wy[bb] * (wx[0] * r[0] + wx[1] * r[1] + wx[2] * r[2] + wx[3] * r[3]);
			ep[(size_t)ky * n + kx] = v;
		}
		/* the samples at the array's last column or row */
		for (int kx = inner ? bl1 + 1 : lo_x; kx <= hi_x; kx++) {
			const double *r0 = eb + (size_t)ky * n + kx;
			int xin = kx + 1 < n, yin = ky + 1 < n;

			ep[(size_t)ky * n + kx] = b00 * r0[0] + (xin ? b01 * r0[1] : 0) +
						  (yin ? b10 * r0[n] : 0) + (xin && yin ? b11 * r0[n + 1] : 0);
		}
	}
}

/* The ePSF half-width in whole pixels. */
int sersic_psf_half(const struct wfs_epsf *e)
{
	return e->centre / e->over;
}

/* The half-width drawn for src: prepare()'s cut (AUX_PSFH), or all of it. */
int sersic_psf_drawn(const struct wfs_epsf *e, const struct wfs_source *src)
{
	int hp = sersic_psf_half(e);
	double h = src->aux[AUX_PSFH];

	return h >= 1 && h < hp ? (int)h : hp;
}

static void box_clip(int *a0, int *a1, int b0, int b1)
{
	if (*a0 < b0)
		*a0 = b0;
	if (*a1 > b1)
		*a1 = b1;
}

/*
 * One convolved render's state, shared by its steps (sersic_render_common):
 * the ePSF, the stamp the wings are drawn and convolved on, the core block
 * Q with its cells on the galaxy's phase grid, and the scratch planes.  The
 * steps copy the scalars their loops read into locals, as the single
 * function did: a store into a plane could otherwise alias them and force
 * a reload each time.
 */
struct sersic_stamp {
	struct sersic_gal g;
	struct wfs_epsf e;
	int over, hp, kn;               /* ePSF samples per pixel, half-width drawn, kernel side */
	double psf_all;                 /* a cut ePSF's whole light (AUX_PSFALL), 0: not cut */
	int sx0, sx1, sy0, sy1;         /* the stamp's pixels */
	int snx, sny;
	int kq;                         /* K: Q is the pixels within K of (icx, icy) */
	double icx, icy;
	double qx0, qx1, qy0, qy1;      /* Q's edges, pixels */
	int a0, b0, na, nb;             /* Q's cells: the first index and the count, per axis */
	int core_on;                    /* whether the core's light reaches the window */
	size_t nker;
	double *img, *gxi, *gyi, *lpi;  /* stamp planes: integrals, gradient terms, Laplacian term */
	double *ker, *kdx, *kdy, *klp;  /* the kernels of those planes, kn x kn */
	double *cells, *ep, *eb;        /* core cells; the ePSF at the phase, and blended */
	double *cpix;                   /* the core's pixels (sersic_core_add) */
	double *poly;                   /* the ePSF rows at the phase split by sample phase */
};

/* Without the PSF: each window pixel the truncation box (gx0..gx1,
 * gy0..gy1) touches gets its integral, nothing else. */
static void sersic_render_pixels(const struct sersic_gal *g, const struct wfs_window *win,
				 const struct sersic_method *m, double gx0, double gx1,
				 double gy0, double gy1)
{
	int x0 = win->x0, x1 = win->x0 + win->nx - 1, y0 = win->y0, y1 = win->y0 + win->ny - 1;

	if (gx0 > x0) x0 = (int)gx0;
	if (gx1 < x1) x1 = (int)gx1;
	if (gy0 > y0) y0 = (int)gy0;
	if (gy1 < y1) y1 = (int)gy1;
	for (int y = y0; y <= y1; y++) {
		double *row = win->pix + (ptrdiff_t)(y - win->y0) * win->stride - win->x0;
		for (int x = x0; x <= x1; x++)
			row[x] += m->cell(g, m->opt, x - 0.5 - g->xc, x + 0.5 - g->xc,
					  y - 0.5 - g->yc, y + 0.5 - g->yc, 1.0);
	}
}

/* Lay out the stamp and the core around the galaxy's pixels (gx0..gx1,
 * gy0..gy1), st->g and st->e filled in.  Returns 0 when the stamp is empty:
 * nothing of the galaxy reaches the window. */
static int sersic_stamp_layout(struct sersic_stamp *st, const struct wfs_window *win,
			       const struct sersic_method *m, double gx0, double gx1,
			       double gy0, double gy1)
{
	const struct sersic_gal *g = &st->g;
	int over = st->e.over, hp = st->hp;

	st->over = over;
	st->hp = hp;
	st->kn = 2 * hp + 1;
	/* Stamp: the window grown by the PSF, cut to the galaxy grown by the
	 * PSF.  It holds every pixel whose light reaches the window and every
	 * window pixel the galaxy's light reaches, including those beyond the
	 * truncation box that only the PSF wings light (they are zero in the
	 * stamp before the convolution). */
	int sx0 = win->x0 - hp, sx1 = win->x0 + win->nx - 1 + hp;
	int sy0 = win->y0 - hp, sy1 = win->y0 + win->ny - 1 + hp;
	if (gx0 - hp > sx0) sx0 = (int)gx0 - hp;
	if (gx1 + hp < sx1) sx1 = (int)gx1 + hp;
	if (gy0 - hp > sy0) sy0 = (int)gy0 - hp;
	if (gy1 + hp < sy1) sy1 = (int)gy1 + hp;
	if (sx0 > sx1 || sy0 > sy1)
		return 0;
	st->sx0 = sx0;
	st->sx1 = sx1;
	st->sy0 = sy0;
	st->sy1 = sy1;
	st->snx = sx1 - sx0 + 1;
	st->sny = sy1 - sy0 + 1;

	/* Core block Q, in pixels, and its cells on the galaxy's phase grid. */
	int kq = m->core_k;
	double icx = floor(g->xc + 0.5), icy = floor(g->yc + 0.5);
	double qx0 = icx - kq - 0.5, qx1 = icx + kq + 0.5;
	double qy0 = icy - kq - 0.5, qy1 = icy + kq + 0.5;
	/* cells that reach into Q, and one more all round (sersic_core_cells) */
	int a0 = (int)ceil((qx0 - g->xc) * over - 0.5) - 1, a1 = (int)floor((qx1 - g->xc) * over + 0.5) + 1;
	int b0 = (int)ceil((qy0 - g->yc) * over - 0.5) - 1, b1 = (int)floor((qy1 - g->yc) * over + 0.5) + 1;
	st->kq = kq;
	st->icx = icx;
	st->icy = icy;
	st->qx0 = qx0;
	st->qx1 = qx1;
	st->qy0 = qy0;
	st->qy1 = qy1;
	st->a0 = a0;
	st->b0 = b0;
	st->na = a1 - a0 + 1;
	st->nb = b1 - b0 + 1;
	/* Does the core reach the window at all? */
	st->core_on = qx1 + hp + 1 >= win->x0 && qx0 - hp - 1 <= win->x0 + win->nx - 1 &&
		      qy1 + hp + 1 >= win->y0 && qy0 - hp - 1 <= win->y0 + win->ny - 1;
	return 1;
}

/* The scratch planes, from the thread's scratch (render never allocates):
 * four stamp planes and four kernels, and the core's cells and two ePSF
 * arrays only when the core reaches the window. */
static int sersic_stamp_scratch(const struct wfs_host *host, void *thread, struct sersic_stamp *st)
{
	size_t nstamp = (size_t)st->snx * st->sny, nker = (size_t)st->kn * st->kn;
	size_t ncell = st->core_on ? (size_t)st->na * st->nb : 0;
	size_t nep = st->core_on ? 2 * (size_t)st->e.n * st->e.n : 0;
	size_t side = 2 * ((size_t)st->kq + st->hp) + 3;
	size_t ncpix = st->core_on ? side * side : 0;
	size_t npoly = st->core_on ? (size_t)st->e.n * st->e.over * (side + st->na / st->e.over + 2) : 0;
	double *buf = host->scratch(thread, (4 * nstamp + 4 * nker + ncell + nep + ncpix + npoly) *
				    sizeof(double));

	if (!buf)
		return host->error(host->ctx, "out of memory for a %d x %d galaxy stamp", st->snx, st->sny);
	st->nker = nker;
	st->img = buf;
	st->gxi = st->img + nstamp;
	st->gyi = st->gxi + nstamp;
	st->lpi = st->gyi + nstamp;
	st->ker = st->lpi + nstamp;
	st->kdx = st->ker + nker;
	st->kdy = st->kdx + nker;
	st->klp = st->kdy + nker;
	st->cells = st->klp + nker;
	st->ep = st->cells + ncell;
	st->eb = st->ep + nep / 2;
	st->cpix = st->eb + nep / 2;
	st->poly = st->cpix + ncpix;
	return 0;
}

/* One wing pixel (x, y), outside Q, into the stamp planes at offset o:
 * its integral, and the gradient at its centre where the light is smooth
 * over it. */
static inline void sersic_wing_pixel(const struct sersic_stamp *st, const struct sersic_method *m,
				     int x, int y, size_t o, int *any, int *rough)
{
	const struct sersic_gal *g = &st->g;
	double v = 0, gx = 0, gy = 0;
	double x0 = x - 0.5 - g->xc, x1 = x + 0.5 - g->xc;
	double y0 = y - 0.5 - g->yc, y1 = y + 0.5 - g->yc;
	int smooth = 0;

	/* The corrections are a Taylor expansion over the pixel: only where
	 * the light is smooth on it (a needle, q -> 0, is not, and would go
	 * negative). */
	v = m->cell(g, m->opt, x0, x1, y0, y1, 1.0);
	if (v != 0 && sersic_cell_scale(g, sersic_rho_min(g, x0, x1, y0, y1),
					x0, x1, y0, y1) >= SERSIC_SMOOTH) {
		sersic_grad(g, x - g->xc, y - g->yc, &gx, &gy);
		smooth = 1;
	}
	sersic_wing_put(st->img, st->gxi, st->gyi, st->lpi, o, v, gx, gy, smooth, any, rough);
}

/* Wings: pixel integrals outside Q, and the profile's gradient at the
 * pixel centres (for the first-moment term), into the stamp planes.
 * With m->block_fn, the stamp is walked in blocks of m->block pixels a
 * side: a dark block is zeros at once, a faint smooth one gets its
 * integral spread linearly over its pixels (a pixel at offset d from the
 * block's centre v / B^2 + grad . d, which keeps the block's sum, and the
 * block's gradient), any other is taken pixel by pixel.  *any: some wing
 * pixel has light; *rough: some has light too rough for the second-order
 * terms, which then need a plane of their own. */
static void sersic_wings_integrate(const struct sersic_stamp *st, const struct sersic_method *m,
				   int *any_out, int *rough_out)
{
	const struct sersic_gal *g = &st->g;
	int sx0 = st->sx0, sx1 = st->sx1, sy0 = st->sy0, sy1 = st->sy1, snx = st->snx, kq = st->kq;
	int qx0 = (int)st->icx - kq, qx1 = (int)st->icx + kq, qy0 = (int)st->icy - kq, qy1 = (int)st->icy + kq;
	int B = m->block_fn && m->block > 1 ? m->block : 1;
	int any = 0, rough = 0;
	/* Blocks lie on the detector's grid of B pixels, not the stamp's, so
	 * a pixel is drawn the same way whichever window (tile) the stamp was
	 * grown from; one the stamp cuts fills only its pixels inside. */
	int ax0 = sx0 - ((sx0 % B) + B) % B, ay0 = sy0 - ((sy0 % B) + B) % B;

	for (int by = ay0; by <= sy1; by += B)
		for (int bx = ax0; bx <= sx1; bx += B) {
			int ex = bx + B - 1, ey = by + B - 1;
			int in_q = !(ex < qx0 || bx > qx1 || ey < qy0 || by > qy1);
			int how = 0;
			double v = 0, gx = 0, gy = 0;

			/* blocks outside Q only */
			if (B > 1 && !in_q)
				how = m->block_fn(g, m->opt, bx - 0.5 - g->xc, ex + 0.5 - g->xc,
						  by - 0.5 - g->yc, ey + 0.5 - g->yc, &v, &gx, &gy);
			for (int y = by > sy0 ? by : sy0; y <= ey && y <= sy1; y++) {
				size_t o = (size_t)(y - sy0) * snx - sx0;
				int in_qy = y >= qy0 && y <= qy1;

				for (int x = bx > sx0 ? bx : sx0; x <= ex && x <= sx1; x++) {
					if ((in_qy && x >= qx0 && x <= qx1) || how < 0) {
						/* the core's own, or dark */
						st->img[o + x] = st->gxi[o + x] = st->gyi[o + x] = st->lpi[o + x] = 0;
					} else if (how > 0) {
						double p = v / ((double)B * B) + gx * (x - 0.5 * (bx + ex)) +
							   gy * (y - 0.5 * (by + ey));

						st->img[o + x] = st->lpi[o + x] = p;
						st->gxi[o + x] = gx;
						st->gyi[o + x] = gy;
						any |= p != 0;
					} else if (m->wing_row) {
						st->img[o + x] = NAN;   /* for the rows below */
					} else {
						sersic_wing_pixel(st, m, x, y, o + x, &any, &rough);
					}
				}
			}
		}
	/* With wing_row, the pixels left marked, a row's runs at a time. */
	for (int y = sy0; m->wing_row && y <= sy1; y++) {
		size_t o = (size_t)(y - sy0) * snx;

		for (int x = sx0; x <= sx1; x++) {
			size_t k = o + (size_t)(x - sx0);
			int xb = x;

			if (!isnan(st->img[k]))
				continue;
			while (xb < sx1 && isnan(st->img[k + (size_t)(xb + 1 - x)]))
				xb++;
			m->wing_row(g, m->opt, y, x, xb, st->img + k, st->gxi + k, st->gyi + k,
				    st->lpi + k, &any, &rough);
			x = xb;
		}
	}
	*any_out = any;
	*rough_out = rough;
}

/*
 * A bound on the gradient of the light at the centre of any pixel outside
 * the core square Q (K pixels about the centre pixel), so at a distance d
 * >= K + 1/2 from the centre: with rho >= d sqrt(min(ia2, ib2)) there and
 * |grad rho| <= sqrt(max(ia2, ib2)), |grad I| <= h(rho) sqrt(max(ia2, ib2)),
 * h(rho) = I0 e^(-b rho^(1/n)) (b/n) rho^(1/n - 1), which for n >= 1 only
 * falls, and for n < 1 rises up to rho^(1/n) = (1 - n) / b and then falls.
 * Zero beyond the truncation.  The same for every window of the galaxy.
 */
static double sersic_grad_bound(const struct sersic_gal *g, int kq)
{
	double rho = (kq + 0.5) * sqrt(fmin(g->ia2, g->ib2));

	if (g->n < 1) {
		double peak = exp(g->n * log((1 - g->n) / g->b));

		rho = fmax(rho, peak);
	}
	if (!(rho < g->rho_t))
		return 0;
	double p = g->b * exp(g->inv_n * log(rho));     /* b rho^(1/n) */

	return exp(g->lni0 - p) * p * g->inv_n / rho * sqrt(fmax(g->ia2, g->ib2));
}

/* The stamp planes through their kernels, summed into the integrals
 * plane img: the gradient planes when moments, the Laplacian plane when
 * rough.  With the host's convolve_sum in one call (the planes' transforms
 * summed and transformed back once), else one convolve() each. */
static int sersic_convolve_planes(const struct wfs_host *host, void *thread,
				  const struct sersic_stamp *st, int moments, int rough)
{
	double *planes[4] = { st->img };
	const double *kers[4] = { st->ker };
	int n = 1, snx = st->snx, sny = st->sny, kn = st->kn;

	if (moments) {
		planes[n] = st->gxi;
		kers[n++] = st->kdx;
		planes[n] = st->gyi;
		kers[n++] = st->kdy;
	}
	if (rough) {
		planes[n] = st->lpi;
		kers[n++] = st->klp;
	}
	if (WFS_HAS(host->size, struct wfs_host, convolve_sum) && host->convolve_sum)
		return host->convolve_sum(host->ctx, thread, planes, kers, n, snx, sny, kn);
	for (int i = 0; i < n; i++)
		if (host->convolve(host->ctx, thread, planes[i], snx, sny, kers[i], kn))
			return -1;
	for (int i = 1; i < n; i++)
		for (size_t k = 0; k < (size_t)snx * sny; k++)
			st->img[k] += planes[i][k];
	return 0;
}

/* The wings through the ePSF: the pixel-offset kernels, the FFT
 * convolutions of the stamp planes, and the window's part of the sum
 * added to it. */
static int sersic_wings_convolve(const struct wfs_host *host, void *thread,
				 const struct sersic_stamp *st, const struct wfs_window *win, int rough,
				 double level)
{
	const struct wfs_epsf *e = &st->e;
	int over = st->over, hp = st->hp, kn = st->kn;
	int sx0 = st->sx0, sx1 = st->sx1, sy0 = st->sy0, sy1 = st->sy1, snx = st->snx, sny = st->sny;
	size_t nker = st->nker;
	double *img = st->img;
	double *ker = st->ker, *kdx = st->kdx, *kdy = st->kdy, *klp = st->klp;

	/* The pixel-offset ePSF kernels: E + lap E / 24 and the gradient
	 * of E over 12, by central differences on the 4x samples. */
	double s2 = over * over / 24.0, s1 = over / 24.0;      /* (over/2) / 12 */
	double in = 0, dmax = 0, kmax = 0;      /* for the first-moment terms' bound */
	for (int ky = 0; ky < kn; ky++)
		for (int kx = 0; kx < kn; kx++) {
			int sx = e->centre + over * (kx - hp), sy = e->centre + over * (ky - hp);
			double c = epsf_at(e, sx, sy);
			double xp = epsf_at(e, sx + 1, sy), xm = epsf_at(e, sx - 1, sy);
			double yp = epsf_at(e, sx, sy + 1), ym = epsf_at(e, sx, sy - 1);
			size_t k = (size_t)ky * kn + kx;
			ker[k] = c;
			in += c;
			klp[k] = (xp + xm + yp + ym - 4 * c) * s2;
			kdx[k] = -(xp - xm) * s1;
			kdy[k] = -(yp - ym) * s1;
			dmax = fmax(dmax, fabs(xp + xm - 2 * c) + fabs(yp + ym - 2 * c));
			kmax = fmax(kmax, fabs(kdx[k]) + fabs(kdy[k]));
		}
	/* A cut ePSF (sersic-psf-cut) carries the light it leaves out in
	 * what it keeps: scaled to the whole ePSF's light, so the galaxy's
	 * flux stays whole; the light moved is below the cut's fraction of
	 * the noise. */
	if (st->psf_all > 0 && in > 0) {
		double f = st->psf_all / in;

		for (size_t k = 0; k < nker; k++) {
			ker[k] *= f;
			klp[k] *= f;
			kdx[k] *= f;
			kdy[k] *= f;
		}
	}
	/* Where every pixel is smooth the Laplacian term's image is the
	 * stamp itself: one convolution with E + lap E / 24 does both. */
	if (!rough)
		for (size_t k = 0; k < nker; k++)
			ker[k] += klp[k];
	/*
	 * The first-moment terms: the gradient planes (the profile's gradient
	 * at the pixels outside the core square Q) through the kernels
	 * -dE / 12.  By parts, a gradient through a kernel is the light
	 * through the kernel's derivative, less the light on the region's
	 * edge through the kernel, so they add to any pixel at most
	 *
	 *   F (max |d2E/dx2| + max |d2E/dy2|) / 12
	 *     + (Q's perimeter) I_Q (max |kdx| + max |kdy|),
	 *
	 * F the flux, I_Q the largest surface brightness on Q's edge (at
	 * distance kq or more from the centre, so at rho >= kq / r_e); the
	 * first taken twice over for the sampling.  This bounds the whole
	 * galaxy, whichever window the stamp serves, so the choice is the
	 * same in every window.  Below moment_level the terms are left out.
	 * Their total is the planes' sums times the kernels' sums, which a
	 * difference kernel makes nearly zero: the flux stays.
	 */
	int moments = 1;
	if (level > 0) {
		const struct sersic_gal *g = &st->g;
		/* kmax was taken before the scaling above; dmax gets it here */
		double f = st->psf_all > 0 && in > 0 ? st->psf_all / in : 1;

		kmax *= f;
		double iq = st->kq > 0 ? exp(g->lni0 - g->b * exp(log(st->kq / g->re) / g->n)) : exp(g->lni0);
		double bound = 2 * g->flux * f * dmax * over * over / 12 + 4 * (2 * st->kq + 1) * iq * kmax;
		/* and directly: no pixel gets more than the largest gradient
		 * outside Q times the kernels' absolute sums */
		double sk = 0;

		for (size_t k = 0; k < nker; k++)
			sk += fabs(kdx[k]) + fabs(kdy[k]);
		bound = fmin(bound, sersic_grad_bound(g, st->kq) * sk);
		moments = !(bound <= level);
	}
	if (sersic_convolve_planes(host, thread, st, moments, rough) < 0)
		return host->error(host->ctx, "FFT convolution of a %d x %d galaxy stamp failed",
				   snx, sny);
	for (int y = win->y0; y < win->y0 + win->ny; y++) {
		if (y < sy0 || y > sy1)
			continue;
		double *dst = win->pix + (ptrdiff_t)(y - win->y0) * win->stride;
		size_t o = (size_t)(y - sy0) * snx;
		int x0 = win->x0, x1 = win->x0 + win->nx - 1;
		box_clip(&x0, &x1, sx0, sx1);
		for (int x = x0; x <= x1; x++)
			dst[x - win->x0] += img[o + x - sx0];
	}
	return 0;
}

/* Core cells, clipped to Q.  A cell cut by Q's edge keeps only the
 * part inside, whose centroid is off the cell centre by up to half a
 * cell; its light is shared between the two nearest cell centres (per
 * axis, linearly) so its first moment stays where it is.  Left at the
 * cell centre it would move by up to 1/8 pixel, several per cent of the
 * pixels beside Q.  The ring of cells around the grid takes the shares
 * that spill out. */
/* The most cells sersic_core_cells keeps for their mirror images. */
#define SERSIC_MIRROR_CELLS 1024

static void sersic_core_cells(const struct sersic_stamp *st, const struct sersic_method *m)
{
	const struct sersic_gal *g = &st->g;
	int over = st->over, a0 = st->a0, b0 = st->b0, na = st->na, nb = st->nb;
	double qx0 = st->qx0, qx1 = st->qx1, qy0 = st->qy0, qy1 = st->qy1;
	double cell = 1.0 / over, *cells = st->cells;
	/* The profile is the same at -d as at d, and the cells lie on the
	 * galaxy's own grid (centres a / over from it): a whole cell (not cut
	 * by Q) holds the light of the one opposite it, which is taken from
	 * there when that was whole too.  raw[k]: a whole cell's integral,
	 * NaN for one not yet taken or cut. */
	double raw[SERSIC_MIRROR_CELLS];
	int mirror = (size_t)na * nb <= SERSIC_MIRROR_CELLS;

	memset(cells, 0, (size_t)na * nb * sizeof(double));
	for (int k = 0; mirror && k < na * nb; k++)
		raw[k] = NAN;
	for (int bj = 1; bj < nb - 1; bj++) {
		double cy = (b0 + bj) * cell;
		double y0 = fmax(cy - 0.5 * cell, qy0 - g->yc), y1 = fmin(cy + 0.5 * cell, qy1 - g->yc);
		if (!(y1 > y0))
			continue;
		double fy = (0.5 * (y0 + y1) - cy) * over;      /* in [-1/2, 1/2] */
		int sy = fy < 0 ? -1 : 1;
		int bm = -(b0 + bj) - b0, wy = y0 == cy - 0.5 * cell && y1 == cy + 0.5 * cell;
		fy = fabs(fy);
		for (int ai = 1; ai < na - 1; ai++) {
			double cx = (a0 + ai) * cell;
			double x0 = fmax(cx - 0.5 * cell, qx0 - g->xc), x1 = fmin(cx + 0.5 * cell, qx1 - g->xc);
			if (!(x1 > x0))
				continue;
			int am = -(a0 + ai) - a0;
			int whole = mirror && wy && x0 == cx - 0.5 * cell && x1 == cx + 0.5 * cell;
			double v;

			if (whole && am >= 0 && am < na && bm >= 0 && bm < nb &&
			    !isnan(raw[(size_t)bm * na + am]))
				v = raw[(size_t)bm * na + am];
			else
				v = m->cell(g, m->opt, x0, x1, y0, y1, cell);
			if (whole)
				raw[(size_t)bj * na + ai] = v;
			double fx = (0.5 * (x0 + x1) - cx) * over;
			int sx = fx < 0 ? -1 : 1;
			fx = fabs(fx);
			double *c0 = cells + (size_t)bj * na + ai, *c1 = c0 + (ptrdiff_t)sy * na;
			c0[0] += v * (1 - fx) * (1 - fy);
			c0[sx] += v * fx * (1 - fy);
			c1[0] += v * (1 - fx) * fy;
			c1[sx] += v * fx * fy;
		}
	}
}

/*
 * The core's pixels [rx0, rx0 + side) x [ry0, ry0 + side) into out (side
 * x side): pixel (x, y) is the sum over the cells (a0 + i, b0 + j) of
 * C[j][i] ep[ky][kx], kx = bx + over x - a0 - i, ky = by + over y - b0 - j
 * (ep: the ePSF at the galaxy's phase, sersic_phase_epsf; zero outside
 * its en x en samples).  With X = x - rx0 and kx = K0 - i + over X, write
 * K0 - i = over q + r (0 <= r < over): kx = over (X + q) + r, so each ePSF
 * row split by sample phase r (poly) makes the sum for a cell one run
 * along a row of pixels, in vector code.  Each cell's product is added to
 * each pixel in the same order in every clone: the same bytes.
 */
/* The cells whose runs sersic_core_block finds once (more: each time). */
#define SERSIC_CORE_OFFS 512

/* Sample s0 = over q + r (0 <= r < over): where its run starts in the
 * rows of poly of one ePSF row, L samples a phase. */
static inline long long sersic_core_off(long long s0, int over, int L, long long qmin)
{
	long long q = s0 >= 0 ? s0 / over : -((over - 1 - s0) / over);

	return (s0 - q * over) * L + (q - qmin);
}

SIMD_CLONES("avx512f", "avx2", "default")
static void sersic_core_block(const double *restrict cells, int na, int nb, const double *restrict ep,
			      int en, int over, long long K0, long long ky0, int side,
			      double *restrict poly, double *restrict out)
{
	long long qmin = (K0 - na + 1) >= 0 ? (K0 - na + 1) / over : -((over - 1 - (K0 - na + 1)) / over);
	long long qmax = K0 >= 0 ? K0 / over : -((over - 1 - K0) / over);
	int L = side + (int)(qmax - qmin);
	/* the ePSF rows the pixels read: ky0 - (nb - 1) to ky0 + over (side - 1) */
	long long klo = ky0 - nb + 1, khi = ky0 + (long long)over * (side - 1);

	klo = klo < 0 ? 0 : klo;
	khi = khi >= en ? en - 1 : khi;
	/* poly[((ky - klo) over + r) L + m] = ep[ky][over (qmin + m) + r], zero
	 * outside the row; only the samples the cells read (K0 - na + 1 to
	 * K0 + over (side - 1)), which sersic_phase_epsf computed */
	long long xlo = K0 - na + 1 > 0 ? K0 - na + 1 : 0;
	long long xhi = K0 + (long long)over * (side - 1) < en - 1 ? K0 + (long long)over * (side - 1) : en - 1;

	for (int r = 0; r < over; r++) {
		/* the m of phase r whose samples lie in [xlo, xhi] */
		long long m0 = xlo - r - over * qmin, m1 = xhi - r - over * qmin;
		int ma = (int)(m0 <= 0 ? 0 : (m0 + over - 1) / over);
		int mb = (int)(m1 < 0 ? -1 : m1 / over);

		mb = mb < L - 1 ? mb : L - 1;
		for (long long ky = klo; ky <= khi; ky++) {
			double *pr = poly + ((size_t)(ky - klo) * over + r) * L;
			long long k0 = ky * en + over * qmin + r;

			for (int m = 0; m < L; m++)
				pr[m] = m >= ma && m <= mb ? ep[k0 + (long long)over * m] : 0;
		}
	}
	/* where cell i's run starts in a row's block of poly: phase r and
	 * first sample q of K0 - i, once for every row and pixel */
	long long offs[SERSIC_CORE_OFFS];
	int pre = na <= SERSIC_CORE_OFFS;

	for (int i = 0; pre && i < na; i++)
		offs[i] = sersic_core_off(K0 - i, over, L, qmin);
	memset(out, 0, (size_t)side * side * sizeof(double));
	for (int y = 0; y < side; y++) {
		double *o = out + (size_t)y * side;

		for (int j = 0; j < nb; j++) {
			long long ky = ky0 + (long long)over * y - j;

			if (ky < klo || ky > khi)
				continue;
			const double *row = poly + (size_t)(ky - klo) * over * L;
			const double *cj = cells + (size_t)j * na;

			for (int i = 0; i < na; i++) {
				double c = cj[i];

				if (c == 0)
					continue;
				const double *pr = row + (pre ? offs[i] : sersic_core_off(K0 - i, over, L, qmin));

				for (int x = 0; x < side; x++)
					o[x] += c * pr[x];
			}
		}
	}
}

/* The core cells through the ePSF at the galaxy's own phase, summed
 * directly into the window pixels the core reaches. */
static void sersic_core_add(const struct sersic_stamp *st, const struct wfs_window *win,
			    const struct sersic_method *m)
{
	const struct wfs_epsf *e = &st->e;
	int over = st->over, hp = st->hp, kq = st->kq;
	int a0 = st->a0, b0 = st->b0, na = st->na, nb = st->nb;
	double xc = st->g.xc, yc = st->g.yc, icx = st->icx, icy = st->icy;
	double *cells = st->cells, *ep = st->ep, *eb = st->eb;

	/* The ePSF at the galaxy's phase: sample position of pixel i, cell a is
	 * centre + over (i - xc) - a = base + over i - a + phi, so ep[k] holds
	 * E at k + phi. */
	double tx = e->centre - over * xc, ty = e->centre - over * yc;
	double bxf = floor(tx), byf = floor(ty);
	double phx = tx - bxf, phy = ty - byf;
	double core = m->psf_core * over + 2 < e->centre ? m->psf_core : 0;
	long long bx = (long long)bxf, by = (long long)byf;
	/* The pixels the core reaches: K + hp + 1 about its centre pixel.  A
	 * cut ePSF (sersic-psf-cut) is drawn within its half-width hp of
	 * every pixel of the core (so from hp to hp + 2K of each cell), and
	 * the core's pixels are then scaled so that its light is what the
	 * whole ePSF would put down: its cells' sum times the ePSF's light
	 * (AUX_PSFALL). */
	int cut = st->psf_all > 0, r = kq + hp + !cut;
	int rx0 = (int)icx - r, ry0 = (int)icy - r, side = 2 * r + 1;
	int ox0 = rx0, ox1 = rx0 + side - 1, oy0 = ry0, oy1 = ry0 + side - 1;
	double norm = 1;

	/* the samples the pixels [rx0, rx0 + side) x [ry0, ry0 + side) read:
	 * pixel x, cell a0 + i reads k = bx + over x - a0 - i */
	sersic_phase_epsf(e, phx, phy, core, eb, ep, (int)(bx + (long long)over * rx0 - a0 - na + 1),
			  (int)(bx + (long long)over * ox1 - a0), (int)(by + (long long)over * ry0 - b0 - nb + 1),
			  (int)(by + (long long)over * oy1 - b0));
	box_clip(&ox0, &ox1, win->x0, win->x0 + win->nx - 1);
	box_clip(&oy0, &oy1, win->y0, win->y0 + win->ny - 1);
	sersic_core_block(cells, na, nb, ep, e->n, over, bx + (long long)over * rx0 - a0,
			  by + (long long)over * ry0 - b0, side, st->poly, st->cpix);
	if (cut) {
		/* the cut core's light made whole */
		double whole = 0, drawn = 0;

		for (size_t k = 0; k < (size_t)na * nb; k++)
			whole += cells[k];
		whole *= st->psf_all;
		for (size_t k = 0; k < (size_t)side * side; k++)
			drawn += st->cpix[k];
		if (drawn > 0 && whole > 0)
			norm = whole / drawn;
	}
	for (int y = oy0; y <= oy1; y++) {
		double *dst = win->pix + (ptrdiff_t)(y - win->y0) * win->stride - win->x0;
		const double *c = st->cpix + (size_t)(y - ry0) * side - rx0;

		for (int x = ox0; x <= ox1; x++)
			dst[x] += norm * c[x];
	}
}

/*
 * Add the galaxy to window win.
 *
 * Without the PSF each pixel gets its integral.  With it, the value of
 * pixel i is int I(u) E(i - u) du, E the ePSF (the PSF already convolved
 * with the pixel).  Two grids share that integral:
 *
 *  - the core, a (2K+1)^2-pixel block Q around the centre, is cut into
 *    cells of 1/over pixel centred on the galaxy's own sub-pixel phase
 *    (centres xc + a/over), clipped to Q.  Each cell's integral C_a goes
 *    through the ePSF at the one fractional sample offset the phase needs:
 *    P(i) += sum_a C_a E(over (i - xc) - a + centre), the ePSF interpolated
 *    as the point model does.  A galaxy much smaller than a cell falls in
 *    the cell a = 0 and is drawn exactly as a point source of its flux.
 *
 *  - everything else is integrated per pixel, A_m, and convolved with the
 *    ePSF at whole-pixel offsets (no interpolation), sharpened as
 *    K = E + (1/24) lap E.  Why: sum_m A_m E(i - m) puts each pixel's light
 *    at its centre, which for light spread evenly over the pixel blurs by a
 *    second pixel box (variance 1/12 per axis): the error is
 *    -(1/24) lap I * E to second order.  The correction term, applied to
 *    A_m, cancels it; the Laplacian comes from the 4x samples by central
 *    differences.  It needs light that is smooth over a pixel, which the
 *    choice of K (sersic_core_k) ensures.
 *
 * The stamp for the wings is the window grown by the ePSF half-width, so
 * light from outside the window, and outside the detector, that the PSF
 * scatters into the window is included; it is convolved with
 * host->convolve (FFTW) and only the window part is added.
 */
int sersic_render_common(const struct wfs_host *host, void *thread,
			 const struct wfs_source *src, const struct wfs_window *win,
			 const struct sersic_method *m)
{
	struct sersic_stamp st;
	double hx, hy;
	int any, rough;

	if (!(src->flux != 0) || !isfinite(src->flux))
		return 0;
	sersic_unpack(src, &st.g);
	sersic_halfbox(&st.g, &hx, &hy);
	/* The galaxy's pixels: every pixel the truncation box touches. */
	double gx0 = floor(st.g.xc - hx + 0.5), gx1 = floor(st.g.xc + hx + 0.5);
	double gy0 = floor(st.g.yc - hy + 0.5), gy1 = floor(st.g.yc + hy + 0.5);

	if (!m->convolve) {
		sersic_render_pixels(&st.g, win, m, gx0, gx1, gy0, gy1);
		return 0;
	}
	if (sersic_epsf(host, src, &st.e))
		return -1;
	st.hp = sersic_psf_drawn(&st.e, src);
	st.psf_all = st.hp < sersic_psf_half(&st.e) && src->aux[AUX_PSFALL] > 0 ? src->aux[AUX_PSFALL] : 0;
	if (!sersic_stamp_layout(&st, win, m, gx0, gx1, gy0, gy1))
		return 0;
	if (sersic_stamp_scratch(host, thread, &st) < 0)
		return -1;
	if (m->stamp_setup)
		m->stamp_setup(&st.g, m->opt);
	sersic_wings_integrate(&st, m, &any, &rough);
	if (any && sersic_wings_convolve(host, thread, &st, win, rough, m->moment_level) < 0)
		return -1;
	if (!st.core_on)
		return 0;
	sersic_core_cells(&st, m);
	sersic_core_add(&st, win, m);
	return 0;
}
