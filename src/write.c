/*
 * write.c - writing an exposure: FITS header cards and the image, strip by
 * strip.
 *
 * After the last chunk is drawn, each SCA's image is written one strip of
 * tiles at a time: the strip's drawn light is summed for the report, the
 * detector stage (detector.c: background, exposure time, noise) runs on
 * its tiles in parallel, the tiles are converted to float32, checked for
 * values a float cannot hold, written through fitsout.c and freed.  So an exposure never
 * holds a second copy of its image.
 */
#include <math.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "background.h"
#include "date.h"
#include "clock.h"
#include "engine.h"
#include "err.h"
#include "fitsout.h"
#include "names.h"
#include "detector.h"
#include "levels.h"
#include "pool.h"

static int add_card(char **cards, int *n, int *cap, const char *card)
{
	if (*n == *cap) {
		char *more = realloc(*cards, (size_t)(*cap ? 2 * *cap : 64) * 80 + 1);

		if (!more)
			return -1;
		*cards = more;
		*cap = *cap ? 2 * *cap : 64;
	}
	memcpy(*cards + (size_t)*n * 80, card, 80);
	(*n)++;
	return 0;
}

static int primary_cards(struct engine *g, char **cards, int *n)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	char c[81], buf[64];
	int cap = 0, bad = 0;
	const char *epoch = getenv("SOURCE_DATE_EPOCH");
	time_t now = epoch && *epoch ? (time_t)strtoll(epoch, NULL, 10) : time(NULL);
	struct tm tm;

	*cards = NULL;
	*n = 0;
#define CARD(fn, k, v, com) (fn(c, k, v, com), bad |= add_card(cards, n, &cap, c))
	CARD(fits_card_str, "ORIGIN", "wfiscene", "Roman WFI scene simulator");
	CARD(fits_card_str, "WFSVERS", WFS_VERSION, "wfiscene version");
	gmtime_r(&now, &tm);
	strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%S", &tm);
	/* SOURCE_DATE_EPOCH pins the date, so two runs can give the same bytes */
	CARD(fits_card_str, "DATE", buf, "file creation date (UTC)");
	CARD(fits_card_str, "TELESCOP", "ROMAN", NULL);
	CARD(fits_card_str, "INSTRUME", "WFI", NULL);
	CARD(fits_card_str, "FILTER", g->filter_name, "optical element");
	CARD(fits_card_dbl, "EXPTIME", o->exptime, "exposure time (s)");
	CARD(fits_card_dbl, "RA_TARG", g->sky.ra0, "pointing RA (deg)");
	CARD(fits_card_dbl, "DEC_TARG", g->sky.dec0, "pointing Dec (deg)");
	CARD(fits_card_dbl, "PA_APER", g->sky.pa0, "position angle of reference +y (deg E of N)");
	CARD(fits_card_str, "POINTREF", x->boresight ? "BORESIGHT" : "WFI01",
	     "what RA_TARG/DEC_TARG point at");
	CARD(fits_card_str, "GEOMETRY", geom_name(o->geometry),
	     o->geometry == GEOM_STIPS ? "0.11\" square aligned SCAs, TAN" : "Roman SIAF, TAN-SIP");
	CARD(fits_card_int, "SEED", (long long)x->seed, "random seed");
	CARD(fits_card_str, "PSFSRC", o->psf, "PSF source");
	CARD(fits_card_str, "BUNIT", o->level == DETECTOR_L1 ? "DN" : o->bunit_counts ?
	     "counts" : "counts/s", NULL);
	if (o->level) {
		CARD(fits_card_str, "LEVEL", o->level == DETECTOR_L1 ? "1" : "2",
		     "detector level (--level)");
		CARD(fits_card_int, "MATABLE", o->ma_table, "MultiAccum table (--ma-table)");
	}
	CARD(fits_card_str, "BKGRND", o->background_arg ? o->background_arg : "none",
	     "background setting");
	/* Only what every SCA shares: a run split by SCA has the same primary. */
	if (o->bkg_model == BKG_AVG)
		CARD(fits_card_dbl, "BKGRATE", x->background,
		     "STIPS Table 1 (counts/s/px); per SCA in HDUs");
	else if (o->bkg_model != BKG_SKY)
		CARD(fits_card_dbl, "BKGRATE", x->background, "background (counts/s/pixel)");
	if (o->bkg_model == BKG_SKY)
		CARD(fits_card_str, "ZODINORM", background_norm_name(o->zodi_norm),
		     "zodiacal light scale (--zodi)");
	if (!isnan(x->date)) {
		char when[32];

		date_format(x->date, when, sizeof(when));
		CARD(fits_card_str, "DATE-OBS", when, "exposure date (UTC)");
		CARD(fits_card_dbl, "MJD-OBS", x->date, "exposure date (MJD, UTC)");
		CARD(fits_card_dbl, "SUNANGLE", x->bkg.sun_angle, "boresight to Sun (deg)");
	}
	snprintf(buf, sizeof(buf), "%s%s%s%s%s", o->noise & NOISE_POISSON ? "P" : "",
		 o->noise & NOISE_READ ? "R" : "", o->noise & NOISE_DARK ? "D" : "",
		 o->noise & NOISE_FLAT ? "F" : "", o->noise & NOISE_COSMIC ? "C" : "");
	CARD(fits_card_str, "NOISE", buf[0] ? buf : "NONE",
	     "P poisson R read D dark F flat C cosmic");
	if (o->noise & NOISE_READ)
		CARD(fits_card_dbl, "RDNOISE", o->readnoise, "read noise (e-)");
	CARD(fits_card_str, "ZPTABLE", o->zp_stips ? "STIPS" : "RTI-20240301",
	     "AB zeropoints used");
	CARD(fits_card_dbl, "BRIGHTLM", o->bright_limit, "bright ePSF box limit (AB)");
	CARD(fits_card_dbl, "XBRITELM", o->xbright_limit, "extra-bright box limit (AB)");
