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
 * loop cheap).  The box is the set of pixels within half = centre / over
 * pixels of the source in x and in y (44 x 44 for the 177-sample ePSF),
 * symmetric about the source; the ePSF array covers exactly that range.
 * Three nested squares about the source decide how the ePSF is read there:
 *
 *   core   |i - x|, |j - y| < psf-core (4): Keys' cubic convolution kernel
 *          (a = -1/2, 4 x 4 taps).  It reproduces quadratics, so the sharp
 *          core is not flattened as bilinear interpolation does (the STIPS
 *          paper's Figures 3-4: about 3% error in the core).
 *   wing   within psf-wing (8) pixels: bilinear (2 x 2 taps).  Beyond the
 *          core the ePSF is smooth on the sample scale.
 *   beyond the nearest sample (1 tap).  On the built-in F129 ePSF that is
 *          within 1e-4 of the peak of the bilinear value from 8 pixels out
 *          (5e-4 from 4 pixels), where the light is a few 1e-4 of the peak.
 *
 * Flux.  Bilinear interpolation's weights sum to 1 at every phase and it
 * reads every sample of the box once per tap, so its sum over the box is
 * the ePSF's enclosed fraction; the other kernels' sums differ from it a
 * little (Keys' kernel by about 1e-4 of the flux over a 4-pixel core).  So
 * everything outside the core is scaled by one factor per source, f, that
 * makes the total exactly the bilinear sum over the box (flux_factor).  The
 * box's totals are weighted sums of rectangles of the phase planes, read
 * from their summed-area tables in constant time in prepare(); the core's
 * is the sum of what it draws, and every window draws the whole core into
 * its buffer (only the rows it holds go into the tile), so every window of
 * a source gets the same f.
 *
 * Speed.  A source's pixels read, for each array, the samples at a few x
 * and y phases, every `over` samples apart.  So each array is copied once
 * into a polyphase layout: over x over planes of pixel-spaced samples
 * (plane (q, r) holds samples (over m + q, over l + r)), and a row is a
 * weighted sum of contiguous rows.  The four grid nodes are blended once
 * per 512-pixel cell, at its centre, into one polyphase array (psf-blend=
 * core, the default), which a faint source reads: one stream per pixel
 * beyond the wing square, four within it.  Blending at the cell's centre
 * instead of the source misplaces the PSF's change with position by up to
 * 362 pixels, first order, and that change lives in the core: there the
 * source's own blend is restored, as the bilinear difference (source's
 * blend - cell's) from the nodes added to the cell's Keys value, a small
 * field whose interpolation error is small.  The core is drawn first into
 * a small float buffer, then every row of the window in one call, straight
 * into the tile (sum_rows_avx2).  The copies and blends are made in
 * prepare(), which the host calls in its main thread before render() sees
 * the source, so render() neither allocates nor locks.
 *
 * Approximations, each a setting (wfiscene(1) POINT SOURCES has their
 * measured error and cost):
 *
 *   psf-interp=bilinear|core|bicubic  Keys' cubic nowhere, within psf-core
 *                                     pixels (default 4), or everywhere
 *   psf-wing=W                        bilinear within W pixels (default 8),
 *                                     the nearest sample beyond, for sources
 *                                     drawn from one array of the faint class
 *   psf-box=fixed|adaptive            the box above, or per source the
 *                                     smallest whose left-out light is below
 *                                     psf-box-noise (0.1) of the noise in it;
 *                                     the noise from the scene's background,
 *                                     read noise and exposure time, or
 *                                     psf-box-sigma (counts/s per pixel)
 *   psf-blend=core|source|cell        blend the four nodes once per psf-cell
 *                                     (512) pixel cell, at the source within
 *                                     psf-core (the default; with
 *                                     psf-interp=bicubic the whole box); per
 *                                     source everywhere (16 streams); or per
 *                                     cell everywhere
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"
#include "halo.h"

/* Polyphase copies of the ePSF nodes, found by the node's address (the
 * host's arrays stay put until fini), and of blended cells, found by an odd
 * key (node addresses are even).  Open addressing, never removed. */
#define POLY_SLOTS 8192
#define MAX_ROW 1024            /* widest window row of the general path */
/* Planes carry PAD zero samples on each side, so that the Keys taps (one
 * sample before, two after) of any pixel inside the box stay inside the
 * plane and read zeros beyond the ePSF, and no pixel needs a range test. */
#define PAD 2

/* Eight floats, loaded and stored unaligned: the row sums below are written
 * with GCC's vector extension so that a 44-pixel row is 6 steps with no
 * alignment prologue or scalar tail (rows are summed to a multiple of 8;
 * the planes carry VSLACK floats so the last step can read on). */
typedef float v8f __attribute__((vector_size(32), aligned(4), may_alias));
#define VSLACK 8

typedef float v4f __attribute__((vector_size(16), aligned(4), may_alias));
typedef double v4d __attribute__((vector_size(32), aligned(8), may_alias));
#define SPLAT4(f) ((v4d){ (f), (f), (f), (f) })
#define TO_V4D(p) __builtin_convertvector(*(const v4f *)(p), v4d)
#define SPLAT(f) ((v8f){ (f), (f), (f), (f), (f), (f), (f), (f) })

struct poly {
	uint64_t key;
	int n, over, centre, m; /* m = samples per phase plane side, padded */
	float *plane;           /* over * over planes of m x m */
	/* per plane, its summed-area table: (m + 1) x (m + 1), entry (r, c)
	 * the sum of the plane's rows < r and columns < c, summed in double
	 * and kept in float (a rectangle's sum to ~1e-8 of the flux) */
	float *sat;
	int nee;                /* centre / over */
	double *ee;             /* ee[h], h = 1..nee: see ee_table() */
	/* a blended cell: the nodes and weights it was blended from, and
	 * (psf-blend=core) the nodes' own polyphase copies */
	const float *cnode[4];
	double cweight[4];
	const struct poly *cpoly[4];
};

/* Pixels [x0, x1) x [y0, y1), 0-based; empty when x0 >= x1 or y0 >= y1. */
struct zone {
	long x0, x1, y0, y1;
};

/* Where a source's pixels read an array (every array of a size class has
 * the same layout).  Tap a (sample offsets -1, 0, 1, 2 from the sample
 * below the pixel's) of pixel i is sample o (i + mx[a]) + rx[a]: plane
 * column i + mx[a] + PAD of x phase rx[a]; likewise in y. */
struct geom {
	int o;
	long mx[4], rx[4], my[4], ry[4];
	double bx[2], by[2];    /* bilinear weights of taps 1 and 2 */
	double kx[4], ky[4];    /* Keys' weights of taps 0..3 */
	int an, bn;             /* the nearest sample's taps (1 or 2) */
	/* tap (a, b) of pixel (i, j): plane + tx[a] + ty[b] + j m + i, and
	 * its summed-area table: sat + sx[a] + sy[b] + j (m + 1) + i */
	ptrdiff_t tx[4], ty[4], sx[4], sy[4];
	ptrdiff_t m;
};

/* How one source is drawn: the arrays it reads with their weights times the
 * flux, psf-blend=core's correction arrays, and its zones. */
struct draw {
	int nn, ncor, keys;
	int cell;               /* one blended cell (psf-blend=cell or core) */
	const struct poly *pl[4];
	double wn[4];
	const struct poly *cp[8];
	double cw[8];
	struct geom g;
	struct zone box;        /* every pixel it lights */
	struct zone core;       /* Keys' cubic (or psf-blend=core's bilinear
				 * correction), not scaled by f */
	struct zone wing;       /* bilinear; beyond it the nearest sample */
};

enum { INTERP_BILINEAR, INTERP_CORE, INTERP_BICUBIC };
enum { EXTENT_NOISE, EXTENT_STIPS };
/* aux[0] holds the box's half-width plus HALO_PACK times the halo's radius
 * (both whole numbers of pixels) */
#define HALO_PACK 65536.0
#define WFS_PSF_HALO 3          /* the host's class of the halo array */
enum { BLEND_SOURCE, BLEND_CELL, BLEND_CORE };

/* One array, the whole window, straight into the tile: for each row j and
 * pixel i < nx,
 *
 *   pix[j stride + i] += wn sn[j m + i]
 *
 * but on the wing rows jw <= j < jw + nw, over wa <= i < wb,
 *
 *   w0 s0[j m + i] + w1 s1[..] + w2 s2[..] + w3 s3[..]
 *
 * (the last three products fused: fmaf)
 * and on the core rows jc <= j < jc + nc, over ka <= i < kb, kv[] replaces
 * the sum; in float.  Two builds with the same operations per pixel in the
 * same order, so the same bits: 8 pixels at a time with AVX2 (reading on
 * into the planes' slack and into kv's margins, the lanes outside a run
 * masked), and one by one.  The float sums are converted and added in
 * registers. */
#define KV_ROWS 48              /* core rows and columns the fast path takes: */
#define KV_COLS 48              /* the 44-pixel box, so psf-interp=bicubic too */
#define KV_PITCH (KV_COLS + 16) /* a core row of kv: 8 floats margin, then column ka */

struct rows_args {
	const float *s[4];      /* the bilinear streams at the window's first pixel */
	const float *sn;        /* the nearest sample's stream */
	ptrdiff_t m;            /* floats from one plane row to the next */
	float w[4], wn;         /* their weights: flux f bilinear weight; flux f */
	int jw, nw, wa, wb;     /* the wing square, window coordinates */
	int jc, nc, ka, kb;     /* the core, window coordinates */
	const float *kv;        /* pixel i of row jc + c: kv[c KV_PITCH + 8 + i - ka] */
};

static void sum_rows_plain(double *pix, ptrdiff_t stride, int nx, int ny,
			   const struct rows_args *r)
{
	for (int j = 0; j < ny; j++) {
		const float *s0 = r->s[0] + j * r->m, *s1 = r->s[1] + j * r->m;
		const float *s2 = r->s[2] + j * r->m, *s3 = r->s[3] + j * r->m;
		const float *sn = r->sn + j * r->m;
		double *out = pix + j * stride;
		int c = j - r->jc, core = c >= 0 && c < r->nc;
		int wing = j >= r->jw && j < r->jw + r->nw;

		for (int i = 0; i < nx; i++) {
			float v = r->wn * sn[i];

			if (wing && i >= r->wa && i < r->wb) {
				v = r->w[0] * s0[i];
				v = fmaf(r->w[1], s1[i], v);
				v = fmaf(r->w[2], s2[i], v);
				v = fmaf(r->w[3], s3[i], v);
			}
			if (core && i >= r->ka && i < r->kb)
				v = r->kv[c * KV_PITCH + 8 + i - r->ka];
			out[i] += v;
		}
	}
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HAVE_ROWS_AVX2 1

/* out[0..8) += v */
#define ADD8(out, v) do { \
	__m256 v_ = (v); \
	_mm256_storeu_pd((out), _mm256_add_pd(_mm256_loadu_pd(out), \
					      _mm256_cvtps_pd(_mm256_castps256_ps128(v_)))); \
	_mm256_storeu_pd((out) + 4, _mm256_add_pd(_mm256_loadu_pd((out) + 4), \
						  _mm256_cvtps_pd(_mm256_extractf128_ps(v_, 1)))); \
} while (0)
/* the same for the first n < 8 lanes only (AMD's masked stores are slow) */
__attribute__((target("avx2,fma"), always_inline)) static inline void add8_tail(double *out, __m256 v,
									    int n)
{
	__m256d lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
	double t[4];

	if (n >= 4) {
		_mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out), lo));
		lo = _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1));
		out += 4;
		n -= 4;
	}
	if (!n)
		return;
	_mm256_storeu_pd(t, lo);
	for (int l = 0; l < n; l++)
		out[l] += t[l];
}

