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
 *
 * Speed.  A source's bilinear pixels read, for each of its four nodes, the
 * samples at two x phases and two y phases, every `over` samples apart.  So
 * each node is copied once into a polyphase layout: over x over planes of
 * pixel-spaced samples (plane (q, r) holds samples (over m + q, over l + r)).
 * Then a row of a source is a weighted sum of 16 contiguous rows (4 nodes x
 * 2 x 2 taps), a loop the compiler vectorises.  The copies are made in
 * footprint(), which the host calls in its main thread before render() sees
 * the source, so render() neither allocates nor locks.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"

/* Polyphase copies of the ePSF nodes, found by the node's address (the
 * host's arrays stay put until fini).  Open addressing, never removed. */
#define POLY_SLOTS 2048
#define MAX_ROW 1024            /* widest window row handled in one pass */

struct poly {
	const float *node;      /* key */
	int n, over, m;         /* m = samples per phase plane side */
	float *plane;           /* over * over planes of m x m */
};

struct point {
	const struct wfs_host *host;
	double core;            /* radius of the bicubic core, pixels */
	struct poly slot[POLY_SLOTS];
};

static size_t poly_hash(const float *node)
{
	uintptr_t h = (uintptr_t)node;

	h ^= h >> 17;
	h *= 0x9e3779b97f4a7c15ULL;
	return (h >> 20) & (POLY_SLOTS - 1);
}

static const struct poly *poly_find(const struct point *p, const float *node)
{
	for (size_t i = poly_hash(node), k = 0; k < POLY_SLOTS; k++, i = (i + 1) & (POLY_SLOTS - 1)) {
		if (p->slot[i].node == node)
			return &p->slot[i];
		if (!p->slot[i].node)
			return NULL;
	}
	return NULL;
}

/* Make the polyphase copy of a node.  Main thread only (footprint). */
static int poly_add(struct point *p, const float *node, int n, int over)
{
	int m = (n + over - 1) / over + 1;
	size_t i = poly_hash(node), k;
	float *plane;

	if (poly_find(p, node))
		return 0;
	for (k = 0; k < POLY_SLOTS && p->slot[i].node; k++)
		i = (i + 1) & (POLY_SLOTS - 1);
	if (k == POLY_SLOTS)
		return p->host->error(p->host->ctx, "too many ePSF nodes (%d)", POLY_SLOTS);
	if (!(plane = calloc((size_t)over * over * m * m, sizeof(float))))
		return p->host->error(p->host->ctx, "out of memory");
	for (int q = 0; q < over; q++)
		for (int r = 0; r < over; r++) {
			float *pl = plane + (size_t)(q * over + r) * m * m;

			for (int y = q, a = 0; y < n; y += over, a++)
				for (int x = r, b = 0; x < n; x += over, b++)
					pl[a * m + b] = node[(size_t)y * n + x];
		}
	p->slot[i] = (struct poly){ node, n, over, m, plane };
	return 0;
}

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
	struct point *p = state;

	for (int i = 0; p && i < POLY_SLOTS; i++)
		free(p->slot[i].plane);
	free(p);
}

