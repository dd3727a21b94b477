/*
 * point_kernels.c - the inner loops of the point model: a window's rows
 * (sum_rows) and a source's core (core_rows), each built plain and with
 * AVX2 and FMA, the core also with AVX-512VL's 32 registers (the same
 * 256-bit operations), the same operations in the same order so the same
 * bits.  The arguments and what they compute are described in point.h.
 */
#include <math.h>
#include <stdlib.h>

#include "point.h"

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

#ifdef SIMD_X86

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

				/* with the other class's cell written out apart
				 * from the cell alone, as in core_avx2 */
				if (a->keys && a->dbase) {
					const float *q = a->dbase + o + i0 + l;

					v = 0;
					for (int b = 0; b < 4; b++) {
						const float *rb = r + a->ty[b], *qb = q + a->ty[b];
						float h = a->kx[0] * fmaf(a->ds, qb[a->tx[0]], rb[a->tx[0]]);

						h = fmaf(a->kx[1], fmaf(a->ds, qb[a->tx[1]], rb[a->tx[1]]), h);
						h = fmaf(a->kx[2], fmaf(a->ds, qb[a->tx[2]], rb[a->tx[2]]), h);
						h = fmaf(a->kx[3], fmaf(a->ds, qb[a->tx[3]], rb[a->tx[3]]), h);
						v = b ? fmaf(a->ky[b], h, v) : a->ky[0] * h;
					}
				} else if (a->keys) {
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
				/* each tap's sum over the corrections apart, then
				 * the four summed in pairs, as in core_avx2 */
				float e1 = 0, e2 = 0, e3 = 0;

				for (int k = 0; k < a->ncor; k++) {
					const float *rk = a->cbase[k] + o + i0 + l;

					e = fmaf(a->cw[4 * k], rk[a->ty[1] + a->tx[1]], e);
					e1 = fmaf(a->cw[4 * k + 1], rk[a->ty[1] + a->tx[2]], e1);
					e2 = fmaf(a->cw[4 * k + 2], rk[a->ty[2] + a->tx[1]], e2);
					e3 = fmaf(a->cw[4 * k + 3], rk[a->ty[2] + a->tx[2]], e3);
				}
				e = (e + e1) + (e2 + e3);
				kv[i0 + l] = lane[l] = v + e;
			}
			for (int l = 0; l < 4; l++)
				ks[l] += (double)(i0 + l < a->nk ? lane[l] : 0) +
					 (double)(i0 + l + 4 < a->nk ? lane[l + 4] : 0);
		}
	}
	return (ks[0] + ks[1]) + (ks[2] + ks[3]);
}

#ifdef SIMD_X86
/* ncor is a->ncor and taps which taps the core has (CORE_BILINEAR,
 * CORE_KEYS, or CORE_KEYS2 with dbase), constants where the caller
 * passes them: then the correction weights, set once before the rows,
 * stay in registers where there are enough (the 32 of AVX-512VL), where
 * a count read at run time had them broadcast again for every step (5 %
 * of the CPU of 10^6 faint stars on one SCA) */
enum { CORE_BILINEAR, CORE_KEYS, CORE_KEYS2 };

