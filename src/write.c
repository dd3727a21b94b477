/*
 * write.c - an exposure's products, made once and handed to a writer
 * (product.h: write_fits.c or write_asdf.c).
 *
 * After the last chunk is drawn, each SCA's image is made one strip of
 * tiles at a time: the strip's drawn light is summed for the report, the
 * detector stage (detector.c: background, exposure time, noise) runs on
 * its tiles in parallel, the tiles are converted to float32, checked for
 * values a float cannot hold, given to the writer and freed.  So an
 * exposure never holds a second copy of its image.  At levels 1 and 2 the
 * SCA goes through levels.c, which hands the writer its strips.
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
#include "names.h"
#include "detector.h"
#include "levels.h"
#include "pool.h"
#include "product.h"
#include "simd.h"

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

/* Row r's nx values added to the four running sums s[x & 3] in column
 * order (tile_sum's order), and with out converted to float into it;
 * returns whether a float came out infinite or NaN.  The AVX2 loop keeps
 * s[k] in lane k, so both give the same bits. */
static int row_fold_c(const double *r, float *out, int nx, double *s)
{
	int bad = 0;

	for (int x = 0; x < nx; x++) {
		if (out) {
			out[x] = (float)r[x];
			bad |= !isfinite(out[x]);
		}
		s[x & 3] += r[x];
	}
	return bad;
}

#ifdef SIMD_X86
__attribute__((target("avx2"))) static int row_fold_avx2(const double *r, float *out, int nx,
							 double *s)
{
	__m256d acc = _mm256_loadu_pd(s);
	__m128i em = _mm_set1_epi32(0x7f800000), bad = _mm_setzero_si128();
	int x = 0;

	if (out)
		for (; x + 4 <= nx; x += 4) {
			__m256d v = _mm256_loadu_pd(r + x);
			__m128 f = _mm256_cvtpd_ps(v);

			acc = _mm256_add_pd(acc, v);
			_mm_storeu_ps(out + x, f);
			bad = _mm_or_si128(bad, _mm_cmpeq_epi32(
							_mm_and_si128(_mm_castps_si128(f), em), em));
		}
	else
		for (; x + 4 <= nx; x += 4)
			acc = _mm256_add_pd(acc, _mm256_loadu_pd(r + x));
	_mm256_storeu_pd(s, acc);
	return row_fold_c(r + x, out ? out + x : NULL, nx - x, s) |
	       !_mm_testz_si128(bad, bad);
}
#endif

static int row_fold(const double *r, float *out, int nx, double *s)
{
#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX2)
		return row_fold_avx2(r, out, nx, s);
#endif
	return row_fold_c(r, out, nx, s);
}

/* The sum of rows [y0, y1) of a tile of side T, nx pixels each: the
 * drawn light of --report.  Four running sums over the columns, added at
 * the end, so that the adds need not wait for one another. */
static double tile_sum(const double *t, int T, int y0, int y1, int nx)
{
	double s[4] = { 0, 0, 0, 0 };

	for (int y = y0; y < y1; y++)
		row_fold(t + (size_t)y * T, NULL, nx, s);
	return (s[0] + s[1]) + (s[2] + s[3]);
}

/* A strip's float32 rows, made on the pool beside the detector stage:
 * rows [ya, yb) of strip ty of tiles (WFS_NPIX floats a row), and for
 * each tile the index in out of its first value a float cannot hold, in
 * row order (-1: none); with sums set (no detector stage: the tiles are
 * as drawn), each drawn tile's tile_sum() too, for the report. */
struct strip_f32 {
	int T, ya, yb;
	double *const *row;
	float *out;
	ptrdiff_t *bad;
	double *sum;
	int sums;               /* whether the pool sums (else the main thread) */
};

/* Tile tx of the strip into its columns of out (zeros for a tile never
 * drawn on), and its bad[tx]. */
