/*
 * ramp_fit.c - level 2: the ramp of each pixel fitted as the Roman pipeline
 * does it, following Casertano et al. (2022, "Up-the-ramp fitting for
 * unevenly averaged resultants"; romancal's ramp fitting): optimal weights
 * for unevenly averaged resultants, jumps found and the ramp split there,
 * reads after saturation dropped, non-linearity corrected.  See ramp.h and
 * ramp_fit_pixel().
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ramp.h"
#include "simd.h"

static const double cas_power[6] = { 0, 0.4, 1, 3, 6, 10 };
/* ... and the edges of its signal-to-noise bins, squared */
static const double snr_edge2[5] = { 25, 100, 400, 2500, 10000 };

/* Fixsen et al. (2000) / Casertano et al. (2022): the weighting power for a
 * ramp of signal-to-noise snr. */
static int power_index(double sig, double var)
{
	/* snr = sig / sqrt(var) against the edges, squared */
	double s2 = sig * sig;
	int i = 0;

	while (i < 5 && !(s2 < snr_edge2[i] * var))
		i++;
	return i;
}

/* Optimal weights W[a..b) of the slope over resultants a .. b-1 with power
 * index pi; returns the read-noise and Poisson (per unit rate) variances. */
static void seg_weights(const struct ramp_pattern *p, const double *var_read,
			int a, int b, int pi, double *W, double *vr, double *vp)
{
	double P = cas_power[pi], tmid = (p->tbar[a] + p->tbar[b - 1]) / 2;
	double F0 = 0, F1 = 0, F2 = 0, Dt, run = 0;

	for (int i = a; i < b; i++) {
		double N = p->nread[i], dtm = fabs(p->tbar[i] - tmid);
		double w = (1 + P) * N / (1 + P * N) * (P ? pow(dtm, P) : 1);

		W[i] = w;
		F0 += w;
		F1 += w * p->tbar[i];
		F2 += w * p->tbar[i] * p->tbar[i];
	}
	Dt = F2 * F0 - F1 * F1;
	*vr = *vp = 0;
	for (int i = a; i < b; i++) {
		W[i] *= (F0 * p->tbar[i] - F1) / Dt;
		*vr += W[i] * W[i] * var_read[i];
		/* Cov(R_i, R_j) = rate tbar_i for i < j; Var(R_i) = rate tau_i */
		*vp += W[i] * W[i] * p->tau[i] + 2 * W[i] * run;
		run += W[i] * p->tbar[i];
	}
}

int ramp_fit_plan_init(struct ramp_fit_plan *fp, const struct ramp_pattern *p,
		       const struct ramp_det *d)
{
	memset(fp, 0, sizeof(*fp));
	fp->p = *p;
	fp->d = *d;
	fp->nres = p->nres;
	/* The level from which the fit takes a resultant as saturated.  IPC
	 * shares the measured charge after each pixel's own was clipped, so a
	 * saturated pixel beside fainter ones reads as little as its reset
	 * level R plus K0 (saturation - R), K0 the kernel's centre, and its
	 * later resultants level off there, below the clip: fitted as signal
	 * they give a flat ramp (a rate near 0) or false jumps.  So the fit
	 * starts saturation there, R taken 5 sigma of reset noise low (as
	 * romancal's saturation threshold sits below the physical level).  A
	 * uniform field still reads the clip (the kernel sums to 1); with no
	 * IPC (K0 = 1) the level is the clip. */
	{
		double r = ramp_nl(d, d->pedestal - 5 * d->reset_noise);
		double s = d->saturation * d->gain, k0 = d->ipc[1][1];

		if (k0 > 0 && k0 < 1 && r < s)
			fp->d.saturation = floor((r + k0 * (s - r)) / d->gain);
	}
	for (int i = 0; i < p->nres; i++)
		fp->var_read[i] = d->read_noise * d->read_noise / p->nread[i] +
				  d->gain * d->gain / 12;
	if (p->nres >= 2)
		for (int pi = 0; pi < 6; pi++)
			seg_weights(p, fp->var_read, 0, p->nres, pi, fp->w[pi],
				    &fp->vr[pi], &fp->vp[pi]);
	/* the difference of resultants i and i + 1: its time, its read
	 * variance and its Poisson variance per unit rate */
	for (int i = 0; i + 1 < p->nres; i++) {
		fp->dtbar[i] = p->tbar[i + 1] - p->tbar[i];
		fp->vdiff[i] = fp->var_read[i] + fp->var_read[i + 1];
		fp->cdiff[i] = p->tau[i + 1] + p->tau[i] - 2 * p->tbar[i];
	}
	fp->jump2 = d->jump_threshold * d->jump_threshold;
	/* resultants are 16-bit: their linearised charge is a table */
	if (!(fp->nlinv = malloc(65536 * sizeof(double))))
		return -1;
	fp->nl_dn = 65536;
	for (int v = 0; v < 65536; v++) {
		fp->nlinv[v] = ramp_nl_inverse(d, v * d->gain);
		if (v > 0 && fp->nl_dn == 65536 && d->nonlinear_flag > 0 &&
		    fp->nlinv[v] > (v * d->gain) * (1 + d->nonlinear_flag))
			fp->nl_dn = v;
	}
	return 0;
}

