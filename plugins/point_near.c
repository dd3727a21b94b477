/*
 * point_near.c - psf-halo-near: within a bright source's halo array, only
 * the pixels at or above its drawing level are drawn.  The step map of
 * each halo (per pixel offset from the source's pixel, the level step of
 * its largest value at any phase), its runs of row segments per level
 * step, and the light each step leaves to the diffuse grid; and the
 * drawing of a source's runs in a window, in AVX-512, AVX2 or plain C
 * (the same bits).
 */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

/* x, or a where a stands beyond it: above it, or with lo below it. */
static inline float near_pick(float a, float x, int lo)
{
	return lo ? (a < x ? a : x) : (a > x ? a : x);
}

/* The largest value of each pixel offset dx in [-rc, rc] of row dy from
 * the pixel nearest a source at any phase (|phase| <= 1/2), into v[dx +
 * rc]: the largest of the samples its bilinear read may take times s (the
 * largest sample times s, or with s < 0 the least: rounding keeps the
 * order), and in the hand-over to the tail the tail at its corners.  m:
 * scratch of side floats. */
static void near_vmax_row(const struct halo *h, int rc, int dy, double *v, float *m)
{
	long o = h->over, hw = (o + 1) / 2, n = h->n, side = 2L * rc + 1;
	int lo = h->s < 0;

	for (long i = 0; i < side; i++)
		m[i] = lo ? INFINITY : -INFINITY;
	/* the window's sample rows, each row's extreme over its columns */
	for (long j = -hw; j <= hw; j++) {
		long w = h->c + o * dy + j;
		const float *row;

		if (w < 0 || w >= n)
			continue;
		row = h->a + w * n;
		for (long i = 0; i < side; i++) {
			long u0 = h->c + o * (i - rc) - hw, u1 = u0 + 2 * hw;
			float x = m[i];

			if (hw == 1 && u0 >= 0 && u1 < n) {     /* the usual window */
				x = near_pick(row[u0], x, lo);
				x = near_pick(row[u0 + 1], x, lo);
				m[i] = near_pick(row[u1], x, lo);
				continue;
			}
			u0 = u0 < 0 ? 0 : u0;
			u1 = u1 >= n ? n - 1 : u1;
			for (long u = u0; u <= u1; u++)
				x = near_pick(row[u], x, lo);
			m[i] = x;
		}
	}
	for (long i = 0; i < side; i++) {
		long dx = i - rc;
		double d = sqrt((double)dx * dx + (double)dy * dy), t;

		v[i] = m[i] * h->s > 0 ? m[i] * h->s : 0;
		/* (beyond R + 1 the step is not taken: near_setup) */
		if (d + 0.75 > h->R - h->taper && d < h->R + 1)
			for (int c = 0; c < 5; c++) {
				t = halo_tail(h, dx + (c < 4 ? (c & 1) - 0.5 : 0),
					      dy + (c < 4 ? (c >> 1) - 0.5 : 0));
				v[i] = t > v[i] ? t : v[i];
			}
	}
}

/* floor(FAR_STEPS log2 v), v > 0, from v's exponent and its mantissa
 * against the steps' thresholds; by log2() itself where the mantissa lies
 * within 1e-9 of a threshold (there the two roundings may differ). */
_Static_assert(FAR_STEPS == 4, "near_step() holds the thresholds of four steps an octave");

static int near_step(double v)
{
	static const double t[5] = { 1.0, 1.189207115002721, 1.4142135623730951,
				     1.681792830507429, 2.0 };
	int e, q;
	double m = 2 * frexp(v, &e);    /* v = m 2^(e - 1), 1 <= m < 2 */

	for (int i = 0; i < 5; i++)
		if (fabs(m - t[i]) < 1e-9 * t[i])
			return (int)floor(FAR_STEPS * log2(v));
	q = (m >= t[1]) + (m >= t[2]) + (m >= t[3]);
	return FAR_STEPS * (e - 1) + q;
}

/* whether near_jobs_avx512() may run */
static int near_jobs_ok(void)
{
#ifdef SIMD_X86
	int f = simd_flags();

	return (f & (SIMD_AVX512 | SIMD_AVX2 | SIMD_FMA)) == (SIMD_AVX512 | SIMD_AVX2 | SIMD_FMA);
#else
	return 0;
#endif
}

