/*
 * exposure.h - the unit the engine iterates over: one exposure of the WFI.
 *
 * A run simulates one exposure (the pointing of --ra/--dec/--pa) or, with
 * --pointings, one per line of that file, all from one reading of the
 * catalogs.  An exposure is everything that differs between them: where the
 * telescope points, when, which SCAs are read, to which level the detector is
 * simulated, the background, the random seed and the files written.  What is
 * common to all (filter, PSF, models, tiles) stays in struct scene_opts.
 */
#ifndef WFS_EXPOSURE_H
#define WFS_EXPOSURE_H

#include <stdint.h>

#include "background.h"

struct err;
struct scene_opts;

/* At most this many exposures in one run (--pointings lines); they are
 * drawn as many at a time as --memory holds (run.c). */
#define MAX_EXPOSURES 100000

struct exposure {
	char name[64];          /* --pointings name ("001", ...), "" for one exposure */
	int index;              /* 0-based position in the run */
	double ra, dec, pa;     /* pointing, degrees */
	int boresight;          /* reference aperture: 1 the boresight, 0 WFI01 */
	double date;            /* MJD of the exposure; NaN when none was given */
	unsigned sca_mask;      /* bit s-1 for SCA s */
	int level;              /* enum detector_level: how far the detector is simulated */
	double background;      /* counts/s/pixel: the number, or avg's filter-wide one */
	struct bkg_exposure bkg;/* the background of each SCA and its parts */
	uint64_t seed;
	/* -o as given (a names.h template: %d the SCA, %s the name, %%),
	 * expanded per SCA by the writer; --placed and --report expanded (%s
	 * the name, %% a '%'), owned by the exposure, NULL when not asked for. */
	const char *output;
	char *placed, *report;
	/* The run's persistence state (persist.h), shared by its exposures
	 * and taken forward in their order; NULL without persistence. */
	struct persist *persist;
};

/* The exposures of a run: one from the options, or one per line of
 * o->pointings, each with its background worked out (and, with a date, a
 * pointing Roman cannot take refused: see background_exposure).  Returns 0
 * with *out (free with exposures_free) and *n, or -1 with the message in e. */
int exposures_make(const struct scene_opts *o, struct exposure **out, int *n, struct err *e);

void exposures_free(struct exposure *x, int n);

#endif
