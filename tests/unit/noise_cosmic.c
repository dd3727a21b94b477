/*
 * noise_cosmic - cosmic-ray hits on a whole SCA: rate, energies, two
 * independent populations, the template, hits beyond the edge, and the
 * residual fraction.  Fixed seeds, tolerances of 5 sampling sigmas.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "noise.h"
#include "instrument.h"

enum { S = WFS_NPIX, B = S / 4 };
#define NPIX ((double)S * S)
#define W_C 0.88127             /* template centre weight */
#define W_E 0.028748            /* template edge weight */

/* The cosmic-ray stage alone, for an exposure of t s and residual resid. */
static void cosmic_opts(struct noise_opts *o, double t, double resid)
{
	noise_opts_default(o);
	o->stages = NOISE_COSMIC;
	o->exptime = t;
	o->cosmic_residual = resid;
	o->seed = 99;
	o->filter = F087;
	o->counts = 1;
}

static double *sca_image(double t, double resid, int sca)
{
	struct noise_opts o;
	double *a = calloc((size_t)S * S, sizeof(double));

	cosmic_opts(&o, t, resid);
	/* four tiles, in no particular order */
	noise_tile(&o, sca, 2000, 2000, S - 2000, S - 2000, a + 2000 * (size_t)S + 2000, S);
	noise_tile(&o, sca, 0, 0, 2000, 2000, a, S);
	noise_tile(&o, sca, 2000, 0, S - 2000, 2000, a + 2000, S);
	noise_tile(&o, sca, 0, 2000, 2000, S - 2000, a + 2000 * (size_t)S, S);
	return a;
}

/* Rows [0, rows) of the SCA at full width, as one tile: the same pixels
 * as those rows of sca_image (noise_tiles pins that the cut does not
 * matter). */
static double *sca_band(double t, int sca, int rows)
{
	struct noise_opts o;
	double *a = calloc((size_t)S * rows, sizeof(double));

	cosmic_opts(&o, t, 1);
	noise_tile(&o, sca, 0, 0, S, rows, a, S);
	return a;
}

/* Is interior pixel (x, y) a strict local maximum of its 3x3? */
static int local_max(const double *a, int x, int y)
{
	double v = a[(size_t)y * S + x];

	for (int dy = -1; dy <= 1; dy++)
		for (int dx = -1; dx <= 1; dx++) {
			int xx = x + dx, yy = y + dy;

			if ((dx || dy) && xx >= 0 && yy >= 0 && xx < S && yy < S &&
			    a[(size_t)yy * S + xx] >= v)
				return 0;
		}
	return v > 0;
}

