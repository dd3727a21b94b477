/*
 * psfclass.c - the spectral classes of the built-in PSF (psf.h): a few
 * power-law spectra whose effective wavelengths span a filter, one ePSF
 * grid each; a source's ePSF is interpolated between the two classes
 * nearest its own effective wavelength through the SCA's throughput.
 */
#include <math.h>
#include <stdio.h>

#include "err.h"
#include "instrument.h"
#include "psf.h"
#include "spectrum.h"

/*
 * The defaults, from the measurements in BENCHMARKS.md ("Colour"): the
 * fewest classes for which every spectrum from 2500 to 50000 K and beta
 * -3 to 3 is within 1e-3 of the peak of its own polychromatic ePSF, with
 * PSF_COLOUR_STEPS steps between classes.
 */
int psf_default_classes(int filter)
{
	/* F062 F087 F106 F129 F158 F184 F213 F146 */
	static const int nc[WFS_NFILTER] = { 4, 2, 2, 2, 2, 2, 2, 5 };

	return filter >= 0 && filter < WFS_NFILTER ? nc[filter] : 4;
}

/* The slope whose effective wavelength on SCA sca is lam: bisection,
 * lam_eff falling with beta. */
static double beta_at(struct colour *c, int sca, double lam)
{
	double lo = -16, hi = 16;

	for (int i = 0; i < 60; i++) {
		double mid = 0.5 * (lo + hi);

		if (colour_lam_eff(c, sca, &(struct spectrum){ SPEC_POWER, mid }) > lam)
			lo = mid;
		else
			hi = mid;
	}
	return 0.5 * (lo + hi);
}

int psf_classes_make(struct psf_classes *pc, struct colour *c, int filter, int n, int steps,
		     struct err *e)
{
	if (n < 2 || n > PSF_COLOUR_MAX)
		return err_set(e, EXIT_INPUT, "psf-colour-classes: expected 2 to %d, not %d",
			       PSF_COLOUR_MAX, n);
	if (steps < 1 || steps > PSF_COLOUR_STEPS_MAX)
		return err_set(e, EXIT_INPUT, "psf-colour-steps: expected 1 to %d, not %d",
			       PSF_COLOUR_STEPS_MAX, steps);
	pc->filter = filter;
	pc->n = n;
	pc->steps = steps;
	/* the span: the bluest and reddest of the spectra the classes are
	 * measured for, on SCA 1 */
	double l[4] = {
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_POWER, 3 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_BLACKBODY, 50000 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_POWER, -3 }),
		colour_lam_eff(c, 1, &(struct spectrum){ SPEC_BLACKBODY, 2500 }),
	};
	double lo = fmin(l[0], l[1]), hi = fmax(l[2], l[3]);

	for (int k = 0; k < n; k++) {
		/* rounded, so that the cache keys are short and stable */
		pc->beta[k] = round(1e6 * beta_at(c, 1, lo + (hi - lo) * k / (n - 1))) / 1e6;
		for (int s = 1; s <= WFS_NSCA; s++)
			pc->lam[s - 1][k] = colour_lam_eff(c, s, &(struct spectrum){
							   SPEC_POWER, pc->beta[k] });
	}
	return 0;
}

double psf_classes_u(const struct psf_classes *pc, int sca, double lam)
{
	const double *l = pc->lam[sca - 1];
	int k;

	if (!(lam > l[0]))
		return 0;
	if (lam >= l[pc->n - 1])
		return pc->n - 1;
	for (k = 0; k < pc->n - 2 && lam >= l[k + 1]; k++)
		;
	return k + (lam - l[k]) / (l[k + 1] - l[k]);
}

int psf_classes_index(const struct psf_classes *pc, int sca, double lam)
{
	return (int)lround(psf_classes_u(pc, sca, lam) * pc->steps);
}
