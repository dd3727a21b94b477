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
 * Blended per source, a row is a weighted sum of 16 contiguous rows (4
 * nodes x 2 x 2 taps) and the Keys core reads 4 x 4 taps of 4 nodes: about
 * 78 000 instructions per faint star, 7.7x the floor of adding a
 * precomputed stamp (contrib/bench/floor.c, BENCHMARKS.md).  So by default
 * (psf-blend=core) the four nodes are blended once per 512-pixel cell, at
 * its centre, into one polyphase array, and a source reads that: 4 streams
 * outside its core.  Blending at the cell's centre instead of the source
 * misplaces the PSF's change with position by up to 362 pixels, first
 * order: 2e-2 of the peak on the bench's grid (psf-blend=cell alone).
 * That change lives in the core, so there the source's own blend is
 * restored: the core's pixels are Keys' cubic of the cell plus the
 * bilinear difference (source's blend - cell's) from the nodes, a small
 * field whose interpolation error is small.  Outside the core the cell's
 * blend is scaled by one factor per source so that the total is the
 * source's (core_box_sums' comment).  The core is drawn first into a
 * small float buffer, then every row of the window in one call, straight
 * into the tile (sum_rows_avx2).  The copies and blends are made in
 * footprint(), which the host calls in its main thread before render()
 * sees the source, so render() neither allocates nor locks.
 *
 * Approximations, each a setting (wfiscene(1) POINT SOURCES has their
 * measured error and cost):
 *
 *   psf-interp=bilinear|core|bicubic  Keys' cubic nowhere, within psf-core
 *                                     pixels (default 4), or everywhere
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
 *                                     cell everywhere (4 streams)
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"

/* Polyphase copies of the ePSF nodes, found by the node's address (the
 * host's arrays stay put until fini), and of blended cells, found by an odd
 * key (node addresses are even).  Open addressing, never removed. */
#define POLY_SLOTS 8192
#define MAX_ROW 1024            /* widest window row handled in one pass */
/* Planes carry PAD zero samples on each side, so that the Keys taps (one
 * sample before, two after) of any pixel inside the box stay inside the
 * plane and read zeros beyond the ePSF, and no pixel needs a range test. */
#define PAD 2

/* Eight floats, loaded and stored unaligned: the row sums below are written
 * with GCC's vector extension so that a 44-pixel row is 6 steps with no
 * alignment prologue or scalar tail (rows are summed to a multiple of 8
 * into acc[]; the planes carry VSLACK floats so the last step can read on). */
typedef float v8f __attribute__((vector_size(32), aligned(4), may_alias));
#define VSLACK 8

typedef float v4f __attribute__((vector_size(16), aligned(4), may_alias));
typedef double v4d __attribute__((vector_size(32), aligned(8), may_alias));
#define SPLAT4(f) ((v4d){ (f), (f), (f), (f) })
#define TO_V4D(p) __builtin_convertvector(*(const v4f *)(p), v4d)
#define SPLAT(f) ((v8f){ (f), (f), (f), (f), (f), (f), (f), (f) })
typedef int32_t v8i __attribute__((vector_size(32)));
#define LANES ((v8i){ 0, 1, 2, 3, 4, 5, 6, 7 })

struct poly {
	uint64_t key;
	int n, over, centre, m; /* m = samples per phase plane side, padded */
	float *plane;           /* over * over planes of m x m */
	int nee;                /* centre / over */
	double *ee;             /* ee[h], h = 1..nee: see ee_table() */
	double *psum;           /* psum[plane]: the sum of each phase plane */
	/* a blended cell: the nodes and weights it was blended from */
	const float *cnode[4];
	double cweight[4];
};

/* psf-blend=core: the factor on the cell's blend outside the core that
 * places the flux of the source's own blend.  The core (Keys' cubic of the
 * cell plus the bilinear difference d = source's blend - cell's) holds
 * what the source's blend puts there; outside it the cell's blend alone
 * would miss d's part, which is not small where the PSF's core and wings
 * trade light with position (a core that narrows feeds the wings: 2.5e-3
 * of the flux on t3004's grid).  With B the bilinear sums over the box and
 * C over the core's pixels,
 *
 *   f = 1 + (B(d) - C(d)) / (B(cell) - C(cell))
 *
 * makes the total that of the source's blend, up to the difference of
 * Keys' and the bilinear kernel on d in the core (second order).  B comes
 * from the planes' sums (the fixed box reads each bilinear phase whole but
 * for the ePSF's outermost sample row or column: a part of d far below
 * 1e-6 of the flux; an adaptive box is taken as whole too), C from the
 * pixels of the whole core, whichever window is drawn, so that every
 * window of a source gets the same f. */
