/* ramp_pois.c - the Poisson counts of a row for the ramp; see ramp_pois.h. */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <string.h>

#include "ramp_pois.h"
#include "rng.h"
#include "simd.h"

/*
 * Poisson counts of a row from one Philox call per pixel (draw 0 of its
 * cell in generator g), whose four words all serve:
 *
 * Means below POIS_INV are split into m0 = mu rounded down to a multiple
 * of POIS_STEP and the rest delta = mu - m0 (both exact in binary), and the
 * count is Poisson(m0) from words 0-1 plus Poisson(delta) from words 2-3:
 * the sum of independent Poisson counts is a Poisson count of the summed
 * mean, so this is exact.  Each part is the inversion k = min{k : u < F(k)}
 * (rng_poisson_invert), a function of u and its mean alone.  The m0 part
 * is looked up in a table of F for that m0: one table for each of the
 * POIS_NM - 1 multiples of POIS_STEP below POIS_INV, built once for the
 * process (530 kB) and shared by every thread, so that a crowded field,
 * whose m0 changes from pixel to pixel, looks its counts up as a flat sky
 * does (tables kept per worker and rebuilt when m0 changed took 2.6x the
 * level-2 time of an empty SCA on a crowded one).  A guide table (Chen &
 * Asau 1974) of the first k with F(k) > j / POIS_GUIDE starts the search,
 * so a lookup is one or two comparisons.  The delta part is 0 unless u2 >=
 * exp(-delta) and 1 unless u2 >= F(1); bounds on both settle all but
 * ~delta^2 / 2 of the draws without the exp.
 *
 * Means from POIS_INV to the normal limit go to rng_poisson_fill_approx
 * (PTRS, Hormann 1993, exact) on the same cells, a run of such pixels at a
 * time (a star); from the limit (ramp_key.poisson_normal) the
 * skew-corrected normal rng_poisson_normal() of the ziggurat deviate of
 * words 0-1.  So a count never depends on the pixels beside it, nor on
 * what the tables held.
 */
#define POIS_INV 32.0
#define POIS_STEP 0.125
#define POIS_NM 256             /* POIS_INV / POIS_STEP: tables j = 1 .. 255 */

_Static_assert(POIS_NM * POIS_STEP == POIS_INV, "a table for every m0");

static void pois_tabulate(struct pois_tab *t, double mu)
{
	double pk = exp(-mu), f = pk;
	int k, j = 0;

	/* the same products as rng_poisson_invert, so the same counts */
	t->mu = mu;
	t->cdf[0] = f;
	for (int n = 1; n < POIS_TAB; n++) {
		pk *= mu * (1.0 / n);
		f += pk;
		t->cdf[n] = f;
	}
	/* guide j: the first k with F(k) > j / POIS_GUIDE, the least count
	 * of a u in [j, j + 1) / POIS_GUIDE; bit 7 (POIS_PAST) when F(k) <
	 * (j + 1) / POIS_GUIDE, where such a u may pass it (without, the
	 * count is k) */
	/* by runs: the j with j / G < F(k) are those below ceil(F(k) G)
	 * (G a power of 2, so exactly), and of the run of k only its last
	 * bucket can hold F(k), unless F(k) G is a whole number */
	for (k = 0; k < POIS_TAB - 1 && j < POIS_GUIDE; k++) {
		double c = t->cdf[k] * POIS_GUIDE, e = ceil(c);
		int end = e < POIS_GUIDE ? (int)e : POIS_GUIDE;

		if (end <= j)
			continue;
		memset(t->guide + j, k, (size_t)(end - j));
		if (c < end)
			t->guide[end - 1] |= POIS_PAST;
		j = end;
	}
	/* past F(POIS_TAB - 2): the table's last count */
	for (; j < POIS_GUIDE; j++)
		t->guide[j] = (unsigned char)((POIS_TAB - 1) |
					      (t->cdf[POIS_TAB - 1] < (double)(j + 1) / POIS_GUIDE ?
					       POIS_PAST : 0));
}

static inline int pois_lookup(const struct pois_tab *t, double u)
{
	int k = t->guide[(int)(u * POIS_GUIDE)] & (POIS_PAST - 1);

	/* one step without a branch: whether u is past the guide's k is
	 * a coin toss for the predictor; a second step is rare */
	k += u >= t->cdf[k];
	while (u >= t->cdf[k])
		k++;
	return k;
}

