/* rng.c - Philox4x32-10 and the Poisson and normal samplers; see rng.h. */
#include <math.h>
#include <string.h>

#include "rng.h"
#include "simd.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/*
 * Philox4x32: each round multiplies words 0 and 2 by two constants (32x32 ->
 * 64 bits), swaps the halves across the words and XORs in the round key;
 * the key is bumped by two Weyl constants (golden ratio and sqrt(3) - 1)
 * between rounds.  The paper finds seven rounds enough for BigCrush and
 * recommends ten for a safety margin.  Constants from the paper.
 */
#define PHILOX_M0 0xD2511F53u
#define PHILOX_M1 0xCD9E8D57u
#define PHILOX_W0 0x9E3779B9u
#define PHILOX_W1 0xBB67AE85u

/* The version word of every counter: change it if the meaning of the
 * streams changes, so old and new images never share numbers by accident. */
#define RNG_VERSION 0x57465331u /* "WFS1" */

void rng_philox(const uint32_t ctr[4], const uint32_t key[2], uint32_t out[4])
{
	uint32_t c0 = ctr[0], c1 = ctr[1], c2 = ctr[2], c3 = ctr[3];
	uint32_t k0 = key[0], k1 = key[1];

	for (int r = 0; r < 10; r++) {
		uint64_t p0 = (uint64_t)PHILOX_M0 * c0;
		uint64_t p1 = (uint64_t)PHILOX_M1 * c2;
		uint32_t n0 = (uint32_t)(p1 >> 32) ^ c1 ^ k0;
		uint32_t n2 = (uint32_t)(p0 >> 32) ^ c3 ^ k1;

		c1 = (uint32_t)p1;
		c3 = (uint32_t)p0;
		c0 = n0;
		c2 = n2;
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	out[0] = c0;
	out[1] = c1;
	out[2] = c2;
	out[3] = c3;
}

void rng_init(struct rng *g, uint64_t seed, uint32_t dom)
{
	g->key[0] = (uint32_t)seed;
	g->key[1] = (uint32_t)(seed >> 32);
	g->dom[0] = dom;
	g->dom[1] = RNG_VERSION;
}

void rng_bits(const struct rng *g, uint32_t cell, uint32_t draw, uint32_t out[4])
{
	uint32_t ctr[4] = { cell, draw, g->dom[0], g->dom[1] };

	rng_philox(ctr, g->key, out);
}

#if defined(__SSE2__)
/*
 * Eight Philox calls at once with SSE2: two groups of four lanes, so that
 * the two multiply chains overlap.  _mm_mul_epu32 multiplies lanes 0 and 2
 * to 64 bits; lanes 1 and 3 are shifted down and multiplied separately, and
 * the high and low halves are gathered back into lane order.
 */
static inline void mulhilo4(__m128i x, __m128i m, __m128i *hi, __m128i *lo)
{
	const __m128i low = _mm_set_epi32(0, -1, 0, -1);
	__m128i even = _mm_mul_epu32(x, m);
	__m128i odd = _mm_mul_epu32(_mm_srli_epi64(x, 32), m);

	*hi = _mm_or_si128(_mm_srli_epi64(even, 32), _mm_andnot_si128(low, odd));
	*lo = _mm_or_si128(_mm_and_si128(even, low), _mm_slli_epi64(odd, 32));
}

static inline void store4(__m128i x0, __m128i x1, __m128i x2, __m128i x3,
			  uint32_t out[4][4])
{
	__m128i t0 = _mm_unpacklo_epi32(x0, x1), t1 = _mm_unpacklo_epi32(x2, x3);
	__m128i t2 = _mm_unpackhi_epi32(x0, x1), t3 = _mm_unpackhi_epi32(x2, x3);

	_mm_storeu_si128((__m128i *)out[0], _mm_unpacklo_epi64(t0, t1));
	_mm_storeu_si128((__m128i *)out[1], _mm_unpackhi_epi64(t0, t1));
	_mm_storeu_si128((__m128i *)out[2], _mm_unpacklo_epi64(t2, t3));
	_mm_storeu_si128((__m128i *)out[3], _mm_unpackhi_epi64(t2, t3));
}

/* Philox of the eight cells a0 (lanes 0-3) and b0 (4-7) at draw. */
static inline __attribute__((always_inline)) void
philox8_cells(const struct rng *g, __m128i a0, __m128i b0, uint32_t draw, uint32_t out[8][4])
{
	const __m128i m0 = _mm_set1_epi32((int)PHILOX_M0);
	const __m128i m1 = _mm_set1_epi32((int)PHILOX_M1);
	__m128i a1 = _mm_set1_epi32((int)draw), b1 = a1;
	__m128i a2 = _mm_set1_epi32((int)g->dom[0]), b2 = a2;
	__m128i a3 = _mm_set1_epi32((int)g->dom[1]), b3 = a3;
	uint32_t k0 = g->key[0], k1 = g->key[1];

	for (int r = 0; r < 10; r++) {
		__m128i k0v = _mm_set1_epi32((int)k0), k1v = _mm_set1_epi32((int)k1);
		__m128i ah0, al0, ah1, al1, bh0, bl0, bh1, bl1;

		mulhilo4(a0, m0, &ah0, &al0);
		mulhilo4(a2, m1, &ah1, &al1);
		mulhilo4(b0, m0, &bh0, &bl0);
		mulhilo4(b2, m1, &bh1, &bl1);
		a0 = _mm_xor_si128(_mm_xor_si128(ah1, a1), k0v);
		a2 = _mm_xor_si128(_mm_xor_si128(ah0, a3), k1v);
		a1 = al1;
		a3 = al0;
		b0 = _mm_xor_si128(_mm_xor_si128(bh1, b1), k0v);
		b2 = _mm_xor_si128(_mm_xor_si128(bh0, b3), k1v);
		b1 = bl1;
		b3 = bl0;
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	store4(a0, a1, a2, a3, out);
	store4(b0, b1, b2, b3, out + 4);
}

/* The same for four cells a0 (a group of four alone: half the work). */
static void philox4_cells(const struct rng *g, __m128i a0, uint32_t draw, uint32_t out[4][4])
{
	const __m128i m0 = _mm_set1_epi32((int)PHILOX_M0);
	const __m128i m1 = _mm_set1_epi32((int)PHILOX_M1);
	__m128i a1 = _mm_set1_epi32((int)draw), a2 = _mm_set1_epi32((int)g->dom[0]);
	__m128i a3 = _mm_set1_epi32((int)g->dom[1]);
	uint32_t k0 = g->key[0], k1 = g->key[1];

	for (int r = 0; r < 10; r++) {
		__m128i ah0, al0, ah1, al1;

		mulhilo4(a0, m0, &ah0, &al0);
		mulhilo4(a2, m1, &ah1, &al1);
		a0 = _mm_xor_si128(_mm_xor_si128(ah1, a1), _mm_set1_epi32((int)k0));
		a2 = _mm_xor_si128(_mm_xor_si128(ah0, a3), _mm_set1_epi32((int)k1));
		a1 = al1;
		a3 = al0;
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	store4(a0, a1, a2, a3, out);
}

static void philox8(const struct rng *g, uint32_t cell0, uint32_t draw,
		    uint32_t out[8][4])
{
	__m128i a0 = _mm_add_epi32(_mm_set1_epi32((int)cell0), _mm_set_epi32(3, 2, 1, 0));

	philox8_cells(g, a0, _mm_add_epi32(a0, _mm_set1_epi32(4)), draw, out);
}

void rng_bits_cells(const struct rng *g, const uint32_t *cells, uint32_t draw, size_t n,
		    uint32_t (*out)[4])
{
	for (size_t i = 0; i < n; i += 8) {
		uint32_t c[8], tmp[8][4];
		size_t m = n - i < 8 ? n - i : 8;

		for (size_t l = 0; l < 8; l++)
			c[l] = cells[i + (l < m ? l : m - 1)];
		if (m <= 4)
			philox4_cells(g, _mm_loadu_si128((const __m128i *)c), draw, tmp);
		else
			philox8_cells(g, _mm_loadu_si128((const __m128i *)c),
				      _mm_loadu_si128((const __m128i *)(c + 4)), draw, tmp);
		memcpy(out + i, tmp, m * sizeof(tmp[0]));
	}
}
#else
static void philox8(const struct rng *g, uint32_t cell0, uint32_t draw,
		    uint32_t out[8][4])
{
	for (uint32_t l = 0; l < 8; l++)
		rng_bits(g, cell0 + l, draw, out[l]);
}

void rng_bits_cells(const struct rng *g, const uint32_t *cells, uint32_t draw, size_t n,
		    uint32_t (*out)[4])
{
	while (n--)
		rng_bits(g, *cells++, draw, *out++);
}
#endif

#ifdef SIMD_X86
/*
 * Sixteen calls with AVX2, the same arithmetic as philox8 on eight lanes
 * per register, chosen at run time (the results are the same integers, so
 * the choice never changes an image).
 */
__attribute__((target("avx2"))) static inline void
mulhilo8(__m256i x, __m256i m, __m256i *hi, __m256i *lo)
{
	const __m256i low = _mm256_set1_epi64x(0xffffffff);
	__m256i even = _mm256_mul_epu32(x, m);
	__m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(x, 32), m);

	*hi = _mm256_or_si256(_mm256_srli_epi64(even, 32), _mm256_andnot_si256(low, odd));
	*lo = _mm256_or_si256(_mm256_and_si256(even, low), _mm256_slli_epi64(odd, 32));
}

__attribute__((target("avx2"))) static void
philox16_avx2(const struct rng *g, uint32_t cell0, uint32_t draw, uint32_t out[16][4])
{
	const __m256i m0 = _mm256_set1_epi32((int)PHILOX_M0);
	const __m256i m1 = _mm256_set1_epi32((int)PHILOX_M1);
	__m256i a0 = _mm256_add_epi32(_mm256_set1_epi32((int)cell0),
				      _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0));
	__m256i b0 = _mm256_add_epi32(a0, _mm256_set1_epi32(8));
	__m256i a1 = _mm256_set1_epi32((int)draw), b1 = a1;
	__m256i a2 = _mm256_set1_epi32((int)g->dom[0]), b2 = a2;
	__m256i a3 = _mm256_set1_epi32((int)g->dom[1]), b3 = a3;
	uint32_t k0 = g->key[0], k1 = g->key[1];
	__m256i t0, t1, t2, t3, u0, u1, u2, u3;

	for (int r = 0; r < 10; r++) {
		__m256i k0v = _mm256_set1_epi32((int)k0), k1v = _mm256_set1_epi32((int)k1);
		__m256i ah0, al0, ah1, al1, bh0, bl0, bh1, bl1;

		mulhilo8(a0, m0, &ah0, &al0);
		mulhilo8(a2, m1, &ah1, &al1);
		mulhilo8(b0, m0, &bh0, &bl0);
		mulhilo8(b2, m1, &bh1, &bl1);
		a0 = _mm256_xor_si256(_mm256_xor_si256(ah1, a1), k0v);
		a2 = _mm256_xor_si256(_mm256_xor_si256(ah0, a3), k1v);
		a1 = al1;
		a3 = al0;
		b0 = _mm256_xor_si256(_mm256_xor_si256(bh1, b1), k0v);
		b2 = _mm256_xor_si256(_mm256_xor_si256(bh0, b3), k1v);
		b1 = bl1;
		b3 = bl0;
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	/* 4x4 transposes within each 128-bit half: lanes 0-3 land in the
	 * low halves, lanes 4-7 in the high halves. */
	for (int h = 0; h < 2; h++) {
		__m256i x0 = h ? b0 : a0, x1 = h ? b1 : a1, x2 = h ? b2 : a2, x3 = h ? b3 : a3;
		uint32_t (*o)[4] = out + 8 * h;

		t0 = _mm256_unpacklo_epi32(x0, x1);
		t1 = _mm256_unpacklo_epi32(x2, x3);
		t2 = _mm256_unpackhi_epi32(x0, x1);
		t3 = _mm256_unpackhi_epi32(x2, x3);
		u0 = _mm256_unpacklo_epi64(t0, t1);
		u1 = _mm256_unpackhi_epi64(t0, t1);
		u2 = _mm256_unpacklo_epi64(t2, t3);
		u3 = _mm256_unpackhi_epi64(t2, t3);
		_mm256_storeu_si256((__m256i *)o[0], _mm256_permute2x128_si256(u0, u1, 0x20));
		_mm256_storeu_si256((__m256i *)o[2], _mm256_permute2x128_si256(u2, u3, 0x20));
		_mm256_storeu_si256((__m256i *)o[4], _mm256_permute2x128_si256(u0, u1, 0x31));
		_mm256_storeu_si256((__m256i *)o[6], _mm256_permute2x128_si256(u2, u3, 0x31));
	}
}
#endif

#ifdef SIMD_X86
/*
 * Calls with AVX-512, a counter word in the low half of each 64-bit lane:
 * the 32 x 32 -> 64 bit multiplication then gives a lane's high and low
 * words with no shuffling (the upper halves carry junk that the next
 * multiplication ignores and the end drops), and one ternary-logic step
 * XORs three words.  PHILOX_SETS sets of eight calls go through the
 * rounds side by side, so that one set's multiplications run while
 * another's wait (the loops unrolled, the words in registers).  The same
 * integers as rng_philox, chosen at run time as philox16_avx2 is.
 */
#define PHILOX_SETS 6

__attribute__((target("avx512f"), always_inline)) static inline void
philox_sets_avx512(const struct rng *g, uint32_t cell0, uint32_t draw, uint32_t (*out)[4],
		   int nsets)
{
	const __m512i m0 = _mm512_set1_epi64(PHILOX_M0), m1 = _mm512_set1_epi64(PHILOX_M1);
	const __m512i lo = _mm512_set_epi64(11, 3, 10, 2, 9, 1, 8, 0);
	const __m512i hi = _mm512_set_epi64(15, 7, 14, 6, 13, 5, 12, 4);
	__m512i c[PHILOX_SETS][4];
	uint32_t k0 = g->key[0], k1 = g->key[1];

#pragma GCC unroll 6
	for (int h = 0; h < nsets; h++) {
		c[h][0] = _mm512_add_epi64(_mm512_set1_epi64(cell0 + 8 * h),
					   _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0));
		c[h][1] = _mm512_set1_epi64(draw);
		c[h][2] = _mm512_set1_epi64(g->dom[0]);
		c[h][3] = _mm512_set1_epi64(g->dom[1]);
	}
#pragma GCC unroll 10
	for (int r = 0; r < 10; r++) {
		__m512i k0v = _mm512_set1_epi64(k0), k1v = _mm512_set1_epi64(k1);

#pragma GCC unroll 6
		for (int h = 0; h < nsets; h++) {
			__m512i p0 = _mm512_mul_epu32(c[h][0], m0), p1 = _mm512_mul_epu32(c[h][2], m1);

			/* 0x96: the XOR of the three operands */
			c[h][0] = _mm512_ternarylogic_epi64(_mm512_srli_epi64(p1, 32), c[h][1], k0v,
							    0x96);
			c[h][2] = _mm512_ternarylogic_epi64(_mm512_srli_epi64(p0, 32), c[h][3], k1v,
							    0x96);
			c[h][1] = p1;
			c[h][3] = p0;
		}
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	/* words 0 and 1 of a call side by side in a 64-bit lane, so are
	 * 2 and 3; then the lanes of the two interleaved into calls */
#pragma GCC unroll 6
	for (int h = 0; h < nsets; h++) {
		__m512i w01 = _mm512_mask_blend_epi32(0xaaaa, c[h][0], _mm512_slli_epi64(c[h][1], 32));
		__m512i w23 = _mm512_mask_blend_epi32(0xaaaa, c[h][2], _mm512_slli_epi64(c[h][3], 32));

		_mm512_storeu_si512(out[8 * h], _mm512_permutex2var_epi64(w01, lo, w23));
		_mm512_storeu_si512(out[8 * h + 4], _mm512_permutex2var_epi64(w01, hi, w23));
	}
}

/* 8 * PHILOX_SETS calls, and 16 for what is left of a row. */
__attribute__((target("avx512f"))) static void
philox_avx512(const struct rng *g, uint32_t cell0, uint32_t draw, uint32_t (*out)[4])
{
	philox_sets_avx512(g, cell0, draw, out, PHILOX_SETS);
}

__attribute__((target("avx512f"))) static void
philox16_avx512(const struct rng *g, uint32_t cell0, uint32_t draw, uint32_t (*out)[4])
{
	philox_sets_avx512(g, cell0, draw, out, 2);
}
#endif

void rng_bits_n(const struct rng *g, uint32_t cell0, uint32_t draw, size_t n,
		uint32_t (*out)[4])
{
	size_t i = 0;

#ifdef SIMD_X86
	if (n >= 16 && (simd_flags() & SIMD_AVX512)) {
		for (; i + 8 * PHILOX_SETS <= n; i += 8 * PHILOX_SETS)
			philox_avx512(g, cell0 + (uint32_t)i, draw, out + i);
		for (; i + 16 <= n; i += 16)
			philox16_avx512(g, cell0 + (uint32_t)i, draw, out + i);
	}
	if (n - i >= 16 && (simd_flags() & SIMD_AVX2))
		for (; i + 16 <= n; i += 16)
			philox16_avx2(g, cell0 + (uint32_t)i, draw, out + i);
#endif

	for (; i + 8 <= n; i += 8)
		philox8(g, cell0 + (uint32_t)i, draw, out + i);
	if (i < n) {
		uint32_t tmp[8][4];

		philox8(g, cell0 + (uint32_t)i, draw, tmp);
		memcpy(out + i, tmp, (n - i) * sizeof(tmp[0]));
	}
}

void rng_cell_refill(struct rng_cell *c)
{
	uint32_t w[4];

	rng_bits(c->g, c->cell, c->draw++, w);
	c->buf[0] = rng_u01(w[0], w[1]);
	c->buf[1] = rng_u01(w[2], w[3]);
	c->left = 2;
}

/* log k! for k < 10, exactly rounded. */
static const double log_fact[10] = {
	0.0, 0.0, 0.69314718055994531, 1.7917594692280550,
	3.1780538303479458, 4.7874917427820458, 6.5792512120101012,
	8.5251613610654147, 10.604602902745251, 12.801827480081469,
};

/*
 * Stirling's series for the error of Stirling's formula,
 *   s(k) = log k! - [(k + 1/2) log k - k + log(2 pi) / 2]
 *        = 1/(12k) - 1/(360k^3) + 1/(1260k^5) - 1/(1680k^7) + 1/(1188k^9) ...
 * (Bernoulli numbers B_2j / (2j(2j-1) k^(2j-1))).  The series is asymptotic
 * with alternating terms, so the error is below the first omitted term,
 * 691/(360360 k^11) < 2e-14 for k >= 10.
 */
static double stirling_err(double k)
{
	double r = 1.0 / k, r2 = r * r;

	return r * (1.0 / 12 - r2 * (1.0 / 360 - r2 * (1.0 / 1260 -
		r2 * (1.0 / 1680 - r2 * (1.0 / 1188)))));
}

/*
 * log P(k; mu) = k log mu - mu - log k! for k >= 10, without the
 * cancellation of the direct formula when k is close to mu (at mu = 1e12
 * the terms are ~1e13 and the result ~-15).  Stirling's formula gives
 *
 *   log P = -bd0 - (log(2 pi) + log k) / 2 - s(k),
 *   bd0 = k log(k/mu) + mu - k >= 0,
 *
 * and with d = k - mu (exact, from the caller), v = d / (k + mu), so that
 * k/mu = (1 + v)/(1 - v):
 *
 *   log(k/mu) = 2 atanh(v) = 2 (v + v^3/3 + v^5/5 + ...)
 *   bd0 = 2k atanh(v) - d = d v + 2k (v^3/3 + v^5/5 + ...)   (2kv - d = dv)
 *
 * a sum of terms of one sign (the idea of C. Loader, "Fast and accurate
 * computation of binomial probabilities", 2000).  For |v| < 0.1 the terms
 * fall by v^2 < 0.01, so 8 of them reach 1e-17 relative, and log k comes
 * from the same series; otherwise the direct formula loses nothing because
 * bd0 is not small against k.
 */
#define LOG_2PI 1.8378770664093455

static double poisson_logpmf(double k, double mu, double log_mu, double d)
{
	double v, bd, log_k;

	if (k < 10)
		return k * log_mu - mu - log_fact[(int)k];
	v = d / (k + mu);
	if (fabs(v) < 0.1) {
		/* s = v^3/3 + v^5/5 + ... + v^17/17 by Horner */
		double v2 = v * v;
		double s = v * v2 * (1.0 / 3 + v2 * (1.0 / 5 + v2 * (1.0 / 7 +
			v2 * (1.0 / 9 + v2 * (1.0 / 11 + v2 * (1.0 / 13 +
			v2 * (1.0 / 15 + v2 * (1.0 / 17))))))));

		bd = d * v + 2 * k * s;
		log_k = log_mu + 2 * (v + s);
	} else {
		log_k = log(k);
		bd = k * (log_k - log_mu) + mu - k;
	}
	return -bd - 0.5 * (LOG_2PI + log_k) - stirling_err(k);
}

int rng_poisson_invert(double u, double mu, double emu)
{
	double pk = emu, f = pk;
	int k = 0;

	while (u >= f && k < RNG_INVERT_MAX) {
		k++;
		pk *= mu * (k < RNG_RECIP ? rng_recip[k] : 1.0 / k);
		f += pk;
	}
	return k;
}

void rng_poisson_setup(struct rng_poisson *p, double mu)
{
	p->mu = mu;
	p->ncdf = 0;
	p->log_mu = 0;
	if (!(mu > 0)) {
		p->method = 0;
	} else if (mu < 10) {
		p->method = 1;
		p->emu = exp(-mu);
	} else if (mu <= RNG_POISSON_EXACT_MAX) {
		/* Hormann's constants, fitted in the paper for mu >= 10. */
		p->method = 2;
		p->smu = sqrt(mu);
		p->b = 0.931 + 2.53 * p->smu;
		p->a = -0.059 + 0.02483 * p->b;
		p->vr = 0.9277 - 3.6224 / (p->b - 2);
	} else {
		p->method = 3;
		p->smu = sqrt(mu);
	}
}

/*
 * Small means (mu < 10): inversion by sequential search (Devroye,
 * "Non-Uniform Random Variate Generation", 1986, X.3.3): the smallest k with
 * u < F(k), building F from p(0) = exp(-mu) and p(k) = p(k-1) mu / k.  Exact
 * up to the rounding of F (k ulps, k < 40 in practice); expected mu + 1
 * steps.  The cap at 200 only guards against u within an ulp of 1, where the
 * rounded F may never exceed it; P(k >= 200) < 1e-200 for mu < 10.
 *
 * Means 10 .. 2^52: PTRS, the transformed rejection with squeeze of
 * W. Hormann, "The transformed rejection method for generating Poisson
 * random variables", Insurance: Mathematics and Economics 12 (1993) 39-45.
 * A hat built from the inverse of a fitted rational transformation covers
 * the pmf for every mu >= 10; 1.1 to 1.2 uniform pairs per draw, and most
 * draws are accepted by the squeeze (us >= 0.07, v <= vr) without a
 * logarithm.  The acceptance test needs log P(k) to absolute accuracy
 * ~1e-12 even at mu = 1e12, hence bd0 and Stirling's series above, and k is
 * formed as floor(mu) + floor(frac(mu) + ...) so that it is an exact integer
 * up to 2^53.
 *
 * Above 2^52 a double cannot even hold every integer near mu (the spacing
 * is 1, then 2 above 2^53), and the count is mu + sqrt(mu) z rounded.  The
 * Edgeworth expansion bounds the distance between the two distribution
 * functions by about |1 - z^2| phi(z) / (6 sqrt(mu)) + 1/sqrt(2 pi mu) (the
 * lattice term) < 1e-8 for mu > 2^52, a difference that needs ~1e16
 * samples to see: far beyond any image.
 */
double rng_poisson_draw(struct rng_poisson *p, struct rng_cell *c)
{
	switch (p->method) {
	case 0:
		return 0;
	case 1: {
		double u = rng_cell_u01(c);

		if (p->ncdf) {
			/* F is increasing, so the count of F(i) <= u is the
			 * smallest k with u < F(k); counting without branches
			 * avoids a mispredicted exit per draw. */
			int n = 0;

			for (int i = 0; i < p->ncdf; i++)
				n += u >= p->cdf[i];
			if (n < p->ncdf)
				return n;
		}

		return rng_poisson_invert(u, p->mu, p->emu);
	}
	case 2: {
		double m_int = floor(p->mu), m_frac = p->mu - m_int;

		for (;;) {
			double u = rng_cell_u01(c) - 0.5;
			double v = rng_cell_u01(c);
			double us = 0.5 - fabs(u);
			double j = floor((2 * p->a / us + p->b) * u + m_frac + 0.43);
			double k = m_int + j;

			if (us >= 0.07 && v <= p->vr)
				return k;
			if (!(k >= 0) || (us < 0.013 && v > us))
				continue;
			/* log mu and 1/alpha only here, once per set-up: most
			 * draws never get this far.  The test is Hormann's
			 * log(v / alpha / (a / us^2 + b)) <= log P(k). */
			if (p->log_mu == 0) {
				p->log_mu = log(p->mu);
				p->inv_alpha = 1.1239 + 1.1328 / (p->b - 3.4);
			}
			if (log(v * p->inv_alpha * us * us / (p->a + p->b * us * us)) <=
			    poisson_logpmf(k, p->mu, p->log_mu, j - m_frac))
				return k;
		}
	}
	default: {
		double u1 = 1.0 - rng_cell_u01(c), u2 = rng_cell_u01(c);
		double z = sqrt(-2 * log(u1)) * cos(2 * M_PI * u2);

		return nearbyint(p->mu + p->smu * z);
	}
	}
}

/*
 * Many Poisson counts at once, the same numbers as rng_poisson_draw gives
 * cell by cell (tests/unit/rng_poisson.c checks it bit for bit), but in
 * passes: first every pixel's first PTRS attempt and squeeze, without
 * branches, then the log test for the third or so that the squeeze left,
 * then further attempts for the few rejected.  Mixed in one loop, the
 * unpredictable squeeze branch costs a pipeline flush on a third of the
 * pixels.  Attempt d of a cell uses its draw d, as the cell stream does.
 */
#define FILL_MAX 256

static inline double zig_normal(const struct rng *g, uint32_t cell, uint32_t hi, uint32_t lo);

/* The PTRS constants of FILL_MAX pixels, by column. */
struct ptrs_cols {
	double mu[FILL_MAX], b[FILL_MAX], a[FILL_MAX], vr[FILL_MAX];
	double m_int[FILL_MAX], m_frac[FILL_MAX], u[FILL_MAX], v[FILL_MAX];
	double k[FILL_MAX];
	int64_t fast[FILL_MAX];
};

/*
 * The first attempt for pixels 0 .. n-1 of q (mu, u, v set): the set-up
 * expressions of rng_poisson_setup and the first attempt of
 * rng_poisson_draw, the same operations in the same order, so the values
 * are equal bit for bit (IEEE arithmetic, no contraction under -std=c11).
 * Pixels outside 10 .. 2^52 get meaningless values that the caller
 * ignores.
 */
static inline void ptrs_first_one(struct ptrs_cols *q, size_t i)
{
	double b = 0.931 + 2.53 * sqrt(q->mu[i]);
	double a = -0.059 + 0.02483 * b;
	double vr = 0.9277 - 3.6224 / (b - 2);
	double m_int = floor(q->mu[i]), m_frac = q->mu[i] - m_int;
	double u = q->u[i], us = 0.5 - fabs(u);

	q->b[i] = b;
	q->a[i] = a;
	q->vr[i] = vr;
	q->m_int[i] = m_int;
	q->m_frac[i] = m_frac;
	q->k[i] = m_int + floor((2 * a / us + b) * u + m_frac + 0.43);
	q->fast[i] = (us >= 0.07) & (q->v[i] <= vr);
}

static void ptrs_first(struct ptrs_cols *q, size_t n)
{
	for (size_t i = 0; i < n; i++)
		ptrs_first_one(q, i);
}

#ifdef SIMD_X86
/* The same, four pixels at a time; sqrt, division and floor are exactly
 * rounded in both. */
__attribute__((target("avx2"))) static void ptrs_first_avx2(struct ptrs_cols *q, size_t n)
{
	const __m256d sign = _mm256_set1_pd(-0.0);
	size_t i = 0;

	for (; i + 4 <= n; i += 4) {
		__m256d mu = _mm256_loadu_pd(q->mu + i);
		__m256d b = _mm256_add_pd(_mm256_set1_pd(0.931),
					  _mm256_mul_pd(_mm256_set1_pd(2.53), _mm256_sqrt_pd(mu)));
		__m256d a = _mm256_add_pd(_mm256_set1_pd(-0.059),
					  _mm256_mul_pd(_mm256_set1_pd(0.02483), b));
		__m256d vr = _mm256_sub_pd(_mm256_set1_pd(0.9277),
					   _mm256_div_pd(_mm256_set1_pd(3.6224),
							 _mm256_sub_pd(b, _mm256_set1_pd(2))));
		__m256d m_int = _mm256_floor_pd(mu), m_frac = _mm256_sub_pd(mu, m_int);
		__m256d u = _mm256_loadu_pd(q->u + i), v = _mm256_loadu_pd(q->v + i);
		__m256d us = _mm256_sub_pd(_mm256_set1_pd(0.5), _mm256_andnot_pd(sign, u));
		__m256d t = _mm256_add_pd(_mm256_div_pd(_mm256_mul_pd(_mm256_set1_pd(2), a), us), b);
		__m256d j = _mm256_floor_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(t, u), m_frac),
							  _mm256_set1_pd(0.43)));
		__m256d fast = _mm256_and_pd(_mm256_cmp_pd(us, _mm256_set1_pd(0.07), _CMP_GE_OQ),
					     _mm256_cmp_pd(v, vr, _CMP_LE_OQ));

		_mm256_storeu_pd(q->b + i, b);
		_mm256_storeu_pd(q->a + i, a);
		_mm256_storeu_pd(q->vr + i, vr);
		_mm256_storeu_pd(q->m_int + i, m_int);
		_mm256_storeu_pd(q->m_frac + i, m_frac);
		_mm256_storeu_pd(q->k + i, _mm256_add_pd(m_int, j));
		_mm256_storeu_si256((__m256i *)(q->fast + i), _mm256_castpd_si256(fast));
	}
	for (; i < n; i++)
		ptrs_first_one(q, i);
}
#endif