/* Rows [j0, j1) beyond the wing square: one stream each. */
__attribute__((target("avx2,fma"), always_inline)) static inline void
nearest_rows(double *pix, ptrdiff_t stride, const float *sn, ptrdiff_t m, __m256 wn, int j0,
	     int j1, int nv, int tail)
{
	for (int j = j0; j < j1; j++) {
		const float *s = sn + j * m;
		double *out = pix + j * stride;
		int i;

		for (i = 0; i < nv; i += 8)
			ADD8(out + i, _mm256_mul_ps(wn, _mm256_loadu_ps(s + i)));
		if (tail)
			add8_tail(out + nv, _mm256_mul_ps(wn, _mm256_loadu_ps(s + nv)), tail);
	}
}

__attribute__((target("avx2,fma"))) static void sum_rows_avx2(double *pix, ptrdiff_t stride, int nx,
							  int ny, const struct rows_args *r)
{
	__m256 w0 = _mm256_set1_ps(r->w[0]), w1 = _mm256_set1_ps(r->w[1]);
	__m256 w2 = _mm256_set1_ps(r->w[2]), w3 = _mm256_set1_ps(r->w[3]);
	__m256 wn = _mm256_set1_ps(r->wn);
	__m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
	__m256i wa = _mm256_set1_epi32(r->wa - 1), wb = _mm256_set1_epi32(r->wb);
	__m256i ka = _mm256_set1_epi32(r->ka - 1), kb = _mm256_set1_epi32(r->kb);
	/* the row's last, partial step: its lanes below nx */
	int nv = nx & ~7, tail = nx - nv;
	/* on the wing's rows, the steps [va, vb) meet the wing's columns */
	int va = r->wa <= 0 ? 0 : r->wa & ~7, vb = r->wb <= 0 ? 0 : (r->wb + 7) & ~7;
	/* the wing's rows in the window, [j0, j1) */
	int j0 = r->jw < 0 ? 0 : r->jw > ny ? ny : r->jw;
	int j1 = r->jw + r->nw > ny ? ny : r->jw + r->nw < j0 ? j0 : r->jw + r->nw;
	ptrdiff_t m = r->m;

	if (vb > nx)
		vb = (nx + 7) & ~7;
	if (va > vb)
		va = vb;
	nearest_rows(pix, stride, r->sn, m, wn, 0, j0, nv, tail);
	for (int j = j0; j < j1; j++) {
		const float *sn = r->sn + j * m, *s0 = r->s[0] + j * m, *s1 = r->s[1] + j * m;
		const float *s2 = r->s[2] + j * m, *s3 = r->s[3] + j * m;
		double *out = pix + j * stride;
		int c = j - r->jc, core = c >= 0 && c < r->nc;
		int i;

		/* full steps before the wing's; then the steps meeting it, the
		 * row's partial one among them if it does; then the rest */
		for (i = 0; i < va && i < nv; i += 8)
			ADD8(out + i, _mm256_mul_ps(wn, _mm256_loadu_ps(sn + i)));
		for (; i < vb; i += 8) {
			__m256i lane = _mm256_add_epi32(lanes, _mm256_set1_epi32(i));
			__m256i in = _mm256_and_si256(_mm256_cmpgt_epi32(lane, wa),
						      _mm256_cmpgt_epi32(wb, lane));
			__m256 b = _mm256_fmadd_ps(w3, _mm256_loadu_ps(s3 + i), _mm256_fmadd_ps(
				w2, _mm256_loadu_ps(s2 + i), _mm256_fmadd_ps(
				w1, _mm256_loadu_ps(s1 + i), _mm256_mul_ps(w0, _mm256_loadu_ps(s0 + i)))));
			__m256 v = _mm256_blendv_ps(_mm256_mul_ps(wn, _mm256_loadu_ps(sn + i)), b,
						    _mm256_castsi256_ps(in));

			if (core && i < r->kb && i + 8 > r->ka) {
				__m256 k = _mm256_loadu_ps(r->kv + (c * KV_PITCH + 8 + i - r->ka));

				in = _mm256_and_si256(_mm256_cmpgt_epi32(lane, ka), _mm256_cmpgt_epi32(kb, lane));
				v = _mm256_blendv_ps(v, k, _mm256_castsi256_ps(in));
			}
			if (i < nv)
				ADD8(out + i, v);
			else
				add8_tail(out + i, v, tail);
		}
		for (; i < nv; i += 8)
			ADD8(out + i, _mm256_mul_ps(wn, _mm256_loadu_ps(sn + i)));
		if (i < nx)
			add8_tail(out + i, _mm256_mul_ps(wn, _mm256_loadu_ps(sn + i)), tail);
	}
	nearest_rows(pix, stride, r->sn, m, wn, j1, ny, nv, tail);
}

#endif

/* The core: for rows c < nc and pixels i < nk (8 at a time; kv gets a
 * multiple of 8), each lane
 *
 *   v = sum over b of ky[b] (kx[0] t[b][0] + kx[1] t[b][1] + ...)   Keys
 *   v = bw[0] t[1][1] + bw[1] t[1][2] + bw[2] t[2][1] + bw[3] t[2][2] bilinear
 *   kv = v + sum over k of cw[k] ct[k]         psf-blend=core's correction
 *
 * every product but the first of a sum fused (fmaf), in this order, so
 * that the AVX2 build and the plain one give the same bits; and K, the sum
 * of kv over the core, in double (lanes l and l + 4 to accumulator l). */
struct core_args {
	/* tap (a, b) of core row c, pixel i: base + ty[b] + tx[a] + c m + i;
	 * the correction's array k, bilinear tap (a, b): cbase[k] + ty[b + 1]
	 * + tx[a + 1] + c m + i */
	const float *base, *cbase[8];
	ptrdiff_t tx[4], ty[4], m;
	int ncor, keys, nc, nk;
	float kx[4], ky[4], bw[4], cw[32];
};

static double core_plain(const struct core_args *a, float *kvb)
{
	double ks[4] = { 0 };

	for (int c = 0; c < a->nc; c++) {
		ptrdiff_t o = (ptrdiff_t)c * a->m;
		float *kv = kvb + c * KV_PITCH + 8;

		for (int i0 = 0; i0 < a->nk; i0 += 8) {
			float lane[8];

			for (int l = 0; l < 8; l++) {
				const float *r = a->base + o + i0 + l;
				float v, e = 0;

				if (a->keys) {
					v = 0;
					for (int b = 0; b < 4; b++) {
						const float *rb = r + a->ty[b];
						float h = a->kx[0] * rb[a->tx[0]];

						h = fmaf(a->kx[1], rb[a->tx[1]], h);
						h = fmaf(a->kx[2], rb[a->tx[2]], h);
						h = fmaf(a->kx[3], rb[a->tx[3]], h);
						v = b ? fmaf(a->ky[b], h, v) : a->ky[0] * h;
					}
				} else {
					v = a->bw[0] * r[a->ty[1] + a->tx[1]];
					v = fmaf(a->bw[1], r[a->ty[1] + a->tx[2]], v);
					v = fmaf(a->bw[2], r[a->ty[2] + a->tx[1]], v);
					v = fmaf(a->bw[3], r[a->ty[2] + a->tx[2]], v);
				}
				for (int k = 0; k < a->ncor; k++) {
					const float *rk = a->cbase[k] + o + i0 + l;

					e = fmaf(a->cw[4 * k], rk[a->ty[1] + a->tx[1]], e);
					e = fmaf(a->cw[4 * k + 1], rk[a->ty[1] + a->tx[2]], e);
					e = fmaf(a->cw[4 * k + 2], rk[a->ty[2] + a->tx[1]], e);
					e = fmaf(a->cw[4 * k + 3], rk[a->ty[2] + a->tx[2]], e);
				}
				kv[i0 + l] = lane[l] = v + e;
			}
			for (int l = 0; l < 4; l++)
				ks[l] += (double)(i0 + l < a->nk ? lane[l] : 0) +
					 (double)(i0 + l + 4 < a->nk ? lane[l + 4] : 0);
		}
	}
	return (ks[0] + ks[1]) + (ks[2] + ks[3]);
}