static void core_box_sums(const struct poly *cell, const struct poly *const cp[],
			  const double cw[], int ncor, double flux, const long rx[4],
			  const long ry[4], const double bx[2], const double by[2],
			  double *bc, double *bd)
{
	int o = cell->over;

	*bc = *bd = 0;
	for (int t = 0; t < 4; t++) {
		int b = t >> 1, a = t & 1, pl = (int)(ry[b + 1] * o + rx[a + 1]);

		*bc += flux * by[b] * bx[a] * cell->psum[pl];
		for (int c = 0; c < ncor; c++)
			*bd += cw[c] * by[b] * bx[a] * cp[c]->psum[pl];
	}
}

/* C(cell) and C(d) one pixel at a time, for the windows render() does not
 * draw in one call (a psf-core wider than KV_COLS / 2). */
static void core_disk_sums(const struct poly *cell, const struct poly *const cp[],
			   const double cw[], int ncor, double flux, double x, double y,
			   double core2, const long rx[4], const long mx[4], const long ry[4],
			   const long my[4], const double bx[2], const double by[2],
			   double *cc, double *cd)
{
	int o = cell->over, m = cell->m;
	double r = core2 >= 0 ? sqrt(core2) : -1;

	*cc = *cd = 0;
	for (long j = (long)ceil(y - r); r >= 0 && j <= (long)floor(y + r); j++) {
		double dy = j - y;
		long ca = (long)floor(x - r), cb = (long)ceil(x + r) + 1;

		/* the run [ca, cb) by the exact test, as render() takes it */
		while (ca < cb && (ca - x) * (ca - x) + dy * dy > core2)
			ca++;
		while (cb > ca && (cb - 1 - x) * (cb - 1 - x) + dy * dy > core2)
			cb--;
		for (int t = 0; t < 4 && ca < cb; t++) {
			int b = t >> 1, a = t & 1;
			size_t off = (size_t)(ry[b + 1] * o + rx[a + 1]) * m * m +
				     (size_t)(j + my[b + 1] + PAD) * m + (size_t)(mx[a + 1] + PAD);
			double s = 0;

			for (long i = ca; i < cb; i++)
				s += cell->plane[off + i];
			*cc += flux * by[b] * bx[a] * s;
			for (int c = 0; c < ncor; c++) {
				s = 0;
				for (long i = ca; i < cb; i++)
					s += cp[c]->plane[off + i];
				*cd += cw[c] * by[b] * bx[a] * s;
			}
		}
	}
}

/* One array (psf-blend=cell or core), the whole window, straight into the
 * tile: for each row j and pixel i < nx,
 *
 *   pix[j stride + i] += ((w0 s0[j m + i] + w1 s1[..]) + w2 s2[..]) + w3 s3[..]
 *
 * summed in float; on the core rows jc <= j < jc + nc, over the row's run
 * ia <= i < ib, kv[] replaces the sum.  Two
 * builds with the same operations per pixel in the same order, so the same
 * bits: 8 pixels at a time with AVX2 (reading on into the planes' slack and
 * into kv's margins, the lanes outside the row or the run masked), and one
 * by one.  The float sums are converted and added in registers (through a
 * row buffer the loads of a just-stored row cost as much as the sums, and
 * GCC's vector extension converted one lane at a time). */
#define KV_ROWS 48              /* core rows and columns the fast path takes: */
#define KV_COLS 48              /* the 44-pixel box, so psf-interp=bicubic too */
#define KV_PITCH (KV_COLS + 16) /* a core row of kv: 8 floats margin, then column ka */

struct rows_args {
	const float *s[4];      /* the bilinear streams at the window's first row */
	ptrdiff_t m;            /* floats from one plane row to the next */
	float w[4];
	int jc, nc;             /* the core's rows, [jc, jc + nc) of the window */
	const int *ia, *ib;     /* their runs, [ia[r], ib[r]) */
	const float *kv;        /* pixel i of core row r: kv[r * KV_PITCH + 8 + i - ka] */
	int ka;
};

