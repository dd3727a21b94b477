/*
 * ramp_stats.h - two statistics of a level-2 ramp fit that the Roman
 * pipeline's level 2 carries (RAD's chisq and dumo) and wfiscene's FITS
 * product does not: computed beside the fit (levels.c) when the writer
 * asks for them (the ASDF writer).
 */
#ifndef WFS_RAMP_STATS_H
#define WFS_RAMP_STATS_H

#include <stddef.h>
#include <stdint.h>

#include "ramp.h"

/* Doubles of scratch for a row of n pixels. */
#define RAMP_STATS_SCRATCH(n) (10 * (size_t)(n))

/*
 * The n pixels of a row, resultant r of pixel x at dn[r * plane + x] (DN),
 * fitted rate fit[x] (ramp_fit_row's); each resultant through the fit's
 * non-linearity correction (fp->nlinv), those before the first saturated
 * one used:
 *   dumo: the slope of uniform weights (least squares of the resultants
 *     against their mean read times) minus the fitted rate, in DN/s;
 *   chisq: of the differences of consecutive resultants against the
 *     fitted rate, each of variance rate dt + read_noise^2 (1/n_i +
 *     1/n_{i+1}) (the resultants' covariance left out), over their number
 *     less one.
 * NaN for a DO_NOT_USE pixel, or with too few resultants (2 for dumo, 3
 * for chisq).  Resultant by resultant along the row.  Thread-safe.
 */
void ramp_stats_row(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane,
		    const struct ramp_fit *fit, int n, double *scratch, float *chisq,
		    float *dumo);

#endif
