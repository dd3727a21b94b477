/*
 * readnoise_stats - the correlated read noise (readnoise.c) measured as
 * the Roman Project measures its detectors: 55 reads 3.16247 s apart, the
 * top/bottom and smoothed side reference correction, the CDS noise of two
 * reads and the total noise (a least-squares slope through all reads, its
 * scatter times 54 read times, the median dark current's shot noise
 * added) against WFI_CDS_Noise_summary.ecsv and WFI_Total_noise.ecsv
 * (their values are in data/readnoise.tsv's cds and total columns), with
 * and without the pixels' slow part; the power spectrum along a channel's
 * readout against the model's 1/f; and amp33 following the channels.
 * "calib" prints the constants contrib/tables/derive_readnoise.py takes.
 */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "err.h"
#include "amp33.h"
#include "ramp.h"
#include "readnoise.h"
#include "rng.h"

enum { NREAD = 55, NROW = 4096, NY = 24, HALF = RN_SIDE_HALF };

/* WFI_Dark_current_summary.ecsv, median, e-/s */
static const double dark_median[18] = {
	0.019, 0.018, 0.019, 0.018, 0.03, 0.016, 0.027, 0.016, 0.017,
	0.012, 0.029, 0.02, 0.013, 0.018, 0.016, 0.017, 0.013, 0.015,
};

struct exposure {
	struct rnoise R[2];     /* reads 1..28, 29..55 */
	struct rng white;
	double w;               /* white e- */
};

/* read k (1..55) of frame row y, columns fx0 .. fx0 + n - 1, into v */
static void read_row(const struct exposure *x, int k, int y, int fx0, int n, double *v)
{
	float f[NROW];
	int piece = k > 28, r = piece ? k - 29 : k - 1;

	memset(f, 0, sizeof(float) * (size_t)n);
	rnoise_add_frame(&x->R[piece], r, y, fx0, n, f);
	rnoise_slow_add(&x->R[piece], (uint32_t)y * NROW + (uint32_t)fx0, n, r, r + 1, f, 0);
	rng_normal_fill(&x->white, ((uint64_t)k * NROW + (uint64_t)y) * NROW + (uint64_t)fx0,
			(size_t)n, v);
	for (int i = 0; i < n; i++)
		v[i] = v[i] * x->w + f[i];
}

static int patterns(struct ramp_pattern p[2], double read_time)
{
	memset(p, 0, 2 * sizeof(*p));
	for (int h = 0; h < 2; h++) {
		int a = h ? 29 : 1, b = h ? 55 : 28;

		p[h].table = 900 + h;
		p[h].read_time = read_time;
		p[h].nres = b - a + 1;
		for (int i = 0; i < p[h].nres; i++)
			p[h].first[i] = p[h].last[i] = a + i;
		if (ramp_pattern_finish(&p[h]) < 0)
			return -1;
	}
	return 0;
}

/* the CDS and total noise of SCA sca, seed seed, corrected (c = 1) and raw;
 * with noslow, the slow part left out */