/* The tables of m0 = j POIS_STEP, j = 1 .. POIS_NM - 1 (j = 0, a mean of
 * 0, has none), built by the first ramp_pois_row(). */
static struct pois_tab pois_tabs[POIS_NM];
static double pois_top;          /* the least of their F(POIS_TAB - 1) */
static pthread_once_t pois_once = PTHREAD_ONCE_INIT;

static void pois_build(void)
{
	pois_top = 1;
	for (int j = 1; j < POIS_NM; j++) {
		pois_tabulate(&pois_tabs[j], j * POIS_STEP);
		if (pois_tabs[j].cdf[POIS_TAB - 1] < pois_top)
			pois_top = pois_tabs[j].cdf[POIS_TAB - 1];
	}
}

/* What pois_row() carries from pixel to pixel: exp(-delta) of the last
 * delta that needed it. */
struct pois_state {
	double dlast, edlast;
};

/* The count of the rest 0 < delta < 1/8 from the uniform u2. */
static inline double pois_rest(double delta, double u2, struct pois_state *st)
{
	double d2 = delta * delta;

	/*
	 * For 0 < d < 1/8 the alternating series of falling terms bound
	 *   1 - d + d^2/2 - d^3/6 < exp(-d) < 1 - d + d^2/2,
	 *   exp(-d) (1 + d) > 1 - d^2/2 + d^3/3 - d^4/8,
	 * the last F(1), the probability of a count of 0 or 1.  With 2^-50
	 * for the roundings of both sides (the exp's and F(1)'s included),
	 * they give the count 0 or 1 without the exp, which only the rest
	 * (~d^2 / 2) needs.
	 */
	if (u2 < (1 - delta + d2 * (0.5 - delta * (1.0 / 6))) * (1 - 0x1p-50))
		return 0;
	if (u2 >= (1 - delta + 0.5 * d2) * (1 + 0x1p-50) &&
	    u2 < (1 - d2 * (0.5 - delta * (1.0 / 3) + d2 * 0.125)) * (1 - 0x1p-50))
		return 1;
	if (delta != st->dlast) {
		st->dlast = delta;
		st->edlast = exp(-delta);
	}
	return u2 >= st->edlast ? rng_poisson_invert(u2, delta, st->edlast) : 0;
}

/* The count of a mean 0 < v < POIS_INV from its call w. */
static inline double pois_small(double v, const uint32_t w[4], struct pois_state *st)
{
	/* 0 < v < 32: truncation is floor, without a call */
	int j = (int)(v * (1 / POIS_STEP));
	double m0 = (double)j * POIS_STEP;
	double delta = v - m0;
	double u = rng_u01(w[0], w[1]), k = 0;

	if (j > 0) {
		const struct pois_tab *t = &pois_tabs[j];

		if (u < t->cdf[POIS_TAB - 1])
			k = pois_lookup(t, u);
		else
			k = rng_poisson_invert(u, m0, exp(-m0));
	}
	if (delta > 0)
		k += pois_rest(delta, rng_u01(w[2], w[3]), st);
	return k;
}

#ifdef SIMD_X86
/*
 * pois_small() for the eight means v[0..8) with AVX-512, when each is
 * below POIS_INV: the table lookups by gathers, the rest's count 0 or 1
 * from the same bounds, the rest's exact count (rare) by pois_rest().
 * The same counts into out; returns 0, having done nothing, when the
 * eight do not qualify.
 */
