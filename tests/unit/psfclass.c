/*
 * psfclass.c - the spectral classes of the built-in PSF (src/psfclass.c),
 * for every filter at its default number of classes and at 2 and 6:
 *  - each class's own spectrum is that class on every SCA (u = k), and
 *    psf_classes_spectrum() gives it back;
 *  - a family's classes are evenly spaced in effective wavelength on SCA
 *    1, from blue to red, and the power laws' span holds the blackbodies';
 *  - any spectrum's class is its effective wavelength interpolated
 *    linearly between the two nearest classes of its family, and
 *    spectra beyond the family's span take its end class;
 *  - cooler stars and redder slopes have higher classes;
 *  - a number of classes outside 2 .. PSF_COLOUR_MAX is refused.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "psf.h"
#include "spectrum.h"

static void check(struct colour *c, int f, int n)
{
	const char *name = filter_get(f)->name;
	struct psf_classes pc;
	struct err e = { 0 };
	double worst_self = 0, worst_lin = 0, worst_even = 0;
	int monotone = 1, ends = 1, kinds = 1;

	if (!ok(psf_classes_make(&pc, c, f, n, &e) == 0, "%s, %d classes: made", name, n))
		return;
	for (int fam = 0; fam < 2; fam++) {
		const double *l = pc.lam[0][fam];
		double step = (l[n - 1] - l[0]) / (n - 1);

		for (int k = 0; k < n; k++) {
			int kind;
			double v;

			psf_classes_spectrum(&pc, fam * n + k, &kind, &v);
			kinds &= kind == (fam ? SPEC_BLACKBODY : SPEC_POWER) &&
				 v == (fam ? pc.teff[k] : pc.beta[k]);
			for (int sca = 1; sca <= WFS_NSCA; sca += 8)
				worst_self = fmax(worst_self, fabs(psf_classes_of(&pc, c, sca,
					&(struct spectrum){ kind, v }) - (fam * n + k)));
			if (k)
				worst_even = fmax(worst_even, fabs(l[k] - l[k - 1] - step));
		}
		monotone &= step > 0;
	}
	/* classes are rounded (beta to 1e-6, T to 0.1 K) and the class of a
	 * spectrum comes from the tables (1e-7 of the sums) */
	ok(kinds, "%s, %d classes: each class's spectrum given back", name, n);
	ok(worst_self < 1e-3, "%s, %d classes: a class's own spectrum is that class on SCAs 1, 9, "
	   "17 (worst %.2g)", name, n, worst_self);
	/* (with 2 classes true by construction: the defaults and 6 test it) */
	ok(worst_even < 1e-5, "%s, %d classes: evenly spaced on SCA 1 (worst %.2g micron)", name,
	   n, worst_even);
	/* (the end classes solved to the same wavelength, their parameters
	 * rounded) */
	ok(pc.lam[0][0][0] <= pc.lam[0][1][0] + 1e-6 &&
	   pc.lam[0][0][n - 1] >= pc.lam[0][1][n - 1] - 1e-6,
	   "%s, %d classes: the power laws span the blackbodies (%.4f-%.4f, %.4f-%.4f)", name, n,
	   pc.lam[0][0][0], pc.lam[0][0][n - 1], pc.lam[0][1][0], pc.lam[0][1][n - 1]);
	srand(f * 31 + n);
	for (int i = 0; i < 300; i++) {
		int sca = 1 + i % WFS_NSCA, fam = i % 2;
		struct spectrum s = { fam ? SPEC_BLACKBODY : SPEC_POWER,
				      fam ? exp(log(2500) + log(20.0) * rand() / RAND_MAX) :
					    -3 + 6.0 * rand() / RAND_MAX };
		double u = psf_classes_of(&pc, c, sca, &s) - fam * n, lam = colour_lam_eff(c, sca, &s);
		const double *l = pc.lam[sca - 1][fam];
		int k = (int)floor(u);

		if (u <= 0 || u >= n - 1) {
			ends &= (u == 0 && lam <= l[0]) || (u == n - 1 && lam >= l[n - 1]);
			continue;
		}
		worst_lin = fmax(worst_lin, fabs(l[k] + (u - k) * (l[k + 1] - l[k]) - lam));
	}
	ok(worst_lin < 1e-12, "%s, %d classes: a spectrum's class is its effective wavelength "
	   "between the nearest two (worst %.2g micron)", name, n, worst_lin);
	ok(ends, "%s, %d classes: beyond the span, the end class", name, n);
	for (int fam = 0; fam < 2; fam++) {
		double last = -1;

		for (int i = 0; i <= 40; i++) {
			struct spectrum s = { fam ? SPEC_BLACKBODY : SPEC_POWER,
					      fam ? 100000 * pow(0.01, i / 40.0) : 8 - 16.0 * i / 40 };
			double u = psf_classes_of(&pc, c, 4, &s) - fam * n;

			monotone &= u >= last && u >= 0 && u <= n - 1;
			last = u;
		}
		ends &= psf_classes_of(&pc, c, 4, &(struct spectrum){ fam ? SPEC_BLACKBODY :
					SPEC_POWER, fam ? 1000 : -8 }) == fam * n + n - 1;
		ends &= psf_classes_of(&pc, c, 4, &(struct spectrum){ fam ? SPEC_BLACKBODY :
					SPEC_POWER, fam ? 100000 : 8 }) == fam * n;
	}
	ok(monotone, "%s, %d classes: cooler and redder is a higher class, within 0 .. %d", name,
	   n, n - 1);
	ok(ends, "%s, %d classes: 1000 K and beta -8 the reddest class, 1e5 K and beta 8 the "
	   "bluest", name, n);
}

int main(void)
{
	struct err e = { 0 };

	if (instrument_init(&e))
		return printf("not ok 1 - %s\n", e.msg), 1;
	for (int f = 0; f < WFS_NFILTER; f++) {
		struct colour *c = colour_new(f, &e);
		int nd = psf_default_classes(f);
		struct psf_classes pc;

		if (!ok(c, "%s: colour tables", filter_get(f)->name))
			continue;
		check(c, f, nd);
		if (nd != 2)
			check(c, f, 2);
		check(c, f, 6);
		for (int k = 0; k < 2; k++) {
			int bad = k ? PSF_COLOUR_MAX + 1 : 1;
			struct err be = { 0 };

			ok(psf_classes_make(&pc, c, f, bad, &be) < 0 && be.code == EXIT_INPUT &&
			   strstr(be.msg, "psf-colour-classes"), "%s: %d classes refused: %s",
			   filter_get(f)->name, bad, be.msg);
		}
		colour_free(c);
	}
	ok(psf_default_classes(7) == 4 && !strcmp(filter_get(7)->name, "F146"),
	   "F146 takes 4 classes by default, the others 2 or 3");
	return done_testing();
}
