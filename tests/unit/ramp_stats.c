/*
 * ramp_stats - the statistics of levels 1 and 2 (wfiscene(1) LEVELS): many
 * pixels of one flux through ramp_level1_row and ramp_fit_pixel, fixed
 * seeds.  The table printed as diagnostics is the one in BENCHMARKS.md.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "tap.h"
#include "err.h"
#include "ramp.h"

enum { ROW = 4096 };

struct result {
	double mean, sd, err_rms, frac_sat, frac_jump, frac_dnu, frac_nl, frac_nlc;
	long n;
};

/* npix pixels of rate `rate` (e-/s), rows of ROW from pixel 0: level 1,
 * then level 2; jumps/saturation flags counted. */
static struct result run(const struct ramp_pattern *p, const struct ramp_det *d,
			 const struct ramp_key *k, double rate, long npix,
			 double *rates_out)
{
	struct ramp_fit_plan fp;
	double *r = malloc(ROW * sizeof(double));
	double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double));
	uint16_t *dn = malloc((size_t)p->nres * ROW * sizeof(uint16_t));

	ramp_scratch_init(scr);
	struct result res = { 0 };
	double sum = 0, sum2 = 0, var = 0;
	long used = 0;

	if (ramp_fit_plan_init(&fp, p, d) < 0)
		exit(1);
	for (int i = 0; i < ROW; i++)
		r[i] = rate;
	for (long c = 0; c < npix; c += ROW) {
		int n = npix - c < ROW ? (int)(npix - c) : ROW;

		ramp_level1_row(p, d, k, (uint32_t)c, n, r, 1, dn, ROW, scr);
		for (int i = 0; i < n; i++) {
			struct ramp_fit f;

			ramp_fit_pixel(&fp, dn + i, ROW, &f);
			if (rates_out)
				rates_out[c + i] = (f.dq & RAMP_DO_NOT_USE) ? NAN : f.rate;
			res.frac_sat += !!(f.dq & RAMP_SATURATED);
			res.frac_jump += !!(f.dq & RAMP_JUMP_DET);
			res.frac_nl += !!(f.dq & RAMP_NONLINEAR);
			res.frac_nlc += !!(f.dq & RAMP_NO_LIN_CORR);
			if (f.dq & RAMP_DO_NOT_USE) {
				res.frac_dnu++;
				continue;
			}
			sum += f.rate;
			sum2 += f.rate * f.rate;
			var += f.var_poisson + f.var_rnoise;
			used++;
		}
	}
	res.n = used;
	if (used > 1) {
		res.mean = sum / used;
		res.sd = sqrt((sum2 - sum * sum / used) / (used - 1));
		res.err_rms = sqrt(var / used);
	}
	res.frac_sat /= npix;
	res.frac_jump /= npix;
	res.frac_dnu /= npix;
	res.frac_nl /= npix;
	res.frac_nlc /= npix;
	free(r);
	free(scr);
	free(dn);
	ramp_fit_plan_free(&fp);
	return res;
}

/* Whether row r of ROW pixels, drawn whole into w and then in pieces of
 * `piece` pixels into s (both nres planes of ROW), gives the same
 * resultants: the bytes must not depend on how a row is cut (pieces below
 * eight pixels never take the eight-at-a-time loops). */
static int same_in_pieces(const struct ramp_pattern *p, const struct ramp_det *d,
			  const struct ramp_key *k, const double *r, int piece)
{
	double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double));
	uint16_t *w = malloc((size_t)p->nres * ROW * 2), *s = malloc((size_t)p->nres * ROW * 2);
	int same = 0;

	if (scr && w && s) {
		ramp_scratch_init(scr);
		ramp_level1_row(p, d, k, 8192, ROW, r, 1, w, ROW, scr);
		for (int x = 0; x < ROW; x += piece) {
			int n = ROW - x < piece ? ROW - x : piece;

			ramp_level1_row(p, d, k, 8192 + x, n, r + x, 1, s + x, ROW, scr);
		}
		same = !memcmp(w, s, (size_t)p->nres * ROW * 2);
	}
	free(scr);
	free(w);
	free(s);
	return same;
}

/* A faint sky that rises across the row (its Poisson tables change), with
 * a star every 50 pixels, e-/s. */
static void faint_sky(double r[ROW])
{
	for (int i = 0; i < ROW; i++)
		r[i] = 0.2 + 2e-3 * i + (i % 50 < 3 ? 40.0 / (1 + i % 50) : 0);
}

