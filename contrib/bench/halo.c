/*
 * halo.c - the error and cost of the halo model (plugins/halo.h) against a
 * direct large computation of the built-in optics.
 *
 *   halo [FILTER [SCA [RADIUS]]]       (default F158 1 256)
 *
 * Computes, with the same optical model, wavelengths, pupil sampling and
 * jitter as the built-in grids:
 *
 *   fine   the ePSF at 4 samples per pixel over +-384 pixels, at the SCA's
 *          centre: the reference within the halo's array
 *   far    the ePSF at 2 samples per pixel over +-1024 pixels: the
 *          reference for the tail
 *   halo   the halo's array (2 per pixel, +-RADIUS), at the centre and at
 *          the SCA's corner node
 *
 * and prints, per annulus of the source's distance (a source centred a
 * quarter pixel off a pixel centre in x and y, so the halo's array is
 * interpolated), the model's light over the reference's (the annulus sums),
 * the median and the 99th percentile over the annulus of |model - ref| / ref
 * mean of the annulus, and the same for the corner node against the centre
 * (how much the far wing changes over an SCA).  Then the azimuthal-mean
 * power of the far reference between 100 and 1000 pixels, the share of
 * the light beyond each radius, and the build times.  Run by hand
 * (minutes, 1.5 GB); BENCHMARKS.md "Halo" has its output.
 *
 * cc -O2 -Isrc -Iinclude -Iplugins contrib/bench/halo.c build/libwfs.a \
 *    $(pkg-config --libs cfitsio wcslib fftw3 zlib libzstd libpng) \
 *    -lfftw3_threads -lltdl -lm -lpthread
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "err.h"
#include "instrument.h"
#include "optics.h"
#include "psf.h"
#include "halo.h"

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;

	return x < y ? -1 : x > y;
}

/* The reference ePSF's pixel value at offset (dx, dy): a sample of the
 * array when the offset is on its lattice, else 0 (not asked). */
static double ref_at(const struct psf_grid *g, double dx, double dy)
{
	int c = (g->n - 1) / 2;
	double u = c + g->over * dx, v = c + g->over * dy;
	long i = lround(u), j = lround(v);

	if (i < 0 || j < 0 || i >= g->n || j >= g->n)
		return NAN;
	return g->data[(size_t)j * g->n + i];
}