/* The log test of rng_poisson_draw for attempt (u, v) with count k of
 * pixel i.  cache holds log mu and 1/alpha of the last mean that needed
 * them, for runs of equal means (a flat sky). */
static int ptrs_slow(const struct ptrs_cols *q, size_t i, double u, double v,
		     double k, double cache[3])
{
	double us = 0.5 - fabs(u), j = k - q->m_int[i];

	if (!(k >= 0) || (us < 0.013 && v > us))
		return 0;
	if (q->mu[i] != cache[0]) {
		cache[0] = q->mu[i];
		cache[1] = log(q->mu[i]);
		cache[2] = 1.1239 + 1.1328 / (q->b[i] - 3.4);
	}
	return log(v * cache[2] * us * us / (q->a[i] + q->b[i] * us * us)) <=
	       poisson_logpmf(k, q->mu[i], cache[1], j - q->m_frac[i]);
}

void rng_poisson_fill(const struct rng *g, uint32_t cell0, size_t n,
		      const double *mu, double *out)
{
	rng_poisson_fill_approx(g, cell0, n, mu, out, INFINITY);
}

void rng_poisson_fill_approx(const struct rng *g, uint32_t cell0, size_t n,
			     const double *mu, double *out, double normal_above)
{
	uint32_t w[FILL_MAX][4];
	struct ptrs_cols q;
	uint16_t pend[FILL_MAX], next[FILL_MAX];
	struct rng_poisson other = { .mu = -1 };
	int repeats = 0;
	double cache[3] = { -1, 0, 0 };
	size_t np = 0, nptrs = 0;

	if (n > FILL_MAX) {
		for (size_t i = 0; i < n; i += FILL_MAX)
			rng_poisson_fill_approx(g, cell0 + (uint32_t)i,
						n - i < FILL_MAX ? n - i : FILL_MAX, mu + i,
						out + i, normal_above);
		return;
	}
	rng_bits_n(g, cell0, 0, n, w);
	for (size_t i = 0; i < n; i++) {
		q.mu[i] = mu[i];
		q.u[i] = rng_u01(w[i][0], w[i][1]) - 0.5;
		q.v[i] = rng_u01(w[i][2], w[i][3]);
		nptrs += (mu[i] >= 10) & (mu[i] <= RNG_POISSON_EXACT_MAX) &
			 (mu[i] < normal_above);
	}
	if (nptrs) {
#ifdef SIMD_X86
		if (simd_flags() & SIMD_AVX2)
			ptrs_first_avx2(&q, n);
		else
#endif
			ptrs_first(&q, n);
	}
	for (size_t i = 0; i < n; i++) {
		double m = q.mu[i];

		if (m >= normal_above && m <= RNG_POISSON_EXACT_MAX) {
			/* zig_normal's slow cases use the cell's draws 1, 2,
			 * ..., which PTRS would have used: the same stream */
			out[i] = rng_poisson_normal(m, zig_normal(g, cell0 + (uint32_t)i,
								   w[i][0], w[i][1]));
			continue;
		}
		if (!(m >= 10) || m > RNG_POISSON_EXACT_MAX) {
			struct rng_cell c;

			/* The set-up (an exp below 10) is kept while the
			 * mean repeats, as on a flat sky, and tabulated
			 * when it has repeated twice. */
			if (!(m > 0)) {
				out[i] = 0;
				continue;
			}
			if (m != other.mu) {
				rng_poisson_setup(&other, m);
				repeats = 0;
			} else if (++repeats == 2) {
				/* a flat sky: the table gives the same counts */
				rng_poisson_tabulate(&other);
			}
			rng_cell_preload(&c, g, cell0 + (uint32_t)i, w[i]);
			out[i] = rng_poisson_draw(&other, &c);
			continue;
		}
		out[i] = q.k[i];
		pend[np] = (uint16_t)i;
		np += !q.fast[i];
	}
	/* The log test for attempt 0, then whole attempts 1, 2, ... */
	for (uint32_t draw = 1; np; draw++) {
		size_t nn = 0;

		for (size_t t = 0; t < np; t++) {
			size_t i = pend[t];

			if (!ptrs_slow(&q, i, q.u[i], q.v[i], out[i], cache))
				next[nn++] = (uint16_t)i;
		}
		np = 0;
		for (size_t t = 0; t < nn; t++) {
			size_t i = next[t];
			uint32_t b[4];
			double u, v, us;

			rng_bits(g, cell0 + (uint32_t)i, draw, b);
			u = rng_u01(b[0], b[1]) - 0.5;
			v = rng_u01(b[2], b[3]);
			us = 0.5 - fabs(u);
			out[i] = q.m_int[i] + floor((2 * q.a[i] / us + q.b[i]) * u +
						    q.m_frac[i] + 0.43);
			q.u[i] = u;
			q.v[i] = v;
			if (!(us >= 0.07 && v <= q.vr[i]))
				pend[np++] = (uint16_t)i;
		}
	}
}