static void measure(int sca, uint64_t seed, int noslow, double cds[2], double total[2],
		    double *dark_part)
{
	struct err e = { 0 };
	struct ramp_det d;
	struct rnoise_par par;
	struct ramp_pattern p[2];
	struct exposure x;
	struct ramp_key key = { .seed = seed, .filter = 2, .sca = sca };
	static double tb[NREAD + 1][32][2], side[NREAD + 1][NROW], sm[NROW], v[NROW];
	static double slope[2][NY][NROW], d12[2][NY][NROW];
	double w[NREAD + 1], tm = 0, s2 = 0, vd = 0, T;

	if (ramp_det_get(sca, &d, &e) < 0 || rnoise_par_get(sca, &par, &e) < 0) {
		diag("%s", e.msg);
		exit(1);
	}
	if (noslow)
		par.slow = 0;
	if (patterns(p, d.read_time) < 0 || rnoise_init(&x.R[0], &p[0], &par, &key, NREAD, &e) < 0 ||
	    rnoise_init(&x.R[1], &p[1], &par, &key, NREAD, &e) < 0) {
		diag("%s", e.msg);
		exit(1);
	}
	rng_init(&x.white, seed, 0x7e57u | (uint32_t)sca << 16);
	x.w = par.white;
	for (int k = 1; k <= NREAD; k++)
		tm += k * d.read_time / NREAD;
	for (int k = 1; k <= NREAD; k++)
		s2 += pow(k * d.read_time - tm, 2);
	for (int k = 1; k <= NREAD; k++)
		w[k] = (k * d.read_time - tm) / s2;
	for (int i = 1; i <= NREAD; i++)
		for (int j = 1; j <= NREAD; j++)
			vd += w[i] * w[j] * (i < j ? i : j) * d.read_time * dark_median[sca - 1];
	T = (NREAD - 1) * d.read_time;
	*dark_part = vd * T * T;
	memset(tb, 0, sizeof(tb));
	memset(slope, 0, sizeof(slope));
	for (int k = 1; k <= NREAD; k++) {
		for (int yy = 0; yy < 8; yy++) {
			read_row(&x, k, yy < 4 ? yy : NROW - 8 + yy, 0, NROW, v);
			for (int fx = 0; fx < NROW; fx++)
				tb[k][fx / RN_COLS][fx & 1] += v[fx] / (8 * RN_COLS / 2);
		}
		for (int y = 0; y < NROW; y++) {
			double s = 0;

			read_row(&x, k, y, 0, 4, v);
			read_row(&x, k, y, NROW - 4, 4, v + 4);
			for (int i = 0; i < 8; i++) {
				int fx = i < 4 ? i : NROW - 8 + i;

				s += v[i] - tb[k][fx / RN_COLS][fx & 1];
			}
			side[k][y] = s / 8;
		}
		for (int y = 0; y < NROW; y++) {
			int a = y - HALF < 0 ? 0 : y - HALF, b = y + HALF >= NROW ? NROW - 1 : y + HALF;
			double m = 0;

			for (int i = a; i <= b; i++)
				m += side[k][i];
			sm[y] = m / (b - a + 1);
		}
		for (int iy = 0; iy < NY; iy++) {
			int y = 64 + iy * 163;

			read_row(&x, k, y, 4, NROW - 8, v);
			for (int i = 0; i < NROW - 8; i++) {
				int fx = i + 4;
				double raw = v[i], cor = raw - tb[k][fx / RN_COLS][fx & 1] - sm[y];

				slope[0][iy][i] += w[k] * raw;
				slope[1][iy][i] += w[k] * cor;
				if (k == 1) {
					d12[0][iy][i] = -raw;
					d12[1][iy][i] = -cor;
				} else if (k == 2) {
					d12[0][iy][i] += raw;
					d12[1][iy][i] += cor;
				}
			}
		}
	}
	for (int c = 0; c < 2; c++) {
		double sc = 0, ss = 0, mc = 0, ms = 0, n = (double)NY * (NROW - 8);

		for (int iy = 0; iy < NY; iy++)
			for (int i = 0; i < NROW - 8; i++) {
				mc += d12[c][iy][i] / n;
				ms += slope[c][iy][i] / n;
			}
		for (int iy = 0; iy < NY; iy++)
			for (int i = 0; i < NROW - 8; i++) {
				sc += pow(d12[c][iy][i] - mc, 2) / n;
				ss += pow(slope[c][iy][i] - ms, 2) / n;
			}
		cds[c == 1 ? 0 : 1] = sqrt(sc);
		total[c == 1 ? 0 : 1] = sqrt(ss * T * T + *dark_part);
	}
	rnoise_free(&x.R[0]);
	rnoise_free(&x.R[1]);
}