static void det_for_tests(struct ramp_det *d)
{
	struct err e = { 0 };

	if (ramp_det_get(2, d, &e) < 0) {
		printf("Bail out! %s\n", e.msg);
		exit(1);
	}
	d->dark = 0;            /* the rate in is the rate out */
	d->cosmic_rate = 0;
}

int main(void)
{
	struct err e = { 0 };
	struct ramp_pattern p;
	struct ramp_det d;
	struct ramp_key k = { .seed = 20261125, .filter = 4, .sca = 2 };

	/* tables */
	ok(ramp_pattern_get(4, &p, &e) == 0, "MA table 4 is there");
	ok(p.nres == 9 && p.first[3] == 5 && p.last[3] == 9 && p.last[8] == 44,
	   "table 4: 9 resultants, the fourth of reads 5-9, last read 44");
	is_near(p.exptime, 139.149, 1e-3, "table 4 lasts 44 reads of 3.16247 s");
	is_near(p.tbar[3], 7 * 3.16247, 1e-9, "mean time of reads 5-9 is read 7");
	ok(ramp_pattern_get(2, &p, &e) < 0 && strstr(e.msg, "no MultiAccum table 2") &&
	   strstr(e.msg, "109"), "a missing table is named with the list: %s", e.msg);
	ok(ramp_det_get(1, &d, &e) == 0 && d.gain == 2 && d.saturation == 55000 &&
	   fabs(d.read_noise - 17.49 / sqrt(2)) < 1e-3 && d.dark == 0.049,
	   "WFI01: gain 2, saturation 55000 DN, read noise 17.49/sqrt2, dark 0.049");
	{
		double s = 0;

		for (int i = 0; i < 9; i++)
			s += d.ipc[i / 3][i % 3];
		is_near(s, 1, 1e-8, "the IPC kernel sums to 1");
		ok(d.ipc[1][1] > 0.93 && d.ipc[1][1] < 0.94, "IPC centre %.4f", d.ipc[1][1]);
	}

	/* non-linearity round trip */
	{
		double worst = 0;

		for (double x = 0; x < d.sat_true; x += 997) {
			double y = ramp_nl_inverse(&d, ramp_nl(&d, x));

			if (fabs(y - x) > worst)
				worst = fabs(y - x);
		}
		ok(worst < 1e-9 * d.sat_true, "NL inverse round-trips to %.2g e- below saturation", worst);
		is_near(ramp_nl(&d, 1e5), 1e5 - 6e-7 * 1e10, 1e-6, "NL(1e5 e-) = 1e5 + beta 1e10");
		ok(ramp_nl(&d, 1e9) == d.sat_e, "NL saturates at %g e-", d.sat_e);
	}

	/* level 1 follows the read pattern: means r tbar, variances r tau
	 * (no read noise, reset, NL or quantisation to speak of: gain 0.01) */
	ok(ramp_pattern_get(4, &p, &e) == 0, "table 4 again");
	{
		struct ramp_det q;
		enum { NP = 200000 };
		double rate = 50, *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double));
		double *r = malloc(ROW * sizeof(double));
		uint16_t *dn = malloc((size_t)p.nres * ROW * sizeof(uint16_t));
		double m[RAMP_MAX_RES] = { 0 }, v[RAMP_MAX_RES] = { 0 };
		int bad_mean = 0, bad_var = 0;

		det_for_tests(&q);
		q.read_noise = q.reset_noise = q.beta = 0;
		q.gain = 0.125;         /* DN of 1/8 e-: rounding invisible */
		q.pedestal = 0;
		q.saturation = 65535;
		ramp_det_finish(&q);
		ramp_scratch_init(scr);
		for (int i = 0; i < ROW; i++)
			r[i] = rate;
		for (long c = 0; c < NP; c += ROW) {
			int n = NP - c < ROW ? (int)(NP - c) : ROW;

			ramp_level1_row(&p, &q, &k, (uint32_t)c, n, r, 1, dn, ROW, scr);
			for (int g = 0; g < p.nres; g++)
				for (int i = 0; i < n; i++) {
					double x = dn[(size_t)g * ROW + i] * q.gain;

					m[g] += x;
					v[g] += x * x;
				}
		}
		for (int g = 0; g < p.nres; g++) {
			double mean = m[g] / NP, var = v[g] / NP - mean * mean;
			double want = rate * p.tbar[g], wvar = rate * p.tau[g] + q.gain * q.gain / 12;

			bad_mean += fabs(mean - want) > 5 * sqrt(wvar / NP);
			bad_var += fabs(var / wvar - 1) > 5 * sqrt(2.0 / NP);
			diag("resultant %d: mean %.4f e- (rate x tbar %.4f), var %.3f (rate x tau %.3f)",
			     g, mean, want, var, wvar);
		}
		ok(!bad_mean, "level-1 resultants follow the mean read times (5 sigma)");
		ok(!bad_var, "level-1 resultants have the Poisson variance rate x tau (exact split)");
		free(scr);
		free(r);
		free(dn);
	}

	/* level 2: bias and scatter against ERR from 0.01 e-/s to saturation */
	det_for_tests(&d);
	{
		static const struct {
			double rate;
			long n;
		} flux[] = {
			{ 0.01, 9000000 }, { 0.1, 1000000 }, { 1, 400000 }, { 10, 200000 },
			{ 100, 100000 }, { 1000, 100000 }, { 5000, 100000 },
			{ 20000, 100000 }, { 30000, 100000 },
		};

		diag("rate e-/s | pixels | mean rate | bias %% | 3 sdom %% | scatter/ERR | saturated | jump");
		for (size_t f = 0; f < sizeof(flux) / sizeof(flux[0]); f++) {
			struct result s = run(&p, &d, &k, flux[f].rate, flux[f].n, NULL);
			double bias = (s.mean - flux[f].rate) / flux[f].rate;
			double sdom = s.sd / sqrt((double)s.n) / flux[f].rate;

			diag("%9g | %7ld | %.6g | %+.3f | %.3f | %.4f | %.3f | %.5f", flux[f].rate,
			     s.n, s.mean, 100 * bias, 300 * sdom, s.sd / s.err_rms, s.frac_sat,
			     s.frac_jump);
			ok(fabs(bias) < 0.01, "rate %g e-/s: level-2 rate unbiased within 1%% (%+.3f%%)",
			   flux[f].rate, 100 * bias);
			ok(fabs(s.sd / s.err_rms - 1) < 0.10,
			   "rate %g e-/s: scatter matches ERR within 10%% (ratio %.4f)",
			   flux[f].rate, s.sd / s.err_rms);
			if (d.pedestal + flux[f].rate * p.exptime > d.sat_true)
				ok(s.frac_sat == 1, "rate %g e-/s saturates: flagged (%.3f), "
				   "the rate from the reads before", flux[f].rate, s.frac_sat);
			else
				ok(s.frac_sat == 0, "rate %g e-/s: nothing saturated", flux[f].rate);
		}
	}

	/* saturated in the first resultant */
	{
		struct result s = run(&p, &d, &k, 1e6, 4096, NULL);

		ok(s.frac_dnu == 1 && s.frac_sat == 1,
		   "1e6 e-/s: every pixel saturated in its first resultant is DO_NOT_USE|SATURATED");
	}

	/* the linearity flags: NONLINEAR where a used resultant's correction
	 * exceeds nonlinear_flag (5 %, from 75,586 e- measured), none below;
	 * NO_LIN_CORR for a used resultant at 0 DN */
	{
		struct ramp_fit_plan fp;
		double m5 = (1 - (2 / 1.05 - 1) * (2 / 1.05 - 1)) / (-4 * d.beta);
		struct result lo = run(&p, &d, &k, 400, 20000, NULL);
		struct result hi = run(&p, &d, &k, 600, 20000, NULL);
		uint16_t dn[RAMP_MAX_RES];
		struct ramp_fit f;

		is_near(m5, 75586, 5, "a 5 %% correction from %.0f e- measured", m5);
		/* rate 400: 10000 + 400 x 139 = 65,700 e- at the last read,
		 * 600: 93,500 (below saturation, 118,000 true) */
		ok(lo.frac_nl == 0 && lo.frac_nlc == 0 && lo.frac_sat == 0,
		   "400 e-/s: no linearity flag (%.3f)", lo.frac_nl);
		ok(hi.frac_nl == 1 && hi.frac_nlc == 0 && hi.frac_sat == 0,
		   "600 e-/s: NONLINEAR everywhere (%.3f), not saturated", hi.frac_nl);
		if (ramp_fit_plan_init(&fp, &p, &d) < 0)
			return 1;
		ok(fabs(fp.nl_dn * d.gain - m5) < 2 * d.gain, "NONLINEAR from %d DN", fp.nl_dn);
		for (int i = 0; i < p.nres; i++)
			dn[i] = (uint16_t)(5000 + 100 * i);
		dn[2] = 0;
		ramp_fit_pixel(&fp, dn, 1, &f);
		ok((f.dq & RAMP_NO_LIN_CORR) && !(f.dq & RAMP_NONLINEAR),
		   "a used resultant at 0 DN: NO_LIN_CORR (dq %u)", f.dq);
		dn[2] = 5200;
		ramp_fit_pixel(&fp, dn, 1, &f);
		ok(!(f.dq & (RAMP_NO_LIN_CORR | RAMP_NONLINEAR)), "a clean ramp: neither (dq %u)", f.dq);
		ramp_fit_plan_free(&fp);
	}

	/* cosmic rays: the pixels whose resultants changed when hits are on */
	{
		struct ramp_det c = d;
		enum { NP = 400000 };
		double *a = malloc(NP * sizeof(double)), *b = malloc(NP * sizeof(double));
		double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double));
		double *r = malloc(ROW * sizeof(double));
		uint16_t *d0 = malloc((size_t)p.nres * ROW * 2), *d1 = malloc((size_t)p.nres * ROW * 2);
		struct ramp_fit_plan fp;
		long hit = 0, hit_flag = 0, clean = 0, clean_flag = 0;
		double rate = 10, sum = 0;

		ramp_scratch_init(scr);
		c.cosmic_rate = 0.3 / (2 * c.pixel_area * p.exptime);   /* 0.3 hits/pixel */
		ramp_fit_plan_init(&fp, &p, &c);
		for (int i = 0; i < ROW; i++)
			r[i] = rate;
		for (long x = 0; x < NP; x += ROW) {
			int n = NP - x < ROW ? (int)(NP - x) : ROW;

			ramp_level1_row(&p, &d, &k, (uint32_t)x, n, r, 1, d0, ROW, scr);
			ramp_level1_row(&p, &c, &k, (uint32_t)x, n, r, 1, d1, ROW, scr);
			for (int i = 0; i < n; i++) {
				struct ramp_fit f;
				int changed = 0;

				/* a hit in the first read's interval moves every
				 * resultant alike (but for the non-linearity, a few
				 * DN): the intercept, not a jump */
				for (int g = 1; g < p.nres; g++)
					changed |= abs((d1[(size_t)g * ROW + i] - d1[i]) -
						       (d0[(size_t)g * ROW + i] - d0[i])) > 10;
				ramp_fit_pixel(&fp, d1 + i, ROW, &f);
				if (changed) {
					hit++;
					hit_flag += !!(f.dq & RAMP_JUMP_DET);
					sum += f.rate;
				} else {
					clean++;
					clean_flag += !!(f.dq & RAMP_JUMP_DET);
				}
			}
		}
		diag("cosmic rays: %ld pixels hit, %ld flagged; %ld clean, %ld flagged; mean rate of hit pixels %.5f",
		     hit, hit_flag, clean, clean_flag, sum / hit);
		ok(hit > 50000 && hit_flag > 0.99 * hit, "a cosmic ray leaves JUMP_DET (%.4f of hit pixels)",
		   (double)hit_flag / hit);
		ok(clean_flag < 1e-3 * clean, "few false jumps (%.2g of clean pixels)",
		   (double)clean_flag / clean);
		ok(fabs(sum / hit / rate - 1) < 0.01, "the rate of hit pixels is unbiased (%+.3f%%)",
		   100 * (sum / hit / rate - 1));
		ramp_fit_plan_free(&fp);
		free(a);
		free(b);
		free(scr);
		free(r);
		free(d0);
		free(d1);
	}

	/* the split of a group's arrivals among its reads: the normal above 4
	 * arrivals against the exact placement of every arrival (--set
	 * ramp-split-exact=1e9): the fitted rates agree in mean and scatter */
	{
		struct ramp_key ex = k;
		struct result a, b;
		clock_t t0, t1, t2;

		ex.split_exact_max = 1e9;
		t0 = clock();
		a = run(&p, &d, &k, 5, 400000, NULL);
		t1 = clock();
		b = run(&p, &d, &ex, 5, 400000, NULL);
		t2 = clock();
		diag("split at 5 e-/s: normal above 4: mean %.5f sd %.5f (%.2f s); exact: mean %.5f sd %.5f (%.2f s)",
		     a.mean, a.sd, (double)(t1 - t0) / CLOCKS_PER_SEC, b.mean, b.sd,
		     (double)(t2 - t1) / CLOCKS_PER_SEC);
		ok(fabs(a.mean - b.mean) < 4 * a.sd / sqrt(200000.0) && fabs(a.sd / b.sd - 1) < 0.01,
		   "the normal split gives the exact split's rate and scatter (sd ratio %.4f)", a.sd / b.sd);
	}

	/* same bytes for any split of a row */
	{
		double r[ROW];
		struct ramp_pattern q;

		for (int i = 0; i < ROW; i++)
			r[i] = i * 3.7;
		ok(same_in_pieces(&p, &d, &k, r, 1000), "a row cut in pieces gives the same resultants");
		/* pieces of 7 pixels go one by one, never eight at a time:
		 * the rates above, then a faint sky */
		ok(same_in_pieces(&p, &d, &k, r, 7),
		   "pixels one by one give the resultants of eight at a time (0 to 15,000 e-/s)");
		faint_sky(r);
		ok(same_in_pieces(&p, &d, &k, r, 7),
		   "pixels one by one give the resultants of eight at a time (a faint sky)");
		/* the same with a table that skips reads: the gaps' counts are
		 * drawn in place of their means */
		if (ramp_pattern_get(109, &q, &e) < 0)
			return 1;
		ok(same_in_pieces(&q, &d, &k, r, 7),
		   "pixels one by one give the resultants of eight at a time (table 109's gaps)");
	}
	/* the charge and the pixels' own part, joined by an IPC kernel of
	 * centre 1, are the resultants of ramp_level1_row: the same random
	 * numbers (the sum of the two parts may round apart at a DN's half,
	 * the own part being a float) */
	{
		double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double)), r[ROW];
		double *ch = malloc((size_t)p.nres * ROW * sizeof(double));
		float *own = malloc((size_t)p.nres * ROW * sizeof(float));
		uint16_t *w = malloc((size_t)p.nres * ROW * 2), *s = malloc((size_t)p.nres * ROW * 2);
		struct ramp_det one = d;
		long differ = 0, far = 0;

		memset(one.ipc, 0, sizeof(one.ipc));
		one.ipc[1][1] = 1;
		ramp_scratch_init(scr);
		for (int i = 0; i < ROW; i++)
			r[i] = i * 3.7;     /* 0 to 15,000 e-/s: saturation included */
		ramp_level1_row(&p, &one, &k, 8192, ROW, r, 1, w, ROW, scr);
		ramp_level1_charge(&p, &one, &k, 8192, ROW, r, ch, own, ROW, scr);
		ramp_level1_finish(&one, p.nres, ROW, NULL, ch, NULL, own, ROW, s, ROW);
		for (long i = 0; i < (long)p.nres * ROW; i++) {
			differ += w[i] != s[i];
			far += abs((int)w[i] - (int)s[i]) > 1;
		}
		diag("charge + own against the row: %ld of %ld resultants 1 DN apart", differ,
		     (long)p.nres * ROW);
		ok(!far && differ < p.nres * ROW / 1000,
		   "the charge split for IPC draws the row's numbers (%ld apart by 1 DN, %ld more)",
		   differ, far);
		free(scr);
		free(ch);
		free(own);
		free(w);
		free(s);
	}
	/* the fits of a row are those of its pixels one by one: clean ramps,
	 * jumps (many cosmic rays), saturation and the NONLINEAR flag */
	{
		double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double)), r[ROW];
		uint16_t *w = malloc((size_t)p.nres * ROW * 2);
		struct ramp_fit *a = malloc(ROW * sizeof(*a)), b;
		struct ramp_fit_plan fp;
		struct ramp_det c = d;
		long differ = 0, fast = 0;

		c.cosmic_rate = 0.1 / (2 * c.pixel_area * p.exptime);
		if (ramp_fit_plan_init(&fp, &p, &c) < 0)
			return 1;
		ramp_scratch_init(scr);
		for (int y = 0; y < 4; y++) {
			for (int i = 0; i < ROW; i++)
				r[i] = y < 2 ? 0.01 * pow(1e6, (double)i / ROW) : 0.5 + i % 7;
			ramp_level1_row(&p, &c, &k, (uint32_t)(y * ROW), ROW, r, 1, w, ROW, scr);
			/* the first half eight at a time, the second in pieces
			 * of 7, one by one */
			ramp_fit_row(&fp, w, ROW, ROW / 2, a);
			for (int x = ROW / 2; x < ROW; x += 7)
				ramp_fit_row(&fp, w + x, ROW, ROW - x < 7 ? ROW - x : 7, a + x);
			for (int i = 0; i < ROW; i++) {
				ramp_fit_pixel(&fp, w + i, ROW, &b);
				differ += !(a[i].rate == b.rate && a[i].var_poisson == b.var_poisson &&
					    a[i].var_rnoise == b.var_rnoise && a[i].dq == b.dq &&
					    a[i].njump == b.njump && a[i].nuse == b.nuse);
				fast += !b.dq;
			}
		}
		ok(!differ, "a row's fits are its pixels' (%ld of %d differ; %ld clean)", differ,
		   4 * ROW, fast);
		ramp_fit_plan_free(&fp);
		free(scr);
		free(w);
		free(a);
	}
	return done_testing();
}