void rng_poisson_tabulate(struct rng_poisson *p)
{
	double pk, f;

	if (p->method != 1)
		return;
	pk = f = p->emu;
	p->cdf[0] = f;
	/* Up to mu + 7 sqrt(mu) + 8, where 1 - F < 1e-10; draws beyond the
	 * table fall back to the search, which gives the same count. */
	p->ncdf = (int)(p->mu + 7 * sqrt(p->mu) + 8);
	if (p->ncdf > 64)
		p->ncdf = 64;
	for (int k = 1; k < p->ncdf; k++) {
		pk *= p->mu * rng_recip[k];
		f += pk;
		p->cdf[k] = f;
	}
}

double rng_poisson(double mu, struct rng_cell *c)
{
	struct rng_poisson p;

	if (!(mu > 0))
		return 0;
	if (mu < 10) {
		/* The set-up of the inversion is one exp; skip the rest. */
		p.mu = mu;
		p.method = 1;
		p.ncdf = 0;
		p.emu = exp(-mu);
		return rng_poisson_draw(&p, c);
	}
	rng_poisson_setup(&p, mu);
	return rng_poisson_draw(&p, c);
}

/*
 * Normal deviates by the ziggurat method (G. Marsaglia & W. W. Tsang, "The
 * ziggurat method for generating random variables", J. Stat. Software 5(8),
 * 2000), with 256 layers of equal area v under f(x) = exp(-x^2/2):
 *
 *   x_1 = r = 3.6541528853610088,   v = r f(r) + int_r^inf f = 4.9286732e-3,
 *   x_0 = v / f(r)  (the base layer: a rectangle plus the tail beyond r),
 *   x_{i+1} = f^-1(f(x_i) + v / x_i),  down to x_256 = 0
 *
 * (the recurrence closes at f = 1 + 3e-15; the table below is that
 * recurrence in double precision, and tests/unit/rng_philox.c recomputes
 * it).  A deviate takes 64 bits: 8 pick the layer i, the top 53 a signed
 * uniform u in [-1, 1); x = u x_i is accepted at once when |x| < x_{i+1}
 * (99.3% of draws).  Otherwise it is in a wedge (accept when a uniform
 * height under layer i falls below f(x)) or, in layer 0, beyond r, where
 * Marsaglia's tail method applies; a rejected draw starts over.  These rare
 * paths take their numbers from the pixel's own cell, draws 1, 2, ...
 *
 * Deviate 2m takes words 0-1 and deviate 2m+1 words 2-3 of Philox call
 * (m, draw 0), so any slice gives the same numbers as the whole.
 */
