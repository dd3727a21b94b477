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
#include "options.h"
#include "persist.h"
#include "pool.h"
#include "scene.h"
#include "sky.h"

int detector_parse(const char *s, unsigned *parts, struct err *e)
{
	static const struct {
		const char *name;
		unsigned bit;
	} part[] = {
		{ "persistence", DETECTOR_PERSISTENCE },
		{ "correlated", DETECTOR_CORRELATED },
	};
	const char *p = s;

	*parts = 0;
	if (!strcmp(s, "all")) {
		*parts = DETECTOR_ALL;
		return 0;
	}
	if (!strcmp(s, "none"))
		return 0;
	while (*p) {
		size_t len = strcspn(p, ","), i;

		for (i = 0; i < sizeof(part) / sizeof(part[0]); i++)
			if (strlen(part[i].name) == len && !strncmp(p, part[i].name, len))
				break;
		if (i == sizeof(part) / sizeof(part[0]))
			return err_set(e, EXIT_INPUT, "--detector: unknown part '%.*s' in '%s' "
				       "(all, none, or a list of: persistence, correlated)", (int)len, p, s);
		*parts |= part[i].bit;
		p += len;
		if (*p == ',')
			p++;
	}
	return 0;
}

int detector_init(struct detector *d, const struct scene_opts *o, const struct exposure *x,
		  struct err *e)
{
	int any_bkg = 0;

	d->level = x->level;
	d->sky = NULL;
	d->poisson_normal = 0;
	d->persist = NULL;
	d->exptime = o->exptime;
	d->parts = o->detector;
	/* --set poisson-normal=N (the last one given wins) */
	const char *pn = setting_last(o->settings, "poisson-normal");

	if (pn) {
		char *end;
		double val = strtod(pn, &end);

		if (end == pn || *end || isnan(val) || val < 10)
			return err_set(e, EXIT_INPUT, "--set poisson-normal=%s: expected a mean "
				       "of 10 or more (inf: always the exact count)", pn);
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
		if (ramp_pattern_get(o->ma_table, &d->pattern, e) < 0)
			return -1;
		d->exptime = d->pattern.exptime;
	}
	if (x->persist) {
		if (persist_begin(x->persist, x->name, x->date, d->exptime, e) < 0)
			return -1;
		d->persist = x->persist;
	}
	if (d->level != DETECTOR_SCENE)
		return 0;
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
	d->active = o->noise || any_bkg || o->bunit_counts || d->persist;
	return 0;
}

static void detector_tile(void *arg, int wid, size_t tx)
{
	struct detector_run *j = arg;
	int x0 = (int)tx * j->T;
	int nx = x0 + j->T > WFS_NPIX ? WFS_NPIX - x0 : j->T;
	struct noise_opts no = j->d->noise;

	const struct geom_sca *geo = j->d->sky ? &j->d->sky->sca[j->sca - 1].geo : NULL;
	double *tile = j->tiles[tx];
	double sky = j->d->bkg_sky[j->sca - 1], thermal = j->d->bkg_pixel[j->sca - 1];

	if (!j->d->active) {
		j->done(j->done_arg, tx);
		return;
	}
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
	else if (j->done)
		j->done(j->done_arg, tx);
}

/*
 * Persistence at the scene level, on the calling thread before the noise:
 * each pixel's fluence (its light, background included, times the
 * exposure time) is the exposure's stimulus, row by row in order, and the
 * afterglow of the state's pixels is added as its mean rate over the
 * exposure, which the noise stages then treat as light.
 */
static int strip_persist(const struct detector *d, int sca, int y0, int ny,
			 double *const *tiles, int ntx, int T)
{
	struct persist *P = d->persist;
	const struct persist_list *l = &P->now[sca - 1];
	const struct persist_curve *c = &P->curve[sca - 1];
	const struct geom_sca *geo = d->sky ? &d->sky->sca[sca - 1].geo : NULL;
	double sky = d->bkg_sky[sca - 1], thermal = d->bkg_pixel[sca - 1];
	double *flu = malloc(2 * WFS_NPIX * sizeof(double)), *area = flu + WFS_NPIX;

	if (!flu)
		return -1;
	for (int y = 0; y < ny; y++) {
		size_t first, n;

		if (y0 + y < P->ylo || y0 + y >= P->yhi)
			continue;
		if (geo && geo->kind == GEOM_SIAF && sky != 0)
			geom_area_row(geo, y0 + y, 0, WFS_NPIX, area);
		else
			for (int x = 0; x < WFS_NPIX; x++)
				area[x] = 1;
		for (int tx = 0; tx < ntx; tx++) {
			int x0 = tx * T, nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;
			const double *r = tiles[tx] + (size_t)y * T;

			for (int x = 0; x < nx; x++)
				flu[x0 + x] = (r[x] + sky * area[x0 + x] + thermal) * d->exptime;
		}
		if (persist_add(P, sca, y0 + y, 0, WFS_NPIX, flu) < 0) {
			free(flu);
			return -1;
		}
		n = persist_row(P, sca, y0 + y, &first);
		for (size_t k = first; k < first + n; k++) {
			int x = (int)(l->pix[k] - (uint32_t)(y0 + y) * WFS_NPIX);
			double lag = P->t0 - l->tend[k];

			tiles[x / T][(size_t)y * T + x % T] +=
				persist_charge(c, l->scale[k], lag, lag + d->exptime) / d->exptime;
		}
	}
	free(flu);
	return 0;
}

int detector_strip_start(struct detector_run *r, const struct detector *d, struct pool *pool,
			 int sca, int y0, int ny, double *const *tiles, int ntx, int T,
			 void (*done)(void *, size_t), void *done_arg)
{
	*r = (struct detector_run){ .d = d, .pool = pool, .sca = sca, .y0 = y0, .ny = ny,
				    .T = T, .tiles = tiles, .done = done, .done_arg = done_arg };
	atomic_init(&r->failed, 0);
	if (!d->active && !done)
		return 0;
	if (d->active && d->persist && strip_persist(d, sca, y0, ny, tiles, ntx, T) < 0)
		return -1;
	pool_start(pool, detector_tile, r, ntx);
	r->started = 1;
	return 0;
}

int detector_strip_wait(struct detector_run *r)
{
	if (r->started)
		pool_wait(r->pool);
	r->started = 0;
	return atomic_load(&r->failed) ? -1 : 0;
}

void detector_level_setup(const struct detector *d, int sca, struct level_sca *L)
{
	const struct geom_sca *geo = d->sky ? &d->sky->sca[sca - 1].geo : NULL;

	L->background = d->bkg_sky[sca - 1] + d->bkg_pixel[sca - 1];
	L->geo = geo && geo->kind == GEOM_SIAF ? geo : NULL;
	L->bkg_sky = d->bkg_sky[sca - 1];
	L->key.poisson_normal = d->poisson_normal;
	L->persist = d->persist;
	L->correlated = !!(d->parts & DETECTOR_CORRELATED);
}