static void strip_convert(void *arg, size_t tx)
{
	struct strip_f32 *c = arg;
	int T = c->T, x0 = (int)tx * T, nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;
	const double *t = c->row[tx];
	double s[4] = { 0, 0, 0, 0 };

	c->bad[tx] = -1;
	for (int y = c->ya; y < c->yb; y++) {
		float *out = c->out + (size_t)(y - c->ya) * WFS_NPIX + x0;
		ptrdiff_t k;

		if (!t) {
			memset(out, 0, nx * sizeof(float));
			continue;
		}
		/* converted, checked and (for the report) summed in one pass */
		if (row_fold(t + (size_t)y * T, out, nx, s) && c->bad[tx] < 0 &&
		    (k = first_nonfinite(out, nx)) >= 0)
			c->bad[tx] = (out - c->out) + k;
	}
	if (c->sums)
		c->sum[tx] = (s[0] + s[1]) + (s[2] + s[3]);
}

/* The strip of tiles ty of slot s: its drawn light for the report, its
 * missing tiles allocated when the detector stage will fill them, and the
 * stage started on them in run (the pool must be idle), with the rows
 * written made into c.  Returns 0, or -1 with the error in g->e (and
 * nothing started). */
static int strip_start(struct engine *g, int s, int ty, const struct detector *d,
		       struct detector_run *run, struct strip_f32 *c)
{
	int T = g->tile, y0 = ty * T, ny = y0 + T > WFS_NPIX ? WFS_NPIX - y0 : T;
	int ya = g->ylo > y0 ? g->ylo - y0 : 0, yb = g->yhi < y0 + ny ? g->yhi - y0 : ny;
	double **row = &g->slot[s].tile[ty * g->ntx];

	/* the drawn light: here before a detector stage changes the tiles,
	 * else by the pool beside the conversion (strip_write adds it up in
	 * the same order), so that the pool need not wait for it */
	for (int tx = 0; tx < g->ntx; tx++) {
		int nx = tx * T + T > WFS_NPIX ? WFS_NPIX - tx * T : T;

		if (row[tx] && d->active)
			g->image_sum[g->slot[s].sca - 1] += tile_sum(row[tx], T, ya, yb, nx);
		g->tiles_drawn += row[tx] != NULL;
	}
	g->tiles += g->ntx;
	for (int tx = 0; d->active && tx < g->ntx; tx++)
		if (!row[tx] && !(row[tx] = tile_alloc(T)))
			return err_sys(g->e, "tile memory");
	c->T = T;
	c->ya = ya;
	c->yb = yb;
	c->row = row;
	c->sums = !d->active;
	if (detector_strip_start(run, d, g->pool, g->slot[s].sca, y0, ny, row, g->ntx, T,
				 strip_convert, c) < 0)
		return err_set(g->e, EXIT_SYSTEM, "noise stage failed");
	return 0;
}

/* Strip ty's rows in float32 (c, made by the pool), checked and written;
 * its tiles freed. */
static int strip_write(struct engine *g, struct writer *w, int s, int ty,
		       const struct strip_f32 *c)
{
	int y0 = ty * g->tile;
	double **row = &g->slot[s].tile[ty * g->ntx];
	ptrdiff_t k = -1;

	/* the drawn light the pool summed, in the order strip_start would */
	for (int tx = 0; c->sums && tx < g->ntx; tx++)
		if (row[tx])
			g->image_sum[g->slot[s].sca - 1] += c->sum[tx];
	/* make_source bounds each source, but many sources on one pixel, or
	 * a model that draws more than its flux or NaN, could still put an
	 * infinity or NaN in the file: the first in row order */
	for (int tx = 0; tx < g->ntx; tx++)
		if (c->bad[tx] >= 0 && (k < 0 || c->bad[tx] < k))
			k = c->bad[tx];
	if (k >= 0) {
		int px = (int)(k % WFS_NPIX) + 1, py = y0 + c->ya + (int)(k / WFS_NPIX) + 1;

		if (isnan(c->out[k]))
			return err_set(g->e, EXIT_PLUGIN, "WFI%02d: pixel x=%d, y=%d (1-based) "
				       "is NaN: a source model drew a value that is not a "
				       "number", g->slot[s].sca, px, py);
		return err_set(g->e, EXIT_INPUT, "WFI%02d: pixel x=%d, y=%d (1-based) is "
			       "beyond the largest 32-bit float (3.4e38): the sources "
			       "there sum to more than the image can hold",
			       g->slot[s].sca, px, py);
	}
	if (w->ops->rows(w, c->out, c->yb - c->ya, g->e) < 0)
		return -1;
	for (int tx = 0; tx < g->ntx; tx++) {
		tile_free(row[tx], g->tile);
		row[tx] = NULL;
	}
	return 0;
}