/* Each level's first and last row with a run (point.h, struct near: ry)
 * and, where near_jobs_avx512() may run, the runs' chunks (ci, cs) of
 * every level and row, in that order: each run's offsets from where the
 * last chunk ended or the run starts, whichever is later, a chunk at a
 * time. */
static int near_chunks(struct near *n)
{
	size_t nk = (size_t)(n->kmax - n->kmin + 1), side = (size_t)n->side, m = 0, cap = 1024;
	int16_t *cs;
	int chunks = near_jobs_ok();

	if (!(n->ry = malloc(2 * nk * sizeof(*n->ry))) ||
	    (chunks && (!(n->ci = malloc((nk * side + 1) * sizeof(*n->ci))) ||
			!(n->cs = malloc(cap * sizeof(*n->cs))))))
		return -1;
	for (size_t q = 0; q < nk * side; q++) {
		long at = LONG_MIN;
		int16_t *ry = n->ry + 2 * (q / side);

		if (q % side == 0) {
			ry[0] = (int16_t)side;
			ry[1] = -1;
		}
		if (n->ri[q] < n->ri[q + 1]) {   /* the rows come in order */
			ry[0] = ry[1] < 0 ? (int16_t)(q % side) : ry[0];
			ry[1] = (int16_t)(q % side);
		}
		if (!chunks)
			continue;
		n->ci[q] = (int32_t)m;
		for (int32_t t = n->ri[q]; t < n->ri[q + 1]; t++) {
			long a = (long)n->rs[2 * t] * NEAR_SEG, e = (n->rs[2 * t + 1] + 1L) * NEAR_SEG;

			for (at = at > a ? at : a; at < e; at += NEAR_CHUNK) {
				if (m == cap) {
					if (!(cs = realloc(n->cs, 2 * cap * sizeof(*cs))))
						return -1;
					n->cs = cs;
					cap *= 2;
				}
				n->cs[m++] = (int16_t)at;
			}
		}
	}
	if (chunks)
		n->ci[nk * side] = (int32_t)m;
	return 0;
}

/* The runs of segments (point.h, struct near: ri, rs) of every level and
 * row, in that order, rs grown as they are found; then their chunks. */
static int near_segments(struct near *n)
{
	size_t nk = (size_t)(n->kmax - n->kmin + 1), side = (size_t)n->side, t = 0, cap = 1024;
	int16_t *lim, *rs;

	if (!(n->ri = malloc((nk * side + 1) * sizeof(*n->ri))) ||
	    !(n->rs = malloc(cap * 2 * sizeof(*n->rs))) ||
	    !(lim = malloc(3 * side * sizeof(*lim))))
		return -1;
	/* each row's largest step (no runs at levels above it), and its first
	 * and last segment with any step (runs lie between) */
	for (size_t row = 0; row < side; row++) {
		const int16_t *sm = n->smax + row * n->nseg;
		int16_t *l = lim + 3 * row;

		l[0] = INT16_MIN;
		l[1] = (int16_t)n->nseg;
		l[2] = -1;
		for (int g = 0; g < n->nseg; g++)
			if (sm[g] > INT16_MIN) {
				l[0] = sm[g] > l[0] ? sm[g] : l[0];
				l[1] = (int16_t)(g < l[1] ? g : l[1]);
				l[2] = (int16_t)g;
			}
	}
	for (size_t L = 0; L < nk; L++)
		for (size_t row = 0; row < side; row++) {
			const int16_t *sm = n->smax + row * n->nseg, *l = lim + 3 * row;
			int k = n->kmin + (int)L;

			n->ri[L * side + row] = (int32_t)t;
			if (l[0] < k)
				continue;
			for (int g = l[1]; g <= l[2]; g++) {
				int e = g;

				if (sm[g] < k)
					continue;
				while (e + 1 <= l[2] && sm[e + 1] >= k)
					e++;
				if (t == cap) {
					if (!(rs = realloc(n->rs, 2 * cap * 2 * sizeof(*rs)))) {
						free(lim);
						return -1;
					}
					n->rs = rs;
					cap *= 2;
				}
				n->rs[2 * t] = (int16_t)g;
				n->rs[2 * t + 1] = (int16_t)e;
				t++;
				g = e + 1;      /* sm[e + 1] < k, or beyond */
			}
		}
	free(lim);
	n->ri[nk * side] = (int32_t)t;
	return near_chunks(n);
}

