/*
 * source.c - a catalog row as a source on one SCA: its flux in counts/s
 * through its unit, zeropoint and spectrum, checked, and the facts the
 * models read (place.c calls it for each placement, on any thread).
 */
#include <math.h>
#include <string.h>

#include "catalog.h"
#include "engine.h"
#include "err.h"
#include "source.h"
#include "spectrum.h"

/* The row's flux in counts/s on SCA sca: a magnitude or flux density
 * (f_nu at the filter's pivot wavelength) through the row's spectrum and
 * the SCA's throughput (spectrum.h), a flat f_nu without one.  *mag is
 * the AB magnitude of an AB magnitude's row on the SCA, from the row's
 * own value (exact, without a round trip through the flux, which can
 * come back an ulp brighter); NaN for other units. */
static double counts_on(const struct engine *g, const struct rows *r, size_t i, int sca,
			double k, double *mag)
{
	double v = r->flux[i];

	*mag = NAN;
	switch (r->unit[i]) {
	case UNIT_COUNTS:
		return v;
	case UNIT_ABMAG:
		*mag = k == 1 ? v : v - 2.5 * log10(k);
		return pow(10.0, -0.4 * (v - filter_zeropoint(g->o->filter, sca,
							      g->o->zp_stips))) * k;
	default:
		/* unit_to_counts() goes through the SCA's RTI zeropoint, as
		 * 1 / PHOTFNU; STIPS's fixed zeropoint zs gives PHOTFNU's
		 * ratio 10^(0.4 (zs - z_rti)) on top of it. */
		if (g->o->zp_stips)
			return v * unit_to_counts(g->o->filter, sca, r->unit[i]) *
			       pow(10.0, 0.4 * (filter_stips_zp(g->o->filter) -
						filter_get(g->o->filter)->zp_ab[sca - 1])) * k;
		return v * unit_to_counts(g->o->filter, sca, r->unit[i]) * k;
	}
}

double source_mag(const struct engine *g, int sca, double flux)
{
	return filter_zeropoint(g->o->filter, sca, g->o->zp_stips) - 2.5 * log10(flux);
}

/* Bright sources get the bigger ePSF boxes; a magnitude equal to a limit
 * counts as the brighter class (STIPS drops such sources). */
int source_psf_class(const struct engine *g, double mag)
{
	if (mag <= g->o->xbright_limit)
		return WFS_PSF_XBRIGHT;
	if (mag <= g->o->bright_limit)
		return WFS_PSF_BRIGHT;
	return WFS_PSF_NORMAL;
}

/* src's flux checked: positive, finite, and within what a float32 image
 * holds.  model names the model that set the flux, NULL for the catalog.
 * The message names the row's flux as the catalog gave it (its column,
 * value and unit: rows_flux_text), made only on failure. */
int source_flux_check(const struct engine *g, const struct rows *r, size_t i,
		      const struct wfs_source *src, const char *model, struct err *e)
{
	double image = src->flux * (g->o->bunit_counts ? g->o->exptime : 1);
	char given[160];

	if (!isfinite(src->flux) || src->flux <= 0)
		return err_set(e, EXIT_INPUT, "%s:%ld: %s %s %g counts/s "
			       "on SCA %d: not a positive finite number", r->file,
			       r->line[i], rows_flux_text(r, i, given, sizeof(given)),
			       model ? "becomes, by its model," : "converts to",
			       src->flux, src->sca);
	/* The image is float32 (at most 3.4e38): one source may bring up to
	 * 1e32 in the image's unit, so no sum of sources can overflow it. */
	if (image > 1e32)
		/* nine digits, so that a value just past 1e32 does not read
		 * as 1e+32 */
		return err_set(e, EXIT_INPUT, "%s:%ld: %s %s %.9g %s on SCA %d, "
			       "more than the 1e32 that one source may put in a "
			       "float32 image", r->file, r->line[i],
			       rows_flux_text(r, i, given, sizeof(given)),
			       model ? "becomes, by its model," : "gives", image,
			       g->o->bunit_counts ? "counts" : "counts/s", src->sca);
	return 0;
}

/* Fill src for row i on SCA sca at pixel (x, y): its flux there, checked,
 * its magnitude and ePSF class, the catalog's facts, the exposure's date.
 * On any thread.  Returns 0, or -1 with the error in e. */
int source_fill(const struct engine *g, const struct rows *r, size_t i, const double *param,
		int sca, double x, double y, struct wfs_source *src, struct err *e)
{
	int spec = r->spec_kind && r->spec_kind[i] != SPEC_DEFAULT;
	struct spectrum sp = { spec ? r->spec_kind[i] : SPEC_DEFAULT, spec ? r->spec_value[i] : 0 };
	/* the colour term (times 1 is exact: a row without a spectrum keeps
	 * its bytes) and the effective wavelength, in one look-up */
	int term = spec && r->unit[i] != UNIT_COUNTS && !g->colour_band;
	double k = 1, lam = 0;

	if (term && g->classes)
		colour_both(g->colour, sca, &sp, &k, &lam);
	else if (term)
		k = colour_factor(g->colour, sca, &sp);
	else if (spec && g->classes)
		lam = colour_lam_eff(g->colour, sca, &sp);
	memset(src, 0, sizeof(*src));
	src->x = x;
	src->y = y;
	src->sca = sca;
	src->flux = counts_on(g, r, i, sca, k, &src->mag);
	if (isnan(src->mag))
		src->mag = source_mag(g, sca, src->flux);
	src->psf_class = source_psf_class(g, src->mag);
	src->id = r->id[i];
	src->param = param;
	src->flux_meaning = g->flux_meaning;
	src->mjd = g->x->date;
	/* the spectral class of the row's effective wavelength (psf.h) */
	src->colour = -1;
	if (spec && g->classes)
		src->colour = psf_classes_at(g->classes, sca, sp.kind == SPEC_BLACKBODY, lam);
	return source_flux_check(g, r, i, src, NULL, e);
}
