/* ramp_stats.c - chisq and dumo of level-2 ramp fits; see ramp_stats.h. */
#include <math.h>

#include "ramp_stats.h"

void ramp_stats_row(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane,
		    const struct ramp_fit *fit, int n, double *scratch, float *chisq,
		    float *dumo)
{
	const struct ramp_pattern *p = &fp->p;
	const struct ramp_det *d = &fp->d;
	const double *lin = fp->nlinv;
	double sat = d->saturation, rn2 = d->read_noise * d->read_noise;
	/* per pixel: resultants used so far, the sums of the least squares,
	 * chi^2, the previous resultant, the rate */
	double *m = scratch, *st = m + n, *sx = st + n, *stt = sx + n, *stx = stt + n;
	double *c2 = stx + n, *prev = c2 + n, *rate = prev + n;

	for (int x = 0; x < n; x++) {
		m[x] = st[x] = sx[x] = stt[x] = stx[x] = c2[x] = prev[x] = 0;
		rate[x] = fit[x].dq & RAMP_DO_NOT_USE ? NAN : fit[x].rate;
	}
	for (int r = 0; r < p->nres; r++) {
		const uint16_t *v = dn + (size_t)r * plane;
		double t = p->tbar[r], dt = r ? t - p->tbar[r - 1] : 0;
		double vr = r ? rn2 * (1.0 / p->nread[r - 1] + 1.0 / p->nread[r]) : 0;

		for (int x = 0; x < n; x++) {
			/* a pixel stops at its first saturated resultant */
			double ok = (m[x] == r) & (v[x] < sat), xv = lin[v[x]];
			double q = xv - prev[x] - rate[x] * dt;
			double var = (rate[x] > 0 ? rate[x] : 0) * dt + vr;

			c2[x] += r ? ok * (q * q / var) : 0;
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