#ifdef HAVE_ROWS_AVX2
__attribute__((target("avx2,fma"))) static double core_avx2(const struct core_args *a, float *kvb)
{
	__m256d ks = _mm256_setzero_pd();
	__m256 kx0 = _mm256_set1_ps(a->kx[0]), kx1 = _mm256_set1_ps(a->kx[1]);
	__m256 kx2 = _mm256_set1_ps(a->kx[2]), kx3 = _mm256_set1_ps(a->kx[3]);
	__m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), nk = _mm256_set1_epi32(a->nk);
	ptrdiff_t x0 = a->tx[0], x1 = a->tx[1], x2 = a->tx[2], x3 = a->tx[3];
	ptrdiff_t y11 = a->ty[1] + x1, y12 = a->ty[1] + x2, y21 = a->ty[2] + x1, y22 = a->ty[2] + x2;
	double k[4];

	for (int c = 0; c < a->nc; c++) {
		ptrdiff_t o = (ptrdiff_t)c * a->m;
		float *kv = kvb + c * KV_PITCH + 8;

		for (int i0 = 0; i0 < a->nk; i0 += 8) {
			const float *r = a->base + o + i0;
			__m256 v, e = _mm256_setzero_ps();
			__m256i in;

			if (a->keys) {
				v = _mm256_setzero_ps();
				for (int b = 0; b < 4; b++) {
					const float *rb = r + a->ty[b];
					__m256 h = _mm256_mul_ps(kx0, _mm256_loadu_ps(rb + x0));

					h = _mm256_fmadd_ps(kx1, _mm256_loadu_ps(rb + x1), h);
					h = _mm256_fmadd_ps(kx2, _mm256_loadu_ps(rb + x2), h);
					h = _mm256_fmadd_ps(kx3, _mm256_loadu_ps(rb + x3), h);
					v = b ? _mm256_fmadd_ps(_mm256_set1_ps(a->ky[b]), h, v) :
						_mm256_mul_ps(_mm256_set1_ps(a->ky[0]), h);
				}
			} else {
				v = _mm256_mul_ps(_mm256_set1_ps(a->bw[0]), _mm256_loadu_ps(r + y11));
				v = _mm256_fmadd_ps(_mm256_set1_ps(a->bw[1]), _mm256_loadu_ps(r + y12), v);
				v = _mm256_fmadd_ps(_mm256_set1_ps(a->bw[2]), _mm256_loadu_ps(r + y21), v);
				v = _mm256_fmadd_ps(_mm256_set1_ps(a->bw[3]), _mm256_loadu_ps(r + y22), v);
			}
			for (int q = 0; q < a->ncor; q++) {
				const float *rk = a->cbase[q] + o + i0;
				const float *w = a->cw + 4 * q;

				e = _mm256_fmadd_ps(_mm256_set1_ps(w[0]), _mm256_loadu_ps(rk + y11), e);
				e = _mm256_fmadd_ps(_mm256_set1_ps(w[1]), _mm256_loadu_ps(rk + y12), e);
				e = _mm256_fmadd_ps(_mm256_set1_ps(w[2]), _mm256_loadu_ps(rk + y21), e);
				e = _mm256_fmadd_ps(_mm256_set1_ps(w[3]), _mm256_loadu_ps(rk + y22), e);
			}
			v = _mm256_add_ps(v, e);
			_mm256_storeu_ps(kv + i0, v);
			in = _mm256_cmpgt_epi32(nk, _mm256_add_epi32(lanes, _mm256_set1_epi32(i0)));
			v = _mm256_and_ps(v, _mm256_castsi256_ps(in));
			ks = _mm256_add_pd(ks, _mm256_add_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(v)),
							     _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))));
		}
	}
	_mm256_storeu_pd(k, ks);
	return (k[0] + k[1]) + (k[2] + k[3]);
}
#endif

struct point {
	const struct wfs_host *host;
	int interp;             /* psf-interp */
	double core;            /* half-width of the cubic core, pixels */
	double wing;            /* half-width of the bilinear square, pixels */
	int adaptive;           /* psf-box=adaptive */
	double box_noise;       /* psf-box-noise: fraction of the box's noise */
	double sigma;           /* noise per pixel, counts/s (psf-box-sigma) */
	int blend;              /* psf-blend */
	int cell;               /* psf-cell: side of a blended cell, pixels */
	int extent;             /* psf-extent: EXTENT_NOISE or EXTENT_STIPS */
	double extent_noise;    /* psf-extent-noise: fraction of sigma */
	double extent_max;      /* psf-extent-max: largest radius, pixels */
	double extent_min;      /* psf-extent-min: smallest box half-width, pixels
				 * (negative: the class's box) */
	double halo_power;      /* psf-halo-power: the tail's power */
	double halo_taper;      /* psf-halo-taper: pixels */
	struct halo halo[19];   /* per SCA, set up in prepare() */
	double cfac[19][3];     /* per SCA and class: the core's scale, 0 unset */
	double requested, left; /* flux of the sources prepared, and left out */
	long long nhalo, npoint; /* sources drawn with a halo, and all */
	void (*sum_rows)(double *, ptrdiff_t, int, int, const struct rows_args *);
	double (*core_rows)(const struct core_args *, float *);
	struct poly slot[POLY_SLOTS];
};

static size_t poly_hash(uint64_t key)
{
	uint64_t h = key;

	h ^= h >> 17;
	h *= 0x9e3779b97f4a7c15ULL;
	return (size_t)(h >> 20) & (POLY_SLOTS - 1);
}

static const struct poly *poly_find(const struct point *p, uint64_t key)
{
	for (size_t i = poly_hash(key), k = 0; k < POLY_SLOTS; k++, i = (i + 1) & (POLY_SLOTS - 1)) {
		if (p->slot[i].key == key)
			return &p->slot[i];
		if (!p->slot[i].key)
			return NULL;
	}
	return NULL;
}

/* ee[h]: the fraction of the flux in the (2h - 1)^2 pixels about a source
 * on a pixel centre.  Any box of pixels with |i - x| < h and |j - y| < h
 * covers at least the area [-(h - 1/2), h - 1/2]^2 about the source, which
 * is what these pixels cover, so flux * (ee[nee] - ee[h]) bounds the light
 * a box of half-width h leaves out compared with the full box. */
static void ee_table(struct poly *q, const float *node)
{
	int n = q->n, o = q->over, c = q->centre;

	q->ee[0] = 0;
	for (int h = 1; h <= q->nee; h++) {
		double s = 0;
		int r = h - 1;

		for (int d = -r; d <= r; d++) {
			s += node[(size_t)(c - o * r) * n + c + o * d];
			if (r > 0)
				s += node[(size_t)(c + o * r) * n + c + o * d];
		}
		for (int d = -r + 1; d <= r - 1; d++)
			s += node[(size_t)(c + o * d) * n + c - o * r] +
			     node[(size_t)(c + o * d) * n + c + o * r];
		q->ee[h] = q->ee[h - 1] + s;
	}
}

/* The summed-area tables of q's planes; row is m + 1 doubles of scratch. */
static void sat_table(struct poly *q, double *row)
{
	int m = q->m, w = m + 1;

	for (int k = 0; k < q->over * q->over; k++) {
		const float *pl = q->plane + (size_t)k * m * m;
		float *s = q->sat + (size_t)k * w * w;

		for (int c = 0; c < w; c++)
			row[c] = s[c] = 0;
		for (int r = 0; r < m; r++) {
			double run = 0;

			s[(size_t)(r + 1) * w] = 0;
			for (int c = 0; c < m; c++) {
				run += pl[(size_t)r * m + c];
				row[c + 1] += run;
				s[(size_t)(r + 1) * w + c + 1] = (float)row[c + 1];
			}
		}
	}
}

/* The polyphase copy of an n x n ePSF array under key, made the first time.
 * Main thread only (prepare).  NULL with an error recorded when it fails. */
static struct poly *poly_add(struct point *p, uint64_t key, const float *node, int n, int over)
{
	int m = (n + over - 1) / over + 2 * PAD + 1;
	size_t i = poly_hash(key), k;
	struct poly q = { .key = key, .n = n, .over = over, .centre = (n - 1) / 2, .m = m };
	double *row;