/* The array's samples by phase (point.h, struct near: pl), each plane's
 * rows padded with 16 zeros (a masked AVX-512 step starting near a row's
 * end spans them, its lanes beyond the run unread). */
static int near_planes(struct near *n, const struct halo *h)
{
	long o = h->over, nh = (h->n + o - 1) / o + 16;

	if (!(n->pl = calloc((size_t)(o * h->n * nh), sizeof(*n->pl))))
		return -1;
	n->nh = nh;
	for (long w = 0; w < h->n; w++) {
		const float *a = h->a + w * h->n;

		if (o == 2) {   /* the built-in sampling: one loop the compiler vectorises */
			float *p0 = n->pl + w * nh, *p1 = n->pl + (h->n + w) * nh;

			for (long m = 0; 2 * m + 1 < h->n; m++) {
				p0[m] = a[2 * m];
				p1[m] = a[2 * m + 1];
			}
			if (h->n % 2)
				p0[h->n / 2] = a[h->n - 1];
			continue;
		}
		for (long r = 0; r < o; r++)
			for (long m = 0; o * m + r < h->n; m++)
				n->pl[(r * h->n + w) * nh + m] = a[o * m + r];
	}
	return 0;
}

/* Set up n from halo h and the box half-width hb: 0, or -1 when out of
 * memory. */
static int near_setup(struct near *n, const struct halo *h, int hb)
{
	int rc = (int)ceil(h->R) + 1, side = 2 * rc + 1;
	double *bin = NULL, *vrow;
	float *mrow;

	n->rc = rc;
	n->side = side;
	n->nseg = (side + NEAR_SEG - 1) / NEAR_SEG;
	n->hb = hb;
	n->kmin = INT_MAX;
	n->kmax = INT_MIN;
	/* the AVX-512 loop reads 16 steps from any pixel of a row, up to 15
	 * past its end: into the next row, or into these 16 past the last
	 * (whose offsets, beyond the disc, have no step anyway) */
	if (!(n->st = calloc((size_t)side * side + 16, sizeof(*n->st))) ||
	    !(n->smax = malloc((size_t)side * n->nseg * sizeof(*n->smax))))
		return -1;
	for (int b = 0; b < side * n->nseg; b++)
		n->smax[b] = INT16_MIN;
	if (!(vrow = malloc((size_t)side * sizeof(*vrow))) ||
	    !(mrow = malloc((size_t)side * sizeof(*mrow)))) {
		free(vrow);
		return -1;
	}
	for (int dy = -rc; dy <= rc; dy++) {
		near_vmax_row(h, rc, dy, vrow, mrow);
		for (int dx = -rc; dx <= rc; dx++) {
			double vm = vrow[dx + rc], d = sqrt((double)dx * dx + (double)dy * dy);
			int st = INT16_MIN, b = (dy + rc) * n->nseg + (dx + rc) / NEAR_SEG;

			if (d < h->R + 1 && vm > 0) {
				st = near_step(vm);
				st = st <= INT16_MIN ? INT16_MIN + 1 : st;
				n->kmin = st < n->kmin ? st : n->kmin;
				n->kmax = st > n->kmax ? st : n->kmax;
			}
			n->st[(size_t)(dy + rc) * side + dx + rc] = (int16_t)st;
			n->smax[b] = (int16_t)(st > n->smax[b] ? st : n->smax[b]);
		}
	}
	free(vrow);
	free(mrow);
	if (n->kmin > n->kmax)
		n->kmin = n->kmax = 0;
	if (near_segments(n) < 0 || near_planes(n, h) < 0)
		return -1;
	if (!(n->under = calloc((size_t)(n->kmax - n->kmin + 2), sizeof(double))) ||
	    !(bin = calloc((size_t)(n->kmax - n->kmin + 2), sizeof(double))))
		return -1;
	/* the light of each step's offsets within the disc outside the box */
	for (int dy = -rc; dy <= rc; dy++)
		for (int dx = -rc; dx <= rc; dx++) {
			int st = n->st[(size_t)(dy + rc) * side + dx + rc];

			if (st >= n->kmin && (double)dx * dx + (double)dy * dy < h->R * h->R &&
			    (abs(dx) >= hb || abs(dy) >= hb))
				bin[st - n->kmin] += halo_value(h, dx, dy);
		}
	for (int k = 1; k <= n->kmax - n->kmin + 1; k++)
		n->under[k] = n->under[k - 1] + bin[k - 1];
	free(bin);
	return 0;
}

