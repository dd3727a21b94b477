/*
 * noise_stages - each noise stage on a flat field: the statistics of
 * wfiscene(1) "NOISE MODEL".  Fixed seeds, tolerances of 5 sampling sigmas.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "noise.h"

enum { SIDE = 1024, N = SIDE * SIDE, X0 = 1500, Y0 = 700 };

struct stats {
	double mean, var;
	int integral;
};

static struct stats stats_of(const double *a, int n)
{
	struct stats s = { 0, 0, 1 };

	for (int i = 0; i < n; i++) {
		s.mean += a[i];
		s.integral &= a[i] == floor(a[i]);
	}
	s.mean /= n;
	for (int i = 0; i < n; i++)
		s.var += (a[i] - s.mean) * (a[i] - s.mean);
	s.var /= n - 1;
	return s;
}

/* A SIDE x SIDE tile of SCA sca at (X0, Y0) holding signal, through
 * noise_tile with options o. */
static double *run(const struct noise_opts *o, int sca, double signal)
{
	double *a = malloc(N * sizeof(double));

	for (int i = 0; i < N; i++)
		a[i] = signal;
	if (noise_tile(o, sca, X0, Y0, SIDE, SIDE, a, SIDE)) {
		free(a);
		return NULL;
	}
	return a;
}

static struct noise_opts opts(unsigned stages, double bkg, double t)
{
	struct noise_opts o;

	noise_opts_default(&o);
	o.stages = stages;
	o.background = bkg;
	o.exptime = t;
	o.seed = 7;
	o.filter = F129;
	o.counts = 1;
	return o;
}

static double corr(const double *a, const double *b, int n)
{
	struct stats sa = stats_of(a, n), sb = stats_of(b, n);
	double c = 0;

	for (int i = 0; i < n; i++)
		c += (a[i] - sa.mean) * (b[i] - sb.mean);
	return c / (n - 1) / sqrt(sa.var * sb.var);
}

static void test_parse(void)
{
	struct err e = { 0 };
	unsigned st = 99;

	ok(!noise_parse("all", &st, &e) && st == NOISE_ALL, "--noise all");
	ok(!noise_parse("none", &st, &e) && st == 0, "--noise none");
	ok(!noise_parse("poisson,readnoise", &st, &e) && st == (NOISE_POISSON | NOISE_READ),
	   "--noise poisson,readnoise");
	ok(!noise_parse("cosmic,flat,dark", &st, &e) &&
	   st == (NOISE_COSMIC | NOISE_FLAT | NOISE_DARK), "--noise cosmic,flat,dark");
	ok(noise_parse("poisson,bogus", &st, &e) == -1 && e.code == EXIT_INPUT &&
	   strstr(e.msg, "--noise: unknown stage 'bogus'"), "unknown stage: %s", e.msg);
	err_clear(&e);
	ok(noise_parse("poisson,", &st, &e) == -1 && strstr(e.msg, "stage ''"),
	   "empty stage: %s", e.msg);
	err_clear(&e);
	ok(noise_parse("", &st, &e) == -1, "empty --noise");
}

static void test_check(void)
{
	struct noise_opts o = opts(NOISE_ALL, 1, 100);
	struct err e = { 0 };

	ok(!noise_check(&o, &e), "defaults pass noise_check");
	o.exptime = 0;
	ok(noise_check(&o, &e) == -1 && strstr(e.msg, "--exptime"), "%s", e.msg);
	err_clear(&e);
	o.exptime = 1;
	o.background = NAN;
	ok(noise_check(&o, &e) == -1 && strstr(e.msg, "--background"), "%s", e.msg);
	err_clear(&e);
	o.background = 0;
	o.readnoise = -1;
	ok(noise_check(&o, &e) == -1 && strstr(e.msg, "--readnoise"), "%s", e.msg);
	err_clear(&e);
	o.readnoise = 12;
	o.cosmic_residual = 2;
	ok(noise_check(&o, &e) == -1 && strstr(e.msg, "--cosmic-residual"), "%s", e.msg);
	o = opts(NOISE_ALL, 1, 100);
	ok(noise_tile(&o, 0, 0, 0, 1, 1, (double[1]){ 0 }, 1) == -1, "SCA 0 is refused");
	ok(noise_tile(&o, 1, 4000, 0, 100, 1, (double[100]){ 0 }, 100) == -1,
	   "a tile beyond the detector is refused");
	o.exptime = -1;
	ok(noise_tile(&o, 1, 0, 0, 1, 1, (double[1]){ 0 }, 1) == -1,
	   "a negative exposure time is refused");
}