void ramp_fit_plan_free(struct ramp_fit_plan *fp)
{
	free(fp->nlinv);
	fp->nlinv = NULL;
}

struct seg {
	int a, b;
	double f, vr, vp;
};

static void fit_seg(const struct ramp_fit_plan *fp, const double *s, struct seg *sg)
{
	const struct ramp_pattern *p = &fp->p;
	int a = sg->a, b = sg->b, pi;
	double sig = s[b - 1] - s[a], Wl[RAMP_MAX_RES];
	const double *W;

	/* the signal-to-noise of the piece: its rise over its noise */
	if (sig < 0)
		sig = 0;
	pi = power_index(sig, sig + fp->var_read[a] + fp->var_read[b - 1]);
	if (a == 0 && b == fp->nres) {
		W = fp->w[pi];
		sg->vr = fp->vr[pi];
		sg->vp = fp->vp[pi];
	} else {
		seg_weights(p, fp->var_read, a, b, pi, Wl, &sg->vr, &sg->vp);
		W = Wl;
	}
	sg->f = 0;
	for (int i = a; i < b; i++)
		sg->f += W[i] * s[i];
}

/* The rate of the pieces combined with inverse-variance weights, the
 * Poisson part of each variance at the combined rate (two passes, so the
 * weights do not follow a piece's own noise). */
static double combine(const struct seg *sg, int nseg, double *vr, double *vp)
{
	double f = 0;

	if (nseg == 1) {
		*vr = sg[0].vr;
		*vp = sg[0].vp * (sg[0].f > 0 ? sg[0].f : 0);
		return sg[0].f;
	}
	for (int pass = 0; pass < 2; pass++) {
		double fr = pass && f > 0 ? f : 0, sw = 0, sf = 0, svr = 0, svp = 0;

		for (int j = 0; j < nseg; j++) {
			double w;

			if (sg[j].b - sg[j].a < 2)
				continue;
			w = 1 / (sg[j].vr + fr * sg[j].vp);
			sw += w;
			sf += w * sg[j].f;
			svr += w * w * sg[j].vr;
			svp += w * w * sg[j].vp;
		}
		if (sw == 0)
			return NAN;
		f = sf / sw;
		*vr = svr / (sw * sw);
		*vp = svp / (sw * sw) * (f > 0 ? f : 0);
	}
	return f;
}

/* The resultants of a pixel linearised into s[0 .. n) and the number the
 * fit uses: those before the first saturated one, less the one before it
 * when its last read, projected along the ramp, reaches saturation (DQ
 * SATURATED in out). */
static int fit_saturation(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t stride,
			  double *s, struct ramp_fit *out)
{
	const struct ramp_pattern *p = &fp->p;
	const struct ramp_det *d = &fp->d;
	double dt = p->read_time, sat_dn = floor(d->saturation);
	int n = p->nres, nuse = n;

	for (int i = 0; i < n; i++) {
		double v = dn[(size_t)i * stride];

		if (v >= sat_dn && nuse == n)
			nuse = i;
		s[i] = fp->nlinv[dn[(size_t)i * stride]];
	}
	if (nuse < n) {
		int i = nuse - 1;

		out->dq |= RAMP_SATURATED;
		if (i >= 0) {
			double f, from, tfrom, xlast = p->last[i] * dt;

			if (i >= 2) {
				f = (s[i - 1] - s[i - 2]) / (p->tbar[i - 1] - p->tbar[i - 2]);
				from = s[i - 1];
				tfrom = p->tbar[i - 1];
			} else {
				f = (s[0] - d->pedestal) / p->tbar[0];
				from = s[0];
				tfrom = p->tbar[0];
			}
			if (from + f * (xlast - tfrom) >= d->sat_true)
				nuse = i;
		}
	}
	return nuse;
}