void near_free(struct near *n)
{
	free(n->st);
	free(n->smax);
	free(n->ri);
	free(n->rs);
	free(n->ci);
	free(n->cs);
	free(n->ry);
	free(n->under);
	free(n->pl);
	memset(n, 0, sizeof(*n));
}

/* The light (over the flux) a source of level step k leaves to the grid
 * within the array's disc. */
double near_under(const struct near *n, int k)
{
	if (k <= n->kmin)
		return 0;
	return n->under[(k > n->kmax + 1 ? n->kmax + 1 : k) - n->kmin];
}

/* Slot s's lists, set up on first use under its lock (the box: hb). */
const struct near *near_of(struct point *p, struct hslot *s, int hb)
{
	struct near *n = &s->near;
	int ok = 1;

	if (atomic_load_explicit(&s->near_ready, memory_order_acquire))
		return n;
	pthread_mutex_lock(set_lock_of(p, s));
	if (!atomic_load_explicit(&s->near_ready, memory_order_relaxed)) {
		if ((ok = near_setup(n, &s->h, hb) == 0))
			atomic_store_explicit(&s->near_ready, 1, memory_order_release);
		else
			near_free(n);
	}
	pthread_mutex_unlock(set_lock_of(p, s));
	if (!ok) {
		p->host->error(p->host->ctx, "out of memory for the halo's pixel lists");
		return NULL;
	}
	return n;
}

/* near_render's pixels i0 + dx of window row `row` for dx in [a, b],
 * those whose step (st, indexed by dx) reaches k.  Pixel dx's four
 * samples are p0[dx], p1[dx] (its sample row) and p0[nh + dx], p1[nh +
 * dx] (the next), from the phase planes (struct near: pl). */
struct near_row {
	const struct halo *h;
	const float *p0, *p1;
	long nh;
	float w[4];
	double flux, x, dy, rin2;
	long i0;
};

/* The bilinear value of pixel dx of row q, as every path below computes
 * it (the same products and fused sums in float). */
static inline float near_value(const struct near_row *q, long dx)
{
	float v = q->w[0] * q->p0[dx];

	v = fmaf(q->w[1], q->p1[dx], v);
	v = fmaf(q->w[2], q->p0[q->nh + dx], v);
	return fmaf(q->w[3], q->p1[q->nh + dx], v);
}

/* Pixels dx in [a, b] of row q, every one in the array's plain part: each
 * adds its bilinear value where its step reaches k, and 0 elsewhere. */
static inline void near_span_c(const struct near_row *q, const int16_t *st, int k, long a,
			       long b, double *row)
{
	for (long dx = a; dx <= b; dx++) {
		float v = near_value(q, dx);

		row[dx] += st[dx] >= k ? (double)v : 0;
	}
}

#ifdef SIMD_X86
/* near_span_c eight pixels a step in AVX2 and FMA, the same operations in
 * the same order, so the same bits. */