__attribute__((target("avx512f,avx512dq"))) static int
pois8_avx512(const double *v, const uint32_t (*w)[4], struct pois_state *st, double *out)
{
	const __m512i ev = _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0);
	const __m512i od = _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1);
	const __m512i one = _mm512_set1_epi64(1);
	const __m512d u53 = _mm512_set1_pd(0x1p-53), c1 = _mm512_set1_pd(1);
	const long long stride = (long long)sizeof(struct pois_tab);
	const unsigned char *guide0 = pois_tabs[0].guide;
	const double *cdf0 = pois_tabs[0].cdf;
	__m512d x = _mm512_loadu_pd(v), m0, delta, u, u2, d2, kd;
	__m512i lo4, hi4, w01, w23, j, k, off, ci;
	__mmask8 lit, more, rest, slow;
	double rests[8], vq[8];

	if (_mm512_cmp_pd_mask(x, _mm512_setzero_pd(), _CMP_GT_OQ) != 0xff ||
	    _mm512_cmp_pd_mask(x, _mm512_set1_pd(POIS_INV), _CMP_LT_OQ) != 0xff)
		return 0;
	j = _mm512_cvtepi32_epi64(_mm512_cvttpd_epi32(_mm512_mul_pd(x, _mm512_set1_pd(1 / POIS_STEP))));
	m0 = _mm512_mul_pd(_mm512_cvtepi64_pd(j), _mm512_set1_pd(POIS_STEP));
	lit = _mm512_cmpgt_epi64_mask(j, _mm512_setzero_si512());
	lo4 = _mm512_loadu_si512(w[0]);
	hi4 = _mm512_loadu_si512(w[4]);
	w01 = _mm512_ror_epi64(_mm512_permutex2var_epi64(lo4, ev, hi4), 32);
	w23 = _mm512_ror_epi64(_mm512_permutex2var_epi64(lo4, od, hi4), 32);
	u = _mm512_mul_pd(_mm512_cvtepu64_pd(_mm512_srli_epi64(w01, 11)), u53);
	/* each lane's table: its offset from pois_tabs[0] in bytes, in
	 * doubles for the cdf (a table is a whole number of doubles) */
	off = _mm512_mul_epu32(j, _mm512_set1_epi64(stride));
	ci = _mm512_srli_epi64(off, 3);
	/* past the least table's top (u within ulps of 1: never seen), the
	 * lane's own table decides, below */
	slow = lit & _mm512_cmp_pd_mask(u, _mm512_set1_pd(pois_top), _CMP_NLT_UQ);
	k = _mm512_mask_i64gather_epi64(_mm512_setzero_si512(), lit & ~slow,
					_mm512_add_epi64(off, _mm512_cvttpd_epi64(_mm512_mul_pd(
						u, _mm512_set1_pd(POIS_GUIDE)))), guide0, 1);
	/* the search from the guide's k, where it is flagged: u >= F(k)
	 * steps on; the first two steps' F together (F(k + 1) counts only
	 * past F(k): F rises, and the guide's k may be the table's last,
	 * below the top) */
	more = lit & ~slow & _mm512_test_epi64_mask(k, _mm512_set1_epi64(POIS_PAST));
	k = _mm512_and_epi64(k, _mm512_set1_epi64(POIS_PAST - 1));
	if (more) {
		__m512i c = _mm512_add_epi64(ci, k);
		__m512d f0 = _mm512_mask_i64gather_pd(c1, more, c, cdf0, 8);
		__m512d f1 = _mm512_mask_i64gather_pd(c1, more, _mm512_add_epi64(c, one), cdf0, 8);
		__mmask8 a = more & _mm512_cmp_pd_mask(u, f0, _CMP_GE_OQ);

		k = _mm512_mask_add_epi64(k, a, k, one);
		more = a & _mm512_cmp_pd_mask(u, f1, _CMP_GE_OQ);
		k = _mm512_mask_add_epi64(k, more, k, one);
	}
	while (more) {
		__m512d f = _mm512_mask_i64gather_pd(c1, more, _mm512_add_epi64(ci, k), cdf0, 8);

		more &= _mm512_cmp_pd_mask(u, f, _CMP_GE_OQ);
		k = _mm512_mask_add_epi64(k, more, k, one);
	}
	kd = _mm512_cvtepi64_pd(k);
	/* the rest */
	delta = _mm512_sub_pd(x, m0);
	rest = _mm512_cmp_pd_mask(delta, _mm512_setzero_pd(), _CMP_GT_OQ);
	if (rest) {
		__m512d l0, u0, l1;
		__mmask8 z, o;

		u2 = _mm512_mul_pd(_mm512_cvtepu64_pd(_mm512_srli_epi64(w23, 11)), u53);
		d2 = _mm512_mul_pd(delta, delta);
		l0 = _mm512_add_pd(_mm512_sub_pd(c1, delta),
				   _mm512_mul_pd(d2, _mm512_sub_pd(_mm512_set1_pd(0.5),
								   _mm512_mul_pd(delta, _mm512_set1_pd(1.0 / 6)))));
		l0 = _mm512_mul_pd(l0, _mm512_set1_pd(1 - 0x1p-50));
		u0 = _mm512_add_pd(_mm512_sub_pd(c1, delta), _mm512_mul_pd(_mm512_set1_pd(0.5), d2));
		u0 = _mm512_mul_pd(u0, _mm512_set1_pd(1 + 0x1p-50));
		l1 = _mm512_add_pd(_mm512_sub_pd(_mm512_set1_pd(0.5),
						 _mm512_mul_pd(delta, _mm512_set1_pd(1.0 / 3))),
				   _mm512_mul_pd(d2, _mm512_set1_pd(0.125)));
		l1 = _mm512_mul_pd(_mm512_sub_pd(c1, _mm512_mul_pd(d2, l1)),
				   _mm512_set1_pd(1 - 0x1p-50));
		z = rest & _mm512_cmp_pd_mask(u2, l0, _CMP_LT_OQ);
		o = rest & ~z & _mm512_cmp_pd_mask(u2, u0, _CMP_GE_OQ) &
		    _mm512_cmp_pd_mask(u2, l1, _CMP_LT_OQ);
		kd = _mm512_mask_add_pd(kd, o, kd, c1);
		rest &= ~z & ~o;
		if (rest)
			_mm512_storeu_pd(rests, u2);
	}
	/* out may be v (the gap's counts replace their means) */
	_mm512_storeu_pd(vq, x);
	_mm512_storeu_pd(out, kd);
	/* the lanes left: the table's top passed (the inversion), the rest's
	 * exact count; in pixel order, as pois_small() would */
	for (int q = 0; q < 8 && (slow | rest); q++) {
		double mq = (double)(int)(vq[q] * (1 / POIS_STEP)) * POIS_STEP;

		if (slow >> q & 1) {
			const struct pois_tab *t = &pois_tabs[(int)(vq[q] * (1 / POIS_STEP))];
			double uq = rng_u01(w[q][0], w[q][1]);

			out[q] += uq < t->cdf[POIS_TAB - 1] ? pois_lookup(t, uq) :
				  rng_poisson_invert(uq, mq, exp(-mq));
		}
		if (rest >> q & 1)
			out[q] += pois_rest(vq[q] - mq, rests[q], st);
	}
	return 1;
}
#endif