static void test_none(void)
{
	struct noise_opts o = opts(0, 0.54, 100);
	double *a, *b;

	o.counts = 0;
	a = run(&o, 1, 2.5);
	o.seed = 8;
	b = run(&o, 1, 2.5);
	ok(a && a[0] == 2.5 + 0.54 && !memcmp(a, b, N * sizeof(double)),
	   "no stages: signal + background in counts/s, seed irrelevant");
	free(a);
	free(b);
	o.counts = 1;
	a = run(&o, 1, 2.5);
	ok(a && a[N - 1] == (2.5 + 0.54) * 100, "no stages, --counts: (S + B) t");
	free(a);
}

static void test_poisson(void)
{
	static const double means[] = { 0, 1e-3, 0.5, 30, 1e4, 1e9, 1e12 };

	for (size_t m = 0; m < sizeof(means) / sizeof(means[0]); m++) {
		double mu = means[m];
		struct noise_opts o = opts(NOISE_POISSON, mu, 1);
		double *a = run(&o, 3, 0);
		struct stats s = stats_of(a, N);

		ok(s.integral, "Poisson %g: integer counts", mu);
		is_near(s.mean, mu, 5 * sqrt(mu / N), "Poisson %g: mean", mu);
		is_near(s.var, mu, 5 * sqrt((mu + 2 * mu * mu) / N), "Poisson %g: variance", mu);
		free(a);
	}
	/* counts/s in, the exposure time applied before the draw */
	{
		struct noise_opts o = opts(NOISE_POISSON, 0.54, 100);
		double *a;
		struct stats s;

		o.counts = 0;
		a = run(&o, 3, 0.26);
		s = stats_of(a, N);
		is_near(s.mean, 0.8, 5 * sqrt(80.0 / N) / 100, "Poisson in counts/s: mean 0.8");
		is_near(s.var, 0.008, 5 * sqrt((80 + 2 * 6400.0) / N) / 1e4,
			"Poisson in counts/s: variance 80 / 100^2");
		free(a);
	}
	{
		struct noise_opts o = opts(NOISE_POISSON, 0, 1);
		double *a = run(&o, 3, -400);
		struct stats s = stats_of(a, N);

		ok(s.integral && s.mean < 0, "a negative mean gives -Poisson(-mean)");
		is_near(s.var, 400, 5 * sqrt((400 + 2 * 160000.0) / N), "... with variance |mean|");
		free(a);
	}
}

static void test_read(void)
{
	struct noise_opts o = opts(NOISE_READ, 0, 1);
	struct noise_opts op = opts(NOISE_POISSON, 144, 1);
	struct noise_opts opr = opts(NOISE_POISSON | NOISE_READ, 144, 1);
	double *r = run(&o, 5, 0), *p = run(&op, 5, 0), *pr = run(&opr, 5, 0);
	struct stats s = stats_of(r, N), st = stats_of(pr, N);
	double c;

	is_near(s.mean, 0, 5 * 12 / sqrt(N), "read noise: mean 0");
	is_near(sqrt(s.var), 12, 5 * 12 / sqrt(2.0 * N), "read noise: sigma 12 e-");
	/* Pixels 2m and 2m+1 share a Philox call (different bits): no
	 * correlation between them, nor between rows. */
	{
		static double e[N / 2], f[N / 2];

		for (int i = 0; i < N / 2; i++) {
			e[i] = r[2 * i];
			f[i] = r[2 * i + 1];
		}
		c = corr(e, f, N / 2);
		is_near(c, 0, 5 / sqrt(N / 2.0), "read noise: neighbours in a pair uncorrelated (r = %.5f)", c);
		c = corr(r, r + SIDE, N - SIDE);
		is_near(c, 0, 5 / sqrt((double)N - SIDE), "read noise: rows uncorrelated (r = %.5f)", c);
	}
	o.readnoise = 3.5;
	free(r);
	r = run(&o, 5, 0);
	s = stats_of(r, N);
	is_near(sqrt(s.var), 3.5, 5 * 3.5 / sqrt(2.0 * N), "--readnoise 3.5");
	/* The read part of poisson+readnoise is pr - p, since each stage
	 * has its own numbers; it must not correlate with the Poisson part. */
	for (int i = 0; i < N; i++)
		r[i] = pr[i] - p[i];
	c = corr(p, r, N);
	is_near(c, 0, 5 / sqrt(N), "Poisson and read noise uncorrelated (r = %.5f)", c);
	/* STIPS #196: 144 e- with 12 e- read noise gave sigma 24; the sum of
	 * independent terms has sigma sqrt(144 + 144) = 16.97. */
	is_near(sqrt(st.var), sqrt(288.0), 5 * sqrt(288.0) / sqrt(2.0 * N),
		"total sigma for 144 e- and 12 e- read noise is 16.97, not 24");
	free(r);
	free(p);
	free(pr);
}