__attribute__((target("avx2,fma"))) static inline void
near_span_avx2(const struct near_row *q, const int16_t *st, int k, long a, long b, double *row)
{
	const float *p0 = q->p0, *p1 = q->p1, *p2 = q->p0 + q->nh, *p3 = q->p1 + q->nh;
	__m256 w0 = _mm256_set1_ps(q->w[0]), w1 = _mm256_set1_ps(q->w[1]);
	__m256 w2 = _mm256_set1_ps(q->w[2]), w3 = _mm256_set1_ps(q->w[3]);
	__m256i km = _mm256_set1_epi32(k - 1);
	long dx;

	for (dx = a; dx + 7 <= b; dx += 8) {
		__m256i sv = _mm256_cvtepi16_epi32(_mm_loadu_si128((const __m128i *)(st + dx)));
		__m256 v = _mm256_mul_ps(w0, _mm256_loadu_ps(p0 + dx));

		v = _mm256_fmadd_ps(w1, _mm256_loadu_ps(p1 + dx), v);
		v = _mm256_fmadd_ps(w2, _mm256_loadu_ps(p2 + dx), v);
		v = _mm256_fmadd_ps(w3, _mm256_loadu_ps(p3 + dx), v);
		v = _mm256_and_ps(v, _mm256_castsi256_ps(_mm256_cmpgt_epi32(sv, km)));
		_mm256_storeu_pd(row + dx, _mm256_add_pd(_mm256_loadu_pd(row + dx),
							 _mm256_cvtps_pd(_mm256_castps256_ps128(v))));
		_mm256_storeu_pd(row + dx + 4, _mm256_add_pd(_mm256_loadu_pd(row + dx + 4),
							     _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))));
	}
	near_span_c(q, st, k, dx, b, row);
}
#endif

/* Any pixels dx in [a, b] of row q whose step reaches k: the bilinear
 * read within the array's plain part, halo_value() beyond it. */
static inline void near_run(const struct near_row *q, const int16_t *st, int k, long a, long b,
			    double *row)
{
	double xa = q->i0 + a - q->x, xb = q->i0 + b - q->x;

	if (xa * xa + q->dy * q->dy < q->rin2 && xb * xb + q->dy * q->dy < q->rin2) {
#ifdef SIMD_X86
		if ((simd_flags() & (SIMD_AVX2 | SIMD_FMA)) == (SIMD_AVX2 | SIMD_FMA)) {
			near_span_avx2(q, st, k, a, b, row);
			return;
		}
#endif
		near_span_c(q, st, k, a, b, row);
		return;
	}
	for (long dx = a; dx <= b; dx++) {
		double ex = q->i0 + dx - q->x, d2 = ex * ex + q->dy * q->dy;

		if (st[dx] < k)
			continue;
		if (d2 < q->rin2)
			row[dx] += (double)near_value(q, dx);
		else
			row[dx] += q->flux * halo_value(q->h, ex, q->dy);
	}
}

typedef void near_span_fn(const struct near_row *q, const int16_t *st, int k, long a, long b,
			  double *row);

/* Row q's runs t in [r0, r1) of n's segments (offsets from the source's
 * pixel), each cut to the ranges cut[c] .. cut[c + 1], c even: `span`
 * draws each part.  Inlined with its span, so that each is one loop. */
static inline __attribute__((always_inline)) void
near_runs(near_span_fn *span, const struct near_row *q, const struct near *n, int32_t r0,
	  int32_t r1, const long *cut, int nc, const int16_t *st, int k, double *row)
{
	for (int c = 0; c + 1 < nc; c += 2)
		for (int32_t t = r0; t < r1; t++) {
			long a = (long)n->rs[2 * t] * NEAR_SEG - n->rc;
			long e = (long)(n->rs[2 * t + 1] + 1) * NEAR_SEG - 1 - n->rc;

			if (a > cut[c + 1])
				break;
			a = a > cut[c] ? a : cut[c];
			e = e < cut[c + 1] ? e : cut[c + 1];
			if (a <= e)
				span(q, st, k, a, e, row);
		}
}

/* near_runs of a row whose every pixel drawn is in the array's plain
 * part, in AVX2 or plain C (near_plain_choose; with AVX-512,
 * near_jobs_avx512). */
#ifdef SIMD_X86
__attribute__((target("avx2,fma"))) static void
near_plain_avx2(const struct near_row *q, const struct near *n, int32_t r0, int32_t r1,
		const long *cut, int nc, const int16_t *st, int k, double *row)
{
	near_runs(near_span_avx2, q, n, r0, r1, cut, nc, st, k, row);
}
#endif

static void near_plain_c(const struct near_row *q, const struct near *n, int32_t r0, int32_t r1,
			 const long *cut, int nc, const int16_t *st, int k, double *row)
{
	near_runs(near_span_c, q, n, r0, r1, cut, nc, st, k, row);
}

typedef void near_plain_fn(const struct near_row *q, const struct near *n, int32_t r0, int32_t r1,
			   const long *cut, int nc, const int16_t *st, int k, double *row);