static const double zig_x[257] = {
	3.9107579595249167, 3.6541528853610088, 3.4492782985614312,
	3.3202447338398251, 3.2245750520478009, 3.147889289518,
	3.0835261320021425, 3.0278377917695929, 2.9786032798818427,
	2.9343668672088872, 2.8941210536134121, 2.8571387308732241,
	2.8228773968264425, 2.7909211740019271, 2.7609440052799856,
	2.732685359044011, 2.7059336561230616, 2.6805146432857443,
	2.6562830375767423, 2.6331163936315818, 2.6109105184888226,
	2.5895759867082857, 2.5690354526818426, 2.5492215503247819,
	2.5300752321598527, 2.5115444416266928, 2.4935830412710454,
	2.4761499396705218, 2.4592083743347035, 2.4427253182003628,
	2.4266709849371453, 2.4110184139011182, 2.3957431197819261,
	2.3808227951720844, 2.3662370567172899, 2.3519672273791441,
	2.337996148796528, 2.324308018871132, 2.3108882506013715,
	2.297723348902863, 2.2848008027244915, 2.2721089902283813,
	2.2596370951737872, 2.2473750329473887, 2.2353133849299205,
	2.2234433400925098, 2.21175664288416, 2.2002455466112756,
	2.1889027716263598, 2.1777214677402918, 2.1666951803543073,
	2.1558178198767362, 2.1450836340478876, 2.1344871828460157,
	2.1240233156895223, 2.1136871506866517, 2.1034740557148757,
	2.0933796311387902, 2.0833996939983028, 2.0735302635187414,
	2.0637675478117306, 2.0541079316506505, 2.04454796521753,
	2.0350843537296175, 2.0257139478638528, 2.0164337349062027,
	2.0072408305605274, 1.9981324713584183, 1.9891060076174367,
	1.9801588969004753, 1.9712886979336579, 1.9624930649443617,
	1.9537697423846454, 1.9451165600086768, 1.9365314282756931,
	1.928012334052664, 1.9195573365931864, 1.9111645637712515,
	1.9028322085504275, 1.8945585256707029, 1.886341828536781,
	1.8781804862929941, 1.870072921071265, 1.8620176053996724,
	1.8540130597602003, 1.8460578502851839, 1.8381505865828049,
	1.8302899196827553, 1.8224745400938844, 1.8147031759662813,
	1.8069745913508195, 1.7992875845497187, 1.791640986552161,
	1.7840336595494399, 1.7764644955245215, 1.7689324149112673,
	1.7614363653189091, 1.7539753203176704, 1.7465482782817214,
	1.7391542612859108, 1.7317923140529623, 1.7244615029480441,
	1.7171609150178224, 1.7098896570713011, 1.7026468547999223,
	1.6954316519345607, 1.6882432094371944, 1.681080704725173,
	1.6739433309261242, 1.6668302961616648, 1.6597408228581818,
	1.6526741470830553, 1.6456295179047817, 1.638606196775547,
	1.6316034569348727, 1.624620582833034, 1.6176568695730149,
	1.6107116223698297, 1.6037841560260941, 1.5968737944227878,
	1.5899798700241905, 1.5831017233960289, 1.5762387027359059,
	1.5693901634151233, 1.5625554675310445, 1.5557339834691761,
	1.5489250854741732, 1.5421281532290017, 1.5353425714415139,
	1.528567729437712, 1.5218030207609978, 1.5150478427767144,
	1.5083015962813113, 1.5015636851154637, 1.4948335157804935,
	1.4881104970574472, 1.4813940396281871, 1.4746835556978553,
	1.4679784586180793, 1.4612781625102753, 1.4545820818884101,
	1.4478896312805758, 1.4412002248487237, 1.4345132760058918,
	1.4278281970302555, 1.4211443986753085, 1.4144612897754707,
	1.4077782768463982, 1.4010947636792503, 1.3944101509281404,
	1.3877238356899755, 1.3810352110758548, 1.3743436657731656,
	1.3676485835974754, 1.3609493430332822, 1.354245316762634,
	1.3475358711805863, 1.3408203658964031, 1.334098153219359,
	1.3273685776279247, 1.3206309752210552, 1.3138846731502194,
	1.30712898903073, 1.3003632303308361, 1.2935866937369467,
	1.2867986644932425, 1.2799984157138169, 1.2731852076653554,
	1.2663582870182284, 1.2595168860637131, 1.2526602218948961,
	1.2457874955486261, 1.2388978911056863, 1.231990574746135,
	1.2250646937565297, 1.2181193754854807, 1.2111537262436982,
	1.2041668301443804, 1.1971577478794404, 1.190125515426691,
	1.1830691426826856, 1.1759876120154509, 1.1688798767308322,
	1.1617448594456106, 1.1545814503599268, 1.1473885054208481,
	1.1401648443681505, 1.132909248652533, 1.1256204592155323,
	1.1182971741193437, 1.1109380460135743, 1.1035416794246382,
	1.09610662785202, 1.0886313906539782, 1.0811144097034022,
	1.0735540657924345, 1.0659486747621207, 1.0582964833306734,
	1.0505956645909282, 1.0428443131441474, 1.0350404398334394,
	1.0271819660356445, 1.019266717465483, 1.0112924174399947,
	1.003256679544672, 0.99515699963509008, 0.98699074709906154,
	0.97875515529422374, 0.97044731106422355, 0.96206414322303968,
	0.95360240988108524, 0.94505868446816454, 0.93642934028657421,
	0.92771053340199916, 0.91889818364958964, 0.90998795349671757,
	0.9009752244612208, 0.89185507073294046, 0.88262222958516456,
	0.87327106808885968, 0.86379554555330784, 0.85418917100816283,
	0.84444495490915294, 0.83455535408638104, 0.82451220875229114,
	0.81430667013521418, 0.80392911698997016, 0.79336905884062225,
	0.78261502330723198, 0.77165442422456687, 0.76047340643010686,
	0.74905666201781407, 0.73738721143429442, 0.72544614090999848,
	0.71321228519097479, 0.70066184110681384, 0.68776789279578721,
	0.67449982283729248, 0.66082257424441826, 0.64669571489499222,
	0.63207223638605947, 0.61689699000774956, 0.60110461775599078,
	0.58461676610637747, 0.5673382570538168, 0.54915170232716304,
	0.52990972066155595, 0.50942332960208958, 0.48744396613923352,
	0.4636343367908794, 0.43751840220786858, 0.40838913461198767,
	0.37512133287837662, 0.33573751921442047, 0.28617459179206622,
	0.21524189598487156, 0,
};