#undef CARD
	return bad ? -1 : 0;
}

static int image_cards(struct engine *g, int s, char **cards, int *n)
{
	const struct scene_opts *o = g->o;
	char c[81], name[16], *wcs = NULL;
	int nwcs = 0, cap = 0, bad = 0, sca = g->slot[s].sca;
	const struct bkg_part *bp = &g->x->bkg.sca[sca - 1];

	*cards = NULL;
	*n = 0;
	if (sky_header(&g->sky, sca, g->ylo, &wcs, &nwcs, g->e) < 0)
		return -1;
	snprintf(name, sizeof(name), "WFI%02d", sca);
#define CARD(fn, k, v, com) (fn(c, k, v, com), bad |= add_card(cards, n, &cap, c))
	CARD(fits_card_str, "EXTNAME", name, "detector");
	CARD(fits_card_str, "DETECTOR", name, NULL);
	CARD(fits_card_str, "FILTER", g->filter_name, NULL);
	CARD(fits_card_dbl, "EXPTIME", o->exptime, "exposure time (s)");
	CARD(fits_card_str, "BUNIT", o->bunit_counts ? "counts" : "counts/s", NULL);
	CARD(fits_card_dbl, "PHOTZPAB", place_zeropoint(g, sca), "AB mag of 1 count/s");
	CARD(fits_card_dbl, "PA_APER", g->sky.sca[sca - 1].pa, "position angle of +y (deg)");
	CARD(fits_card_dbl, "RA_APER", g->sky.sca[sca - 1].ra, "detector centre RA");
	CARD(fits_card_dbl, "DEC_APER", g->sky.sca[sca - 1].dec, "detector centre Dec");
	CARD(fits_card_dbl, "BKGRATE", bp->total, "background (counts/s/pixel)");
	if (o->bkg_model == BKG_AVG || o->bkg_model == BKG_SKY) {
		CARD(fits_card_dbl, "BKGZODI", bp->zodi, "of which zodiacal light");
		CARD(fits_card_dbl, "BKGTHERM", bp->thermal, "of which internal thermal");
	}
	CARD(fits_card_int, "NSOURCES", (long long)g->placed_on[sca - 1], "sources drawn on this SCA");
	if (o->row_first) {
		char rows[32];

		snprintf(rows, sizeof(rows), "%d-%d", o->row_first, o->row_last);
		CARD(fits_card_str, "ROWS", rows, "rows of the SCA in this part (--rows)");
	}
#undef CARD
	for (int k = 0; k < nwcs; k++)
		if (strncmp(wcs + 80 * k, "WCSAXES ", 8) && strncmp(wcs + 80 * k, "COMMENT", 7))
			bad |= add_card(cards, n, &cap, wcs + 80 * k);
	free(wcs);
	return bad ? err_sys(g->e, "header") : 0;
}