#ifdef SIMD_X86
/* A plain row's chunks for near_jobs_avx512(): the row (offset 0 at the
 * source's pixel), its steps, its samples' offset in the planes, its
 * chunks c0 .. c1 - 1, the offsets [lo, hi] drawn and [bx0, bx1) not
 * (the box). */
struct near_job {
	double *row;
	const int16_t *st;
	long pv;
	int32_t c0, c1, lo, hi, bx0, bx1;
};

#define NEAR_JOBS 64

/* Jobs jb[0 .. nj - 1] of a source in AVX-512: of each chunk's sixteen
 * offsets, those in [lo, hi] and outside [bx0, bx1) whose step reaches k
 * add their bilinear value, computed as near_value() does, so with the
 * same bits as near_plain_*() (every offset they draw lies in one chunk,
 * and one only).  One loop over each row's chunks, their lanes picked by
 * comparisons, with no branch per run. */
__attribute__((target("avx512f,avx2,fma"))) static void
near_jobs_avx512(const struct near_row *q, const struct near *n, const float *b0,
		 const float *b1, const struct near_job *jb, int nj, int k)
{
	__m512 w0 = _mm512_set1_ps(q->w[0]), w1 = _mm512_set1_ps(q->w[1]);
	__m512 w2 = _mm512_set1_ps(q->w[2]), w3 = _mm512_set1_ps(q->w[3]);
	__m512i km = _mm512_set1_epi32(k - 1);
	__m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
	const int16_t *cs = n->cs;
	long rc = n->rc, nh = n->nh;

	for (int t = 0; t < nj; t++) {
		const struct near_job *g = jb + t;
		const float *p0 = b0 + g->pv, *p1 = b1 + g->pv, *p2 = p0 + nh, *p3 = p1 + nh;
		__m512i vlo = _mm512_set1_epi32(g->lo), vhi = _mm512_set1_epi32(g->hi);
		__m512i vb0 = _mm512_set1_epi32(g->bx0), vb1 = _mm512_set1_epi32(g->bx1);
		const int16_t *st = g->st;
		double *row = g->row;
		int32_t c0 = g->c0, c1 = g->c1;

		/* the chunks wholly before lo or after hi (another window's) */
		while (c0 < c1 && cs[c0] - rc + NEAR_CHUNK - 1 < g->lo)
			c0++;
		while (c1 > c0 && cs[c1 - 1] - rc > g->hi)
			c1--;
		for (int32_t c = c0; c < c1; c++) {
			long dx = cs[c] - rc;
			__m512i pos = _mm512_add_epi32(_mm512_set1_epi32((int)dx), iota);
			__mmask16 m = _mm512_cmpge_epi32_mask(pos, vlo) &
				      _mm512_cmple_epi32_mask(pos, vhi) &
				      ~(_mm512_cmpge_epi32_mask(pos, vb0) &
					_mm512_cmplt_epi32_mask(pos, vb1));
			__m512i sv = _mm512_cvtepi16_epi32(
				_mm256_loadu_si256((const __m256i *)(st + dx)));
			__mmask16 in = _mm512_mask_cmpgt_epi32_mask(m, sv, km);
			__mmask8 m0 = (__mmask8)in, m1 = (__mmask8)(in >> 8);
			__m512 v = _mm512_mul_ps(w0, _mm512_maskz_loadu_ps(in, p0 + dx));
			__m256 h;

			v = _mm512_fmadd_ps(w1, _mm512_maskz_loadu_ps(in, p1 + dx), v);
			v = _mm512_fmadd_ps(w2, _mm512_maskz_loadu_ps(in, p2 + dx), v);
			v = _mm512_fmadd_ps(w3, _mm512_maskz_loadu_ps(in, p3 + dx), v);
			h = _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1));
			_mm512_mask_storeu_pd(row + dx, m0, _mm512_add_pd(
				_mm512_maskz_loadu_pd(m0, row + dx),
				_mm512_cvtps_pd(_mm512_castps512_ps256(v))));
			_mm512_mask_storeu_pd(row + dx + 8, m1, _mm512_add_pd(
				_mm512_maskz_loadu_pd(m1, row + dx + 8), _mm512_cvtps_pd(h)));
		}
	}
}
#endif

/* near_plain_*() in the widest vectors this process may use, below
 * AVX-512 */