/* f(x_i) = exp(-x_i^2 / 2) at each edge, as exp(-0.5 * x * x) rounds it
 * (tests/unit/rng_philox.c checks that), so that a wedge's test takes one
 * exp, not three. */
static const double zig_f[257] = {
	0x1.f4a946f138416p-12, 0x1.4a605b6b9f70fp-10, 0x1.55f9f43c1b072p-9,
	0x1.08a1f03b0b20dp-8, 0x1.69ea8d90cb873p-8, 0x1.ce160f8ec684dp-8,
	0x1.1a59229952f9fp-7, 0x1.4eb96421acffp-7, 0x1.841040d8da48ap-7,
	0x1.ba48d274f8fb9p-7, 0x1.f152a4f72dd59p-7, 0x1.149033460301fp-6,
	0x1.30d388dab5e21p-6, 0x1.4d6eaf2fbb06cp-6, 0x1.6a5daf40bbf9p-6,
	0x1.879d1b600c113p-6, 0x1.a529f4e22ec02p-6, 0x1.c301983cd0924p-6,
	0x1.e121adb828c7dp-6, 0x1.ff881d718a5ccp-6, 0x1.0f1982e968017p-5,
	0x1.1e9059f1f6ac3p-5, 0x1.2e27ce83df4a5p-5, 0x1.3ddf2ce98eed8p-5,
	0x1.4db5d0e112772p-5, 0x1.5dab23cf2adeap-5, 0x1.6dbe9b398d078p-5,
	0x1.7defb77af2733p-5, 0x1.8e3e02a68b5c1p-5, 0x1.9ea90f929557ap-5,
	0x1.af30790385f8bp-5, 0x1.bfd3e0f282a45p-5, 0x1.d092efeadf17cp-5,
	0x1.e16d547b2519cp-5, 0x1.f262c2b6c6e49p-5, 0x1.01b979e30e49dp-4,
	0x1.0a4ed2c159629p-4, 0x1.12f14d0f217a2p-4, 0x1.1ba0cbe978982p-4,
	0x1.245d344dd0d96p-4, 0x1.2d266cf9b3115p-4, 0x1.35fc5e4d93e7p-4,
	0x1.3edef23269a86p-4, 0x1.47ce1401b2219p-4, 0x1.50c9b06fa2bb4p-4,
	0x1.59d1b577466a9p-4, 0x1.62e6124854d1dp-4, 0x1.6c06b73694a52p-4,
	0x1.753395aaa117bp-4, 0x1.7e6ca013eefdcp-4, 0x1.87b1c9dbf2858p-4,
	0x1.9103075a4a0b4p-4, 0x1.9a604dc9d5b1fp-4, 0x1.a3c9933ea628dp-4,
	0x1.ad3ece9caf63dp-4, 0x1.b6bff78f2e241p-4, 0x1.c04d0680b1027p-4,
	0x1.c9e5f493b7423p-4, 0x1.d38abb9bd91fap-4, 0x1.dd3b56176e8a9p-4,
	0x1.e6f7bf29aa562p-4, 0x1.f0bff29520e33p-4, 0x1.fa93ecb6b2244p-4,
	0x1.0239d54067d38p-3, 0x1.072f94bb8bf91p-3, 0x1.0c2b33d5209c7p-3,
	0x1.112cb1da26ec6p-3, 0x1.16340e5a82d7p-3, 0x1.1b41492757d4fp-3,
	0x1.2054625183c41p-3, 0x1.256d5a2835ec4p-3, 0x1.2a8c3137a0728p-3,
	0x1.2fb0e847c2a73p-3, 0x1.34db805b4ab99p-3, 0x1.3a0bfaae8d7fep-3,
	0x1.3f4258b6931c2p-3, 0x1.447e9c20375e9p-3, 0x1.49c0c6cf5ce44p-3,
	0x1.4f08dade31fdap-3, 0x1.5456da9c8684fp-3, 0x1.59aac88f31d89p-3,
	0x1.5f04a76f88414p-3, 0x1.64647a2adf1b9p-3, 0x1.69ca43e21f275p-3,
	0x1.6f3607e96472dp-3, 0x1.74a7c9c7ab5bcp-3, 0x1.7a1f8d368a338p-3,
	0x1.7f9d5621f7187p-3, 0x1.852128a819a49p-3, 0x1.8aab09192816cp-3,
	0x1.903afbf74fa7bp-3, 0x1.95d105f6a7c3ap-3, 0x1.9b6d2bfd2fe6fp-3,
	0x1.a10f7322d7e5p-3, 0x1.a6b7e0b19268ep-3, 0x1.ac667a2571816p-3,
	0x1.b21b452ccd149p-3, 0x1.b7d647a8731b9p-3, 0x1.bd9787abe18afp-3,
	0x1.c35f0b7d89d53p-3, 0x1.c92cd9971df5fp-3, 0x1.cf00f8a5e6fd5p-3,
	0x1.d4db6f8b25156p-3, 0x1.dabc455c7901p-3, 0x1.e0a381645718dp-3,
	0x1.e6912b2283ce6p-3, 0x1.ec854a4c99c4dp-3, 0x1.f27fe6ce998d8p-3,
	0x1.f88108cb8323bp-3, 0x1.fe88b89df93c7p-3, 0x1.024b7f6c7747fp-2,
	0x1.0555f2242e9d9p-2, 0x1.0863b8f904336p-2, 0x1.0b74d88b242dap-2,
	0x1.0e895598709c4p-2, 0x1.11a134fcf2423p-2, 0x1.14bc7bb34ee67p-2,
	0x1.17db2ed5454e8p-2, 0x1.1afd539c2f05p-2, 0x1.1e22ef6188116p-2,
	0x1.214c079f7cc9ep-2, 0x1.2478a1f17de89p-2, 0x1.27a8c414db11ep-2,
	0x1.2adc73e963fddp-2, 0x1.2e13b77210766p-2, 0x1.314e94d5af62fp-2,
	0x1.348d125f9d19ep-2, 0x1.37cf368081379p-2, 0x1.3b1507cf143aep-2,
	0x1.3e5e8d08ed2dbp-2, 0x1.41abcd1357a19p-2, 0x1.44fccefc324fep-2,
	0x1.485199fad6ad4p-2, 0x1.4baa357109ca2p-2, 0x1.4f06a8ebf6d92p-2,
	0x1.5266fc2533bedp-2, 0x1.55cb3703d01p-2, 0x1.5933619d6eebep-2,
	0x1.5c9f84376c244p-2, 0x1.600fa7480d2c8p-2, 0x1.6383d377be515p-2,
	0x1.66fc11a25cbe2p-2, 0x1.6a786ad88de21p-2, 0x1.6df8e86124caap-2,
	0x1.717d93ba9614cp-2, 0x1.7506769c7b1edp-2, 0x1.78939af9252ebp-2,
	0x1.7c250aff414b1p-2, 0x1.7fbad11b8d913p-2, 0x1.8354f7faa0ddbp-2,
	0x1.86f38a8ac5ab8p-2, 0x1.8a9693fde918bp-2, 0x1.8e3e1fcb9f119p-2,
	0x1.91ea39b33cb1bp-2, 0x1.959aedbe09f98p-2, 0x1.995048418c0ccp-2,
	0x1.9d0a55e1e93e5p-2, 0x1.a0c9239468445p-2, 0x1.a48cbea20c056p-2,
	0x1.a85534aa4d889p-2, 0x1.ac2293a5f5aa5p-2, 0x1.aff4e9ea1855ap-2,
	0x1.b3cc462b331d2p-2, 0x1.b7a8b78071324p-2, 0x1.bb8a4d6716d9ap-2,
	0x1.bf7117c616a1fp-2, 0x1.c35d26f1d2cbfp-2, 0x1.c74e8bb00d7cep-2,
	0x1.cb45573c0a84ep-2, 0x1.cf419b4ae5b75p-2, 0x1.d3436a1021086p-2,
	0x1.d74ad6426de39p-2, 0x1.db57f320b56b6p-2, 0x1.df6ad47763a0ep-2,
	0x1.e3838ea5f9b89p-2, 0x1.e7a236a4ec3cap-2, 0x1.ebc6e20bd1f59p-2,
	0x1.eff1a717e8f9ap-2, 0x1.f4229cb2f7af8p-2, 0x1.f859da7a900cfp-2,
	0x1.fc9778c7bbda8p-2, 0x1.006dc85b8cac8p-1, 0x1.02931e18b822dp-1,
	0x1.04bbcafa63f3p-1, 0x1.06e7dccf03c38p-1, 0x1.091761d995d82p-1,
	0x1.0b4a68d70d9afp-1, 0x1.0d810104142a1p-1, 0x1.0fbb3a2325915p-1,
	0x1.11f9248311f3bp-1, 0x1.143ad105ea9ap-1, 0x1.16805128639dep-1,
	0x1.18c9b709b3c55p-1, 0x1.1b171573fd117p-1, 0x1.1d687fe54996fp-1,
	0x1.1fbe0a9929627p-1, 0x1.2217ca92ff7f7p-1, 0x1.2475d5a90db89p-1,
	0x1.26d84290504f2p-1, 0x1.293f28e93cd1ap-1, 0x1.2baaa14d7954dp-1,
	0x1.2e1ac55ea3bfp-1, 0x1.308fafd6438f1p-1, 0x1.33097c9703a38p-1,
	0x1.358848bf550ebp-1, 0x1.380c32bda00d7p-1, 0x1.3a955a662cd1p-1,
	0x1.3d23e10af31a5p-1, 0x1.3fb7e99585b84p-1, 0x1.425198a355fe5p-1,
	0x1.44f114a49367bp-1, 0x1.479685fdf5014p-1, 0x1.4a42172dc527bp-1,
	0x1.4cf3f4f494ec3p-1, 0x1.4fac4e820b66ap-1, 0x1.526b55a656cd8p-1,
	0x1.55313f08d9e49p-1, 0x1.57fe4264c8d92p-1, 0x1.5ad29acc85c8bp-1,
	0x1.5dae86f4aff6cp-1, 0x1.6092498802667p-1, 0x1.637e298550c1ap-1,
	0x1.667272a92e325p-1, 0x1.696f75e513b2cp-1, 0x1.6c7589e635a8bp-1,
	0x1.6f850baea7afp-1, 0x1.729e5f43f6d14p-1, 0x1.75c1f0770d858p-1,
	0x1.78f033ca0b0d8p-1, 0x1.7c29a779c685bp-1, 0x1.7f6ed4b20e2cep-1,
	0x1.82c050f56cf71p-1, 0x1.861ebfc37bcadp-1, 0x1.898ad48badf04p-1,
	0x1.8d0554fe60aaap-1, 0x1.908f1bd317151p-1, 0x1.94291c21b7a4ap-1,
	0x1.97d4657617ac4p-1, 0x1.9b9228d240685p-1, 0x1.9f63bee651fdcp-1,
	0x1.a34aafdf5af14p-1, 0x1.a748bd550c9e7p-1, 0x1.ab5fef17a250ap-1,
	0x1.af92a3f6ce8a8p-1, 0x1.b3e3a8234dd16p-1, 0x1.b85653a8ff558p-1,
	0x1.bceeb4ee1dc88p-1, 0x1.c1b1cd9eebafp-1, 0x1.c6a5ecea97886p-1,
	0x1.cbd33a8a72df3p-1, 0x1.d144978a119e4p-1, 0x1.d70920657bcfbp-1,
	0x1.dd36fa704de9fp-1, 0x1.e3f11e027f082p-1, 0x1.eb7545b6ca922p-1,
	0x1.f446ac979f097p-1, 0x1p+0
};