static void sum_rows_plain(double *pix, ptrdiff_t stride, int nx, int ny,
			   const struct rows_args *r)
{
	for (int j = 0; j < ny; j++) {
		const float *s0 = r->s[0] + j * r->m, *s1 = r->s[1] + j * r->m;
		const float *s2 = r->s[2] + j * r->m, *s3 = r->s[3] + j * r->m;
		double *out = pix + j * stride;
		int c = j - r->jc, core = c >= 0 && c < r->nc;
		const float *kv = core ? r->kv + c * KV_PITCH : NULL;

		for (int i = 0; i < nx; i++) {
			float v = r->w[0] * s0[i] + r->w[1] * s1[i] + r->w[2] * s2[i] + r->w[3] * s3[i];

			if (core && i >= r->ia[c] && i < r->ib[c])
				v = kv[8 + i - r->ka];
			out[i] += v;
		}
	}
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HAVE_ROWS_AVX2 1

__attribute__((target("avx2"))) static void sum_rows_avx2(double *pix, ptrdiff_t stride, int nx,
							  int ny, const struct rows_args *r)
{
	__m256 w0 = _mm256_set1_ps(r->w[0]), w1 = _mm256_set1_ps(r->w[1]);
	__m256 w2 = _mm256_set1_ps(r->w[2]), w3 = _mm256_set1_ps(r->w[3]);
	__m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);

	for (int j = 0; j < ny; j++) {
		const float *s0 = r->s[0] + j * r->m, *s1 = r->s[1] + j * r->m;
		const float *s2 = r->s[2] + j * r->m, *s3 = r->s[3] + j * r->m;
		double *out = pix + j * stride;
		int c = j - r->jc, core = c >= 0 && c < r->nc;
		int ia = core ? r->ia[c] : 0, ib = core ? r->ib[c] : 0;
		const float *kv = core ? r->kv + c * KV_PITCH : NULL;
		__m256i va = _mm256_set1_epi32(ia - 1), vb = _mm256_set1_epi32(ib);
		int i;

		for (i = 0; i < nx; i += 8) {
			__m256 v = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(
				_mm256_mul_ps(w0, _mm256_loadu_ps(s0 + i)), _mm256_mul_ps(w1, _mm256_loadu_ps(s1 + i))),
				_mm256_mul_ps(w2, _mm256_loadu_ps(s2 + i))), _mm256_mul_ps(w3, _mm256_loadu_ps(s3 + i)));
			__m256d lo, hi;

			if (i < ib && i + 8 > ia) {
				__m256i lane = _mm256_add_epi32(lanes, _mm256_set1_epi32(i));
				__m256 in = _mm256_castsi256_ps(_mm256_and_si256(_mm256_cmpgt_epi32(lane, va),
										 _mm256_cmpgt_epi32(vb, lane)));
				__m256 k = _mm256_loadu_ps(kv + (8 + i - r->ka));

				v = _mm256_blendv_ps(v, k, in);
			}
			lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
			hi = _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1));
			if (i + 8 <= nx) {
				_mm256_storeu_pd(out + i, _mm256_add_pd(_mm256_loadu_pd(out + i), lo));
				_mm256_storeu_pd(out + i + 4, _mm256_add_pd(_mm256_loadu_pd(out + i + 4), hi));
				continue;
			}
			if (i + 4 <= nx) {
				_mm256_storeu_pd(out + i, _mm256_add_pd(_mm256_loadu_pd(out + i), lo));
				lo = hi;
				i += 4;
			}
			{
				double t[4];

				_mm256_storeu_pd(t, lo);
				for (int l = 0; i + l < nx; l++)
					out[i + l] += t[l];
			}
		}
	}
}
#endif

enum { INTERP_BILINEAR, INTERP_CORE, INTERP_BICUBIC };
enum { BLEND_SOURCE, BLEND_CELL, BLEND_CORE };

