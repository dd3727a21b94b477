/*
 * source.h - a catalog row as a source on one SCA (source.c).
 */
#ifndef WFS_SOURCE_H
#define WFS_SOURCE_H

#include <stddef.h>

struct engine;
struct err;
struct rows;
struct wfs_source;

/* Fill src for row i on SCA sca at pixel (x, y): its flux there, checked,
 * its magnitude and ePSF class, the catalog's facts, the exposure's date.
 * On any thread.  Returns 0, or -1 with the error in e. */
int source_fill(const struct engine *g, const struct rows *r, size_t i, const double *param,
		int sca, double x, double y, struct wfs_source *src, struct err *e);

/* src's flux checked: positive, finite, and within what a float32 image
 * holds.  model names the model that set the flux, NULL for the catalog.
 * Returns 0, or -1 with the error in e. */
int source_flux_check(const struct engine *g, const struct rows *r, size_t i,
		      const struct wfs_source *src, const char *model, struct err *e);

/* The ePSF size class of magnitude mag: bright sources get the bigger
 * boxes; a magnitude equal to a limit counts as the brighter class (STIPS
 * drops such sources). */
int source_psf_class(const struct engine *g, double mag);

/* The AB magnitude of flux counts/s on SCA sca, through the zeropoint the
 * run uses. */
double source_mag(const struct engine *g, int sca, double flux);

#endif