const double *const rng_zig_x = zig_x;
const double *const rng_zig_f = zig_f;

/* The slow cases of layer i and signed uniform u, taking uniforms from
 * the cell stream c (its draws 1, 2, ...). */
static double zig_slow_from(struct rng_cell *cp, int i, double u)
{
	struct rng_cell c = *cp;

	for (;;) {
		double x = u * zig_x[i];

		if (fabs(x) < zig_x[i + 1])
			return x;
		if (i == 0) {
			double a, b;

			do {
				a = -log(1 - rng_cell_u01(&c)) / zig_x[1];
				b = -log(1 - rng_cell_u01(&c));
			} while (2 * b < a * a);
			return u < 0 ? -(zig_x[1] + a) : zig_x[1] + a;
		} else {
			double f0 = zig_f[i], f1 = zig_f[i + 1];

			if (f0 + rng_cell_u01(&c) * (f1 - f0) < exp(-0.5 * x * x))
				return x;
		}
		i = (int)(rng_cell_u01(&c) * 256);
		u = 2 * rng_cell_u01(&c) - 1;
	}
}

double rng_normal_slow(const struct rng *g, uint32_t cell, int i, double u)
{
	struct rng_cell c;

	rng_cell_init(&c, g, cell, 1);
	return zig_slow_from(&c, i, u);
}

