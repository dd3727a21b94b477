/* ramp_stats.c - chisq and dumo of level-2 ramp fits; see ramp_stats.h. */
#include <math.h>

#include "ramp_stats.h"
#include "simd.h"

/* The loops are along the row, each pixel on its own: vectorised (the
 * Makefile compiles this file with -O3), one clone a vector width, with
 * the same bytes in each (no fused or reordered arithmetic). */
SIMD_CLONES("avx512f", "avx2", "default")
void ramp_stats_row(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane,
		    const struct ramp_fit *fit, int n, double *scratch, float *chisq,
		    float *dumo)
{
	/* every pointer below reaches its own part of memory */
#define R restrict
	const struct ramp_pattern *p = &fp->p;
	const struct ramp_det *d = &fp->d;
	const double *R lin = fp->nlinv;
	double sat = d->saturation, rn2 = d->read_noise * d->read_noise;
	/* per pixel: resultants used so far, the sums of the least squares,
	 * chi^2, the previous resultant, the rate */
	double *R m = scratch, *R st = scratch + n, *R sx = scratch + 2 * n;
	double *R stt = scratch + 3 * n, *R stx = scratch + 4 * n, *R c2 = scratch + 5 * n;
	double *R prev = scratch + 6 * n, *R rate = scratch + 7 * n, *R xs = scratch + 8 * n;
	double *R below = scratch + 9 * n;
#undef R

	for (int x = 0; x < n; x++) {
		c2[x] = 0;
		rate[x] = fit[x].dq & RAMP_DO_NOT_USE ? NAN : fit[x].rate;
	}
	for (int r = 0; r < p->nres; r++) {
		const uint16_t *restrict v = dn + (size_t)r * plane;
		double t = p->tbar[r], dt = r ? t - p->tbar[r - 1] : 0, fr = r;
		double vr = r ? rn2 * (1.0 / p->nread[r - 1] + 1.0 / p->nread[r]) : 0;

		/* the table's values first (a gather), then arithmetic alone */
#pragma GCC ivdep
		for (int x = 0; x < n; x++) {
			xs[x] = lin[v[x]];
			below[x] = v[x] < sat;
		}
		if (r == 0) {
			/* the first resultant: no difference yet */
			for (int x = 0; x < n; x++) {
				double ok = below[x];

				m[x] = ok;
				st[x] = ok * t;
				sx[x] = ok * xs[x];
				stt[x] = ok * t * t;
				stx[x] = ok * t * xs[x];
				prev[x] = xs[x];
			}
			continue;
		}
#pragma GCC ivdep
		for (int x = 0; x < n; x++) {
			/* a pixel stops at its first saturated resultant */
			double xv = xs[x];
			double ok = (double)(m[x] == fr) * below[x];
			double q = xv - prev[x] - rate[x] * dt;
			double var = (rate[x] > 0 ? rate[x] : 0) * dt + vr;

			c2[x] += ok * (q * q / var);
			m[x] += ok;
			st[x] += ok * t;
			sx[x] += ok * xv;
			stt[x] += ok * t * t;
			stx[x] += ok * t * xv;
			prev[x] = xv;
		}
	}
	for (int x = 0; x < n; x++) {
		double den = m[x] * stt[x] - st[x] * st[x];

		chisq[x] = m[x] >= 3 && !isnan(rate[x]) ? (float)(c2[x] / (m[x] - 2)) : NAN;
		dumo[x] = m[x] >= 2 && !isnan(rate[x]) ?
			  (float)(((m[x] * stx[x] - st[x] * sx[x]) / den - rate[x]) / d->gain) : NAN;
	}
}