struct point {
	const struct wfs_host *host;
	int interp;             /* psf-interp */
	double core;            /* radius of the bicubic core, pixels */
	int adaptive;           /* psf-box=adaptive */
	double box_noise;       /* psf-box-noise: fraction of the box's noise */
	double sigma;           /* noise per pixel, counts/s (psf-box-sigma) */
	int blend;              /* psf-blend */
	int cell;               /* psf-cell: side of a blended cell, pixels */
	void (*sum_rows)(double *, ptrdiff_t, int, int, const struct rows_args *);
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

/* Make the polyphase copy of an n x n ePSF array under key.  Main thread
 * only (footprint). */
static int poly_add(struct point *p, uint64_t key, const float *node, int n, int over)
{
	int m = (n + over - 1) / over + 2 * PAD + 1;
	size_t i = poly_hash(key), k;
	struct poly q = { .key = key, .n = n, .over = over, .centre = (n - 1) / 2, .m = m };

	if (poly_find(p, key))
		return 0;
	for (k = 0; k < POLY_SLOTS && p->slot[i].key; k++)
		i = (i + 1) & (POLY_SLOTS - 1);
	if (k == POLY_SLOTS)
		return p->host->error(p->host->ctx, "too many ePSF nodes and cells (%d)", POLY_SLOTS);
	q.nee = q.centre / over;
	q.plane = calloc((size_t)over * over * m * m + VSLACK, sizeof(float));
	q.ee = calloc((size_t)q.nee + 1, sizeof(double));
	q.psum = calloc((size_t)over * over, sizeof(double));
	if (!q.plane || !q.ee || !q.psum) {
		free(q.plane);
		free(q.ee);
		free(q.psum);
		return p->host->error(p->host->ctx, "out of memory");
	}
	for (int r = 0; r < over; r++)
		for (int s = 0; s < over; s++) {
			float *pl = q.plane + (size_t)(r * over + s) * m * m;

			for (int y = r, a = PAD; y < n; y += over, a++)
				for (int x = s, b = PAD; x < n; x += over, b++)
					pl[a * m + b] = node[(size_t)y * n + x];
		}
	ee_table(&q, node);
	for (int k = 0; k < over * over; k++) {
		const float *pl = q.plane + (size_t)k * m * m;
		double t = 0;

		for (int a = 0; a < m * m; a++)
			t += pl[a];
		q.psum[k] = t;
	}
	p->slot[i] = q;
	return 0;
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
 * array instead of four. */
static int cell_add(struct point *p, const struct wfs_source *src, uint64_t key)
{
	struct wfs_epsf e;
	double cx = (floor(src->x / p->cell) + 0.5) * p->cell - 0.5;
	double cy = (floor(src->y / p->cell) + 0.5) * p->cell - 0.5;
	float *mix;
	size_t nn;
	int r;

	if (poly_find(p, key))
		return 0;
	if (p->host->epsf(p->host->ctx, src->sca, cx, cy, src->psf_class, &e) < 0)
		return -1;
	nn = (size_t)e.n * e.n;
	if (!(mix = malloc(nn * sizeof(float))))
		return p->host->error(p->host->ctx, "out of memory");
	for (size_t i = 0; i < nn; i++) {
		double v = 0;

		for (int k = 0; k < 4; k++)
			if (e.weight[k] != 0)
				v += e.weight[k] * e.node[k][i];
		mix[i] = (float)v;
	}
	r = poly_add(p, key, mix, e.n, e.over);
	free(mix);
	if (r < 0)
		return -1;
	/* what the cell was blended from, for the core's correction
	 * (psf-blend=core): the nodes' own polyphase copies too */
	struct poly *c = (struct poly *)poly_find(p, key);

	for (int k = 0; k < 4; k++) {
		c->cnode[k] = e.weight[k] != 0 ? e.node[k] : NULL;
		c->cweight[k] = e.weight[k] != 0 ? e.weight[k] : 0;
		if (p->blend == BLEND_CORE && c->cnode[k] &&
		    poly_add(p, (uint64_t)(uintptr_t)e.node[k], e.node[k], e.n, e.over) < 0)
			return -1;
	}
	return 0;
}

/* A setting that is one of a list of names: 0 and *out set, or an error
 * naming the key. */
static int setting_choice(const struct wfs_host *host, const char *key,
			  const char *const names[], int nnames, int *out)
{
	const char *s = host->setting(host->ctx, key);

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
	const char *s = host->setting(host->ctx, key);
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
	struct point *p = calloc(1, sizeof(*p));
	double cell = 512;

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	p->sum_rows = sum_rows_plain;
#ifdef HAVE_ROWS_AVX2
	if (__builtin_cpu_supports("avx2"))
		p->sum_rows = sum_rows_avx2;
#endif
	p->interp = INTERP_CORE;
	p->core = 4.0;
	p->blend = BLEND_CORE;
	p->box_noise = 0.1;
	p->sigma = scene_sigma(host);
	if (setting_choice(host, "psf-interp", interp, 3, &p->interp) < 0 ||
	    setting_number(host, "psf-core", 0, 0, &p->core) < 0 ||
	    setting_choice(host, "psf-box", box, 2, &p->adaptive) < 0 ||
	    setting_number(host, "psf-box-noise", 0, 1, &p->box_noise) < 0 ||
	    setting_number(host, "psf-box-sigma", 0, 1, &p->sigma) < 0 ||
	    setting_choice(host, "psf-blend", blend, 3, &p->blend) < 0 ||
	    setting_number(host, "psf-cell", 1, 0, &cell) < 0)
		goto fail;
	if (cell != floor(cell) || cell > 4096) {
		host->error(host->ctx, "psf-cell: expected a whole number of pixels up to 4096, not '%s'",
			    host->setting(host->ctx, "psf-cell"));
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
		free(p->slot[i].ee);
		free(p->slot[i].psum);
	}
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

static int point_footprint(void *state, const struct wfs_source *src,
			   struct wfs_box *box)
{
	struct point *p = state;
	const struct poly *pl[4];
	double wn[4], half;
	int nn, blend = source_blend(p, src);

	if (blend != BLEND_SOURCE && cell_add(p, src, cell_key(p, src)) < 0)
		return -1;
	if (blend != BLEND_CELL) {
		struct wfs_epsf e;

		if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class, &e) < 0)
			return -1;
		for (int k = 0; k < 4; k++)
			if (e.weight[k] != 0 &&
			    poly_add(p, (uint64_t)(uintptr_t)e.node[k], e.node[k], e.n, e.over) < 0)
				return -1;
	}
	/* the box from the blend at the source, but for psf-blend=cell */
	if ((nn = source_polys(p, src, blend == BLEND_CELL ? BLEND_CELL : BLEND_SOURCE,
			       pl, wn)) < 0)
		return -1;
	half = (double)pl[0]->centre / pl[0]->over;
	if (p->adaptive) {
		/* the smallest half-width whose left-out light is below
		 * box_noise times the noise summed over the box */
		int h, H = pl[0]->nee;

		for (h = 1; h < H; h++) {
			double out = 0;

			for (int k = 0; k < nn; k++)
				out += wn[k] * (pl[k]->ee[H] - pl[k]->ee[h]);
			if (fabs(out) <= p->box_noise * p->sigma * 2 * h)
				break;
		}
		if (h < half)
			half = h;
	}
	/* pixels i with x - half < i < x + half */
	box->x0 = (int)floor(src->x - half) + 1;
	box->x1 = (int)ceil(src->x + half);
	box->y0 = (int)floor(src->y - half) + 1;
	box->y1 = (int)ceil(src->y + half);
	return 0;
}

/* row[i] += acc[i] for i < len */
static inline __attribute__((always_inline)) void add_row(double *row, const float *acc, int len)
{
	for (int i = 0; i < len; i++)
		row[i] += acc[i];
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
 * row sums run 8 floats wide where the processor allows.
 *
 * Per row, the bilinear part is a weighted sum of 4 streams per array (2 x
 * 2 taps), taken 4 streams at a time, each pixel summing its streams in
 * one fixed order.  One array (psf-blend=cell) and no core on the row: the
 * sum goes straight into the tile.  The core's pixels on a row are a run;
 * the Keys sums there run over the run in double, in the same order for
 * every pixel as a pixel-by-pixel loop would take. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
__attribute__((target_clones("avx2,fma", "default")))
#endif
static int point_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct point *p = state;
	const struct poly *pl[4];
	double wn[4], bx[2], by[2], cx[4], cy[4];
	float wt[16];
	const float *tap0[64];  /* [node][y tap][x tap] at the window's first row */
	int blend = source_blend(p, src);
	const struct poly *cp[8];
	double cw[8], ccw[32];
	const float *ctap0[32]; /* psf-blend=core: [node][y tap][x tap], bilinear */
	double bc = 0, bd = 0;  /* psf-blend=core: box sums of the cell and the difference */
	long rx[4], mx[4], ry[4], my[4];
	int nn, ncor = 0, o, m, basex, basey, keys;
	double tx, ty, fx, fy, core2;
	float acc[MAX_ROW + 8];
	double dv[MAX_ROW + 4], tv[MAX_ROW + 4];

	if ((nn = source_polys(p, src, blend, pl, wn)) < 0)
		return -1;
	if (blend == BLEND_CORE && (ncor = core_correction(p, src, pl[0], cp, cw)) < 0)
		return -1;
	o = pl[0]->over;
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
	/* tap a (sample offsets -1, 0, 1, 2) of pixel i is sample
	 * o (i + mx[a]) + rx[a]: plane rx[a], column i + mx[a] + PAD */
	for (int a = 0; a < 4; a++) {
		long sx = pl[0]->centre + basex + a - 1, sy = pl[0]->centre + basey + a - 1;

		mx[a] = floordiv(sx, o);
		rx[a] = sx - o * mx[a];
		my[a] = floordiv(sy, o);
		ry[a] = sy - o * my[a];
	}
	if (win->x0 + mx[0] + PAD < 0 || win->x0 + win->nx + mx[3] + PAD > m ||
	    win->y0 + my[0] + PAD < 0 || win->y0 + win->ny + my[3] + PAD > m)
		return p->host->error(p->host->ctx, "window outside the source's box");
	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 2; b++)
			for (int a = 0; a < 2; a++)
				wt[(k * 2 + b) * 2 + a] = (float)(wn[k] * by[b] * bx[a]);
	/* psf-blend=core: the box's sums for the flux factor f */
	if (ncor)
		core_box_sums(pl[0], cp, cw, ncor, wn[0], rx, ry, bx, by, &bc, &bd);
	/* the cubic's taps must stay inside the array (bicubic everywhere
	 * reads the planes' zero padding at the box's edge instead) */
	keys = p->interp != INTERP_BILINEAR;
	if (p->interp == INTERP_BICUBIC)
		core2 = INFINITY;
	else if (p->interp == INTERP_BILINEAR && blend != BLEND_CORE)
		core2 = -1;
	else
		core2 = p->core * o + 2 < pl[0]->centre ? p->core * p->core : 0;
	for (int c = 0; c < ncor; c++)
		for (int b = 0; b < 2; b++)
			for (int a = 0; a < 2; a++) {
				ccw[(c * 2 + b) * 2 + a] = cw[c] * by[b] * bx[a];
				ctap0[(c * 2 + b) * 2 + a] = cp[c]->plane +
					((size_t)(ry[b + 1] * o + rx[a + 1]) * m + (win->y0 + my[b + 1] + PAD)) * m +
					(win->x0 + mx[a + 1] + PAD);
			}