static near_plain_fn *near_plain_choose(void)
{
#ifdef SIMD_X86
	if ((simd_flags() & (SIMD_AVX2 | SIMD_FMA)) == (SIMD_AVX2 | SIMD_FMA))
		return near_plain_avx2;
#endif
	return near_plain_c;
}

/* Row q's runs r0 .. r1 - 1 within offsets [lo, hi] and, in a row of the
 * box (inbox), outside [bx0, bx1): each run's part in each range drawn by
 * plain_rows, or with plain_rows NULL pixel by pixel (near_run). */
static void near_row_runs(const struct near_row *q, const struct near *n, near_plain_fn *plain_rows,
			  int32_t r0, int32_t r1, long lo, long hi, int inbox, long bx0, long bx1,
			  const int16_t *st, int k, double *row)
{
	long cut[4];
	int nc = 0;

	cut[nc++] = lo;
	if (inbox && bx1 - 1 >= lo && bx0 <= hi) {
		if (bx0 - 1 >= lo)
			cut[nc++] = bx0 - 1;
		else
			nc = 0;
		cut[nc++] = bx1;
	}
	cut[nc++] = hi;
	if (plain_rows)
		plain_rows(q, n, r0, r1, cut, nc, st, k, row);
	else
		near_runs(near_run, q, n, r0, r1, cut, nc, st, k, row);
}

/* The window's rows *jlo .. *jhi (from its first) that can meet the disc
 * of radius^2 rm2 about a source at row y (its pixel's j0), each tested by
 * near_render, and have runs at the source's level (ry: its first and last
 * row with any). */
static void near_window_rows(const struct near *n, const int16_t *ry, double y, long j0,
			     double rm2, const struct wfs_window *win, long *jlo, long *jhi)
{
	long a = lfloor(y - sqrt(rm2)) - 1, b = lceil(y + sqrt(rm2)) + 1;

	a = a > j0 - n->rc ? a : j0 - n->rc;
	b = b < j0 + n->rc ? b : j0 + n->rc;
	a = a > j0 + ry[0] - n->rc ? a : j0 + ry[0] - n->rc;
	b = b < j0 + ry[1] - n->rc ? b : j0 + ry[1] - n->rc;
	a -= win->y0;
	b -= win->y0;
	*jlo = a > 0 ? a : 0;
	*jhi = b < win->ny - 1 ? b : win->ny - 1;
}

/*
 * psf-halo-near=level: the pixels of the window within the array's disc
 * and radius r of the source, outside its box, whose step reaches k (the
 * step map of near_setup, row by row, skipping the segments none of
 * whose pixels reach k), flux times the halo model; the bilinear weights from
 * the pixel nearest the source, so that they do not depend on the window.
 */