/* The pieces sg[0 .. *nseg) of a ramp s split at its jumps, each fitted
 * (the first fitted already): the rise most beyond the threshold splits
 * its piece, until none is left (see ramp_fit_pixel()). */
static void fit_jumps(const struct ramp_fit_plan *fp, const double *s, struct seg *sg,
		      int *nseg, struct ramp_fit *out)
{
	for (int iter = 0; iter < fp->nres; iter++) {
		double vr, vp, f = combine(sg, *nseg, &vr, &vp), best = 0;
		int bi = -1, bj = -1;

		if (!isfinite(f))
			break;
		if (f < 0)
			f = 0;
		/* z^2 = r^2 / var > threshold^2 for a rise r > 0, tested
		 * without a root or a division, which most pixels never
		 * need */
		for (int j = 0; j < *nseg; j++)
			for (int i = sg[j].a; i < sg[j].b - 1; i++) {
				double r = s[i + 1] - s[i] - f * fp->dtbar[i];
				double var = fp->vdiff[i] + f * fp->cdiff[i];

				if (r > 0 && r * r > fp->jump2 * var) {
					double z = r / sqrt(var);

					if (z > best) {
						best = z;
						bi = i;
						bj = j;
					}
				}
			}
		if (bi < 0)
			break;
		/* split piece bj after resultant bi */
		memmove(&sg[bj + 2], &sg[bj + 1], (size_t)(*nseg - bj - 1) * sizeof(*sg));
		sg[bj + 1].a = bi + 1;
		sg[bj + 1].b = sg[bj].b;
		sg[bj].b = bi + 1;
		++*nseg;
		out->njump++;
		out->dq |= RAMP_JUMP_DET;
		for (int j = bj; j <= bj + 1; j++)
			if (sg[j].b - sg[j].a >= 2)
				fit_seg(fp, s, &sg[j]);
	}
}

/* The rate of a ramp whose only usable resultant is the first: its rise
 * over the nominal reset level. */
static void fit_first(const struct ramp_fit_plan *fp, const double *s, struct ramp_fit *out)
{
	const struct ramp_pattern *p = &fp->p;
	const struct ramp_det *d = &fp->d;
	double t = p->tbar[0];

	out->rate = (s[0] - d->pedestal) / t;
	out->var_rnoise = (fp->var_read[0] + d->reset_noise * d->reset_noise) / (t * t);
	out->var_poisson = (out->rate > 0 ? out->rate : 0) * p->tau[0] / (t * t);
}

/*
 * The fit of one pixel.
 *
 * Saturation: a resultant at the saturation level is saturated, and so are
 * those after it.  The resultant just before the first saturated one may
 * hold reads that saturated (its mean is then below the level): it is
 * dropped too when its last read, projected along the ramp from the clean
 * resultants before it, reaches the saturation level.
 *
 * Jumps: with the rate f of the current pieces, the difference of
 * resultants i and i + 1 should be f (tbar_i+1 - tbar_i) with variance
 * var_read_i + var_read_i+1 + f (tau_i+1 + tau_i - 2 tbar_i); the
 * difference most above that, when beyond jump_threshold sigma, splits its
 * piece there, and the pieces are fitted again until none is left.  Only
 * rises count: a cosmic ray adds charge, and while the jumps are still in
 * the fit the rate f is too high, so the clean differences fall below it
 * (a two-sided test then splits clean differences first).
 */