	/* the streams at the window's first row; each row is m samples on */
	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 4; b++)
			for (int a = 0; a < 4; a++)
				tap0[(k * 4 + b) * 4 + a] = pl[k]->plane +
					((size_t)(ry[b] * o + rx[a]) * m + (win->y0 + my[b] + PAD)) * m +
					(win->x0 + mx[a] + PAD);
	if (nn == 1 && win->nx <= MAX_ROW) {
		/* one array: the core's Keys sums (and the source's blend,
		 * psf-blend=core) first, in float, 8 columns at a time over
		 * the columns of its widest row, then the whole window in one
		 * call */
		double r = core2 >= 0 ? sqrt(core2) : -1;
		int ka = 0, kb = 0, jc = 0, nc = 0, flux = ncor && !isinf(r);
		int cia[KV_ROWS], cib[KV_ROWS];
		float kvb[KV_ROWS * KV_PITCH + 8];
		v8f kxf[4], kyf[4], ccwf[32], sc = { 0 }, sd = { 0 };
		struct rows_args ra = { { tap0[5], tap0[6], tap0[9], tap0[10] }, m,
					{ wt[0], wt[1], wt[2], wt[3] }, 0, 0, cia, cib, kvb, 0 };

		/* the core's rows [jc, jc + nc) and the columns of its widest
		 * row [ka, kb), whole (past the window, for f: the planes
		 * cover the box), but for bicubic: the window */
		if (isinf(r)) {
			kb = win->nx;
			nc = win->ny;
		} else if (r >= 0) {
			ka = (int)ceil(src->x - r) - win->x0;
			kb = (int)floor(src->x + r) - win->x0 + 1;
			jc = (int)ceil(src->y - r) - win->y0;
			nc = (int)floor(src->y + r) - win->y0 + 1 - jc;
			if (ka >= kb || nc < 0)
				ka = kb = nc = 0;
		}
		if (nc <= KV_ROWS && kb - ka <= KV_COLS) {
			v8f b0 = SPLAT(wt[0]), b1 = SPLAT(wt[1]), b2 = SPLAT(wt[2]), b3 = SPLAT(wt[3]);

			for (int a = 0; a < 4; a++) {
				kxf[a] = SPLAT((float)cx[a]);
				kyf[a] = SPLAT((float)(cy[a] * wn[0]));
			}
			for (int c = 0; c < 4 * ncor; c++)
				ccwf[c] = SPLAT((float)ccw[c]);
			for (int c = 0; c < nc; c++) {
				int j = win->y0 + jc + c, ca = ka, cb = kb;
				double dy = j - src->y;
				ptrdiff_t step = (ptrdiff_t)(jc + c) * m;
				float *kv = kvb + c * KV_PITCH + 8;

				/* the run: the exact test decides, as pixel by pixel */
				while (ca < cb && (win->x0 + ca - src->x) * (win->x0 + ca - src->x) + dy * dy > core2)
					ca++;
				while (cb > ca && (win->x0 + cb - 1 - src->x) * (win->x0 + cb - 1 - src->x) + dy * dy > core2)
					cb--;
				/* in the window: rows past it are never drawn */
				cia[c] = ca < 0 ? 0 : ca;
				cib[c] = cb > win->nx ? win->nx : cb;
				for (int i = ka; i < kb; i += 8) {
					v8f v = { 0 }, d = { 0 };

					for (int b = 0; keys && b < 4; b++) {
						const float *const *t = tap0 + b * 4;

						v += kyf[b] * (kxf[0] * *(const v8f *)(t[0] + step + i) +
							       kxf[1] * *(const v8f *)(t[1] + step + i) +
							       kxf[2] * *(const v8f *)(t[2] + step + i) +
							       kxf[3] * *(const v8f *)(t[3] + step + i));
					}
					for (int q = 0; q < 4 * ncor; q += 2)
						d += ccwf[q] * *(const v8f *)(ctap0[q] + step + i) +
						     ccwf[q + 1] * *(const v8f *)(ctap0[q + 1] + step + i);
					if (flux || !keys) {
						/* the cell's bilinear sum, as sum_rows()
						 * takes it before f: with psf-interp=
						 * bilinear the core's base; C(cell),
						 * C(d) over the run */
						v8i lane = LANES + i;
						v8i in = (lane >= ca) & (lane < cb);
						v8f bl = b0 * *(const v8f *)(tap0[5] + step + i) +
							 b1 * *(const v8f *)(tap0[6] + step + i) +
							 b2 * *(const v8f *)(tap0[9] + step + i) +
							 b3 * *(const v8f *)(tap0[10] + step + i);

						if (!keys)
							v = bl;
						sc += (v8f)((v8i)bl & in);
						sd += (v8f)((v8i)d & in);
					}
					*(v8f *)(kv + i - ka) = v + d;
				}
			}
			if (flux) {
				double cc = 0, cd = 0, f;

				for (int l = 0; l < 8; l++) {
					cc += sc[l];
					cd += sd[l];
				}
				f = bc - cc > 0 ? 1 + (bd - cd) / (bc - cc) : 1;
				for (int t = 0; t < 4; t++)
					ra.w[t] = (float)(f * wn[0] * by[t >> 1] * bx[t & 1]);
			}
			ra.jc = jc;
			ra.nc = nc;
			ra.ka = ka;
			p->sum_rows(win->pix, win->stride, win->nx, win->ny, &ra);
			return 0;
		}
	}
	if (ncor && !isinf(core2)) {
		double cc, cd, f;

		core_disk_sums(pl[0], cp, cw, ncor, wn[0], src->x, src->y, core2, rx, mx, ry, my,
			       bx, by, &cc, &cd);
		f = bc - cc > 0 ? 1 + (bd - cd) / (bc - cc) : 1;
		for (int t = 0; t < 4; t++)
			wt[t] = (float)(f * wn[0] * by[t >> 1] * bx[t & 1]);
	}
	for (int j = win->y0; j < win->y0 + win->ny; j++) {
		double *row = win->pix + (ptrdiff_t)(j - win->y0) * win->stride;
		double dy = j - src->y;
		ptrdiff_t step = (ptrdiff_t)(j - win->y0) * m;
		int ca = 0, cb = 0;     /* the core's run on this row, [ca, cb) of the window */

		if (dy * dy <= core2) {
			double r = sqrt(core2 - dy * dy), lo = src->x - r - 1, hi = src->x + r + 1;

			ca = lo < win->x0 ? 0 : lo > win->x0 + win->nx ? win->nx : (int)lo - win->x0;
			cb = hi < win->x0 ? 0 : hi > win->x0 + win->nx ? win->nx : (int)hi - win->x0 + 1;
			if (cb > win->nx)
				cb = win->nx;
			/* the exact test decides, as pixel by pixel */
			while (ca < cb && (win->x0 + ca - src->x) * (win->x0 + ca - src->x) + dy * dy > core2)
				ca++;
			while (cb > ca && (win->x0 + cb - 1 - src->x) * (win->x0 + cb - 1 - src->x) + dy * dy > core2)
				cb--;
		}
		for (int i0 = 0; i0 < win->nx; i0 += MAX_ROW) {
			int len = win->nx - i0 < MAX_ROW ? win->nx - i0 : MAX_ROW;
			int ia = ca - i0, ib = cb - i0;

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
			/* the sharp core: Keys cubic from the same samples */
			if (ia < ib) {
				/* 4 pixels at a time, past the run's end into the
				 * planes' slack; only the run is kept */
				int cn = ib - ia;

				for (int i = 0; i < cn; i += 4)
					*(v4d *)(dv + i) = (v4d){ 0 };
				/* bilinear with psf-blend=core: the cell's sum
				 * before f (one array, so taps 5, 6, 9, 10) */
				if (!keys)
					for (int i = 0; i < cn; i++) {
						ptrdiff_t at = step + i0 + ia + i;

						dv[i] = (float)((float)(wn[0] * by[0] * bx[0]) * tap0[5][at] +
								(float)(wn[0] * by[0] * bx[1]) * tap0[6][at] +
								(float)(wn[0] * by[1] * bx[0]) * tap0[9][at] +
								(float)(wn[0] * by[1] * bx[1]) * tap0[10][at]);
					}
				for (int k = 0; keys && k < nn; k++) {
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(tv + i) = (v4d){ 0 };
					for (int b = 0; b < 4; b++) {
						const float *const *t = tap0 + (k * 4 + b) * 4;
						const float *t0 = t[0] + step + i0 + ia, *t1 = t[1] + step + i0 + ia;
						const float *t2 = t[2] + step + i0 + ia, *t3 = t[3] + step + i0 + ia;
						v4d c0 = SPLAT4(cx[0]), c1 = SPLAT4(cx[1]), c2 = SPLAT4(cx[2]);
						v4d c3 = SPLAT4(cx[3]), cb4 = SPLAT4(cy[b]);

						for (int i = 0; i < cn; i += 4)
							*(v4d *)(tv + i) += cb4 * (c0 * TO_V4D(t0 + i) + c1 * TO_V4D(t1 + i) +
										   c2 * TO_V4D(t2 + i) + c3 * TO_V4D(t3 + i));
					}
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(dv + i) += SPLAT4(wn[k]) * *(v4d *)(tv + i);
				}
				/* psf-blend=core: the cell's blend moved to the
				 * source's position, bilinear (it is a small
				 * difference: its interpolation error is small) */
				for (int c = 0; c < ncor; c++)
					for (int b = 0; b < 2; b++) {
						const float *u0 = ctap0[(c * 2 + b) * 2] + step + i0 + ia;
						const float *u1 = ctap0[(c * 2 + b) * 2 + 1] + step + i0 + ia;
						v4d w0 = SPLAT4(ccw[(c * 2 + b) * 2]), w1 = SPLAT4(ccw[(c * 2 + b) * 2 + 1]);

						for (int i = 0; i < cn; i += 4)
							*(v4d *)(dv + i) += w0 * TO_V4D(u0 + i) + w1 * TO_V4D(u1 + i);
					}
				for (int i = 0; i < cn; i++)
					acc[ia + i] = (float)dv[i];
			}
			add_row(row + i0, acc, len);
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