static inline double zig_normal(const struct rng *g, uint32_t cell, uint32_t hi, uint32_t lo)
{
	double u, x;
	int i = rng_zig_layer(hi, lo, &u);

	x = u * zig_x[i];
	return fabs(x) < zig_x[i + 1] ? x : rng_normal_slow(g, cell, i, u);
}

#ifdef SIMD_X86
/*
 * zig_normal() of the eight deviates of calls w[0 .. 3] into out, with
 * AVX-512: the same operations on each lane, so the same numbers; a lane
 * in a slow case (its bit in the mask returned) is left to the caller.
 */
__attribute__((target("avx512f,avx512dq"))) static unsigned
zig8_avx512(const uint32_t (*w)[4], double *out)
{
	const __m512i b8 = _mm512_set1_epi64(0xff), one = _mm512_set1_epi64(1);
	const __m512d sgn = _mm512_set1_pd(-0.0);
	/* words hi:lo of each half call as a 64-bit number, hi high */
	__m512i v = _mm512_ror_epi64(_mm512_loadu_si512(w[0]), 32);
	__m512i li = _mm512_and_si512(v, b8);
	__m512d x0 = _mm512_i64gather_pd(li, zig_x, 8);
	__m512d x1 = _mm512_i64gather_pd(_mm512_add_epi64(li, one), zig_x, 8);
	__m512d x = _mm512_mul_pd(_mm512_mul_pd(_mm512_cvtepi64_pd(_mm512_srai_epi64(v, 11)),
						_mm512_set1_pd(0x1p-52)), x0);

	_mm512_storeu_pd(out, x);
	return _mm512_cmp_pd_mask(_mm512_andnot_pd(sgn, x), x1, _CMP_NLT_UQ);
}
#endif