/* the spectrum along the readout of read 1 of SCA 1 against the model */
static void spectrum(void)
{
	struct err e = { 0 };
	struct ramp_det d;
	struct rnoise_par par;
	struct ramp_pattern p[2];
	struct rnoise R;
	struct ramp_key key = { .seed = 11, .filter = 2, .sca = 1 };
	static double P[NROW / 2 + 1], x[NROW];
	fftw_complex *X = fftw_malloc(sizeof(fftw_complex) * (NROW / 2 + 1));
	fftw_plan pl = fftw_plan_dft_r2c_1d(NROW, x, X, FFTW_ESTIMATE);
	double w2 = 0, K = 0, sum = 0;
	long h = (long)(NREAD + 2) * NROW / 2;

	if (ramp_det_get(1, &d, &e) < 0 || rnoise_par_get(1, &par, &e) < 0 ||
	    patterns(p, d.read_time) < 0 || rnoise_init(&R, &p[0], &par, &key, NREAD, &e) < 0) {
		diag("%s", e.msg);
		exit(1);
	}
	for (long j = 1; j < h; j++)
		sum += 4.0 / (double)j;
	sum += 1.0 / (double)h;
	K = (par.cpink * par.cpink + par.upink * par.upink) / sum;
	for (int t = 0; t < NROW; t++)
		w2 += pow(0.5 - 0.5 * cos(2 * M_PI * t / NROW), 2);
	for (int rd = 0; rd < 28; rd++)
		for (int c = 0; c < RN_NCHAN; c++) {
			for (int y = 0; y < NROW; y++) {
				float f = 0;

				rnoise_add(&R, rd, c, y, c & 1 ? RN_COLS - 1 : 0, 1, &f);
				x[y] = f * (0.5 - 0.5 * cos(2 * M_PI * y / NROW));
			}
			fftw_execute(pl);
			for (int m = 0; m < NROW / 2; m++)
				P[m] += (creal(X[m]) * creal(X[m]) + cimag(X[m]) * cimag(X[m])) / w2 /
					(28.0 * RN_NCHAN);
		}
	/* expected: two-sided density 2 K / nu, nu = m / 4096 cycles a row */
	{
		double sx = 0, sy = 0, sxx = 0, sxy = 0, nb = 0;

		for (int a = 8; a < NROW / 2; a *= 2) {
			double got = 0, want = 0;

			for (int m = a; m < 2 * a; m++) {
				got += P[m];
				want += 2 * K * NROW / m;
			}
			diag("rows^-1 %6.4f-%6.4f: power %.4g, model %.4g, ratio %.3f",
			     (double)a / NROW, 2.0 * a / NROW, got, want, got / want);
			if (a >= 16 && a <= 512)
				is_rel(got, want, 0.15, "spectrum %d-%d of 4096: 1/f with the model's level",
				       a, 2 * a);
			sx += log((double)a);
			sy += log(got);
			sxx += log((double)a) * log((double)a);
			sxy += log((double)a) * log(got);
			nb++;
		}
		double slope = (nb * sxy - sx * sy) / (nb * sxx - sx * sx);

		/* per octave of m the power summed over twice the bins: slope 0 */
		is_near(slope, 0, 0.1, "spectrum: octave sums flat, i.e. power ~ 1/f (log slope %.3f)",
			slope);
	}
	fftw_destroy_plan(pl);
	fftw_free(X);
	rnoise_free(&R);
}

/*
 * amp33 samples the channels' correlated noise: the row means of its
 * resultant 1 less resultant 0 (DN) follow those of the left border's
 * reference columns (channel 0) row by row, both averaged over 16 rows
 * against their white noise; with the white model alone (rn NULL) they
 * are unrelated.  The correlation of the two.
 */
static double amp33_follows(int correlated)
{
	struct err e = { 0 };
	struct ramp_det d, dw;
	struct rnoise_par par;
	struct ramp_pattern p;
	struct rnoise R;
	struct ramp_key key = { .seed = 31, .filter = 2, .sca = 1 };
	enum { NB = NROW / 16 };
	static uint16_t amp[2 * 16 * AMP33_COLS], ref[2 * 16 * 4];
	double *scr = malloc(sizeof(double) * AMP33_SCRATCH), a[NB], b[NB];
	double ma = 0, mb = 0, sab = 0, saa = 0, sbb = 0;

	memset(&p, 0, sizeof(p));
	p.nres = 2;
	p.first[0] = p.last[0] = 1;
	p.first[1] = p.last[1] = 2;
	if (!scr || ramp_det_get(1, &d, &e) < 0 || rnoise_par_get(1, &par, &e) < 0 ||
	    (p.read_time = d.read_time, ramp_pattern_finish(&p)) < 0 ||
	    rnoise_init(&R, &p, &par, &key, 0, &e) < 0) {
		diag("%s", e.msg);
		exit(1);
	}
	ramp_scratch_init(scr);
	dw = d;
	dw.read_noise = par.white;
	for (int bk = 0; bk < NB; bk++) {
		double sa = 0, sb = 0;

		amp33_rows(&p, &d, &key, correlated ? &R : NULL, bk * 16, 16, amp, scr);
		for (int i = 0; i < 16; i++) {
			int y = bk * 16 + i;

			ramp_level1_row(&p, correlated ? &dw : &d, &key, (uint32_t)y * NROW, 4, NULL, 0,
					ref + i * 4, 16 * 4, scr);
			if (correlated)
				rnoise_add_dn(&R, d.gain, y, 0, 4, ref + i * 4, 16 * 4);
		}
		for (int i = 0; i < 16 * AMP33_COLS; i++)
			sa += (double)amp[16 * AMP33_COLS + i] - amp[i];
		for (int i = 0; i < 16 * 4; i++)
			sb += (double)ref[16 * 4 + i] - ref[i];
		a[bk] = sa / (16 * AMP33_COLS);
		b[bk] = sb / (16 * 4);
		ma += a[bk] / NB;
		mb += b[bk] / NB;
	}
	for (int bk = 0; bk < NB; bk++) {
		sab += (a[bk] - ma) * (b[bk] - mb);
		saa += (a[bk] - ma) * (a[bk] - ma);
		sbb += (b[bk] - mb) * (b[bk] - mb);
	}
	rnoise_free(&R);
	free(scr);
	return sab / sqrt(saa * sbb);
}