__attribute__((target("avx2,fma"), always_inline)) static inline double
core_body(const struct core_args *a, float *kvb, int ncor, int taps)
{
	__m256d ks = _mm256_setzero_pd();
	__m256 kx0 = _mm256_set1_ps(a->kx[0]), kx1 = _mm256_set1_ps(a->kx[1]);
	__m256 kx2 = _mm256_set1_ps(a->kx[2]), kx3 = _mm256_set1_ps(a->kx[3]);
	__m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), nk = _mm256_set1_epi32(a->nk);
	ptrdiff_t x0 = a->tx[0], x1 = a->tx[1], x2 = a->tx[2], x3 = a->tx[3];
	ptrdiff_t y11 = a->ty[1] + x1, y12 = a->ty[1] + x2, y21 = a->ty[2] + x1, y22 = a->ty[2] + x2;
	__m256 bw0 = _mm256_set1_ps(a->bw[0]), bw1 = _mm256_set1_ps(a->bw[1]);
	__m256 bw2 = _mm256_set1_ps(a->bw[2]), bw3 = _mm256_set1_ps(a->bw[3]);
	__m256 ky[4], cw[sizeof(a->cw) / sizeof(a->cw[0])];
	ptrdiff_t ty[4];
	double k[4];

	for (int b = 0; b < 4; b++) {
		ky[b] = _mm256_set1_ps(a->ky[b]);
		ty[b] = a->ty[b];
	}
	for (int q = 0; q < 4 * ncor; q++)
		cw[q] = _mm256_set1_ps(a->cw[q]);
	for (int c = 0; c < a->nc; c++) {
		ptrdiff_t o = (ptrdiff_t)c * a->m;
		float *kv = kvb + c * KV_PITCH + 8;

		for (int i0 = 0; i0 < a->nk; i0 += 8) {
			const float *r = a->base + o + i0;
			__m256 v, e = _mm256_setzero_ps();
			__m256i in;

			/* a colour source's Keys taps with its other class's cell,
			 * written out apart from the cell alone's: one loop for
			 * both, with a test per tap that the compiler keeps, ran
			 * 8-14 % more instructions here for stars without one */
			if (taps == CORE_KEYS2) {
				const float *q = a->dbase + o + i0;
				__m256 ds = _mm256_set1_ps(a->ds);

				v = _mm256_setzero_ps();
				for (int b = 0; b < 4; b++) {
					const float *rb = r + ty[b], *qb = q + ty[b];
					__m256 h = _mm256_mul_ps(kx0, _mm256_fmadd_ps(
						ds, _mm256_loadu_ps(qb + x0), _mm256_loadu_ps(rb + x0)));

					h = _mm256_fmadd_ps(kx1, _mm256_fmadd_ps(ds, _mm256_loadu_ps(qb + x1),
										 _mm256_loadu_ps(rb + x1)), h);
					h = _mm256_fmadd_ps(kx2, _mm256_fmadd_ps(ds, _mm256_loadu_ps(qb + x2),
										 _mm256_loadu_ps(rb + x2)), h);
					h = _mm256_fmadd_ps(kx3, _mm256_fmadd_ps(ds, _mm256_loadu_ps(qb + x3),
										 _mm256_loadu_ps(rb + x3)), h);
					v = b ? _mm256_fmadd_ps(ky[b], h, v) : _mm256_mul_ps(ky[0], h);
				}
			} else if (taps == CORE_KEYS) {
				v = _mm256_setzero_ps();
				for (int b = 0; b < 4; b++) {
					const float *rb = r + ty[b];
					__m256 h = _mm256_mul_ps(kx0, _mm256_loadu_ps(rb + x0));

					h = _mm256_fmadd_ps(kx1, _mm256_loadu_ps(rb + x1), h);
					h = _mm256_fmadd_ps(kx2, _mm256_loadu_ps(rb + x2), h);
					h = _mm256_fmadd_ps(kx3, _mm256_loadu_ps(rb + x3), h);
					v = b ? _mm256_fmadd_ps(ky[b], h, v) : _mm256_mul_ps(ky[0], h);
				}
			} else {
				v = _mm256_mul_ps(bw0, _mm256_loadu_ps(r + y11));
				v = _mm256_fmadd_ps(bw1, _mm256_loadu_ps(r + y12), v);
				v = _mm256_fmadd_ps(bw2, _mm256_loadu_ps(r + y21), v);
				v = _mm256_fmadd_ps(bw3, _mm256_loadu_ps(r + y22), v);
			}
			/* each tap's sum over the corrections apart (four short
			 * chains of dependent FMAs instead of one long one), then
			 * the four summed in pairs */
			__m256 e1 = e, e2 = e, e3 = e;

			for (int q = 0; q < ncor; q++) {
				const float *rk = a->cbase[q] + o + i0;

				e = _mm256_fmadd_ps(cw[4 * q], _mm256_loadu_ps(rk + y11), e);
				e1 = _mm256_fmadd_ps(cw[4 * q + 1], _mm256_loadu_ps(rk + y12), e1);
				e2 = _mm256_fmadd_ps(cw[4 * q + 2], _mm256_loadu_ps(rk + y21), e2);
				e3 = _mm256_fmadd_ps(cw[4 * q + 3], _mm256_loadu_ps(rk + y22), e3);
			}
			e = _mm256_add_ps(_mm256_add_ps(e, e1), _mm256_add_ps(e2, e3));
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

/* Keys' taps with psf-blend=core's four node corrections, nearly every
 * faint star's case (a colour source's with its other class's cell), apart */
#define CORE_CHOOSE(a, kvb) \
	((a)->keys && (a)->ncor == 4 ? ((a)->dbase ? core_body(a, kvb, 4, CORE_KEYS2) : \
					core_body(a, kvb, 4, CORE_KEYS)) : \
	 core_body(a, kvb, (a)->ncor, !(a)->keys ? CORE_BILINEAR : (a)->dbase ? CORE_KEYS2 : CORE_KEYS))

__attribute__((target("avx2,fma"))) static double core_avx2(const struct core_args *a, float *kvb)
{
	return CORE_CHOOSE(a, kvb);
}

__attribute__((target("avx2,fma,avx512f,avx512vl"))) static double core_avx512(const struct core_args *a,
									      float *kvb)
{
	return CORE_CHOOSE(a, kvb);
}
#endif

void kernels_choose(struct point *p)
{
	p->sum_rows = sum_rows_plain;
	p->core_rows = core_plain;
#ifdef SIMD_X86
	if ((simd_flags() & (SIMD_AVX2 | SIMD_FMA)) == (SIMD_AVX2 | SIMD_FMA)) {
		p->sum_rows = sum_rows_avx2;
		p->core_rows = core_avx2;
		if (simd_flags() & SIMD_AVX512)
			p->core_rows = core_avx512;
	}
#endif
}