static void test_flat(void)
{
	struct noise_opts o = opts(NOISE_FLAT, 1000, 1);
	double *a = run(&o, 2, 0), *b, sf = NOISE_FLAT_RESIDUAL;
	struct stats s = stats_of(a, N);
	int same = 1;

	is_near(s.mean, 1000, 5 * 1000 * sf / sqrt(N), "flat residual: mean 1");
	is_near(sqrt(s.var) / 1000, sf, 5 * sf / sqrt(2.0 * N), "flat residual: sigma 0.00068");
	o.background = 2000;
	o.exptime = 3;
	b = run(&o, 2, 0);
	for (int i = 0; i < N; i++)
		same &= fabs(b[i] - 6 * a[i]) <= 1e-9 * b[i];
	ok(same, "the flat is a fixed field: 6x the light gives 6x the image");
	free(b);
	o.filter = F158;
	b = run(&o, 2, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "another filter has another flat");
	free(b);
	o.filter = F129;
	b = run(&o, 3, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "another SCA has another flat");
	free(b);
	o.flat_residual = 0.01;
	o.background = 1000;
	o.exptime = 1;
	b = run(&o, 2, 0);
	s = stats_of(b, N);
	is_near(sqrt(s.var) / 1000, 0.01, 5 * 0.01 / sqrt(2.0 * N), "flat_residual 0.01");
	free(a);
	free(b);
}

static void test_dark(void)
{
	struct noise_opts o = opts(NOISE_DARK, 0, 100);
	double *a = run(&o, 4, 0), *b;
	double d = NOISE_DARK_CURRENT * 100, rt = NOISE_DARK_RESIDUAL * 100;
	double var = d + rt * rt;
	struct stats s = stats_of(a, N);

	is_near(s.mean, d, 5 * sqrt(var / N), "dark: mean D t = 2.8 e-");
	/* fourth central moment of the sum: d + 3 d^2 (Poisson) + 3 rt^4 +
	 * 6 d rt^2 (cross); its sampling sigma of the variance follows. */
	is_near(s.var, var, 5 * sqrt((d + 3 * d * d + 3 * pow(rt, 4) + 6 * d * rt * rt - var * var) / N),
		"dark: variance D t + (s_d t)^2 (shot noise plus residual)");
	free(a);
	/* With poisson on, the dark current is in the same count. */
	o.stages = NOISE_POISSON | NOISE_DARK;
	o.background = 0.3;
	a = run(&o, 4, 0);
	s = stats_of(a, N);
	var += 30;
	is_near(s.mean, d + 30, 5 * sqrt(var / N), "poisson+dark: mean (B + D) t");
	is_near(s.var, var, 5 * sqrt((var + 2 * var * var) / N),
		"poisson+dark: variance (B + D) t + (s_d t)^2");
	free(a);
	o.stages = NOISE_DARK;
	o.background = 0;
	o.dark_current = 0;
	a = run(&o, 4, 0);
	s = stats_of(a, N);
	is_near(s.mean, 0, 5 * rt / sqrt(N), "dark residual field: mean 0");
	is_near(sqrt(s.var), rt, 5 * rt / sqrt(2.0 * N), "dark residual field: sigma 0.0037 e-/s");
	o.filter = F213;
	o.seed = 7;
	b = run(&o, 4, 0);
	ok(!memcmp(a, b, N * sizeof(double)), "the dark residual is the detector's: same in every filter");
	free(b);
	b = run(&o, 5, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "another SCA has another dark residual");
	free(b);
	o.seed = 8;
	b = run(&o, 4, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "another seed has another dark residual");
	free(a);
	free(b);
}

/* Issue #118: different SCAs and filters never share a noise pattern. */
static void test_keys(void)
{
	struct noise_opts o = opts(NOISE_POISSON | NOISE_READ, 100, 1);
	double *a = run(&o, 1, 0), *b;

	b = run(&o, 2, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "SCA 1 and SCA 2 noise uncorrelated");
	free(b);
	o.filter = F158;
	b = run(&o, 1, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "F129 and F158 noise uncorrelated");
	free(b);
	o.filter = F129;
	o.seed = 1ull << 40;
	b = run(&o, 1, 0);
	ok(fabs(corr(a, b, N)) < 5 / sqrt(N), "seeds 7 and 2^40 uncorrelated");
	free(b);
	o.seed = 7;
	b = run(&o, 1, 0);
	ok(!memcmp(a, b, N * sizeof(double)), "the same seed gives the same image");
	free(a);
	free(b);
}

int main(void)
{
	test_parse();
	test_check();
	test_none();
	test_poisson();
	test_read();
	test_flat();
	test_dark();
	test_keys();
	return done_testing();
}