int main(void)
{
	double *a;

	/* Counts of hit centres at t = 100 s: lambda = 5 * 1e-6 * 100 per
	 * pixel and population; STIPS' populations coincide, ours must not. */
	{
		double lambda = 5e-4, n_exp = lambda * (S - 2.0) * (S - 2.0);
		long n_low = 0, n_high = 0, n_both = 0, col[64] = { 0 }, n_all = 0;
		double chi = 0;

		a = sca_image(100, 1, 1);
		for (int y = 1; y < S - 1; y++)
			for (int x = 1; x < S - 1; x++) {
				double e;

				if (!local_max(a, x, y))
					continue;
				e = a[(size_t)y * S + x] / W_C;
				n_low += e > 400 && e < 900;
				n_high += e > 4000 && e < 5300;
				n_both += e > 5300 && e < 6500;
				col[(x + 1) % 64]++;
				n_all++;
			}
		diag("expected %.0f hits per population; low %ld, high %ld, both %ld",
		     n_exp, n_low, n_high, n_both);
		is_near(n_low, n_exp, 5 * sqrt(n_exp), "600 e- hits at 5 /cm^2/s");
		is_near(n_high, n_exp, 5 * sqrt(n_exp), "5000 e- hits at 5 /cm^2/s");
		/* Independent populations share lambda^2 N = 4 pixels. */
		ok(n_both < 25, "the two populations are independent (%ld shared, STIPS: all)", n_both);
		/* Hits are drawn per segment of 64 centres: the position in
		 * the segment must be uniform.  63 dof: 5 sigma is 63 + 56. */
		for (int k = 0; k < 64; k++)
			chi += (col[k] - n_all / 64.0) * (col[k] - n_all / 64.0) / (n_all / 64.0);
		ok(chi < 63 + 5 * sqrt(126.0), "hit centres uniform within segments (chi^2 %.1f)", chi);
		free(a);
	}

	/* Energies at t = 10 s, where hits are too sparse to touch. */
	{
		double s1[2] = { 0 }, s2[2] = { 0 }, n[2] = { 0 };
		static const double e0[2] = { 600, 5000 };

		a = sca_image(10, 1, 2);
		for (int y = 1; y < S - 1; y++)
			for (int x = 1; x < S - 1; x++) {
				double e;
				int p;

				if (!local_max(a, x, y))
					continue;
				e = a[(size_t)y * S + x] / W_C;
				p = e > 4000 && e < 5400 ? 1 : e > 300 && e < 900 ? 0 : -1;
				if (p < 0)
					continue;
				s1[p] += e;
				s2[p] += e * e;
				n[p]++;
			}
		for (int p = 0; p < 2; p++) {
			double m = s1[p] / n[p], v = s2[p] / n[p] - m * m, e = e0[p];

			is_near(m, e, 5 * sqrt(e / n[p]) + 0.002 * e,
				"%g e- hits: mean energy %.1f", e, m);
			is_near(v, e, 5 * e * sqrt(2 / n[p]) + 0.02 * e,
				"%g e- hits: energy variance %.0f (Poisson)", e, v);
		}
		free(a);
	}

	/* Total dose at t = 1000 s: every science pixel receives lambda *
	 * (600 + 5000) e- on average, edge pixels included, because hits
	 * centred one pixel off the detector count.  The sum is compound
	 * Poisson: variance lambda N (E1^2 + E1 + E2^2 + E2). */
	{
		double lambda = 5e-3, sum = 0, sum1 = 0;
		double want = NPIX * lambda * 5600;
		double sd = sqrt(NPIX * lambda * (600.0 * 601 + 5000.0 * 5001));
		double *b;
		int same = 1;
		long n_out = 0;

		a = sca_image(1000, 1, 3);
		for (size_t i = 0; i < (size_t)S * S; i++)
			sum += a[i];
		is_near(sum, want, 5 * sd, "dose: %.4g e- on the SCA (rate x energy)", sum);

		/* Hits centred just off an edge: the edge pixel holds the
		 * template's edge weight of a 5000 e- hit and is the local
		 * maximum.  4 sides x 4088 centres x lambda = 82 expected. */
		for (int i = 1; i < S - 1; i++) {
			int xy[4][2] = { { 0, i }, { S - 1, i }, { i, 0 }, { i, S - 1 } };

			for (int k = 0; k < 4; k++) {
				double v = a[(size_t)xy[k][1] * S + xy[k][0]];

				n_out += local_max(a, xy[k][0], xy[k][1]) &&
					 v > W_E * 4500 && v < W_E * 5500;
			}
		}
		is_near(n_out, 4 * 4088 * lambda, 5 * sqrt(4 * 4088 * lambda),
			"hits centred off the edge reach the edge pixels (%ld)", n_out);

		b = sca_image(1000, NOISE_COSMIC_RESIDUAL, 3);
		for (size_t i = 0; i < (size_t)S * S; i++) {
			sum1 += b[i];
			same &= fabs(b[i] - 0.01 * a[i]) <= 1e-12 * a[i];
		}
		ok(same, "the residual keeps 1%% of every hit");
		diag("mean residual dose %.4f e-/pixel in 1000 s", sum1 / NPIX);
		free(a);
		free(b);
	}
	/* A long exposure, where each segment's count comes from PTRS: the
	 * mean dose is still lambda * 5600 e- per pixel. */
	{
		double lambda = 5e-6 * 1e5, sum = 0;
		double sd = sqrt(NPIX * lambda * (600.0 * 601 + 5000.0 * 5001));

		a = sca_image(1e5, 1, 4);
		for (size_t i = 0; i < (size_t)S * S; i++)
			sum += a[i];
		is_near(sum, NPIX * lambda * 5600, 5 * sd, "dose in 1e5 s: %.1f e-/pixel", sum / NPIX);
		free(a);
	}
	/* From lambda = 1 per centre (2e5 s) each centre is drawn by itself
	 * (count, then the electrons of all its hits at once).  Either side
	 * of the switch and far beyond it, the dose per pixel has the mean
	 * lambda (600 + 5000) and, since the template spreads a centre's
	 * charge over 3x3 pixels, the variance lambda sum_p (E_p^2 + E_p)
	 * sum_k w_k^2; a pixel and its right neighbour covary by lambda
	 * sum_p (E_p^2 + E_p) sum_k w_k w_k', k' the template pixel to the
	 * right of k.  Standard errors from the fourth moments of the data,
	 * with one independent sample per 6 x 5 pixels (pixels further apart
	 * share no centre).  A band of B rows is sample enough: a quarter of
	 * the SCA leaves 5 sigmas at 1.1% of the mean, 2.3% of the variance
	 * and 21% of the covariance, where the defects this is for move them (a
	 * population lost or doubled at the switch: the mean by 11% or more;
	 * the charge left in the centre's pixel: the variance by 28%, the
	 * covariance by 100%; a centre's hits given one draw's electrons
	 * times their count: the variance at 1e9 s by 100% or more). */
	{
		static const double ts[] = { 1.98e5, 2e5, 1e6, 1e9 };
		double w[3][3], sum = 0, w2 = 0, w11 = 0;
		double sig = 0.9 / (2 * sqrt(2 * log(2.0)));
		double e2 = 600.0 * 601 + 5000.0 * 5001;

		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				sum += w[i][j] = exp(-((i - 1) * (i - 1) + (j - 1) * (j - 1)) /
						     (2 * sig * sig));
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++) {
				w2 += w[i][j] * w[i][j] / (sum * sum);
				if (j < 2)
					w11 += w[i][j] * w[i][j + 1] / (sum * sum);
			}
		for (size_t k = 0; k < sizeof(ts) / sizeof(ts[0]); k++) {
			double lambda = 5e-6 * ts[k], want_v = lambda * e2 * w2;
			double want_c = lambda * e2 * w11;
			double m = 0, v = 0, c = 0, v4 = 0, c4 = 0, n = 0, neff;

			a = sca_band(ts[k], 5 + (int)k, B);
			for (int y = 1; y < B - 1; y++)
				for (int x = 1; x < S - 2; x++)
					m += a[(size_t)y * S + x], n++;
			m /= n;
			for (int y = 1; y < B - 1; y++)
				for (int x = 1; x < S - 2; x++) {
					double d = a[(size_t)y * S + x] - m;
					double dd = d * (a[(size_t)y * S + x + 1] - m);

					v += d * d;
					v4 += d * d * d * d;
					c += dd;
					c4 += dd * dd;
				}
			v /= n;
			c /= n;
			neff = n / 30;
			is_near(m, lambda * 5600, 5 * sqrt(v / neff),
				"%g s (lambda %g): mean dose %.1f e-/pixel", ts[k], lambda, m);
			is_near(v, want_v, 5 * sqrt((v4 / n - v * v) / neff),
				"%g s: variance of the dose / expected = %.4f", ts[k], v / want_v);
			is_near(c, want_c, 5 * sqrt((c4 / n - c * c) / neff),
				"%g s: neighbours covary through the template (%.4f)", ts[k],
				c / want_c);
			free(a);
		}
	}
	return done_testing();
}