int main(int argc, char **argv)
{
	struct err e = { 0 };
	const char *fname = argc > 1 ? argv[1] : "F158";
	int sca = argc > 2 ? atoi(argv[2]) : 1, radius = argc > 3 ? atoi(argv[3]) : 256;
	int filter = -1;
	struct psf_build_opts o = { .cache_dir = "", .threads = 2 };
	struct psf_grid *fine, *far, *halo, *corner;
	struct halo h, hc;
	double t0, tf, tr, th;
	static const double edges[] = { 20, 30, 45, 60, 80, 100, 130, 150, 180, 200, 230,
					250, 280, 300, 350, 380, 450, 600, 800, 1000 };
	int ne = sizeof(edges) / sizeof(*edges);

	if (instrument_init(&e))
		return fprintf(stderr, "%s\n", e.msg), 2;
	for (int f = 0; f < WFS_NFILTER; f++)
		if (!strcmp(filter_get(f)->name, fname))
			filter = f;
	if (filter < 0)
		return fprintf(stderr, "no filter %s\n", fname), 1;
	t0 = now();
	if (!(halo = psf_builtin_halo(filter, sca, radius, 1, PSF_EPSF, &o, &e)))
		return fprintf(stderr, "%s\n", e.msg), 2;
	th = now() - t0;
	o.grid = 3;
	if (!(corner = psf_builtin_halo(filter, sca, radius, 3, PSF_EPSF, &o, &e)))
		return fprintf(stderr, "%s\n", e.msg), 2;
	o.grid = 1;
	t0 = now();
	if (!(fine = psf_build_one(filter, sca, 4 * 2 * 384 + 1, 4, PSF_EPSF, &o, &e)))
		return fprintf(stderr, "%s\n", e.msg), 2;
	tf = now() - t0;
	t0 = now();
	if (!(far = psf_build_one(filter, sca, 2 * 2 * 1024 + 1, 2, PSF_EPSF, &o, &e)))
		return fprintf(stderr, "%s\n", e.msg), 2;
	tr = now() - t0;
	if (halo_setup(&h, halo->data, halo->n, halo->over, 3, 16, NULL) ||
	    halo_setup(&hc, corner->data, corner->n, corner->over, 3, 16, NULL))
		return fprintf(stderr, "halo_setup failed\n"), 2;
	printf("# %s SCA %d, halo radius %d: build %.1f s (one node), "
	       "fine reference (4x, +-384 px) %.1f s, far reference (2x, +-1024 px) %.1f s\n",
	       fname, sca, radius, th, tf, tr);
	printf("# halo: scale %.5f (light the optics left beyond the array: %.4f), "
	       "model total %.5f\n", h.s, 1 - h.s, h.total);
	/* far reference: azimuthal means, the power of the wing */
	{
		double sx = 0, sy = 0, sxx = 0, sxy = 0;
		int np = 0;

		for (double r = 100; r <= 1000; r *= 1.25) {
			double sum = 0;
			int cnt = 0;

			for (int a = 0; a < 4096; a++) {
				double t = 2 * M_PI * a / 4096, v = ref_at(far, round(r * cos(t)), round(r * sin(t)));

				if (isfinite(v)) {
					sum += v;
					cnt++;
				}
			}
			sx += log(r);
			sy += log(sum / cnt);
			sxx += log(r) * log(r);
			sxy += log(r) * log(sum / cnt);
			np++;
		}
		printf("# far reference: azimuthal mean ~ r^%.3f between 100 and 1000 px\n",
		       (np * sxy - sx * sy) / (np * sxx - sx * sx));
	}
	printf("# r0-r1 px | reference | model/ref light | median |err|/mean | p99 |err|/mean"
	       " | corner/centre light | p99 |corner-centre|/mean | light beyond r1 (model)\n");
	for (int b = 0; b + 1 < ne; b++) {
		double r0 = edges[b], r1 = edges[b + 1];
		const struct psf_grid *ref = r1 <= 380 ? fine : far;
		/* a quarter pixel off on the fine reference (interpolated in
		 * the halo's array), on the far one's own lattice */
		double ph = ref == fine ? 0.25 : 0.5;
		size_t cap = (size_t)(M_PI * (r1 * r1 - r0 * r0) * 1.2) + 64, m = 0;
		double *err = malloc(cap * sizeof(double)), *cerr = malloc(cap * sizeof(double));
		double sref = 0, smod = 0, scor = 0, scen = 0;

		for (int j = -(int)r1 - 1; j <= (int)r1 + 1; j++)
			for (int i = -(int)r1 - 1; i <= (int)r1 + 1; i++) {
				double dx = i + ph, dy = j + ph, d = hypot(dx, dy), rv, mv;

				if (d < r0 || d >= r1 || m >= cap)
					continue;
				rv = ref_at(ref, dx, dy);
				if (!isfinite(rv))
					continue;
				mv = halo_value(&h, dx, dy);
				sref += rv;
				smod += mv;
				err[m] = mv - rv;
				if (d < hc.R) {
					double cv = halo_value(&hc, dx, dy), zv = mv;

					scor += cv;
					scen += zv;
					cerr[m] = cv - zv;
				} else
					cerr[m] = 0;
				m++;
			}
		double mean = sref / m;

		for (size_t k = 0; k < m; k++) {
			err[k] = fabs(err[k]) / mean;
			cerr[k] = fabs(cerr[k]) / mean;
		}
		qsort(err, m, sizeof(double), cmp);
		qsort(cerr, m, sizeof(double), cmp);
		printf("%4.0f-%-4.0f | %.3e | %.4f | %.4f | %.3f | %.4f | %.3f | %.2e\n", r0, r1,
		       mean, smod / sref, err[m / 2], err[(size_t)(0.99 * m)],
		       scen > 0 ? scor / scen : NAN, cerr[(size_t)(0.99 * m)], halo_beyond(&h, r1));
		free(err);
		free(cerr);
	}
	halo_free(&h);
	halo_free(&hc);
	psf_grid_free(fine);
	psf_grid_free(far);
	psf_grid_free(halo);
	psf_grid_free(corner);
	return 0;
}