	for (k = 0; k < POLY_SLOTS && p->slot[i].key; k++) {
		if (p->slot[i].key == key)
			return &p->slot[i];
		i = (i + 1) & (POLY_SLOTS - 1);
	}
	if (k == POLY_SLOTS) {
		p->host->error(p->host->ctx, "too many ePSF nodes and cells (%d)", POLY_SLOTS);
		return NULL;
	}
	q.nee = q.centre / over;
	q.plane = calloc((size_t)over * over * m * m + VSLACK, sizeof(float));
	q.sat = malloc((size_t)over * over * (m + 1) * (m + 1) * sizeof(float));
	q.ee = calloc((size_t)q.nee + 1, sizeof(double));
	row = malloc((size_t)(m + 1) * sizeof(double));
	if (!q.plane || !q.sat || !q.ee || !row) {
		free(q.plane);
		free(q.sat);
		free(q.ee);
		free(row);
		p->host->error(p->host->ctx, "out of memory");
		return NULL;
	}
	for (int r = 0; r < over; r++)
		for (int s = 0; s < over; s++) {
			float *pl = q.plane + (size_t)(r * over + s) * m * m;

			for (int y = r, a = PAD; y < n; y += over, a++)
				for (int x = s, b = PAD; x < n; x += over, b++)
					pl[a * m + b] = node[(size_t)y * n + x];
		}
	ee_table(&q, node);
	sat_table(&q, row);
	free(row);
	p->slot[i] = q;
	return &p->slot[i];
}

/* The key of the blended cell holding (x, y): odd, so never a node's. */
static uint64_t cell_key(const struct point *p, const struct wfs_source *src)
{
	uint64_t cx = (uint64_t)(int64_t)floor(src->x / p->cell) & 0xffff;
	uint64_t cy = (uint64_t)(int64_t)floor(src->y / p->cell) & 0xffff;

	return 1 | (uint64_t)src->sca << 1 | (uint64_t)src->psf_class << 8 | cx << 16 | cy << 32;
}

/* psf-blend=cell: the ePSF blended once at the centre of the source's cell
 * (bilinear in position, as the host's weights say), so a source reads one
 * array instead of four.  NULL with an error recorded when it fails. */
static struct poly *cell_add(struct point *p, const struct wfs_source *src)
{
	uint64_t key = cell_key(p, src);
	struct wfs_epsf e;
	double cx = (floor(src->x / p->cell) + 0.5) * p->cell - 0.5;
	double cy = (floor(src->y / p->cell) + 0.5) * p->cell - 0.5;
	struct poly *c = (struct poly *)poly_find(p, key);
	float *mix;
	size_t nn;

	if (c)
		return c;
	if (p->host->epsf(p->host->ctx, src->sca, cx, cy, src->psf_class, &e) < 0)
		return NULL;
	nn = (size_t)e.n * e.n;
	if (!(mix = malloc(nn * sizeof(float)))) {
		p->host->error(p->host->ctx, "out of memory");
		return NULL;
	}
	for (size_t i = 0; i < nn; i++) {
		double v = 0;

		for (int k = 0; k < 4; k++)
			if (e.weight[k] != 0)
				v += e.weight[k] * e.node[k][i];
		mix[i] = (float)v;
	}
	c = poly_add(p, key, mix, e.n, e.over);
	free(mix);
	if (!c)
		return NULL;
	/* what the cell was blended from, for the core's correction
	 * (psf-blend=core): the nodes' own polyphase copies too */
	for (int k = 0; k < 4; k++) {
		c->cnode[k] = e.weight[k] != 0 ? e.node[k] : NULL;
		c->cweight[k] = e.weight[k] != 0 ? e.weight[k] : 0;
		c->cpoly[k] = NULL;
		if (p->blend == BLEND_CORE && c->cnode[k] &&
		    !(c->cpoly[k] = poly_add(p, (uint64_t)(uintptr_t)e.node[k], e.node[k], e.n, e.over)))
			return NULL;
	}
	return c;
}

/* The settings point reads, with their defaults: the one place they are
 * written (init() parses the fallback of an unset key; --report lists the
 * table).  psf-box-sigma's default is derived from the scene. */
static const struct wfs_setting point_settings[] = {
	{ "psf-interp", "core", "bilinear|core|bicubic",
	  "Keys' cubic of the ePSF nowhere, within psf-core pixels, or everywhere" },
	{ "psf-core", "4", "number >= 0", "half-width of the Keys' cubic core, pixels" },
	{ "psf-wing", "8", "number >= 0",
	  "half-width of bilinear interpolation beyond the core, pixels" },
	{ "psf-box", "fixed", "fixed|adaptive",
	  "the class's ePSF box, or per source the smallest whose left-out light is small" },
	{ "psf-box-noise", "0.1", "number > 0",
	  "psf-box=adaptive: left-out light as a fraction of the noise in the box" },
	{ "psf-box-sigma", "(the scene's noise)", "number > 0",
	  "psf-box=adaptive: noise per pixel, counts/s" },
	{ "psf-blend", "core", "source|cell|core",
	  "blend the ePSF nodes per source, per cell, or per cell but at the source in the core" },
	{ "psf-cell", "512", "whole number 1 to 4096", "blend cell side, pixels" },
	{ "psf-extent", "noise", "noise|stips",
	  "draw each source out to where it sinks below the noise, or STIPS's boxes" },
	{ "psf-extent-noise", "0.1", "number > 0",
	  "psf-extent=noise: the drawing level as a fraction of the noise per pixel" },
	{ "psf-extent-max", "8192", "number >= 1", "the largest drawing radius, pixels" },
	{ "psf-extent-min", "(the class's box)", "number >= 1",
	  "let a faint source's box shrink toward its drawing radius, down to this" },
	{ "psf-halo-power", "3", "number >= 2.5", "power-law index of the far tail" },
	{ "psf-halo-taper", "16", "number >= 0",
	  "pixels over which the halo array hands over to the tail" },
};
#define NSETTINGS ((int)(sizeof(point_settings) / sizeof(point_settings[0])))

/* The value of setting key: the scene's, else the declared default, else
 * NULL (a default in parentheses is derived, not a value). */
static const char *setting_value(const struct wfs_host *host, const char *key)
{
	const char *s = host->setting(host->ctx, key);

	if (s && *s)
		return s;
	for (int k = 0; k < NSETTINGS; k++)
		if (!strcmp(point_settings[k].key, key))
			return point_settings[k].fallback[0] == '(' ? NULL
			       : point_settings[k].fallback;
	return NULL;
}

/* A setting that is one of a list of names: 0 and *out set, or an error
 * naming the key. */
static int setting_choice(const struct wfs_host *host, const char *key,
			  const char *const names[], int nnames, int *out)
{
	const char *s = setting_value(host, key);

	if (!s || !*s)
		return 0;
	for (int i = 0; i < nnames; i++)
		if (!strcmp(s, names[i])) {
			*out = i;
			return 0;
		}
	return host->error(host->ctx, "%s: expected %s%s%s%s%s, not '%s'", key, names[0],
			   nnames > 2 ? ", " : " or ", names[1],
			   nnames > 2 ? " or " : "", nnames > 2 ? names[2] : "", s);
}

/* A numeric setting >= lo (> lo when strict): 0 and *out set, or an error
 * naming the key. */
static int setting_number(const struct wfs_host *host, const char *key, double lo,
			  int strict, double *out)
{
	const char *s = setting_value(host, key);
	char *end;
	double v;

	if (!s || !*s)
		return 0;
	v = strtod(s, &end);
	if (*end || !isfinite(v) || v < lo || (strict && v == lo))
		return host->error(host->ctx, "%s: expected a number %s %g, not '%s'", key,
				   strict ? ">" : ">=", lo, s);
	*out = v;
	return 0;
}

/* The noise of one pixel in counts/s, as the noise stage will draw it:
 * Poisson noise of the background and read noise, over the exposure time.
 * The source's own shot noise is left out (faint stars are what the
 * adaptive box is for, and they are background-limited). */
static double scene_sigma(const struct wfs_host *host)
{
	const char *ps = host->setting(host->ctx, "pixel-sigma");

	if (ps && strtod(ps, NULL) > 0)
		return strtod(ps, NULL);
	const char *t = host->setting(host->ctx, "exptime");
	const char *b = host->setting(host->ctx, "background");
	const char *r = host->setting(host->ctx, "readnoise");
	const char *n = host->setting(host->ctx, "noise");
	double te = t ? strtod(t, NULL) : 0, bk = b ? strtod(b, NULL) : 0;
	double rn = r ? strtod(r, NULL) : 0, var = rn * rn;

	if (n && strstr(n, "poisson") && bk > 0)
		var += bk * te;
	return te > 0 && var > 0 ? sqrt(var) / te : 0;
}

static int point_init(const struct wfs_host *host, void **state)
{
	static const char *const interp[] = { "bilinear", "core", "bicubic" };
	static const char *const box[] = { "fixed", "adaptive" };
	static const char *const blend[] = { "source", "cell", "core" };
	static const char *const extent[] = { "noise", "stips" };
	struct point *p = calloc(1, sizeof(*p));
	double cell = 0;

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	p->sum_rows = sum_rows_plain;
	p->core_rows = core_plain;
#ifdef HAVE_ROWS_AVX2
	/* WFISCENE_NO_SIMD: the plain loops, for testing that both give the
	 * same bits */
	if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
	    !getenv("WFISCENE_NO_SIMD")) {
		p->sum_rows = sum_rows_avx2;
		p->core_rows = core_avx2;
	}