/*
 * The strips of tiles that hold the rows written, [ylo, yhi) (all of them
 * but with --rows), in a pipeline: while the main thread writes strip ty,
 * the pool runs the detector stage on strip ty + 1 and converts it to
 * float32, into the other of conv[2], so that neither waits for the other
 * (the write was a fifth of an empty focal plane's wall time with the
 * workers idle; then, the conversion on the main thread, half of the
 * writing's time at the end of 10^7 sky rows on 18 SCAs).  --report's
 * noise is the main thread's time opening strips, starting the stage and
 * waiting for it, its write the time writing (and, without a stage,
 * waiting for the conversion).  The bytes are those of any order: a
 * strip's stage depends on its pixels only.
 */
static int write_slot(struct engine *g, struct writer *w, int s, const struct detector *d,
		      struct strip_f32 conv[2])
{
	int T = g->tile, ty0 = g->ylo / T, ty1 = (g->yhi + T - 1) / T;
	struct product p = { .g = g, .slot = s, .sca = g->slot[s].sca, .level = DETECTOR_SCENE,
			     .ylo = g->ylo, .yhi = g->yhi };
	struct detector_run run[2];
	/* the main thread's waits: the stage's, or without one the conversion's */
	double *waits = d->active ? &g->t_noise : &g->t_write;
	double t0;

	if (w->ops->sca_begin(w, &p, g->e) < 0)
		return -1;
	t0 = engine_clock();
	if (ty0 < ty1 && strip_start(g, s, ty0, d, &run[ty0 & 1], &conv[ty0 & 1]) < 0)
		return -1;
	for (int ty = ty0; ty < ty1; ty++) {
		struct detector_run *next = &run[(ty + 1) & 1];
		int failed;

		if (detector_strip_wait(&run[ty & 1]) < 0) {
			*waits += engine_clock() - t0;
			return err_set(g->e, EXIT_SYSTEM, "noise stage failed");
		}
		if (ty + 1 < ty1 && strip_start(g, s, ty + 1, d, next, &conv[(ty + 1) & 1]) < 0)
			return -1;
		*waits += engine_clock() - t0;
		t0 = engine_clock();
		failed = strip_write(g, w, s, ty, &conv[ty & 1]);
		g->t_write += engine_clock() - t0;
		t0 = engine_clock();
		if (failed < 0) {
			if (ty + 1 < ty1)
				detector_strip_wait(next);
			return -1;
		}
		engine_progress(g, "writing", 0);
	}
	*waits += engine_clock() - t0;
	return w->ops->sca_end(w, g->e);
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

static int level_put(void *arg, const struct level_strip *s, struct err *e)
{
	struct writer *w = arg;

	return w->ops->strip(w, s, e);
}

/* Levels 1 and 2: the whole SCA through levels.c, which reads the rendered
 * tiles row by row (with a row on either side, for IPC), then the tiles go. */
static int write_slot_level(struct engine *g, struct writer *w, int s, const struct detector *d)
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
		.put = level_put, .put_arg = w, .keep_l1 = w->ops->l1_at_l2,
		.ramp_stats = w->ops->ramp_stats,
	};
	struct product p = { .g = g, .slot = s, .sca = sca, .level = d->level,
			     .ylo = g->ylo, .yhi = g->yhi, .pat = &d->pattern, .det = &det };

	if (ramp_det_get(sca, &det, g->e) < 0)
		return -1;
	detector_level_setup(d, sca, &L);
	p.correlated = L.correlated;
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
	if (w->ops->sca_begin(w, &p, g->e) < 0)
		return -1;
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
	rc = level_write_sca(&L, g->e);
	if (rc == 0)
		rc = w->ops->sca_end(w, g->e);
	g->t_noise += L.t_ramp;
	g->t_write += L.t_write;
	for (int k = 0; k < g->ntx * g->nty; k++) {
		tile_free(g->slot[s].tile[k], T);
		g->slot[s].tile[k] = NULL;
	}
	return rc;
}