/* "calib": the corrected CDS and total read noise (the dark current's
 * part out) per e- of the white part without the slow part, the means over
 * the 18 SCAs and 3 exposures each, which contrib/tables/derive_readnoise.py
 * takes as CDS_WHITE and TOTAL_WHITE */
static int calibrate(void)
{
	struct err e = { 0 };
	double a = 0, b = 0;
	int n = 0;

	for (int sca = 1; sca <= 18; sca++)
		for (uint64_t seed = 101; seed < 104; seed++) {
			struct rnoise_par par;
			double cds[2], total[2], dark;

			if (rnoise_par_get(sca, &par, &e) < 0)
				return 1;
			measure(sca, seed * 32 + (uint64_t)sca, 1, cds, total, &dark);
			a += cds[0] / par.white;
			b += sqrt(total[0] * total[0] - dark) / par.white;
			n++;
		}
	printf("CDS_WHITE = %.4f\nTOTAL_WHITE = %.4f\n", a / n, b / n);
	return 0;
}

int main(int argc, char **argv)
{
	int all = argc > 1 && !strcmp(argv[1], "all");
	struct err e = { 0 };

	if (argc > 1 && !strcmp(argv[1], "calib"))
		return calibrate();
	spectrum();
	{
		double on = amp33_follows(1), off = amp33_follows(0);

		ok(on > 0.8, "amp33 follows the left reference columns row by row: correlation %.3f", on);
		ok(fabs(off) < 0.3, "with white noise alone it does not: correlation %.3f", off);
	}
	for (int sca = 1; sca <= 18; sca += all ? 1 : 17) {
		struct rnoise_par par;
		double cds[2], total[2], dark, want_cds, cds0[2], total0[2];

		if (rnoise_par_get(sca, &par, &e) < 0)
			return 1;
		want_cds = par.cds;
		measure(sca, 5 + (uint64_t)sca, 0, cds, total, &dark);
		measure(sca, 5 + (uint64_t)sca, 1, cds0, total0, &dark);
		diag("WFI%02d: CDS %.2f e- (raw %.2f), total %.2f e- (raw %.2f, dark %.2f, "
		     "without the slow part %.2f), Project CDS %.2f, total %.2f: ratios %.3f, %.3f",
		     sca, cds[0], cds[1], total[0], total[1], sqrt(dark), total0[0], par.cds, par.total,
		     cds[0] / par.cds, total[0] / par.total);
		is_rel(cds[0], want_cds, 0.05, "WFI%02d: corrected CDS noise within 5 %% of the Project's",
		       sca);
		is_rel(total[0], par.total, 0.10,
		       "WFI%02d: total noise (55 reads, corrected) within 10 %% of the Project's", sca);
		/* the slow part is what brings the total there: without it the
		 * total is short, the CDS noise nearly the same */
		ok(total0[0] < total[0] / 1.05, "WFI%02d: without the slow part the total %.3f x lower",
		   sca, total[0] / total0[0]);
		is_rel(cds0[0], cds[0], 0.02, "WFI%02d: the slow part moves the CDS noise by %.2f %%", sca,
		       100 * (cds[0] / cds0[0] - 1));
		ok(total[1] > 1.15 * total[0], "WFI%02d: total noise without the correction %.2f x worse",
		   sca, total[1] / total[0]);
		ok(cds[1] > 1.2 * cds[0], "WFI%02d: CDS noise without the correction %.2f x worse",
		   sca, cds[1] / cds[0]);
	}
	return done_testing();
}