#endif
	p->sigma = scene_sigma(host);
	p->extent = EXTENT_NOISE;
	p->extent_noise = 0.1;
	p->extent_max = 8192;
	p->extent_min = -1;
	p->halo_power = 3;
	p->halo_taper = 16;
	if (setting_choice(host, "psf-interp", interp, 3, &p->interp) < 0 ||
	    setting_number(host, "psf-core", 0, 0, &p->core) < 0 ||
	    setting_number(host, "psf-wing", 0, 0, &p->wing) < 0 ||
	    setting_choice(host, "psf-box", box, 2, &p->adaptive) < 0 ||
	    setting_number(host, "psf-box-noise", 0, 1, &p->box_noise) < 0 ||
	    setting_number(host, "psf-box-sigma", 0, 1, &p->sigma) < 0 ||
	    setting_choice(host, "psf-blend", blend, 3, &p->blend) < 0 ||
	    setting_number(host, "psf-cell", 1, 0, &cell) < 0 ||
	    setting_choice(host, "psf-extent", extent, 2, &p->extent) < 0 ||
	    setting_number(host, "psf-extent-noise", 1e-6, 0, &p->extent_noise) < 0 ||
	    setting_number(host, "psf-extent-max", 1, 0, &p->extent_max) < 0 ||
	    setting_number(host, "psf-extent-min", 1, 0, &p->extent_min) < 0 ||
	    setting_number(host, "psf-halo-power", 2.5, 0, &p->halo_power) < 0 ||
	    setting_number(host, "psf-halo-taper", 0, 0, &p->halo_taper) < 0)
		goto fail;
	if (p->extent == EXTENT_NOISE && p->adaptive) {
		host->error(host->ctx, "psf-box=adaptive goes with psf-extent=stips; "
			    "psf-extent=noise sizes every box itself");
		goto fail;
	}
	if (p->extent == EXTENT_NOISE && !(p->sigma > 0)) {
		host->error(host->ctx, "psf-extent: noise needs the noise per pixel: "
			    "--set psf-box-sigma=S, or psf-extent=stips");
		goto fail;
	}
	if (cell != floor(cell) || cell > 4096) {
		host->error(host->ctx, "psf-cell: expected a whole number of pixels up to 4096, not '%s'",
			    setting_value(host, "psf-cell"));
		goto fail;
	}
	p->cell = (int)cell;
	if (p->adaptive && !(p->sigma > 0)) {
		host->error(host->ctx, "psf-box: adaptive needs the noise per pixel: --noise "
			    "with --background or read noise, or --set psf-box-sigma=S");
		goto fail;
	}
	*state = p;
	return 0;
fail:
	free(p);
	return -1;
}

static void point_fini(void *state)
{
	struct point *p = state;

	for (int i = 0; p && i < POLY_SLOTS; i++) {
		free(p->slot[i].plane);
		free(p->slot[i].sat);
		free(p->slot[i].ee);
	}
	if (p && p->extent == EXTENT_NOISE && p->requested > 0)
		p->host->log(p->host->ctx, 1, "point: %.6g of %.6g counts/s (%.3g%%) left beyond "
			     "the drawn radii; %lld of %lld sources with a halo", p->left,
			     p->requested, 100 * p->left / p->requested, p->nhalo, p->npoint);
	for (int s = 0; p && s < 19; s++)
		halo_free(&p->halo[s]);
	free(p);
}

/* The arrays a source reads and their weights times its flux: the four
 * nodes of its position (blend = BLEND_SOURCE), or its cell's blend.
 * Returns how many, or -1. */
static int source_polys(const struct point *p, const struct wfs_source *src, int blend,
			const struct poly *pl[4], double wn[4])
{
	struct wfs_epsf e;
	int nn = 0;

	if (blend != BLEND_SOURCE) {
		if (!(pl[0] = poly_find(p, cell_key(p, src))))
			return p->host->error(p->host->ctx, "ePSF cell not prepared");
		wn[0] = src->flux;
		return 1;
	}
	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	for (int k = 0; k < 4; k++)
		if (e.weight[k] != 0) {
			if (!(pl[nn] = poly_find(p, (uint64_t)(uintptr_t)e.node[k])))
				return p->host->error(p->host->ctx, "ePSF node not prepared");
			wn[nn++] = e.weight[k] * src->flux;
		}
	return nn;
}

/* psf-blend=core: the arrays and weights (times the flux) whose sum is the
 * source's own blend less its cell's, so that cell + this is the blend at
 * the source: the source's nodes with their weights and the cell's with
 * minus theirs, a node in both once (the usual case: the same four).
 * Returns how many (up to 8), or -1. */
static int core_correction(const struct point *p, const struct wfs_source *src,
			   const struct poly *cell, const struct poly *cp[8], double cw[8])
{
	int n = source_polys(p, src, BLEND_SOURCE, cp, cw);

	if (n < 0)
		return -1;
	for (int j = 0; j < 4; j++) {
		uint64_t key = (uint64_t)(uintptr_t)cell->cnode[j];
		int k;

		if (!cell->cnode[j])
			continue;
		for (k = 0; k < n && cp[k]->key != key; k++)
			;
		if (k == n) {
			if (!(cp[n] = poly_find(p, key)))
				return p->host->error(p->host->ctx, "ePSF node not prepared");
			cw[n++] = 0;
		}
		cw[k] -= cell->cweight[j] * src->flux;
	}
	return n;
}

/* The blend a source gets: psf-blend=core draws the 44-pixel class only;
 * the bright classes' boxes (88 and 176 pixels) are blended per source, as
 * their cells would be 4 and 16 times larger (0.6 and 2.3 MB each) for a few
 * sources. */