/* The first pixel of a[0 .. n-1] that is not a finite float, or -1. */
/* The first of a[0 .. n-1] that is infinite or NaN (its exponent bits all
 * ones), or -1: counted 1024 at a time in a loop the compiler vectorises,
 * then looked for one by one in the block that has one. */
typedef uint32_t u32_alias __attribute__((may_alias));

static ptrdiff_t first_nonfinite(const float *a, size_t n)
{
	const u32_alias *u = (const u32_alias *)a;

	for (size_t b = 0; b < n; b += 1024) {
		size_t e = n - b < 1024 ? n : b + 1024;
		unsigned bad = 0;

		for (size_t i = b; i < e; i++)
			bad += (u[i] & 0x7f800000u) == 0x7f800000u;
		for (size_t i = b; bad && i < e; i++)
			if (!isfinite(a[i]))
				return (ptrdiff_t)i;
	}
	return -1;
}

/* The sum of rows [y0, y1) of a tile of side T, nx pixels each: the
 * drawn light of --report.  Four running sums over the columns, added at
 * the end, so that the adds need not wait for one another. */
static double tile_sum(const double *t, int T, int y0, int y1, int nx)
{
	double s[4] = { 0, 0, 0, 0 };
	int x4 = nx & ~3;

	for (int y = y0; y < y1; y++) {
		const double *r = t + (size_t)y * T;

		for (int x = 0; x < x4; x += 4) {
			s[0] += r[x];
			s[1] += r[x + 1];
			s[2] += r[x + 2];
			s[3] += r[x + 3];
		}
		for (int x = x4; x < nx; x++)
			s[x & 3] += r[x];
	}
	return (s[0] + s[1]) + (s[2] + s[3]);
}

