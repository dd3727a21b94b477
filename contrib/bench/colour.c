/*
 * colour.c - the spectral classes of the built-in PSF against the exact
 * polychromatic ePSF of each spectrum (BENCHMARKS.md "Colour").
 *
 * For a filter, at the centre of SCA 1 (one node, 177 samples, 4 per
 * pixel): the exact ePSF of blackbodies of 2500-50000 K and power laws of
 * beta -3..3 (the wavelength weights of each spectrum, wfiscene(1)
 * BUILT-IN PSF), and the ePSF interpolated between the grids of the two
 * classes of its family about its effective wavelength, with n classes per
 * family.  Prints the worst |difference| over the array as a fraction of
 * the exact ePSF's peak, for each n, and the build time of one class
 * grid; for the default n the same with the blend rounded to 1/q beyond
 * the 4-pixel core and exact in it (the point model's colour cells,
 * psf-colour-steps = q), and with the blend rounded to 1/q everywhere
 * (galaxies, psf-colour-galaxy-steps = q).  COLOUR_DEFAULT_ONLY=1 skips
 * the other numbers of classes.  Then the FWHM and EE(0.1") of the
 * optical PSF (jitter included, no pixel) of a 3000 K and a 30000 K star
 * and their ratios.  Run by hand:
 *
 * cc -O2 -Isrc -Iinclude contrib/bench/colour.c build/libwfs.a \
 *    $(pkg-config --libs cfitsio wcslib fftw3 libzstd zlib) -lfftw3_threads -lltdl -lm \
 *    -lpthread -o build/colour && build/colour F146 [F129 ...]
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
#include "spectrum.h"

#define N 177

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* The one-node grid of spectrum s (kind SPEC_DEFAULT for 5700 K). */
static float *grid_of(int filter, int kind, double value, int psfkind, double *secs)
{
	struct psf_build_opts o = { .cache_dir = "", .grid = 1, .spec_kind = kind,
				    .spec_value = value, .verbose = -1 };
	struct err e = { 0 };
	double t0 = now();
	struct psf_grid *g = psf_build_one(filter, 1, N, 4, psfkind, &o, &e);
	float *d;

	if (!g) {
		fprintf(stderr, "colour: %s\n", e.msg);
		exit(2);
	}
	if (secs)
		*secs = now() - t0;
	d = malloc(sizeof(float) * N * N);
	memcpy(d, g->data, sizeof(float) * N * N);
	psf_grid_free(g);
	return d;
}

/* FWHM (from the area above half the peak, the image bilinear between
 * samples, 8 x 8 points per sample) and EE within 0.1" (each sample's
 * square cut by the circle in 8 x 8 sub-squares) of an optical PSF at
 * 0.0275" samples. */
static void stats(const float *p, double *fwhm, double *ee)
{
	double peak = 0, tot = 0, area = 0, in = 0, d = 0.11 / 4;
	int c = (N - 1) / 2;

	for (int i = 0; i < N * N; i++) {
		peak = fmax(peak, p[i]);
		tot += p[i];
	}
	for (int y = 0; y < N - 1; y++)
		for (int x = 0; x < N - 1; x++) {
			double v00 = p[y * N + x], v01 = p[y * N + x + 1];
			double v10 = p[(y + 1) * N + x], v11 = p[(y + 1) * N + x + 1];

			if (fmax(fmax(v00, v01), fmax(v10, v11)) > 0.5 * peak)
				for (int b = 0; b < 8; b++)
					for (int a = 0; a < 8; a++) {
						double tx = (a + 0.5) / 8, ty = (b + 0.5) / 8;
						double v = (1 - ty) * ((1 - tx) * v00 + tx * v01) +
							   ty * ((1 - tx) * v10 + tx * v11);
						area += (v > 0.5 * peak) * d * d / 64;
					}
		}
	for (int y = 0; y < N; y++)
		for (int x = 0; x < N; x++) {
			double f = 0;

			for (int b = 0; b < 8; b++)
				for (int a = 0; a < 8; a++) {
					double dx = (x - c + (a + 0.5) / 8 - 0.5) * d;
					double dy = (y - c + (b + 0.5) / 8 - 0.5) * d;
					f += dx * dx + dy * dy < 0.01;
				}
			in += p[y * N + x] * f / 64;
		}
	*fwhm = 2 * sqrt(area / M_PI);
	*ee = in / tot;
}

