/*
 * detector.c - the detector stage after rendering; see detector.h.
 *
 * The scene level of STIPS, a rate image with background, exposure time,
 * noise and detector residuals applied per tile by noise.c; levels 1 and 2
 * (the ramp) are written whole by levels.c from write.c.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "detector.h"
#include "exposure.h"
#include "err.h"
#include "instrument.h"
#include "levels.h"
#include "pool.h"
#include "scene.h"
#include "sky.h"

int detector_init(struct detector *d, const struct scene_opts *o, const struct exposure *x,
		  struct err *e)
{
	int any_bkg = 0;

	d->level = x->level;
	d->sky = NULL;
	d->poisson_normal = 0;
	/* --set poisson-normal=N (the last one given wins) */
	for (const char *const *kv = o->settings; kv && *kv; kv++) {
		static const char key[] = "poisson-normal=";
		const char *v = *kv + sizeof(key) - 1;
		char *end;
		double val;

		if (strncmp(*kv, key, sizeof(key) - 1))
			continue;
		val = strtod(v, &end);
		if (end == v || *end || isnan(val) || val < 10)
			return err_set(e, EXIT_INPUT, "--set poisson-normal=%s: expected a mean "
				       "of 10 or more (inf: always the exact count)", v);
		d->poisson_normal = val;
	}
	for (int s = 0; s < WFS_NSCA; s++) {
		const struct bkg_part *p = &x->bkg.sca[s];
		int split = x->bkg.model == BKG_AVG || x->bkg.model == BKG_SKY;

		d->bkg_sky[s] = split ? p->zodi : p->total;
		d->bkg_pixel[s] = split ? p->thermal : 0;
		any_bkg |= p->total != 0;
	}
	if (d->level != DETECTOR_SCENE) {
		d->active = 1;
		return ramp_pattern_get(o->ma_table, &d->pattern, e);
	}
	d->noise = (struct noise_opts){
		.stages = o->noise, .exptime = o->exptime,
		.poisson_normal = d->poisson_normal,
		.readnoise = o->readnoise, .dark_current = o->dark_current,
		.cosmic_rate = o->cosmic_rate, .cosmic_residual = o->cosmic_residual,
		.seed = x->seed, .filter = o->filter, .counts = o->bunit_counts,
	};
	/* With no noise, no background and counts/s, the stage is the
	 * identity and the tiles never drawn on are never allocated.  (Every
	 * SCA has a background or none does, so that split runs agree.) */
	d->active = o->noise || any_bkg || o->bunit_counts;
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
	struct noise_opts no = j->d->noise;

	const struct geom_sca *geo = j->d->sky ? &j->d->sky->sca[j->sca - 1].geo : NULL;
	double *tile = j->tiles[tx];
	double sky = j->d->bkg_sky[j->sca - 1], thermal = j->d->bkg_pixel[j->sca - 1];

	/* The background comes in two parts: the sky's light, per nominal
	 * 0.11" pixel, and the internal thermal glow, per detector pixel.  In
	 * the SIAF geometry each pixel gets the sky's part times its own area,
	 * added here before the noise stages as noise_tile would add it; in
	 * stips every pixel has the nominal area, so the parts add up to one
	 * number for the SCA that noise_tile adds, as before. */
	no.background = sky + thermal;
	if (geo && geo->kind == GEOM_SIAF && sky != 0 && tile) {
		enum { SPAN = 256 };
		double area[SPAN];

		for (int y = 0; y < j->ny; y++)
			for (int x = 0; x < nx; x += SPAN) {
				int m = nx - x < SPAN ? nx - x : SPAN;
				double *r = tile + (size_t)y * j->T + x;

				geom_area_row(geo, j->y0 + y, x0 + x, m, area);
				for (int i = 0; i < m; i++)
					r[i] += sky * area[i];
			}
		no.background = thermal;
	}
	if (noise_tile(&no, j->sca, x0, j->y0, nx, j->ny, tile, j->T) < 0)
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

void detector_level_setup(const struct detector *d, int sca, struct level_sca *L)
{
	const struct geom_sca *geo = d->sky ? &d->sky->sca[sca - 1].geo : NULL;

	L->background = d->bkg_sky[sca - 1] + d->bkg_pixel[sca - 1];
	L->geo = geo && geo->kind == GEOM_SIAF ? geo : NULL;
	L->bkg_sky = d->bkg_sky[sca - 1];
	L->key.poisson_normal = d->poisson_normal;
}