static int write_slot(struct engine *g, struct fitsout *f, int s, const struct detector *d,
		      float *strip)
{
	int T = g->tile;
	char *cards;
	int ncards;

	if (image_cards(g, s, &cards, &ncards) < 0)
		return -1;
	if (fitsout_image_begin(f, WFS_NPIX, g->yhi - g->ylo, cards, ncards, g->e) < 0) {
		free(cards);
		return -1;
	}
	free(cards);
	/* The strips of tiles that hold the rows written, [ylo, yhi): all of
	 * them but with --rows. */
	for (int ty = g->ylo / T; ty * T < g->yhi; ty++) {
		int y0 = ty * T, ny = y0 + T > WFS_NPIX ? WFS_NPIX - y0 : T;
		int ya = g->ylo > y0 ? g->ylo - y0 : 0;
		int yb = g->yhi < y0 + ny ? g->yhi - y0 : ny;
		double **row = &g->slot[s].tile[ty * g->ntx];
		double t0;

		for (int tx = 0; tx < g->ntx; tx++) {
			int nx = tx * T + T > WFS_NPIX ? WFS_NPIX - tx * T : T;

			if (row[tx])
				g->image_sum[g->slot[s].sca - 1] += tile_sum(row[tx], T, ya, yb, nx);
		}
		for (int tx = 0; tx < g->ntx; tx++)
			g->tiles_drawn += row[tx] != NULL;
		g->tiles += g->ntx;
		t0 = engine_clock();
		if (d->active) {
			for (int tx = 0; tx < g->ntx; tx++)
				if (!row[tx] && !(row[tx] = tile_alloc(T)))
					return err_sys(g->e, "tile memory");
			if (detector_strip(d, g->pool, g->slot[s].sca, y0, ny, row, g->ntx, T) < 0)
				return err_set(g->e, EXIT_SYSTEM, "noise stage failed");
		}
		g->t_noise += engine_clock() - t0;
		t0 = engine_clock();
		for (int y = ya; y < yb; y++)
			for (int tx = 0; tx < g->ntx; tx++) {
				int x0 = tx * T, nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;
				float *out = strip + (size_t)(y - ya) * WFS_NPIX + x0;

				if (row[tx])
					for (int x = 0; x < nx; x++)
						out[x] = (float)row[tx][(size_t)y * T + x];
				else
					memset(out, 0, nx * sizeof(float));
			}
		/* make_source bounds each source, but many sources on one
		 * pixel, or a model that draws more than its flux or NaN,
		 * could still put an infinity or NaN in the file. */
		{
			ptrdiff_t k = first_nonfinite(strip, (size_t)(yb - ya) * WFS_NPIX);
			int px = (int)(k % WFS_NPIX) + 1, py = y0 + ya + (int)(k / WFS_NPIX) + 1;

			if (k >= 0 && isnan(strip[k]))
				return err_set(g->e, EXIT_PLUGIN, "WFI%02d: pixel x=%d, y=%d "
					       "(1-based) is NaN: a source model drew a value "
					       "that is not a number", g->slot[s].sca, px, py);
			if (k >= 0)
				return err_set(g->e, EXIT_INPUT, "WFI%02d: pixel x=%d, y=%d "
					       "(1-based) is beyond the largest 32-bit float "
					       "(3.4e38): the sources there sum to more than "
					       "the image can hold", g->slot[s].sca, px, py);
		}
		if (fitsout_image_rows(f, strip, yb - ya, g->e) < 0)
			return -1;
		for (int tx = 0; tx < g->ntx; tx++) {
			tile_free(row[tx], T);
			row[tx] = NULL;
		}
		g->t_write += engine_clock() - t0;
		engine_progress(g, "writing", 0);
	}
	return fitsout_image_end(f, g->e);
}

/* The rendered rate of science row y of the slot, for levels.c. */
struct level_rows {
	struct engine *g;
	int s;
};

static int level_rate_row(void *arg, int y, double *out, struct err *e)
{
	struct level_rows *r = arg;
	struct engine *g = r->g;
	int T = g->tile, ty = y / T;
	double *const *row = &g->slot[r->s].tile[ty * g->ntx];

	(void)e;
	for (int tx = 0; tx < g->ntx; tx++) {
		int x0 = tx * T, nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;

		if (row[tx])
			memcpy(out + x0, row[tx] + (size_t)(y - ty * T) * T, nx * sizeof(double));
		else
			memset(out + x0, 0, nx * sizeof(double));
	}
	for (int x = 0; x < WFS_NPIX; x++)
		if (!isfinite(out[x]))
			return err_set(g->e, isnan(out[x]) ? EXIT_PLUGIN : EXIT_INPUT,
				       "WFI%02d: pixel x=%d, y=%d (1-based) is %s", g->slot[r->s].sca,
				       x + 1, y + 1, isnan(out[x]) ? "NaN: a source model drew a "
				       "value that is not a number" : "infinite");
	return 0;
}

/* Levels 1 and 2: the whole SCA through levels.c, which reads the rendered
 * tiles row by row (with a row on either side, for IPC), then the tiles go. */