static int source_blend(const struct point *p, const struct wfs_source *src)
{
	return p->blend == BLEND_CORE && src->psf_class != WFS_PSF_NORMAL ? BLEND_SOURCE : p->blend;
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

/* floor(x) and ceil(x) for |x| < 2^62, without a library call (the
 * plugin's baseline build has no rounding instruction) */
static inline long lfloor(double x)
{
	long i = (long)x;

	return i - (x < i);
}

static inline long lceil(double x)
{
	long i = (long)x;

	return i + (x > i);
}

/* floor(a / b) for b > 0 and any sign of a */
static long floordiv(long a, long b)
{
	return a >= 0 ? a / b : -((-a + b - 1) / b);
}

static void geom_of(const struct poly *q, double x, double y, struct geom *g)
{
	/* sample index of pixel i: centre + o i + base, plus the phase f */
	int o = q->over;
	double tx = -o * x, ty = -o * y;
	long basex = lfloor(tx), basey = lfloor(ty);
	double fx = tx - basex, fy = ty - basey;
	long sx = q->centre + basex - 1, sy = q->centre + basey - 1;
	long mx0 = floordiv(sx, o), rx0 = sx - o * mx0, my0 = floordiv(sy, o), ry0 = sy - o * my0;
	ptrdiff_t m = q->m, w = m + 1;

	g->o = o;
	g->m = m;
	g->bx[0] = 1 - fx;
	g->bx[1] = fx;
	g->by[0] = 1 - fy;
	g->by[1] = fy;
	keys_weights(fx, g->kx);
	keys_weights(fy, g->ky);
	g->an = fx < 0.5 ? 1 : 2;
	g->bn = fy < 0.5 ? 1 : 2;
	/* tap a is sample sx + a: the next phase, or the next plane column
	 * after the last phase */
	for (int a = 0; a < 4; a++) {
		long rx = rx0 + a, mx = mx0, ry = ry0 + a, my = my0;

		for (; rx >= o; rx -= o)
			mx++;
		for (; ry >= o; ry -= o)
			my++;
		g->rx[a] = rx;
		g->mx[a] = mx;
		g->ry[a] = ry;
		g->my[a] = my;
		/* plane (ry o + rx) of m x m, row my + PAD, column mx + PAD */
		g->tx[a] = rx * m * m + mx + PAD;
		g->ty[a] = (ry * o * m + my + PAD) * m;
		g->sx[a] = rx * w * w + mx + PAD;
		g->sy[a] = (ry * o * w + my + PAD) * w;
	}
}

/* Tap (a, b) of q's pixel (i, j). */
static inline const float *tap_at(const struct poly *q, const struct geom *g, int a, int b,
				  long i, long j)
{
	return q->plane + g->tx[a] + g->ty[b] + j * g->m + i;
}

/* The pixels within h of (x, y) along both axes: |i - x| < h, |j - y| < h. */
static struct zone square(double x, double y, double h)
{
	return (struct zone){ lfloor(x - h) + 1, lceil(x + h), lfloor(y - h) + 1, lceil(y + h) };
}

static struct zone meet(struct zone a, struct zone b)
{
	a.x0 = a.x0 > b.x0 ? a.x0 : b.x0;
	a.x1 = a.x1 < b.x1 ? a.x1 : b.x1;
	a.y0 = a.y0 > b.y0 ? a.y0 : b.y0;
	a.y1 = a.y1 < b.y1 ? a.y1 : b.y1;
	return a;
}

static int zone_empty(struct zone z)
{
	return z.x0 >= z.x1 || z.y0 >= z.y1;
}

/* The corners of zone z in a summed-area table (every zone lies in the
 * source's box, and every tap of the box inside its plane). */
struct corners {
	ptrdiff_t c00, c01, c10, c11;
};

static inline struct corners corners_of(const struct geom *g, struct zone z)
{
	ptrdiff_t w = g->m + 1;

	return (struct corners){ z.y0 * w + z.x0, z.y0 * w + z.x1, z.y1 * w + z.x0, z.y1 * w + z.x1 };
}

/* The sum of tap (a, b) of q over the pixels of a zone. */
static inline double tap_sum(const struct poly *q, const struct geom *g, int a, int b,
			     struct corners k)
{
	const float *s = q->sat + g->sx[a] + g->sy[b];

	return ((double)s[k.c11] - s[k.c01]) - ((double)s[k.c10] - s[k.c00]);
}

/* Bilinear interpolation's and Keys' sums of q over the pixels of z. */
static double bil_sum(const struct poly *q, const struct geom *g, struct zone z)
{
	struct corners k = corners_of(g, z);

	if (zone_empty(z))
		return 0;
	return g->by[0] * (g->bx[0] * tap_sum(q, g, 1, 1, k) + g->bx[1] * tap_sum(q, g, 2, 1, k)) +
	       g->by[1] * (g->bx[0] * tap_sum(q, g, 1, 2, k) + g->bx[1] * tap_sum(q, g, 2, 2, k));
}

static double keys_sum(const struct poly *q, const struct geom *g, struct zone z)
{
	struct corners k = corners_of(g, z);
	double s = 0;

	for (int b = 0; b < 4 && !zone_empty(z); b++) {
		double t = 0;

		for (int a = 0; a < 4; a++)
			t += g->kx[a] * tap_sum(q, g, a, b, k);
		s += g->ky[b] * t;
	}
	return s;
}

/* The zones of a draw whose arrays are set: box of half-width half, core,
 * wing square. */
static void zones(const struct point *p, const struct wfs_source *src, int blend, double half,
		  struct draw *d)
{
	double r = p->core;

	geom_of(d->pl[0], src->x, src->y, &d->g);
	d->cell = blend != BLEND_SOURCE;
	d->box = square(src->x, src->y, half);
	d->keys = p->interp != INTERP_BILINEAR;
	if (p->interp == INTERP_BILINEAR && blend != BLEND_CORE)
		r = 0;
	/* the cubic's taps must stay inside the array (bicubic everywhere
	 * reads the planes' zero padding at the box's edge instead) */
	if (p->interp == INTERP_BICUBIC)
		d->core = d->box;
	else if (r > 0 && r * d->g.o + 2 < d->pl[0]->centre)
		d->core = meet(square(src->x, src->y, r), d->box);
	else
		d->core = (struct zone){ 0, 0, 0, 0 };
	/* the nearest sample beyond the wing square (which holds the core):
	 * one array of the faint class only; bright sources are bilinear to
	 * the box's edge */
	if (d->cell && src->psf_class == WFS_PSF_NORMAL && p->wing < half && 2 * half <= KV_COLS &&
	    p->interp != INTERP_BICUBIC)
		d->wing = meet(square(src->x, src->y,
				      zone_empty(d->core) || p->wing > r ? p->wing : r), d->box);
	else
		d->wing = d->box;
}

/* render_one() draws it: one blended cell and a core that fits its buffer */
static int one_array(const struct draw *d)
{
	return d->cell && d->core.x1 - d->core.x0 <= KV_COLS && d->core.y1 - d->core.y0 <= KV_ROWS;
}

/* psf-blend=core's correction from the cell's own node copies and the
 * source's node weights w (aux[4..7], in the cell's node order). */
static void cell_correction(const struct poly *cell, double flux, const double w[4],
			    struct draw *d)
{
	d->ncor = 0;
	for (int k = 0; k < 4; k++)
		if (cell->cpoly[k]) {
			d->cp[d->ncor] = cell->cpoly[k];
			d->cw[d->ncor++] = flux * w[k] - flux * cell->cweight[k];
		}
}

/* How src is drawn in render(), its box and what prepare() found in aux:
 * which arrays, and the zones.  Returns 0 or -1. */
static int plan(const struct point *p, const struct wfs_source *src, struct draw *d)
{
	int blend = source_blend(p, src);

	d->ncor = 0;
	if (blend != BLEND_SOURCE && !isnan(src->aux[4])) {
		/* the cell found by prepare(), and its nodes are the source's */
		d->nn = 1;
		d->pl[0] = &p->slot[(size_t)src->aux[3]];
		d->wn[0] = src->flux;
		if (blend == BLEND_CORE)
			cell_correction(d->pl[0], src->flux, src->aux + 4, d);
	} else {
		if ((d->nn = source_polys(p, src, blend, d->pl, d->wn)) < 0)
			return -1;
		if (blend == BLEND_CORE &&
		    (d->ncor = core_correction(p, src, d->pl[0], d->cp, d->cw)) < 0)
			return -1;
	}
	zones(p, src, blend, src->aux[0], d);
	return 0;
}

/*
 * The factor on everything outside the core.  With T the bilinear sum of
 * the source's blend over the box (its enclosed fraction times the flux),
 * K what the core draws and U what the rest draws before scaling,
 *
 *   f = (T - K) / U
 *
 * makes the total T.  One array (psf-blend=cell or core, render_one): U is
 * the array's bilinear sum over the wing square less the core plus its
 * nearest samples beyond; render_one() sums K from the core it draws.
 * Several arrays: U is their bilinear sum outside the core, and K the
 * core's Keys sum, both from the tables here.  Where less than 1% of the
 * light lies outside the core (an adaptive box barely wider than the core,
 * or the cubic everywhere) f is 1: the kernels' totals then agree to ~1e-4.
 */
static double flux_factor(double t, double k, double u)
{
	return u > 0.01 * fabs(t) && isfinite(t - k) ? (t - k) / u : 1;
}

/*
 * prepare(): the arrays the source reads (polyphase copies of its grid
 * nodes and of its cell's blend, made once and kept), its box and what its
 * flux factor needs, in aux:
 *
 *   aux[0]     the box's half-width, pixels
 *   aux[1..2]  T and U (render_one), or f and 0 (several arrays)
 *   aux[3]     the slot of the source's cell
 *   aux[4..7]  the source's weights of its cell's nodes (psf-blend=core),
 *              or NaN when render() must look the arrays up itself
 */
static int fine_prepare(struct point *p, struct wfs_source *src, double cap)
{
	struct wfs_epsf e;
	struct draw d;
	const struct poly *node[4];
	double w[4], half, t = 0;
	struct poly *cell = NULL;
	int nn = 0, blend = source_blend(p, src), same = blend == BLEND_CORE;

	if (blend != BLEND_SOURCE && !(cell = cell_add(p, src)))
		return -1;
	src->aux[4] = src->aux[5] = src->aux[6] = src->aux[7] = 0;
	if (blend != BLEND_CELL) {
		/* the source's nodes: the cell's copies when the cell was
		 * blended from them (their weights go to aux[4..7] in the
		 * cell's order), else copies made here */
		if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
			return -1;
		for (int k = 0; k < 4; k++) {
			const struct poly *q = NULL;

			if (e.weight[k] == 0)
				continue;
			for (int j = 0; cell && j < 4 && !q; j++)
				if (cell->cnode[j] == e.node[k] && cell->cpoly[j]) {
					q = cell->cpoly[j];
					src->aux[4 + j] += e.weight[k];
				}
			if (!q) {
				same = 0;
				if (!(q = poly_add(p, (uint64_t)(uintptr_t)e.node[k], e.node[k], e.n, e.over)))
					return -1;
			}
			node[nn] = q;
			w[nn++] = e.weight[k];
		}
	}
	if (!same)
		src->aux[4] = NAN;
	/* the arrays render() reads */
	d.nn = 0;
	if (cell) {
		src->aux[3] = (double)(cell - p->slot);
		d.pl[d.nn] = cell;
		d.wn[d.nn++] = src->flux;
	} else
		for (int k = 0; k < nn; k++) {
			d.pl[d.nn] = node[k];
			d.wn[d.nn++] = w[k] * src->flux;
		}
	if (d.nn == 0)
		return p->host->error(p->host->ctx, "no ePSF node with a weight");
	half = (double)d.pl[0]->centre / d.pl[0]->over;
	if (p->adaptive) {
		/* the smallest half-width whose left-out light is below
		 * box_noise times the noise summed over the box, for the
		 * blend at the source (at the cell's, psf-blend=cell) */
		int h, H = d.pl[0]->nee;

		for (h = 1; h < H; h++) {
			double out = 0;

			if (blend == BLEND_CELL)
				out = src->flux * (cell->ee[H] - cell->ee[h]);
			for (int k = 0; k < nn; k++)
				out += w[k] * src->flux * (node[k]->ee[H] - node[k]->ee[h]);
			if (fabs(out) <= p->box_noise * p->sigma * 2 * h)
				break;
		}
		if (h < half)
			half = h;
	}
	if (cap > 0 && cap < half)
		half = cap;
	src->aux[0] = half;
	zones(p, src, blend, half, &d);
	/* T: the bilinear sum over the box of the blend at the source (of
	 * the cell's, psf-blend=cell) */
	if (blend == BLEND_CELL)
		t = src->flux * bil_sum(cell, &d.g, d.box);
	for (int k = 0; k < nn; k++)
		t += w[k] * src->flux * bil_sum(node[k], &d.g, d.box);
	if (one_array(&d)) {
		const struct geom *g = &d.g;

		src->aux[1] = t;
		src->aux[2] = src->flux * (tap_sum(cell, g, g->an, g->bn, corners_of(g, d.box)) -
					   (zone_empty(d.wing) ? 0 :
					    tap_sum(cell, g, g->an, g->bn, corners_of(g, d.wing))) +
					   bil_sum(cell, g, d.wing) - bil_sum(cell, g, d.core));
	} else {
		double k = 0, u = t;

		for (int i = 0; i < d.nn; i++) {
			double b = bil_sum(d.pl[i], &d.g, d.core);

			u -= d.wn[i] * b;
			k += d.wn[i] * (d.keys ? keys_sum(d.pl[i], &d.g, d.core) : b);
		}
		src->aux[1] = flux_factor(t, k, u);
		src->aux[2] = 0;
	}
	return 0;
}

/* The halo of SCA sca, set up on first use (main thread). */
static const struct halo *halo_of(struct point *p, const struct wfs_source *src)
{
	struct halo *h = &p->halo[src->sca];
	struct wfs_epsf e;

	if (h->env)
		return h;
	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, WFS_PSF_HALO, &e) < 0)
		return NULL;
	if (halo_setup(h, e.node[0], e.n, e.over, p->halo_power, p->halo_taper) < 0) {
		p->host->error(p->host->ctx, "halo of SCA %d: %d samples at %d per pixel are "
			       "too few (or out of memory)", src->sca, e.n, e.over);
		return NULL;
	}
	return h;
}

