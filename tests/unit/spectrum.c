/*
 * spectrum.c - the colour term and effective wavelengths (src/spectrum.c):
 *  - a flat f_nu (beta = 0, or no spectrum) gives exactly the counts of
 *    the AB zeropoints: factor 1;
 *  - the tables are within 1e-7 (relative) of the sums they stand for, at
 *    random slopes and temperatures, for every filter and a few SCAs;
 *  - a blue source has the shorter effective wavelength, and the
 *    effective wavelength of every spectrum lies inside its filter;
 *  - a hot blackbody tends to the Rayleigh-Jeans slope beta = 2;
 *  - the factor is the ratio of sums a user can check: for beta = 2, in
 *    every filter, a direct sum over data/throughput.tsv's samples.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "spectrum.h"
#include "throughput.h"

int main(void)
{
	struct err e = { 0 };

	if (instrument_init(&e))
		return printf("not ok 1 - %s\n", e.msg), 1;
	for (int f = 0; f < WFS_NFILTER; f++) {
		struct colour *c = colour_new(f, &e);
		const char *name = filter_get(f)->name;
		double worst_f = 0, worst_l = 0;

		if (!ok(c, "%s: colour tables", name))
			continue;
		struct spectrum flat = { SPEC_POWER, 0 }, none = { SPEC_DEFAULT, 0 };
		ok(colour_factor(c, 1, &flat) == 1 && colour_factor(c, 7, &none) == 1,
		   "%s: a flat f_nu keeps the AB zeropoint's counts exactly", name);
		srand(f + 1);
		int both_same = 1;

		for (int i = 0; i < 400; i++) {
			int sca = 1 + i % WFS_NSCA;
			struct spectrum s;
			double fx, lx, fb, lb;

			if (i % 2) {
				s.kind = SPEC_POWER;
				s.value = -8 + 16.0 * rand() / RAND_MAX;
			} else {
				s.kind = SPEC_BLACKBODY;
				s.value = exp(log(1000) + log(100.0) * rand() / RAND_MAX);
			}
			colour_exact(c, sca, &s, &fx, &lx);
			colour_both(c, sca, &s, &fb, &lb);
			both_same &= fb == colour_factor(c, sca, &s) &&
				     lb == colour_lam_eff(c, sca, &s);
			worst_f = fmax(worst_f, fabs(colour_factor(c, sca, &s) / fx - 1));
			worst_l = fmax(worst_l, fabs(colour_lam_eff(c, sca, &s) / lx - 1));
		}
		/* beyond the tables (summed directly), the flat spectrum and
		 * the default one */
		for (int i = 0; i < 6; i++) {
			struct spectrum s = i == 0 ? (struct spectrum){ SPEC_POWER, -9.5 } :
					    i == 1 ? (struct spectrum){ SPEC_POWER, 12 } :
					    i == 2 ? (struct spectrum){ SPEC_BLACKBODY, 950 } :
					    i == 3 ? (struct spectrum){ SPEC_BLACKBODY, 2e5 } :
					    i == 4 ? flat : none;
			double fb, lb;

			colour_both(c, 1 + i, &s, &fb, &lb);
			both_same &= fb == colour_factor(c, 1 + i, &s) &&
				     lb == colour_lam_eff(c, 1 + i, &s);
		}
		ok(both_same, "%s: colour_both gives the same numbers as colour_factor and "
		   "colour_lam_eff, in and beyond the tables", name);
		ok(worst_f < 1e-7, "%s: table's colour factor within 1e-7 of the sum (worst %.2g)",
		   name, worst_f);
		ok(worst_l < 1e-7, "%s: table's effective wavelength within 1e-7 of the sum "
		   "(worst %.2g)", name, worst_l);
		struct spectrum blue = { SPEC_POWER, 3 }, red = { SPEC_POWER, -3 };
		struct spectrum hot = { SPEC_BLACKBODY, 50000 }, cool = { SPEC_BLACKBODY, 2500 };
		double lb = colour_lam_eff(c, 2, &blue), lr = colour_lam_eff(c, 2, &red);
		double lh = colour_lam_eff(c, 2, &hot), lc = colour_lam_eff(c, 2, &cool);
		ok(lb < lr && lh < lc, "%s: blue before red: beta 3 %.4f, -3 %.4f; 50000 K %.4f, "
		   "2500 K %.4f micron", name, lb, lr, lh, lc);
		ok(lb > filter_get(f)->lam_min - 0.05 && lr < filter_get(f)->lam_max + 0.05,
		   "%s: effective wavelengths inside the band", name);
		struct spectrum rj = { SPEC_POWER, 2 }, vhot = { SPEC_BLACKBODY, 100000 };
		double frj = colour_factor(c, 2, &rj), fvh = colour_factor(c, 2, &vhot);
		/* at 1e5 K and 1 micron, h nu / k T = 0.14: a few per cent off R-J
		 * in slope, far less in the factor */
		is_rel(fvh / colour_factor(c, 2, &(struct spectrum){ SPEC_BLACKBODY, 99999 }), 1,
		       1e-5, "%s: smooth near the hot end", name);
		/* the Rayleigh-Jeans limit: the hotter the blackbody, the
		 * nearer its factor and effective wavelength to beta = 2's */
		{
			double lrj = colour_lam_eff(c, 2, &rj), d[3], dl[3];
			const double T[3] = { 10000, 30000, 100000 };

			for (int k = 0; k < 3; k++) {
				struct spectrum bb = { SPEC_BLACKBODY, T[k] };

				d[k] = fabs(colour_factor(c, 2, &bb) / frj - 1);
				dl[k] = fabs(colour_lam_eff(c, 2, &bb) / lrj - 1);
			}
			ok(d[2] < d[1] && d[1] < d[0] && d[2] < 0.02,
			   "%s: blackbodies tend to beta = 2 (factor off by %.3g, %.3g, %.3g "
			   "at 1e4, 3e4, 1e5 K)", name, d[0], d[1], d[2]);
			ok(dl[2] < dl[1] && dl[1] < dl[0] && dl[2] < 0.005,
			   "%s: and so do their effective wavelengths (off by %.3g, %.3g, %.3g)",
			   name, dl[0], dl[1], dl[2]);
		}
		/* the factor by hand for beta = 2: the photon-weighted mean of
		 * (lam / pivot)^-2 over the SCA's effective area, from the
		 * samples of data/throughput.tsv */
		{
			double *tl[WFS_NFILTER], *ta[WFS_NFILTER], sa = 0, sv = 0;
			int tn[WFS_NFILTER];
			struct err te = { 0 };

			if (ok(throughput_read(tl, ta, tn, &te) == 0, "%s: throughput samples", name)) {
				double pv = filter_get(f)->pivot;

				for (int k = 0; k < tn[f]; k++) {
					double a = ta[f][k * WFS_NSCA + 1], l = tl[f][k];

					sa += a / l;
					sv += a / l * (pv / l) * (pv / l);
				}
				is_rel(frj, sv / sa, 1e-7, "%s: beta = 2's factor %.6f is the sum by "
				       "hand over %d samples", name, frj, tn[f]);
				throughput_free(tl, ta);
			}
		}
		diag("%s SCA02: factor beta=2 %.5f, 1e5 K %.5f, 5700 K %.5f, 2500 K %.5f", name,
		     frj, fvh, colour_factor(c, 2, &(struct spectrum){ SPEC_BLACKBODY, 5700 }),
		     colour_factor(c, 2, &cool));
		colour_free(c);
	}
	return done_testing();
}
