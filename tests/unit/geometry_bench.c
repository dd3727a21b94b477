/*
 * geometry_bench - CPU nanoseconds per catalog row of the sky -> pixel
 * projection alone, siaf against stips (wcslib's TAN) in one run, and of
 * the background's pixel area per pixel: 10^6 positions spread over an SCA,
 * the best of five.  Skipped unless WFS_BENCH is set (make bench, or by
 * hand: WFS_BENCH=1 build/tests/geometry_bench).
 */
#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "tap.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "sky.h"

enum { N = 1000000 };

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double project(struct sky *sky, const double *ra, const double *dec, double *x,
		      double *y)
{
	struct err e = { 0 };
	double best = INFINITY;

	for (int k = 0; k < 5; k++) {
		double t0 = now();

		sky_to_pixel(sky, 5, N, ra, dec, x, y, &e);
		best = fmin(best, now() - t0);
	}
	return best / N * 1e9;
}

int main(void)
{
	struct err e = { 0 };
	struct sky siaf, stips;
	double *ra, *dec, *x, *y, ns_siaf, ns_stips, area[4088], best = INFINITY, sum = 0;

	if (!getenv("WFS_BENCH"))
		skip_all("set WFS_BENCH=1 to run");
	if (instrument_init(&e) < 0 || sky_init(&siaf, 10, 20, 30, 1, GEOM_SIAF, 1u << 4, &e) < 0 ||
	    sky_init(&stips, 10, 20, 30, 1, GEOM_STIPS, 1u << 4, &e) < 0)
		return printf("# %s\n", e.msg), 1;
	ra = malloc(N * sizeof(double));
	dec = malloc(N * sizeof(double));
	x = malloc(N * sizeof(double));
	y = malloc(N * sizeof(double));
	if (!ra || !dec || !x || !y)
		return 1;
	srand(3);
	for (int i = 0; i < N; i++)
		geom_pix_to_sky(&siaf.sca[4].geo, 4088.0 * rand() / RAND_MAX,
				4088.0 * rand() / RAND_MAX, &ra[i], &dec[i]);
	ns_siaf = project(&siaf, ra, dec, x, y);
	ns_stips = project(&stips, ra, dec, x, y);
	ok(ns_siaf > 0 && ns_stips > 0, "sky -> pixel: siaf %.1f ns/row, stips (wcslib) %.1f "
	   "ns/row, ratio %.2f", ns_siaf, ns_stips, ns_siaf / ns_stips);
	for (int k = 0; k < 5; k++) {
		double t0 = now();

		for (int r = 0; r < 512; r++) {
			geom_area_row(&siaf.sca[4].geo, r, 0, 4088, area);
			sum += area[r];
		}
		best = fmin(best, now() - t0);
	}
	ok(sum > 0, "pixel area for the background: %.2f ns/pixel", best / (512.0 * 4088) * 1e9);
	sky_free(&siaf);
	sky_free(&stips);
	free(ra);
	free(dec);
	free(x);
	free(y);
	return done_testing();
}