/*
 * The slow cases of rng_normal_fill, put off and drawn in groups: a
 * scalar Philox call for a case's draw 1 cost as much as ~17 lanes of the
 * bulk calls.  Each case takes the very numbers rng_normal_slow() would.
 */
#define ZIG_DEFER 16
struct zig_defer {
	int n;
	uint32_t cell[ZIG_DEFER];
	int layer[ZIG_DEFER];
	double u[ZIG_DEFER];
	double *dst[ZIG_DEFER];
};

void rng_normal_slow_n(const struct rng *g, const uint32_t *cell, const int *layer,
		       const double *u, size_t n, double *out)
{
	for (size_t i = 0; i < n; i += ZIG_DEFER) {
		uint32_t w[ZIG_DEFER][4];
		size_t m = n - i < ZIG_DEFER ? n - i : ZIG_DEFER;

		rng_bits_cells(g, cell + i, 1, m, w);
		for (size_t k = 0; k < m; k++) {
			struct rng_cell c;

			rng_cell_preload(&c, g, cell[i + k], w[k]);
			c.draw++; /* the preloaded call is draw 1 */
			out[i + k] = zig_slow_from(&c, layer[i + k], u[i + k]);
		}
	}
}

static void zig_flush(const struct rng *g, struct zig_defer *d)
{
	double z[ZIG_DEFER];

	rng_normal_slow_n(g, d->cell, d->layer, d->u, (size_t)d->n, z);
	for (int k = 0; k < d->n; k++)
		*d->dst[k] = z[k];
	d->n = 0;
}

/* zig_normal() into *dst, its slow case put off into d. */
static inline void zig_put(const struct rng *g, struct zig_defer *d, uint32_t cell,
			   uint32_t hi, uint32_t lo, double *dst)
{
	double u, x;
	int i = rng_zig_layer(hi, lo, &u);

	*dst = x = u * zig_x[i]; /* a slow case's is written again */
	if (fabs(x) < zig_x[i + 1])
		return;
	d->cell[d->n] = cell;
	d->layer[d->n] = i;
	d->u[d->n] = u;
	d->dst[d->n] = dst;
	if (++d->n == ZIG_DEFER)
		zig_flush(g, d);
}

void rng_normal_fill(const struct rng *g, uint64_t first, size_t n, double *out)
{
	uint32_t w[64][4];
	uint64_t i = first, end = first + n;
	struct zig_defer d;
#ifdef SIMD_X86
	int wide = (simd_flags() & SIMD_AVX512) != 0;
#endif

	d.n = 0;

	while (i < end) {
		uint64_t p0 = i >> 1, p1 = ((end - 1) >> 1) + 1;
		size_t np = p1 - p0 < 64 ? (size_t)(p1 - p0) : 64, k = 0;

		rng_bits_n(g, (uint32_t)p0, 0, np, w);
#ifdef SIMD_X86
		/* eight deviates (four whole calls) at a time */
		for (; wide && !(i & 1) && k + 4 <= np && i + 8 <= end; k += 4, i += 8, out += 8) {
			unsigned slow = zig8_avx512(w + k, out);

			for (int q = 0; slow; q++, slow >>= 1)
				if (slow & 1)
					zig_put(g, &d, (uint32_t)(i + (uint64_t)q),
						w[k + (size_t)q / 2][q & 1 ? 2 : 0],
						w[k + (size_t)q / 2][q & 1 ? 3 : 1], out + q);
		}
#endif
		for (; k < np && i < end; k++) {
			uint64_t pair = p0 + k;

			if (i == 2 * pair) {
				zig_put(g, &d, (uint32_t)i, w[k][0], w[k][1], out++);
				i++;
			}
			if (i < end) {
				zig_put(g, &d, (uint32_t)i, w[k][2], w[k][3], out++);
				i++;
			}
		}
	}
	if (d.n)
		zig_flush(g, &d);
}