void ramp_fit_pixel(const struct ramp_fit_plan *fp, const uint16_t *dn,
		    size_t stride, struct ramp_fit *out)
{
	double s[RAMP_MAX_RES];
	struct seg sg[RAMP_MAX_RES];
	int n = fp->p.nres, nuse, nseg = 1;

	memset(out, 0, sizeof(*out));
	if (n < 2) {
		out->dq = RAMP_DO_NOT_USE;
		return;
	}
	nuse = fit_saturation(fp, dn, stride, s, out);
	out->nuse = nuse;
	/*
	 * The linearity flags, for the resultants the fit uses (saturated ones
	 * are not corrected, so not flagged, as Roman's linearity step does):
	 * NO_LIN_CORR when one is at 0 DN, clipped by the converter below the
	 * range where the law holds, so its correction does not apply;
	 * NONLINEAR when one is so far up the law that its correction exceeds
	 * d.nonlinear_flag (5 %: from 75,586 e- measured, pedestal included).
	 */
	for (int i = 0; i < nuse; i++) {
		int v = dn[(size_t)i * stride];

		if (v == 0)
			out->dq |= RAMP_NO_LIN_CORR;
		if (v >= fp->nl_dn)
			out->dq |= RAMP_NONLINEAR;
	}
	if (nuse == 0) {
		out->dq |= RAMP_DO_NOT_USE;
		return;
	}
	if (nuse == 1) {
		/* one resultant: the rate above the nominal reset level */
		fit_first(fp, s, out);
		return;
	}
	sg[0].a = 0;
	sg[0].b = nuse;
	fit_seg(fp, s, &sg[0]);
	fit_jumps(fp, s, sg, &nseg, out);
	out->rate = combine(sg, nseg, &out->var_rnoise, &out->var_poisson);
	if (!isfinite(out->rate)) {
		if (sg[0].a == 0 && sg[0].b == 1) {
			fit_first(fp, s, out);
		} else {
			out->rate = out->var_rnoise = out->var_poisson = 0;
			out->dq |= RAMP_DO_NOT_USE;
		}
	}
}

/*
 * The common case of ramp_fit_pixel(), without its general machinery: no
 * resultant saturated, at 0 DN or beyond the NONLINEAR flag, so the piece
 * is the whole ramp and its weights are the plan's; the rate is then a
 * fixed weighted sum of the linearised resultants.  When the jump test
 * finds a rise (or a resultant is out of that range), the pixel goes to
 * ramp_fit_pixel(); otherwise the numbers are the very ones it computes:
 * the same operations in the same order.
 */
#ifdef SIMD_X86
/*
 * ramp_fit_row()'s common case for the eight pixels dn[0..8) with
 * AVX-512: the same operations in the same order on each lane, so the
 * same numbers.  Returns the lanes it leaves to ramp_fit_pixel() (out of
 * range, or a jump).
 */
__attribute__((target("avx512f,avx512dq"))) static unsigned
fit8_avx512(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane, int lim,
	    double vb, struct ramp_fit *out)
{
	int nres = fp->nres;
	__m512d s[RAMP_MAX_RES], sig, var, s2, f, fj, zero = _mm512_setzero_pd();
	__m512i pi = _mm512_setzero_si512(), one = _mm512_set1_epi64(1), wi;
	__mmask8 bad = 0;
	double rate[8], vr[8], vp[8];

	for (int i = 0; i < nres; i++) {
		__m512i v = _mm512_cvtepu16_epi64(_mm_loadu_si128((const __m128i *)(dn + (size_t)i *
										    plane)));

		bad |= _mm512_cmplt_epi64_mask(v, one) |
		       _mm512_cmpge_epi64_mask(v, _mm512_set1_epi64(lim));
		s[i] = _mm512_i64gather_pd(v, fp->nlinv, 8);
	}
	if (bad == 0xff)
		return bad;
	sig = _mm512_sub_pd(s[nres - 1], s[0]);
	sig = _mm512_mask_mov_pd(sig, _mm512_cmp_pd_mask(sig, zero, _CMP_LT_OQ), zero);
	/* power_index(): how many edges the snr^2 is not below */
	var = _mm512_add_pd(sig, _mm512_set1_pd(vb));
	s2 = _mm512_mul_pd(sig, sig);
	for (int e = 0; e < 5; e++)
		pi = _mm512_mask_add_epi64(pi, _mm512_cmp_pd_mask(s2, _mm512_mul_pd(
						   _mm512_set1_pd(snr_edge2[e]), var), _CMP_NLT_UQ), pi, one);
	f = zero;
	if (_mm512_cmpeq_epi64_mask(pi, _mm512_set1_epi64(pi[0])) == 0xff) {
		/* one power for the eight (a sky): its weights as they are */
		const double *w = fp->w[pi[0]];

		for (int i = 0; i < nres; i++)
			f = _mm512_add_pd(f, _mm512_mul_pd(_mm512_set1_pd(w[i]), s[i]));
	} else {
		wi = _mm512_mullo_epi64(pi, _mm512_set1_epi64(RAMP_MAX_RES));
		for (int i = 0; i < nres; i++)
			f = _mm512_add_pd(f, _mm512_mul_pd(_mm512_i64gather_pd(
					  _mm512_add_epi64(wi, _mm512_set1_epi64(i)), fp->w[0], 8), s[i]));
	}
	fj = _mm512_mask_mov_pd(f, _mm512_cmp_pd_mask(f, zero, _CMP_LT_OQ), zero);
	for (int i = 0; i + 1 < nres; i++) {
		__m512d r = _mm512_sub_pd(_mm512_sub_pd(s[i + 1], s[i]),
					  _mm512_mul_pd(fj, _mm512_set1_pd(fp->dtbar[i])));
		__m512d vr = _mm512_add_pd(_mm512_set1_pd(fp->vdiff[i]),
					   _mm512_mul_pd(fj, _mm512_set1_pd(fp->cdiff[i])));

		bad |= _mm512_cmp_pd_mask(r, zero, _CMP_GT_OQ) &
		       _mm512_cmp_pd_mask(_mm512_mul_pd(r, r),
					  _mm512_mul_pd(_mm512_set1_pd(fp->jump2), vr), _CMP_GT_OQ);
	}
	_mm512_storeu_pd(rate, f);
	_mm512_storeu_pd(vr, _mm512_i64gather_pd(pi, fp->vr, 8));
	_mm512_storeu_pd(vp, _mm512_mul_pd(_mm512_i64gather_pd(pi, fp->vp, 8),
					   _mm512_maskz_mov_pd(_mm512_cmp_pd_mask(f, zero, _CMP_GT_OQ),
							       f)));
	for (int q = 0; q < 8; q++)
		if (!(bad >> q & 1))
			out[q] = (struct ramp_fit){ .rate = rate[q], .var_rnoise = vr[q],
						    .var_poisson = vp[q], .nuse = nres };
	return bad;
}
#endif