static int point_footprint(void *state, const struct wfs_source *src,
			   struct wfs_box *box)
{
	struct point *p = state;
	struct wfs_epsf e;
	double half;

	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	for (int k = 0; k < 4; k++)
		if (e.weight[k] != 0 && poly_add(p, e.node[k], e.n, e.over) < 0)
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

/* floor(a / b) for b > 0 and any sign of a */
static long floordiv(long a, long b)
{
	return a >= 0 ? a / b : -((-a + b - 1) / b);
}

/* Built twice, for AVX2 and for any x86-64, and chosen at load time: the
 * row sums run 8 floats wide where the processor allows. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
__attribute__((target_clones("avx2,fma", "default")))
#endif
static int point_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct point *p = state;
	struct wfs_epsf e;
	const struct poly *pl[4];
	const float *node[4];
	double wn[4], bx[2], by[2], cx[4], cy[4];
	float wt[16];
	long rx[2], mx[2], ry[2], my[2];
	int nn = 0, n, o, m, basex, basey;
	double tx, ty, fx, fy, core2;
	float acc[MAX_ROW];
	/* zero[] stands in for a missing stream; it is only ever read */
	static const float zero[MAX_ROW + 2048];

	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	for (int k = 0; k < 4; k++)
		if (e.weight[k] != 0) {
			node[nn] = e.node[k];
			if (!(pl[nn] = poly_find(p, e.node[k])))
				return p->host->error(p->host->ctx, "ePSF node not prepared");
			wn[nn++] = e.weight[k] * src->flux;
		}
	n = e.n;
	o = e.over;
	m = pl[0]->m;
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
	/* tap a of pixel i is sample o (i + mx[a]) + rx[a]: plane rx[a], column
	 * i + mx[a] */
	for (int a = 0; a < 2; a++) {
		long sx = e.centre + basex + a, sy = e.centre + basey + a;

		mx[a] = floordiv(sx, o);
		rx[a] = sx - o * mx[a];
		my[a] = floordiv(sy, o);
		ry[a] = sy - o * my[a];
	}
	for (int k = 0; k < 4; k++)
		for (int b = 0; b < 2; b++)
			for (int a = 0; a < 2; a++)
				wt[(k * 2 + b) * 2 + a] = k < nn ? (float)(wn[k] * by[b] * bx[a]) : 0;
	/* the cubic's taps must stay inside the array */
	core2 = p->core * o + 2 < e.centre ? p->core * p->core : 0;

	for (int j = win->y0; j < win->y0 + win->ny; j++) {
		double *row = win->pix + (ptrdiff_t)(j - win->y0) * win->stride;
		double dy = j - src->y;

		for (int i0 = win->x0; i0 < win->x0 + win->nx; i0 += MAX_ROW) {
			int len = win->x0 + win->nx - i0 < MAX_ROW ? win->x0 + win->nx - i0 : MAX_ROW;

			/* 16 streams, 4 nodes x 2 y taps x 2 x taps; a missing node
			 * or a row beyond the planes reads a row of zeros */
			const float *sp[16];
			int ia = 0, ib = len;

			for (int a = 0; a < 2; a++) {
				long lo = -(i0 + mx[a]), hi = m - (i0 + mx[a]);

				if (lo > ia)
					ia = (int)lo;
				if (hi < ib)
					ib = (int)hi;
			}
			for (int k = 0; k < 4; k++)
				for (int b = 0; b < 2; b++) {
					long mrow = j + my[b];

					for (int a = 0; a < 2; a++) {
						int t = (k * 2 + b) * 2 + a;

						if (k >= nn || mrow < 0 || mrow >= m)
							sp[t] = zero;
						else
							sp[t] = pl[k]->plane +
								((size_t)(ry[b] * o + rx[a]) * m + mrow) * m +
								(i0 + mx[a]);
					}
				}
			for (int i = 0; i < ia && i < len; i++)
				acc[i] = 0;
			for (int i = ib > ia ? ib : ia; i < len; i++)
				acc[i] = 0;
			for (int i = ia; i < ib; i++) {
				float v = 0;

				for (int t = 0; t < 16; t++)
					v += wt[t] * sp[t][i];
				acc[i] = v;
			}
			/* the sharp core: Keys cubic from the original samples */
			if (dy * dy <= core2) {
				long iy = e.centre + (long)o * j + basey;

				for (int i = 0; i < len; i++) {
					double dx = i0 + i - src->x, v = 0;
					long ix = e.centre + (long)o * (i0 + i) + basex;

					if (dx * dx + dy * dy > core2)
						continue;
					for (int k = 0; k < nn; k++) {
						const float *s = node[k] + (iy - 1) * n + (ix - 1);
						double t = 0;

						for (int b = 0; b < 4; b++, s += n)
							t += cy[b] * (cx[0] * s[0] + cx[1] * s[1] +
								      cx[2] * s[2] + cx[3] * s[3]);
						v += wn[k] * t;
					}
					acc[i] = (float)v;
				}
			}
			for (int i = 0; i < len; i++)
				row[i0 - win->x0 + i] += acc[i];
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
