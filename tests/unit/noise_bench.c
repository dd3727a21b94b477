/*
 * noise_bench - Mpixel/s of each noise stage on one full SCA (4088^2 in
 * 512^2 tiles, one thread, CPU seconds, the best of three), against writing
 * the same SCA as float32 FITS with cfitsio (also the best of three).  Skipped unless WFS_BENCH is set (make bench, or by hand:
 * WFS_BENCH=1 build/tests/noise_bench).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <fitsio.h>

#include "tap.h"
#include "noise.h"
#include "instrument.h"

enum { S = WFS_NPIX, T = 512 };

/* CPU time of the process (user + system): on a shared machine it varies
 * far less than the wall clock, and writing is charged its system time. */
static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* grad: a signal from 0.2 to 20 counts/s across the SCA (means of 30 to
 * 3000 in 139.8 s, a different one in every pixel), else none. */
static double run(const struct noise_opts *o, double *a, int grad)
{
	double t0;

	for (size_t i = 0; i < (size_t)S * S; i++)
		a[i] = grad ? 0.2 * pow(100, (double)i / ((double)S * S)) : 0;
	t0 = now();
	for (int y = 0; y < S; y += T)
		for (int x = 0; x < S; x += T)
			noise_tile(o, 1, x, y, S - x < T ? S - x : T, S - y < T ? S - y : T,
				   a + (size_t)y * S + x, S);
	return now() - t0;
}

int main(void)
{
	static const struct {
		const char *name;
		unsigned stages;
		double bkg;
		int grad;
	} cases[] = {
		{ "none (background, units)", 0, 0.54, 0 },
		{ "poisson, mean 75", NOISE_POISSON, 0.54, 0 },
		{ "poisson, mean 0.5", NOISE_POISSON, 0.5 / 139.8, 0 },
		{ "poisson, mean 3000", NOISE_POISSON, 3000 / 139.8, 0 },
		{ "poisson, means 30-3000", NOISE_POISSON, 0, 1 },
		{ "readnoise", NOISE_READ, 0.54, 0 },
		{ "flat", NOISE_FLAT, 0.54, 0 },
		{ "dark", NOISE_DARK, 0.54, 0 },
		{ "cosmic", NOISE_COSMIC, 0.54, 0 },
		{ "all", NOISE_ALL, 0.54, 0 },
	};
	const char *path = "/tmp/wfs-noise-bench.fits";
	double *a, t0, tw;
	float *f;
	fitsfile *fp;
	int status = 0;
	long naxes[2] = { S, S };

	if (!getenv("WFS_BENCH"))
		skip_all("set WFS_BENCH=1 to run the noise benchmark");
	a = malloc((size_t)S * S * sizeof(double));
	f = malloc((size_t)S * S * sizeof(float));
	for (size_t i = 0; i < (size_t)S * S; i++)
		f[i] = (float)i;
	tw = 1e30;
	for (int rep = 0; rep < 3; rep++) {
		remove(path);
		t0 = now();
		fits_create_file(&fp, path, &status);
		fits_create_img(fp, FLOAT_IMG, 2, naxes, &status);
		fits_write_img(fp, TFLOAT, 1, (LONGLONG)S * S, f, &status);
		fits_close_file(fp, &status);
		t0 = now() - t0;
		tw = t0 < tw ? t0 : tw;
	}
	remove(path);
	ok(status == 0, "wrote one SCA as float32 FITS");
	diag("%-26s %7.1f Mpixel/s  (%.3f s per SCA)", "write float32 FITS", S * (double)S / tw / 1e6, tw);
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct noise_opts o;
		double t;

		noise_opts_default(&o);
		o.stages = cases[c].stages;
		o.background = cases[c].bkg;
		o.exptime = 139.8;
		o.seed = 7;
		o.filter = F158;
		t = run(&o, a, cases[c].grad);
		for (int rep = 1; rep < 3; rep++) {
			double t1 = run(&o, a, cases[c].grad);

			t = t1 < t ? t1 : t;
		}
		diag("%-26s %7.1f Mpixel/s  (%.3f s per SCA, %.2f x write)", cases[c].name,
		     S * (double)S / t / 1e6, t, t / tw);
		ok(1, "%s", cases[c].name);
	}
	free(a);
	free(f);
	return done_testing();
}