static int write_slot_level(struct engine *g, struct fitsout *f, int s, const struct detector *d)
{
	const struct exposure *x = g->x;
	int sca = g->slot[s].sca, T = g->tile, rc;
	struct ramp_det det;
	struct level_rows rows = { g, s };
	struct level_sca L = {
		.level = d->level, .pat = &d->pattern, .det = &det,
		.key = { .seed = x->seed, .filter = g->o->filter, .sca = sca },
		.ylo = g->ylo, .yhi = g->yhi, .strip = T,
		.background = d->bkg_sky[sca - 1] + d->bkg_pixel[sca - 1],
		.rate_row = level_rate_row, .arg = &rows, .pool = g->pool,
	};
	char *cards;
	int ncards;

	if (ramp_det_get(sca, &det, g->e) < 0)
		return -1;
	detector_level_setup(d, sca, &L);
	/* the knobs of the approximations (wfiscene(1), DETECTOR LEVELS) */
	{
		static const char *const keys[2] = { "ramp-split-exact", "ramp-jump-threshold" };

		for (int k = 0; k < 2; k++) {
			const char *v = host_setting(g, keys[k]);
			char *end;
			double val;

			if (!v)
				continue;
			val = strtod(v, &end);
			if (end == v || *end || !isfinite(val) || val < (k ? 0.5 : 0) || val > 1e9)
				return err_set(g->e, EXIT_INPUT, "--set %s=%s: expected a number "
					       "from %g to 1e9", keys[k], v, k ? 0.5 : 0.0);
			if (k)
				det.jump_threshold = val;
			else
				L.key.split_exact_max = val > 0 ? val : -1;
		}
	}
	if (image_cards(g, s, &cards, &ncards) < 0)
		return -1;
	L.cards = cards;
	L.ncards = ncards;
	for (int k = 0; k < g->ntx * g->nty; k++) {
		double *t = g->slot[s].tile[k];
		int tx = k % g->ntx, ty = k / g->ntx;
		int nx = tx * T + T > WFS_NPIX ? WFS_NPIX - tx * T : T;
		int ny = ty * T + T > WFS_NPIX ? WFS_NPIX - ty * T : T;

		int ya = g->ylo > ty * T ? g->ylo - ty * T : 0;
		int yb = g->yhi < ty * T + ny ? g->yhi - ty * T : ny;

		g->tiles_drawn += t != NULL;
		if (t && ya < yb)
			g->image_sum[sca - 1] += tile_sum(t, T, ya, yb, nx);
	}
	g->tiles += g->ntx * g->nty;
	rc = level_write_sca(&L, f, g->e);
	free(cards);
	g->t_noise += L.t_ramp;
	g->t_write += L.t_write;
	for (int k = 0; k < g->ntx * g->nty; k++) {
		tile_free(g->slot[s].tile[k], T);
		g->slot[s].tile[k] = NULL;
	}
	return rc;
}

int write_exposure(struct engine *g)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	struct detector d;
	int per_sca = (name_fields(x->output) & NAME_SCA) != 0;
	float *strip = malloc((size_t)g->tile * WFS_NPIX * sizeof(float));
	struct fitsout *f = NULL;
	char *cards = NULL;
	int ncards;

	if (!strip)
		return err_sys(g->e, "output buffer");
	if (detector_init(&d, o, x, g->e) < 0)
		goto fail;
	d.sky = &g->sky;
	if (primary_cards(g, &cards, &ncards) < 0) {
		err_sys(g->e, "header");
		goto fail;
	}
	for (int s = 0; s < g->nslot; s++) {
		if (!f || per_sca) {
			char path[PATH_MAX];

			if (name_expand(path, sizeof(path), "-o", x->output, g->slot[s].sca,
					x->name[0] ? x->name : NULL, g->e) < 0 ||
			    !(f = fitsout_open(path, o->compress, g->e)) ||
			    fitsout_primary(f, cards, ncards, g->e) < 0)
				goto fail;
		}
		if ((d.level == DETECTOR_SCENE ? write_slot(g, f, s, &d, strip) :
		     write_slot_level(g, f, s, &d)) < 0)
			goto fail;
		if (per_sca || s == g->nslot - 1) {
			struct fitsout *done = f;

			f = NULL;
			if (fitsout_commit(done, g->e) < 0)
				goto fail;
		}
	}
	free(cards);
	free(strip);
	return 0;
fail:
	fitsout_abort(f);
	free(cards);
	free(strip);
	return -1;
}