SIMD_CLONES("avx2,fma", "default")
void near_render(const struct halo *h, const struct near *n, double flux, double x,
			double y, double r, int k, struct zone box, const struct wfs_window *win)
{
	long i0 = lfloor(x + 0.5), j0 = lfloor(y + 0.5), o = h->over;
	double ux = h->c + o * (i0 - x), uy = h->c + o * (j0 - y), fu, fv, rm2;
	struct near_row q;
	const int32_t *ri;
	const float *b0, *b1;
	double rp, rp2;
	long jlo, jhi, iu, iv0, m0, r0;
	near_plain_fn *plain_rows = near_plain_choose();
#ifdef SIMD_X86
	const int32_t *ci;
	struct near_job jb[NEAR_JOBS];
	int nj = 0, jobs = n->ci != NULL;       /* built where the loop runs */
#endif

	iu = lfloor(ux);
	fu = ux - iu;
	iv0 = lfloor(uy);
	fv = uy - iv0;
	q.h = h;
	q.nh = n->nh;
	q.flux = flux;
	q.x = x;
	q.rin2 = (h->R - h->taper) * (h->R - h->taper);
	q.i0 = i0;
	q.w[0] = (float)(flux * h->s * (1 - fu) * (1 - fv));
	q.w[1] = (float)(flux * h->s * fu * (1 - fv));
	q.w[2] = (float)(flux * h->s * (1 - fu) * fv);
	q.w[3] = (float)(flux * h->s * fu * fv);
	/* sample iu + o dx of a row is plane r0's column m0 + dx; the next
	 * sample plane r0 + 1's, or plane 0's one column on */
	m0 = iu / o;
	r0 = iu - o * m0;
	b0 = n->pl + r0 * h->n * n->nh + m0;
	b1 = r0 + 1 < o ? b0 + h->n * n->nh : n->pl + m0 + 1;
	rm2 = r < h->R ? r * r : h->R * h->R;
	/* beyond the steepest step nothing is drawn; below the lowest, every
	 * offset of the disc, as at the lowest (halo_level keeps k above the
	 * INT16_MIN of the offsets beyond it) */
	if (k > n->kmax)
		return;
	ri = n->ri + (size_t)(k > n->kmin ? k - n->kmin : 0) * n->side;
#ifdef SIMD_X86
	ci = jobs ? n->ci + (ri - n->ri) : NULL;
#endif
	/* a row whose runs' ends lie this far inside both the chord and the
	 * array's plain part (by more than the chord's rounding) draws all of
	 * them as plain reads, without the chord or the per-run tests */
	rp = sqrt(rm2 < q.rin2 ? rm2 : q.rin2) - 1e-6;
	rp2 = rp > 0 ? rp * rp : -1;
	near_window_rows(n, n->ry + 2 * (ri - n->ri) / n->side, y, j0, rm2, win, &jlo, &jhi);
	for (long j = jlo; j <= jhi; j++) {
		long jj = win->y0 + j, dyo = jj - j0, lo, hi, pv;
		long wl = win->x0 - i0, wh = win->x0 + win->nx - 1 - i0;
		double dy = jj - y, xa, xb;
		double *row = win->pix + j * win->stride + i0 - win->x0;
		const int16_t *st;
		int32_t r0, r1;
		int plain, inbox;

		if (labs(dyo) > n->rc || dy * dy >= rm2)
			continue;
		/* the row's runs of segments that reach k */
		r0 = ri[dyo + n->rc];
		r1 = ri[dyo + n->rc + 1];
		if (r0 == r1)
			continue;
		q.dy = dy;
		/* the runs' extent within the window */
		lo = (long)n->rs[2 * r0] * NEAR_SEG - n->rc;
		hi = (long)(n->rs[2 * r1 - 1] + 1) * NEAR_SEG - 1 - n->rc;
		lo = lo < wl ? wl : lo;
		hi = hi > wh ? wh : hi;
		hi = hi > n->rc ? n->rc : hi;
		if (lo > hi)
			continue;
		xa = i0 + lo - x;
		xb = i0 + hi - x;
		plain = xa * xa + dy * dy < rp2 && xb * xb + dy * dy < rp2;
		if (!plain) {
			/* the chord (d2 < rm2, within n->rc) in offsets from i0 */
			double span = sqrt(rm2 - dy * dy);
			long cl = lfloor(x - span) + 1 - i0, ch = lceil(x + span) - 1 - i0;

			lo = lo < cl ? cl : lo;
			hi = hi > ch ? ch : hi;
			if (lo > hi)
				continue;
		}
		st = n->st + (size_t)(dyo + n->rc) * n->side + n->rc;
		pv = (iv0 + o * dyo) * n->nh;
		inbox = jj >= box.y0 && jj < box.y1;
#ifdef SIMD_X86
		if (plain && jobs) {
			jb[nj++] = (struct near_job){ row, st, pv, ci[dyo + n->rc], ci[dyo + n->rc + 1],
						      (int32_t)lo, (int32_t)hi,
						      inbox ? (int32_t)(box.x0 - i0) : 0,
						      inbox ? (int32_t)(box.x1 - i0) : 0 };
			if (nj == NEAR_JOBS) {
				near_jobs_avx512(&q, n, b0, b1, jb, nj, k);
				nj = 0;
			}
			continue;
		}
#endif
		q.p0 = b0 + pv;
		q.p1 = b1 + pv;
		near_row_runs(&q, n, plain ? plain_rows : NULL, r0, r1, lo, hi, inbox,
			      box.x0 - i0, box.x1 - i0, st, k, row);
	}
#ifdef SIMD_X86
	if (nj)
		near_jobs_avx512(&q, n, b0, b1, jb, nj, k);
#endif
}