int product_format_of(const char *path)
{
	size_t n = strlen(path);

	return n >= 5 && !strcmp(path + n - 5, ".asdf") ? FORMAT_ASDF : FORMAT_FITS;
}

/*
 * The SCAs of this pass (all of them but with SCA groups, run.c), each
 * through the detector stage to its writer.  A file that holds several
 * SCAs is opened by the pass that writes its first and committed by the
 * one that writes its last, the SCAs in order (g->out keeps it between
 * passes); persistence begins with the exposure's first pass only, and
 * ends (run.c) after its last.
 */
int write_exposure(struct engine *g)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	const struct writer_ops *ops = o->format == FORMAT_ASDF ? &writer_asdf : &writer_fits;
	struct exposure later = *x;
	struct detector d;
	int per_sca = (name_fields(x->output) & NAME_SCA) != 0;
	float *strip = malloc(2 * (size_t)g->tile * WFS_NPIX * sizeof(float));
	struct writer *w = g->out;
	ptrdiff_t *bad = malloc(2 * (size_t)g->ntx * sizeof(ptrdiff_t));
	double *sum = malloc(2 * (size_t)g->ntx * sizeof(double));
	struct strip_f32 conv[2] = { { .out = strip, .bad = bad, .sum = sum }, { 0 } };

	g->out = NULL;
	later.persist = NULL;
	if (!strip || !bad || !sum) {
		err_sys(g->e, "output buffer");
		goto fail;
	}
	conv[1].out = strip + (size_t)g->tile * WFS_NPIX;
	conv[1].bad = bad + g->ntx;
	conv[1].sum = sum + g->ntx;
	if (detector_init(&d, o, g->pass ? &later : x, g->e) < 0)
		goto fail;
	if (g->pass && x->persist) {
		/* begun by the first pass: its state, as detector_init gives */
		d.persist = x->persist;
		d.active = 1;
	}
	d.sky = &g->sky;
	if (ops->one_sca_per_file && !per_sca && g->nslot > 1) {
		err_set(g->e, EXIT_INPUT, "-o %s: an %s file holds one SCA; put %%d in the name "
			"for one file per SCA (-o %s_WFI%%02d.asdf)", x->output, ops->name, "NAME");
		goto fail;
	}
	for (int s = 0; s < g->nslot; s++) {
		char path[PATH_MAX];

		if (!(g->pass_slots >> s & 1))
			continue;
		if (!w || per_sca) {
			if (name_expand(path, sizeof(path), "-o", x->output, g->slot[s].sca,
					x->name[0] ? x->name : NULL, g->e) < 0 ||
			    !(w = ops->open(g, path, g->e)))
				goto fail;
		}
		if ((d.level == DETECTOR_SCENE ? write_slot(g, w, s, &d, conv) :
		     write_slot_level(g, w, s, &d)) < 0)
			goto fail;
		if (per_sca || s == g->nslot - 1) {
			struct writer *done = w;

			w = NULL;
			if (ops->commit(done, g->e) < 0)
				goto fail;
			/* a file an SCA group wrote before the last: removed
			 * if a later pass fails (run.c), as one pass leaves
			 * none then */
			if (g->pass + 1 < g->npass && g->nwritten < WFS_NSCA) {
				if (!(g->written[g->nwritten] = strdup(path))) {
					err_sys(g->e, "memory");
					goto fail;
				}
				g->nwritten++;
			}
		}
	}
	g->out = w;
	free(strip);
	free(bad);
	free(sum);
	return 0;
fail:
	if (w)
		w->ops->abort(w);
	free(strip);
	free(bad);
	free(sum);
	return -1;
}