int main(int argc, char **argv)
{
	struct err e = { 0 };
	static const double temps[] = { 2500, 3000, 4000, 5700, 8000, 12000, 20000, 30000, 50000 };
	static const double betas[] = { -3, -2.5, -2, -1, 0, 1, 2, 2.5, 3 };
	enum { NT = sizeof(temps) / sizeof(*temps), NB = sizeof(betas) / sizeof(*betas) };
	static const int ns[] = { 2, 3, 4, 5, 6 };
	enum { NN = sizeof(ns) / sizeof(*ns) };

	if (instrument_init(&e))
		return fprintf(stderr, "%s\n", e.msg), 2;
	for (int a = 1; a < argc; a++) {
		int filter = filter_lookup(argv[a]);
		struct colour *c = colour_new(filter, &e);
		float *exact[NT + NB];
		double t_build = 0, worst[NN][2] = { { 0 } }, wq[4][2] = { { 0 } }, wn[2] = { 0 };
		double wg[4][2] = { { 0 } };
		static const int gq[4] = { 4, 8, 16, 32 };
		static const int qs[4] = { 1, 2, 4, 8 };
		struct spectrum sp[NT + NB];

		if (!c)
			return fprintf(stderr, "%s\n", e.msg), 2;
		for (int i = 0; i < NT + NB; i++) {
			sp[i] = i < NT ? (struct spectrum){ SPEC_BLACKBODY, temps[i] }
				       : (struct spectrum){ SPEC_POWER, betas[i - NT] };
			exact[i] = grid_of(filter, sp[i].kind, sp[i].value, PSF_EPSF, &t_build);
		}
		for (int in = 0; in < NN; in++) {
			struct psf_classes pc;
			float *cls[2 * PSF_COLOUR_MAX];

			if (getenv("COLOUR_DEFAULT_ONLY") && ns[in] != psf_default_classes(filter))
				continue;
			if (psf_classes_make(&pc, c, filter, ns[in], &e))
				return fprintf(stderr, "%s\n", e.msg), 2;
			for (int k = 0; k < 2 * pc.n; k++) {
				int kind;
				double v;

				psf_classes_spectrum(&pc, k, &kind, &v);
				cls[k] = grid_of(filter, kind, v, PSF_EPSF, NULL);
			}
			for (int i = 0; i < NT + NB; i++) {
				double u = psf_classes_of(&pc, c, 1, &sp[i]), peak = 0, d = 0;
				int k = (int)floor(u);
				double f = u - k;

				for (int p = 0; p < N * N; p++)
					peak = fmax(peak, exact[i][p]);
				for (int p = 0; p < N * N; p++)
					d = fmax(d, fabs((1 - f) * cls[k][p] + (f > 0 ? f * cls[k + 1][p] : 0) -
							 exact[i][p]));
				worst[in][i >= NT] = fmax(worst[in][i >= NT], d / peak);
				/* the nearest class alone (galaxies) */
				if (ns[in] == psf_default_classes(filter)) {
					int kn = (int)lround(u);
					double dn = 0;

					for (int p = 0; p < N * N; p++)
						dn = fmax(dn, fabs(cls[kn][p] - exact[i][p]));
					wn[i >= NT] = fmax(wn[i >= NT], dn / peak);
				}
				/* galaxies: the pair's blend rounded to 1/q (as
				 * point_pair pairs the last class) */
				for (int iq = 0; ns[in] == psf_default_classes(filter) && iq < 4; iq++) {
					int ka = k, n2 = pc.n;
					double fa = f, dg = 0, ph;

					if (ka % n2 == n2 - 1) {
						ka--;
						fa += 1;
					}
					ph = round(fa * gq[iq]) / gq[iq];
					for (int p = 0; p < N * N; p++)
						dg = fmax(dg, fabs((1 - ph) * cls[ka][p] + ph * cls[ka + 1][p] -
								   exact[i][p]));
					wg[iq][i >= NT] = fmax(wg[iq][i >= NT], dg / peak);
				}
				/* blended cells: the class pair's blend rounded to
				 * 1/q outside the 4-pixel core, exact inside it */
				for (int iq = 0; ns[in] == psf_default_classes(filter) && iq < 4; iq++) {
					double ph = round(f * qs[iq]) / qs[iq], dq = 0;
					int cc = (N - 1) / 2;

					for (int y = 0; y < N; y++)
						for (int x = 0; x < N; x++) {
							int p = y * N + x, in_core = abs(x - cc) < 16 &&
										      abs(y - cc) < 16;
							double ff = in_core ? f : ph;
							double v = (1 - ff) * cls[k][p] +
								   (ff > 0 ? ff * cls[k + 1][p] : 0);
							dq = fmax(dq, fabs(v - exact[i][p]));
						}
					wq[iq][i >= NT] = fmax(wq[iq][i >= NT], dq / peak);
				}
				printf("%s n=%d %s %-6g lam_eff %.4f class %.3f: %.2e of the peak\n",
				       argv[a], ns[in], i < NT ? "T" : "beta", sp[i].value,
				       colour_lam_eff(c, 1, &sp[i]), u, d / peak);
			}
			for (int k = 0; k < 2 * pc.n; k++)
				free(cls[k]);
		}
		printf("%s: one class grid (1 node, 177 samples) %.2f s\n", argv[a], t_build);
		printf("%s: worst |interpolated - exact| over the array, fraction of the peak\n",
		       argv[a]);
		printf("classes per family  2500-50000 K  beta -3..3\n");
		for (int in = 0; in < NN; in++)
			printf("%19d  %.2e      %.2e\n", ns[in], worst[in][0], worst[in][1]);
		printf("%s, %d classes: the blend rounded to 1/q beyond the 4-pixel core\n",
		       argv[a], psf_default_classes(filter));
		for (int iq = 0; iq < 4; iq++)
			printf("q %d  %.2e      %.2e\n", qs[iq], wq[iq][0], wq[iq][1]);
		printf("%s, %d classes, the nearest class alone: %.2e      %.2e\n", argv[a],
		       psf_default_classes(filter), wn[0], wn[1]);
		for (int iq = 0; iq < 4; iq++)
			printf("%s galaxies, the blend rounded to 1/%d: %.2e      %.2e\n", argv[a],
			       gq[iq], wg[iq][0], wg[iq][1]);
		{
			float *cool = grid_of(filter, SPEC_BLACKBODY, 3000, PSF_OPTICAL, NULL);
			float *hot = grid_of(filter, SPEC_BLACKBODY, 30000, PSF_OPTICAL, NULL);
			float *ecool = grid_of(filter, SPEC_BLACKBODY, 3000, PSF_EPSF, NULL);
			float *ehot = grid_of(filter, SPEC_BLACKBODY, 30000, PSF_EPSF, NULL);
			double fc, ec, fh, eh;

			stats(cool, &fc, &ec);
			stats(hot, &fh, &eh);
			printf("%s optical PSF (jitter, no pixel): 3000 K FWHM %.4f\" EE(0.1\") %.4f; "
			       "30000 K FWHM %.4f\" EE %.4f; ratio 3000/30000: FWHM %.4f, EE %.4f\n",
			       argv[a], fc, ec, fh, eh, fc / fh, ec / eh);
			stats(ecool, &fc, &ec);
			stats(ehot, &fh, &eh);
			printf("%s ePSF (pixel, IPC): 3000 K FWHM %.4f\" EE(0.1\") %.4f; 30000 K FWHM "
			       "%.4f\" EE %.4f; ratio FWHM %.4f, EE %.4f\n", argv[a], fc, ec, fh, eh,
			       fc / fh, ec / eh);
			free(cool);
			free(hot);
			free(ecool);
			free(ehot);
		}
		for (int i = 0; i < NT + NB; i++)
			free(exact[i]);
		colour_free(c);
	}
	return 0;
}