/*
 * The core's scale for SCA sca and the source's class: the halo's light in
 * the class's box over the core's own (the cores are normalised within
 * their boxes, so they hold the light beyond them too), both for a source
 * on a pixel centre, from the first node of the source's position.
 */
static double core_scale(struct point *p, const struct wfs_source *src, const struct halo *h)
{
	double *c = &p->cfac[src->sca][src->psf_class];
	struct wfs_epsf e;

	if (*c > 0)
		return *c;
	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
		return -1;
	double fine = 0, far = 0;
	int half = e.centre / e.over;

	for (int j = -half; j <= half; j++)
		for (int i = -half; i <= half; i++) {
			if (abs(i) == half || abs(j) == half)
				continue;       /* the box: |i - x| < half */
			fine += e.node[0][(size_t)(e.centre + e.over * j) * e.n + e.centre + e.over * i];
			far += h->s * h->a[(size_t)(h->c + h->over * j) * h->n + h->c + h->over * i];
		}
	*c = fine > 0 && far > 0 ? far / fine : 1;
	return *c;
}

/* The source's halo radius (0: none) and its box's half-width from aux[0]. */
static inline double halo_radius_of(const struct wfs_source *src)
{
	return floor(src->aux[0] / HALO_PACK);
}

static inline double box_half_of(const struct wfs_source *src)
{
	return src->aux[0] - HALO_PACK * halo_radius_of(src);
}

/*
 * prepare(), psf-extent=noise: the radius r beyond which the source's model
 * stays below psf-extent-noise of the noise per pixel (the halo's
 * envelope, spikes included); the core's box is the class's, or the
 * square of half-width r when that is smaller; the halo draws the disc of
 * radius r outside the box.  The core is scaled to the halo's light in its
 * box (core_scale).
 */
static int point_prepare(void *state, struct wfs_source *src)
{
	struct point *p = state;
	const struct halo *h;
	struct wfs_source fs;
	double r, half, c, fl = src->flux;

	if (p->extent == EXTENT_STIPS)
		return fine_prepare(p, src, 0);
	if (!(h = halo_of(p, src)) || (c = core_scale(p, src, h)) < 0)
		return -1;
	r = fl > 0 ? halo_radius(h, p->extent_noise * p->sigma / fl, p->extent_max) : 1;
	if (r < 1)
		r = 1;
	fs = *src;
	fs.flux = c * fl;
	/* the box: the class's unless psf-extent-min lets it shrink toward r */
	if (fine_prepare(p, &fs, p->extent_min > 0 ? fmax(r, p->extent_min) : 0) < 0)
		return -1;
	memcpy(src->aux, fs.aux, sizeof(src->aux));
	half = fs.aux[0];
	/* no halo when the box holds everything above the level; the core's
	 * own values at the box's edge may stand a few per cent above the
	 * halo's (it is sampled twice as finely), so the halo takes over
	 * once the envelope there reaches half the level */
	if (r <= half && fl * halo_envelope(h, half - 1) < 0.5 * p->extent_noise * p->sigma)
		r = 0;
	else if (r <= half)
		r = half + 1;
	src->aux[0] = half + HALO_PACK * r;
	p->requested += fabs(fl);
	p->npoint++;
	p->nhalo += r > 0;
	p->left += fabs(fl) * (r > 0 ? halo_beyond(h, r) : halo_beyond(h, half - 0.5));
	return 0;
}

static int point_footprint(void *state, const struct wfs_source *src,
			   struct wfs_box *box)
{
	/* pixels i with x - half < i < x + half, or within the halo's radius */
	double half = box_half_of(src), r = halo_radius_of(src);
	struct zone z = square(src->x, src->y, r + 1 > half ? r + 1 : half);

	box->x0 = (int)z.x0;
	box->x1 = (int)z.x1;
	box->y0 = (int)z.y0;
	box->y1 = (int)z.y1;
	return 0;
}

/* One array (psf-blend=cell or core) whose core fits the kv buffer: the
 * core's pixels first (Keys' cubic of the array, or bilinear, plus
 * psf-blend=core's correction), in float, 8 columns at a time over the
 * core's columns, and all its rows, inside the window or not, so that their
 * sum K, and with prepare()'s T and U the flux factor, is the same in every
 * window of the source; then the whole window in one call. */
static inline __attribute__((always_inline)) int render_one(const struct point *p,
							    const struct draw *d, double t,
							    double u, const struct wfs_window *win)
{
	const struct poly *q = d->pl[0];
	const struct geom *g = &d->g;
	long X = win->x0, Y = win->y0;
	ptrdiff_t m = q->m;
	double fl = d->wn[0];
	int empty = zone_empty(d->core);
	int ka = empty ? 0 : (int)(d->core.x0 - X), kb = empty ? 0 : (int)(d->core.x1 - X);
	int jc = empty ? 0 : (int)(d->core.y0 - Y), nc = empty ? 0 : (int)(d->core.y1 - d->core.y0);
	float kvb[KV_ROWS * KV_PITCH + 8];
	double k = 0, f;
	struct rows_args ra = {
		{ tap_at(q, g, 1, 1, X, Y), tap_at(q, g, 2, 1, X, Y),
		  tap_at(q, g, 1, 2, X, Y), tap_at(q, g, 2, 2, X, Y) },
		tap_at(q, g, g->an, g->bn, X, Y), m, { 0 }, 0,
		(int)(d->wing.y0 - Y), (int)(d->wing.y1 - d->wing.y0),
		(int)(d->wing.x0 - X), (int)(d->wing.x1 - X),
		jc, nc, ka, kb, kvb
	};

	if (nc > 0) {
		struct core_args ca = { .ncor = d->ncor, .keys = d->keys, .nc = nc,
					.nk = kb - ka, .m = m };
		ptrdiff_t at = (ptrdiff_t)d->core.y0 * m + d->core.x0;

		ca.base = q->plane + at;
		for (int a = 0; a < 4; a++) {
			ca.tx[a] = g->tx[a];
			ca.ty[a] = g->ty[a];
			ca.kx[a] = (float)g->kx[a];
			ca.ky[a] = (float)(g->ky[a] * fl);
			ca.bw[a] = (float)(fl * g->by[a >> 1] * g->bx[a & 1]);
		}
		for (int c = 0; c < d->ncor; c++) {
			ca.cbase[c] = d->cp[c]->plane + at;
			for (int t = 0; t < 4; t++)
				ca.cw[4 * c + t] = (float)(d->cw[c] * g->by[t >> 1] * g->bx[t & 1]);
		}
		k = p->core_rows(&ca, kvb);
	}
	f = flux_factor(t, k, u);
	for (int a = 0; a < 4; a++)
		ra.w[a] = (float)(f * fl * g->by[a >> 1] * g->bx[a & 1]);
	ra.wn = (float)(f * fl);
	p->sum_rows(win->pix, win->stride, win->nx, win->ny, &ra);
	return 0;
}

/* Several arrays (psf-blend=source, and the bright classes under the
 * default), or a cell's blend with a core too wide for render_one (the
 * cubic everywhere in a bright box under psf-blend=cell): row by row, the
 * bilinear sum of every array's 4 streams times f into a float row, then
 * Keys' cubic over the core's columns, in double, from the same samples.
 * No psf-blend=core correction comes here (a faint box's core always fits
 * render_one), and a core here is always cubic (a bilinear one is only
 * psf-blend=core's). */