void ramp_pois_row(const struct rng *g, uint32_t cell0, int n, const double *mu,
		   double *out, double normal_above)
{
	uint32_t w[256][4];
	struct pois_state st = { .dlast = -1, .edlast = 1 };
#ifdef SIMD_X86
	int wide = (simd_flags() & SIMD_AVX512) != 0;
#endif

	pthread_once(&pois_once, pois_build);
	for (int i0 = 0; i0 < n; i0 += 256) {
		int m = n - i0 < 256 ? n - i0 : 256;

		rng_bits_n(g, cell0 + (uint32_t)i0, 0, (size_t)m, w);
		for (int j = 0; j < m; j++) {
			int i = i0 + j;
			double v = mu[i];

#ifdef SIMD_X86
			if (wide && !(j & 7) && j + 8 <= m &&
			    pois8_avx512(mu + i, w + j, &st, out + i)) {
				j += 7;
				continue;
			}
#endif
			if (!(v > 0)) {
				out[i] = 0;
			} else if (v < POIS_INV) {
				out[i] = pois_small(v, w[j], &st);
			} else if (v >= normal_above) {
				out[i] = rng_poisson_normal(v, rng_normal_bits(g, cell0 + (uint32_t)i,
									       w[j][0], w[j][1]));
			} else {
				/* a run of PTRS means, drawn together */
				int e = j + 1;

				while (e < m && mu[i0 + e] >= POIS_INV && mu[i0 + e] < normal_above)
					e++;
				rng_poisson_fill(g, cell0 + (uint32_t)i, (size_t)(e - j), mu + i, out + i);
				j = e - 1;
			}
		}
	}
}