void ramp_fit_row(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane, int n,
		  struct ramp_fit *out)
{
	const double *nlinv = fp->nlinv;
	int nres = fp->nres;
	double sat_dn = floor(fp->d.saturation);
	/* resultants v in 1 .. lim - 1 raise no flag and saturate nothing */
	int lim = sat_dn < fp->nl_dn ? (int)sat_dn : fp->nl_dn;
	double vb = fp->var_read[0] + fp->var_read[nres - 1], jump2 = fp->jump2;
	int x = 0;

#ifdef SIMD_X86
	if (nres >= 2 && (simd_flags() & SIMD_AVX512))
		for (; x + 8 <= n; x += 8) {
			unsigned bad = fit8_avx512(fp, dn + x, plane, lim, vb, out + x);

			for (int q = 0; bad; q++, bad >>= 1)
				if (bad & 1)
					ramp_fit_pixel(fp, dn + x + q, plane, &out[x + q]);
		}
#endif
	for (; x < n; x++) {
		double s[RAMP_MAX_RES], sig, f, fj;
		const double *w;
		int ok = nres >= 2, pi, jump = 0;

		for (int i = 0; i < nres; i++) {
			int v = dn[(size_t)i * plane + (size_t)x];

			ok &= v >= 1 && v < lim;
			s[i] = nlinv[v];
		}
		if (!ok)
			goto general;
		sig = s[nres - 1] - s[0];
		if (sig < 0)
			sig = 0;
		pi = power_index(sig, sig + vb);
		w = fp->w[pi];
		f = 0;
		for (int i = 0; i < nres; i++)
			f += w[i] * s[i];
		fj = f < 0 ? 0 : f;
		/* the jump test without branches: a rise is as likely as
		 * a fall in a clean ramp, which no predictor guesses */
		for (int i = 0; i + 1 < nres; i++) {
			double r = s[i + 1] - s[i] - fj * fp->dtbar[i];
			double var = fp->vdiff[i] + fj * fp->cdiff[i];

			jump |= (r > 0) & (r * r > jump2 * var);
		}
		if (jump)
			goto general;
		out[x] = (struct ramp_fit){ .rate = f, .var_rnoise = fp->vr[pi],
					    .var_poisson = fp->vp[pi] * (f > 0 ? f : 0),
					    .nuse = nres };
		continue;
general:
		ramp_fit_pixel(fp, dn + x, plane, &out[x]);
	}
}