static inline __attribute__((always_inline)) int render_many(const struct draw *d, double f,
		       const struct wfs_window *win)
{
	const struct geom *g = &d->g;
	int nn = d->nn;
	long X = win->x0, Y = win->y0;
	float wt[16];
	const float *tap0[64];  /* [array][y tap][x tap] at the window's first pixel */
	float acc[MAX_ROW + 8];
	double dv[MAX_ROW + 4], tv[MAX_ROW + 4];
	int core = !zone_empty(d->core);
	ptrdiff_t m = d->pl[0]->m;

	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 2; b++)
			for (int a = 0; a < 2; a++)
				wt[(k * 2 + b) * 2 + a] = (float)(f * d->wn[k] * g->by[b] * g->bx[a]);
	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 4; b++)
			for (int a = 0; a < 4; a++)
				tap0[(k * 4 + b) * 4 + a] = tap_at(d->pl[k], g, a, b, X, Y);
	for (int j = 0; j < win->ny; j++) {
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		ptrdiff_t step = (ptrdiff_t)j * m;
		long jj = Y + j;
		/* the core's columns on this row, [ca, cb) of the window */
		long ca = 0, cb = 0;

		if (core && jj >= d->core.y0 && jj < d->core.y1) {
			ca = d->core.x0 - X < 0 ? 0 : d->core.x0 - X;
			cb = d->core.x1 - X > win->nx ? win->nx : d->core.x1 - X;
		}
		for (int i0 = 0; i0 < win->nx; i0 += MAX_ROW) {
			int len = win->nx - i0 < MAX_ROW ? win->nx - i0 : MAX_ROW;
			long ia = ca - i0, ib = cb - i0;

			if (ia < 0)
				ia = 0;
			if (ib > len)
				ib = len;
			for (int k = 0; k < nn; k++) {
				const float *const *t = tap0 + 16 * k;
				const float *s0 = t[5] + step + i0, *s1 = t[6] + step + i0;
				const float *s2 = t[9] + step + i0, *s3 = t[10] + step + i0;
				v8f w0 = SPLAT(wt[4 * k]), w1 = SPLAT(wt[4 * k + 1]);
				v8f w2 = SPLAT(wt[4 * k + 2]), w3 = SPLAT(wt[4 * k + 3]);

				for (int i = 0; i < len; i += 8) {
					v8f v = { 0 };

					if (k > 0)
						v = *(const v8f *)(acc + i);
					v += w0 * *(const v8f *)(s0 + i);
					v += w1 * *(const v8f *)(s1 + i);
					v += w2 * *(const v8f *)(s2 + i);
					v += w3 * *(const v8f *)(s3 + i);
					*(v8f *)(acc + i) = v;
				}
			}
			/* the core: Keys' cubic from the same samples, 4 pixels
			 * at a time, past the run's end into the planes' slack;
			 * only the run is kept */
			if (ia < ib) {
				int cn = (int)(ib - ia);

				for (int i = 0; i < cn; i += 4)
					*(v4d *)(dv + i) = (v4d){ 0 };
				for (int k = 0; k < nn; k++) {
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(tv + i) = (v4d){ 0 };
					for (int b = 0; b < 4; b++) {
						const float *const *t = tap0 + (k * 4 + b) * 4;
						const float *t0 = t[0] + step + i0 + ia, *t1 = t[1] + step + i0 + ia;
						const float *t2 = t[2] + step + i0 + ia, *t3 = t[3] + step + i0 + ia;
						v4d c0 = SPLAT4(g->kx[0]), c1 = SPLAT4(g->kx[1]);
						v4d c2 = SPLAT4(g->kx[2]), c3 = SPLAT4(g->kx[3]);
						v4d cb4 = SPLAT4(g->ky[b]);

						for (int i = 0; i < cn; i += 4)
							*(v4d *)(tv + i) += cb4 * (c0 * TO_V4D(t0 + i) + c1 * TO_V4D(t1 + i) +
										   c2 * TO_V4D(t2 + i) + c3 * TO_V4D(t3 + i));
					}
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(dv + i) += SPLAT4(d->wn[k]) * *(v4d *)(tv + i);
				}
				for (int i = 0; i < cn; i++)
					acc[ia + i] = (float)dv[i];
			}
			for (int i = 0; i < len; i++)
				row[i0 + i] += acc[i];
		}
	}
	return 0;
}

/* Built twice, for AVX2 and for any x86-64, and chosen at load time: the
 * core's sums run 8 floats wide where the processor allows. */
/* Not under the sanitizers: the clones' resolver runs while the plugin is
 * being relocated, before the instrumentation it calls can be reached (a
 * ThreadSanitizer build jumped to a bad address in dlopen). */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
	!defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
__attribute__((target_clones("avx2,fma", "default")))
#endif
static int fine_render(struct point *p, const struct wfs_source *src,
		       const struct wfs_window *win)
{
	struct draw d;
	const struct geom *g = &d.g;
	int m;

	if (plan(p, src, &d) < 0)
		return -1;
	m = d.pl[0]->m;
	if (win->x0 + g->mx[0] + PAD < 0 || win->x0 + win->nx + g->mx[3] + PAD > m ||
	    win->y0 + g->my[0] + PAD < 0 || win->y0 + win->ny + g->my[3] + PAD > m)
		return p->host->error(p->host->ctx, "window outside the source's box");
	if (one_array(&d))
		return render_one(p, &d, src->aux[1], src->aux[2], win);
	if (d.ncor || (!zone_empty(d.core) && !d.keys))
		return p->host->error(p->host->ctx, "no drawing for this blend and core");
	return render_many(&d, src->aux[1], win);
}

/*
 * The halo of a source: every pixel of the window within radius r of it and
 * outside its box (the zone box), flux times the halo model.  Inside the
 * array's disc less the taper, the bilinear read with one set of weights
 * for the source (its pixels share one sub-sample phase); elsewhere
 * halo_value().
 */
static void halo_render(const struct halo *h, double flux, double x, double y, double r,
			struct zone box, const struct wfs_window *win)
{
	double ux = h->c + h->over * (win->x0 - x), uy = h->c + h->over * (win->y0 - y);
	long iu = (long)floor(ux), iv = (long)floor(uy);
	double fu = ux - iu, fv = uy - iv;
	double w00 = flux * h->s * (1 - fu) * (1 - fv), w10 = flux * h->s * fu * (1 - fv);
	double w01 = flux * h->s * (1 - fu) * fv, w11 = flux * h->s * fu * fv;
	double rin = h->R - h->taper, rin2 = rin * rin, r2 = r * r, R2 = h->R * h->R;
	long n = h->n, o = h->over;

	for (int j = 0; j < win->ny; j++) {
		double dy = win->y0 + j - y, dy2 = dy * dy;
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		long jj = win->y0 + j;
		int inbox = jj >= box.y0 && jj < box.y1;
		double span, lo, hi;

		if (dy2 > r2)
			continue;
		span = sqrt(r2 - dy2);
		lo = ceil(x - span) - win->x0;
		hi = floor(x + span) - win->x0;
		if (lo < 0)
			lo = 0;
		if (hi > win->nx - 1)
			hi = win->nx - 1;
		for (int i = (int)lo; i <= (int)hi; i++) {
			long ii = win->x0 + i;
			double dx = ii - x, d2 = dx * dx + dy2;

			if (inbox && ii >= box.x0 && ii < box.x1) {
				i = (int)(box.x1 - win->x0) - 1;
				continue;
			}
			if (d2 < rin2) {
				const float *q = h->a + (iv + o * j) * n + iu + o * i;

				row[i] += w00 * q[0] + w10 * q[1] + w01 * q[n] + w11 * q[n + 1];
			} else if (d2 >= R2)
				row[i] += flux * halo_tail(h, dx, dy);
			else
				row[i] += flux * halo_value(h, dx, dy);
		}
	}
}

/* Built twice, for AVX2 and for any x86-64, and chosen at load time: the
 * core's sums run 8 floats wide where the processor allows. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
__attribute__((target_clones("avx2,fma", "default")))
#endif
static int point_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct point *p = state;
	struct wfs_source fs;
	struct wfs_window sub;
	struct zone box, w;
	double r, half;

	if (p->extent == EXTENT_STIPS)
		return fine_render(p, src, win);
	fs = *src;
	r = halo_radius_of(src);
	half = box_half_of(src);
	fs.aux[0] = half;
	fs.flux = src->flux * p->cfac[src->sca][src->psf_class];
	box = square(src->x, src->y, half);
	w = meet(box, (struct zone){ win->x0, win->x0 + win->nx, win->y0, win->y0 + win->ny });
	if (!zone_empty(w)) {
		sub.pix = win->pix + (w.y0 - win->y0) * win->stride + (w.x0 - win->x0);
		sub.stride = win->stride;
		sub.x0 = (int)w.x0;
		sub.y0 = (int)w.y0;
		sub.nx = (int)(w.x1 - w.x0);
		sub.ny = (int)(w.y1 - w.y0);
		if (fine_render(p, &fs, &sub) < 0)
			return -1;
	}
	if (r > 0)
		halo_render(&p->halo[src->sca], src->flux, src->x, src->y, r, box, win);
	return 0;
}

/*
 * How far a source's light can reach, for the host's culling: the
 * extra-bright class's half-width (STIPS's 176-pixel box), or with
 * psf-extent=noise the radius where the source's halo sinks below the
 * drawing level, when that is farther.  Called on the host's thread, as
 * prepare() is, so the halo may be set up here.
 */
static int point_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct point *p = state;
	const struct halo *h;
	double r;

	*pixels = 88;
	if (p->extent == EXTENT_STIPS || !(src->flux > 0))
		return 0;
	if (!(h = halo_of(p, src)))
		return -1;
	r = halo_radius(h, p->extent_noise * p->sigma / src->flux, p->extent_max) + 1;
	if (r > *pixels)
		*pixels = r;
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
	.prepare = point_prepare,
	.footprint = point_footprint,
	.render = point_render,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = point_settings,
	.nsettings = NSETTINGS,
	.reach = point_reach,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &point_model : NULL;
}
