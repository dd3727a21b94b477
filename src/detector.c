/*
 * detector.c - the detector stage after rendering; see detector.h.
 *
 * The scene level of STIPS, a rate image with background, exposure time,
 * noise and detector residuals applied per tile by noise.c; levels 1 and 2
 * (the ramp) are written whole by levels.c from write.c.
 */
#include <stdatomic.h>

#include "detector.h"
#include "exposure.h"
#include "instrument.h"
#include "pool.h"
#include "scene.h"

int detector_init(struct detector *d, const struct scene_opts *o, const struct exposure *x,
		  struct err *e)
{
	d->level = x->level;
	if (d->level != DETECTOR_SCENE) {
		d->active = 1;
		return ramp_pattern_get(o->ma_table, &d->pattern, e);
	}
	d->noise = (struct noise_opts){
		.stages = o->noise, .background = x->background, .exptime = o->exptime,
		.readnoise = o->readnoise, .dark_current = o->dark_current,
		.cosmic_rate = o->cosmic_rate, .cosmic_residual = o->cosmic_residual,
		.seed = x->seed, .filter = o->filter, .counts = o->bunit_counts,
	};
	/* With no noise, no background and counts/s, the stage is the
	 * identity and the tiles never drawn on are never allocated. */
	d->active = o->noise || x->background != 0 || o->bunit_counts;
	return 0;
}

struct strip_job {
	const struct detector *d;
	int sca, y0, ny, T;
	double *const *tiles;
	atomic_int failed;
};

static void detector_tile(void *arg, int wid, size_t tx)
{
	struct strip_job *j = arg;
	int x0 = (int)tx * j->T;
	int nx = x0 + j->T > WFS_NPIX ? WFS_NPIX - x0 : j->T;

	if (noise_tile(&j->d->noise, j->sca, x0, j->y0, nx, j->ny, j->tiles[tx], j->T) < 0)
		atomic_store(&j->failed, 1);
}

int detector_strip(const struct detector *d, struct pool *pool, int sca, int y0, int ny,
		   double *const *tiles, int ntx, int T)
{
	struct strip_job j = { .d = d, .sca = sca, .y0 = y0, .ny = ny, .T = T, .tiles = tiles };

	if (!d->active)
		return 0;
	atomic_init(&j.failed, 0);
	pool_run(pool, detector_tile, &j, ntx);
	return atomic_load(&j.failed) ? -1 : 0;
}
