/*
 * psfclass.c - the spectral classes of the built-in PSF (psf.h): two
 * families of spectra, power laws and blackbodies, whose effective
 * wavelengths span a filter, one ePSF grid each; a source's ePSF is
 * interpolated between the two classes of its family nearest its own
 * effective wavelength through the SCA's throughput.
 *
 * Why two families: the ePSF of a spectrum is not a function of its
 * effective wavelength alone.  In F146 a 2500 K blackbody's ePSF differs
 * by 1.8e-3 of its peak from that of the power law with the same
 * effective wavelength (contrib/bench/colour.c), the spread of the
 * photons about their mean being another; within one family the
 * effective wavelength does fix the spectrum.
 */
#include <math.h>
#include <stdio.h>

#include "err.h"
#include "instrument.h"
#include "psf.h"
#include "spectrum.h"

/*
 * The defaults, from the measurements in BENCHMARKS.md ("Colour"): the
 * fewest classes per family for which every spectrum from 2500 to 50000 K
 * and beta -3 to 3 is within 1e-3 of the peak of its own polychromatic
 * ePSF.
 */
int psf_default_classes(int filter)
{
	/* F062 F087 F106 F129 F158 F184 F213 F146 */
	static const int nc[WFS_NFILTER] = { 3, 2, 2, 2, 2, 2, 2, 4 };

	return filter >= 0 && filter < WFS_NFILTER ? nc[filter] : 4;
}

/* The value of family fam's parameter (beta, or log T) whose effective
 * wavelength on SCA 1 is lam: bisection, lam_eff falling with both. */
static double solve(struct colour *c, int fam, double lam)
{
	double lo = fam ? log(1000) : -16, hi = fam ? log(1e5) : 16;

	for (int i = 0; i < 60; i++) {
		double mid = 0.5 * (lo + hi);
		struct spectrum s = { fam ? SPEC_BLACKBODY : SPEC_POWER, fam ? exp(mid) : mid };

		if (colour_lam_eff(c, 1, &s) > lam)
			lo = mid;
		else
			hi = mid;
	}
	return 0.5 * (lo + hi);
}

void psf_classes_spectrum(const struct psf_classes *pc, int k, int *kind, double *value)
{
	int fam = k >= pc->n;

	*kind = fam ? SPEC_BLACKBODY : SPEC_POWER;
	*value = fam ? pc->teff[k - pc->n] : pc->beta[k];
}

int psf_classes_make(struct psf_classes *pc, struct colour *c, int filter, int n,
		     struct err *e)
{
	if (n < 2 || n > PSF_COLOUR_MAX)
		return err_set(e, EXIT_INPUT, "psf-colour-classes: expected 2 to %d, not %d",
			       PSF_COLOUR_MAX, n);
	pc->filter = filter;
	pc->n = n;
	pc->gsteps = 0;
	pc->blend = NULL;
	double l[4] = {
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_POWER, 3 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_BLACKBODY, 50000 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_POWER, -3 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_BLACKBODY, 2500 }),
	};
	double plo = fmin(l[0], l[1]), phi = fmax(l[2], l[3]);

	for (int k = 0; k < n; k++) {
		/* rounded, so that the cache keys are short and stable: beta
		 * to 1e-6, T to 0.1 K */
		pc->beta[k] = round(1e6 * solve(c, 0, plo + (phi - plo) * k / (n - 1))) / 1e6;
		pc->teff[k] = round(10 * exp(solve(c, 1, l[1] + (l[3] - l[1]) * k / (n - 1)))) / 10;
		/* summed, not from the tables: filling an SCA's tables costs
		 * some 8 million instructions, and a scene uses few SCAs (the
		 * two differ by 3e-10 micron, tests/unit/spectrum.c) */
		for (int s = 1; s <= WFS_NSCA; s++) {
			double f;

			colour_exact(c, s, &(struct spectrum){ SPEC_POWER, pc->beta[k] }, &f,
				     &pc->lam[s - 1][0][k]);
			colour_exact(c, s, &(struct spectrum){ SPEC_BLACKBODY, pc->teff[k] }, &f,
				     &pc->lam[s - 1][1][k]);
		}
	}
	return 0;
}

double psf_classes_of(const struct psf_classes *pc, struct colour *c, int sca,
		      const struct spectrum *s)
{
	return psf_classes_at(pc, sca, s->kind == SPEC_BLACKBODY, colour_lam_eff(c, sca, s));
}

double psf_classes_at(const struct psf_classes *pc, int sca, int fam, double lam)
{
	const double *l = pc->lam[sca - 1][fam];
	int k;

	if (!(lam > l[0]))
		return fam * pc->n;
	if (lam >= l[pc->n - 1])
		return fam * pc->n + pc->n - 1;
	for (k = 0; k < pc->n - 2 && lam >= l[k + 1]; k++)
		;
	return fam * pc->n + k + (lam - l[k]) / (l[k + 1] - l[k]);
}
