/* levels.c - an SCA at detector level 1 or 2, strip by strip; see levels.h. */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "levels.h"
#include "persist.h"
#include "pool.h"
#include "product.h"
#include "ramp_stats.h"
#include "readnoise.h"

#define FRAME 4096              /* the array with its reference border */
#define BORDER 4
/* Rows a worker takes at once: it draws their charge and that of the row
 * either side one row ahead of IPC and the fits, keeping three rows of
 * charge (12 bytes a pixel and resultant each, 1.3 MB at MA table 4) in
 * its cache; the two margin rows' charge is drawn again by the bands
 * beside (2 / BAND of the charge's time) */
#define BAND 64

int level_parse(const char *s, int *level, struct err *e)
{
	if (!strcmp(s, "scene"))
		*level = LEVEL_SCENE;
	else if (!strcmp(s, "1") || !strcmp(s, "l1"))
		*level = LEVEL_1;
	else if (!strcmp(s, "2") || !strcmp(s, "l2"))
		*level = LEVEL_2;
	else
		return err_set(e, EXIT_INPUT, "--level: expected scene, 1 or 2, not '%s'", s);
	return 0;
}

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* The state of one strip, shared by its row tasks. */
struct strip {
	struct level_sca *L;
	struct ramp_fit_plan *fp;
	const struct rnoise *rn;        /* NULL: white read noise only */
	const struct rnoise_ref *ref;   /* level 2 with rn */
	double read_noise;      /* e- a read as simulated (corrected): DQ PERSISTENCE's unit */
	int fy0, ny;            /* frame rows [fy0, fy0 + ny) */
	const double *const *light;     /* science row sy at light[sy - sy0 + 1] */
	int sy0;
	/* per worker: the collected charge and the pixels' own part of
	 * three science rows (ring[wid] and oring[wid], a row's resultants
	 * WFS_NPIX apart, rows nres WFS_NPIX apart) */
	double **ring;
	float **oring;
	double **scr;
	uint16_t **dnrow;
	double **sscr;          /* ramp_stats_row's, with L->ramp_stats */
	/* out */
	uint16_t *l1;           /* [nres][ny][FRAME] */
	float *rt, *er, *vp, *vr;       /* [ny][WFS_NPIX] */
	uint32_t *dq;
	float *chisq, *dumo;            /* with L->ramp_stats */
};

/* The charge of science row sy (the strip's, or the one either side,
 * whose charge IPC shares with the strip's edge rows) into ch and own.  A
 * margin row draws the same keyed numbers as when it is the row of a
 * band, so the seams leave no trace. */
static void strip_charge(struct strip *s, int wid, int sy, double *ch, float *own)
{
	struct level_sca *L = s->L;
	struct ramp_glow glow = { 0 };

	if (L->persist) {
		const struct persist *P = L->persist;
		const struct persist_list *l = &P->now[L->key.sca - 1];
		size_t first;

		glow.n = (int)persist_row(P, L->key.sca, sy, &first);
		glow.pix = l->pix + first;
		glow.base = (uint32_t)sy * WFS_NPIX;
		glow.scale = l->scale + first;
		glow.tend = l->tend + first;
		glow.t0 = P->t0;
		glow.curve = &P->curve[L->key.sca - 1];
	}
	ramp_level1_charge_glow(L->pat, L->det, &L->key,
				(uint32_t)(sy + BORDER) * FRAME + BORDER, WFS_NPIX,
				s->light[sy - s->sy0 + 1], &glow, ch, own, WFS_NPIX, s->scr[wid]);
	if (s->rn) {
		for (int r = 0; r < L->pat->nres; r++)
			rnoise_add_frame(s->rn, r, sy + BORDER, BORDER, WFS_NPIX,
					 own + (size_t)r * WFS_NPIX);
		rnoise_slow_add(s->rn, (uint32_t)(sy + BORDER) * FRAME + BORDER, WFS_NPIX, 0,
				L->pat->nres, own, WFS_NPIX);
	}
}

/* DQ PERSISTENCE on science row sy's pixels (dq[0 .. 4088)) whose
 * afterglow over the exposure reaches the flag's fraction of the read
 * noise of one read, read_noise (as simulated: with the correlated read
 * noise that of a reference-corrected read, which the fit assumes). */
static void strip_persist_dq(const struct level_sca *L, double read_noise, int sy, uint32_t *dq)
{
	const struct persist *P = L->persist;
	const struct persist_list *l = &P->now[L->key.sca - 1];
	const struct persist_curve *c = &P->curve[L->key.sca - 1];
	double limit = P->flag * read_noise, T = L->pat->exptime;
	size_t first, n = persist_row(P, L->key.sca, sy, &first);

	for (size_t k = first; k < first + n; k++) {
		double lag = P->t0 - l->tend[k];

		if (persist_charge(c, l->scale[k], lag, lag + T) >= limit)
			dq[l->pix[k] - (uint32_t)sy * WFS_NPIX] |= PERSIST_DQ;
	}
}

/* Frame row task of the strip: its resultants, IPC acting on the charge
 * ch[0 .. 2] of the science rows below, at and above (NULL off the
 * array) and its own part own, then its ramp fit at level 2. */
static void strip_row(struct strip *s, int wid, size_t task, const double *const ch[3],
		      const float *own)
{
	struct level_sca *L = s->L;
	const struct ramp_pattern *p = L->pat;
	int fy = s->fy0 + (int)task, sy = fy - BORDER;
	int light = sy >= 0 && sy < WFS_NPIX;
	double *scr = s->scr[wid];
	uint32_t cell0 = (uint32_t)fy * FRAME;
	uint16_t *out;
	size_t plane;

	if (s->l1) {
		plane = (size_t)s->ny * FRAME;
		out = s->l1 + task * FRAME;
	} else {
		plane = FRAME;
		out = s->dnrow[wid];
	}
	/* the reference columns, the science columns, the reference columns */
	ramp_level1_row(p, L->det, &L->key, cell0, BORDER, NULL, 0, out, plane, scr);
	if (light) {
		ramp_level1_finish(L->det, p->nres, WFS_NPIX, ch[0], ch[1], ch[2], own, WFS_NPIX,
				   out + BORDER, plane);
	} else {
		ramp_level1_row(p, L->det, &L->key, cell0 + BORDER, WFS_NPIX, NULL, 0,
				out + BORDER, plane, scr);
	}
	ramp_level1_row(p, L->det, &L->key, cell0 + BORDER + WFS_NPIX, BORDER, NULL, 0,
			out + BORDER + WFS_NPIX, plane, scr);
	if (s->rn && light) {
		rnoise_add_dn(s->rn, L->det->gain, fy, 0, BORDER, out, plane);
		rnoise_add_dn(s->rn, L->det->gain, fy, BORDER + WFS_NPIX, BORDER,
			      out + BORDER + WFS_NPIX, plane);
	} else if (s->rn) {
		rnoise_add_dn(s->rn, L->det->gain, fy, 0, FRAME, out, plane);
	}
	if (L->level == LEVEL_2) {
		struct ramp_fit fit[256];

		/* the reference correction before the fit, on a copy where
		 * the level-1 resultants are kept (written as they are) */
		if (s->ref && s->l1) {
			uint16_t *cp = s->dnrow[wid];

			for (int r = 0; r < p->nres; r++)
				memcpy(cp + (size_t)r * FRAME, out + (size_t)r * plane,
				       FRAME * sizeof(uint16_t));
			out = cp;
			plane = FRAME;
		}
		if (s->ref)
			rnoise_ref_apply(s->ref, fy, out + BORDER, plane, p->nres);

		for (int x0 = 0; x0 < WFS_NPIX; x0 += 256) {
			int m = WFS_NPIX - x0 < 256 ? WFS_NPIX - x0 : 256;
			size_t o = task * WFS_NPIX + (size_t)x0;

			ramp_fit_row(s->fp, out + BORDER + x0, plane, m, fit);
			for (int x = 0; x < m; x++) {
				const struct ramp_fit *f = &fit[x];
				int dnu = !!(f->dq & RAMP_DO_NOT_USE);

				/* the pipeline's dark step: the mean dark
				 * current out */
				s->rt[o + x] = dnu ? 0 : (float)(f->rate - L->det->dark);
				s->er[o + x] = (float)sqrt(f->var_poisson + f->var_rnoise);
				s->vp[o + x] = (float)f->var_poisson;
				s->vr[o + x] = (float)f->var_rnoise;
				s->dq[o + x] = f->dq;
			}
			if (s->chisq)
				ramp_stats_row(s->fp, out + BORDER + x0, plane, fit, m,
					       s->sscr[wid], s->chisq + o, s->dumo + o);
		}
		if (L->persist && light)
			strip_persist_dq(L, s->read_noise, sy, s->dq + task * WFS_NPIX);
	}
}

/*
 * Band b of the strip: its frame rows BAND b .. in order, each row's
 * charge drawn into the worker's ring of three rows just before the row
 * that needs it last, so IPC reads it from the cache (two passes over a
 * whole strip, the charge of all its rows held between them, went to
 * memory and back: 19 MB a 64 rows at MA table 4).
 */
static void strip_band(void *arg, int wid, size_t b)
{
	struct strip *s = arg;
	size_t rowlen = (size_t)s->L->pat->nres * WFS_NPIX;
	int t0 = (int)b * BAND, t1 = t0 + BAND < s->ny ? t0 + BAND : s->ny;
	int have[3] = { -2, -2, -2 };   /* the science row in each slot */

	for (int t = t0; t < t1; t++) {
		int sy = s->fy0 + t - BORDER;
		const double *ch[3] = { NULL, NULL, NULL };
		const float *own = NULL;

		if (sy >= 0 && sy < WFS_NPIX) {
			for (int k = 0; k < 3; k++) {
				int ry = sy - 1 + k, slot = (ry + 3) % 3;
				double *c = s->ring[wid] + (size_t)slot * rowlen;
				float *o = s->oring[wid] + (size_t)slot * rowlen;

				if (ry < 0 || ry >= WFS_NPIX)
					continue;
				if (have[slot] != ry) {
					strip_charge(s, wid, ry, c, o);
					have[slot] = ry;
				}
				ch[k] = c;
				if (k == 1)
					own = o;
			}
		}
		strip_row(s, wid, (size_t)t, ch, own);
	}
}

/* Hand computed strip s to the writer. */
static int strip_write(const struct level_sca *L, const struct strip *s, struct err *e)
{
	struct level_strip out = { .fy0 = s->fy0, .ny = s->ny, .l1 = s->l1, .rn = s->rn };

	if (L->level == LEVEL_2) {
		/* science rows only: the reference rows have no fit */
		int a = s->fy0 < BORDER ? BORDER - s->fy0 : 0;
		int b = s->fy0 + s->ny > BORDER + WFS_NPIX ? BORDER + WFS_NPIX - s->fy0 : s->ny;
		size_t o = (size_t)a * WFS_NPIX;

		out.sy0 = s->fy0 + a - BORDER;
		out.nsy = b > a ? b - a : 0;
		out.rate = s->rt + o;
		out.err = s->er + o;
		out.dq = s->dq + o;
		out.var_poisson = s->vp + o;
		out.var_rnoise = s->vr + o;
		out.chisq = s->chisq ? s->chisq + o : NULL;
		out.dumo = s->dumo ? s->dumo + o : NULL;
	}
	return L->put(L->put_arg, &out, e);
}

/* The buffers of one SCA's pass, shared by its strips. */
struct sca_pass {
	struct ramp_fit_plan fp;        /* level 2 */
	/* two strips: the workers compute one while this thread writes the
	 * other, so that writing hides behind the ramp (or the ramp behind
	 * the writing); the per-worker scratch is shared, as only one strip
	 * is computed at a time */
	struct strip st[2];
	int nthr;
	int S;                  /* frame rows a strip */
	double *lightbuf, *pixarea, *fluence;
	const double **light;
	/* the correlated read noise and its correction (L->correlated) */
	struct rnoise rn;
	struct rnoise_ref ref;
	struct ramp_det det;    /* L's constants with the white read noise */
};

/* Allocate the buffers of w (zeroed by the caller, fp set up at level 2)
 * for L.  0 or -1 out of memory; sca_pass_free() frees what was. */
static int sca_pass_alloc(struct sca_pass *w, struct level_sca *L)
{
	const struct ramp_pattern *p = L->pat;
	size_t rowlen = (size_t)p->nres * WFS_NPIX, area;
	int S = L->strip > 0 ? L->strip : 64, nthr = pool_threads(L->pool);
	struct strip *st = w->st;

	w->nthr = nthr;
	w->S = S;
	area = (size_t)S * WFS_NPIX;
	st[0].scr = calloc((size_t)nthr, sizeof(*st[0].scr));
	st[0].dnrow = calloc((size_t)nthr, sizeof(*st[0].dnrow));
	w->lightbuf = malloc((size_t)(S + 2) * WFS_NPIX * sizeof(double));
	w->light = calloc((size_t)S + 2, sizeof(*w->light));
	w->pixarea = malloc(WFS_NPIX * sizeof(double));
	w->fluence = malloc(WFS_NPIX * sizeof(double));
	st[0].ring = calloc((size_t)nthr, sizeof(*st[0].ring));
	st[0].oring = calloc((size_t)nthr, sizeof(*st[0].oring));
	if (!st[0].scr || !st[0].dnrow || !w->lightbuf || !w->light || !w->pixarea ||
	    !st[0].ring || !st[0].oring || !w->fluence)
		return -1;
	for (int i = 0; i < nthr; i++)
		if (!(st[0].scr[i] = malloc(RAMP_SCRATCH(FRAME) * sizeof(double))) ||
		    !(st[0].dnrow[i] = malloc((size_t)p->nres * FRAME * sizeof(uint16_t))) ||
		    !(st[0].ring[i] = malloc(3 * rowlen * sizeof(double))) ||
		    !(st[0].oring[i] = malloc(3 * rowlen * sizeof(float))))
			return -1;
		else
			ramp_scratch_init(st[0].scr[i]);
	if (L->level == LEVEL_2 && L->ramp_stats) {
		if (!(st[0].sscr = calloc((size_t)nthr, sizeof(*st[0].sscr))))
			return -1;
		for (int i = 0; i < nthr; i++)
			if (!(st[0].sscr[i] = malloc(RAMP_STATS_SCRATCH(256) * sizeof(double))))
				return -1;
	}
	st[1].scr = st[0].scr;
	st[1].ring = st[0].ring;
	st[1].oring = st[0].oring;
	st[1].dnrow = st[0].dnrow;
	st[1].sscr = st[0].sscr;
	for (int b = 0; b < 2; b++) {
		struct strip *s = &st[b];

		s->L = L;
		s->fp = &w->fp;
		s->light = w->light;
		s->rn = L->correlated ? &w->rn : NULL;
		s->ref = L->correlated && L->level == LEVEL_2 ? &w->ref : NULL;
		if ((L->level == LEVEL_1 || L->keep_l1) &&
		    !(s->l1 = malloc((size_t)p->nres * S * FRAME * sizeof(uint16_t))))
			return -1;
		if (L->level == LEVEL_2 && (!(s->rt = malloc(area * sizeof(float))) ||
			   !(s->er = malloc(area * sizeof(float))) ||
			   !(s->vp = malloc(area * sizeof(float))) ||
			   !(s->vr = malloc(area * sizeof(float))) ||
			   !(s->dq = malloc(area * sizeof(uint32_t)))))
			return -1;
		if (L->level == LEVEL_2 && L->ramp_stats &&
		    (!(s->chisq = malloc(area * sizeof(float))) ||
		     !(s->dumo = malloc(area * sizeof(float)))))
			return -1;
	}
	return 0;
}

static void sca_pass_free(struct sca_pass *w)
{
	struct strip *st = w->st;

	for (int i = 0; st[0].scr && i < w->nthr; i++) {
		free(st[0].scr[i]);
		free(st[0].dnrow[i]);
		if (st[0].ring)
			free(st[0].ring[i]);
		if (st[0].oring)
			free(st[0].oring[i]);
	}
	free(st[0].scr);
	free(st[0].dnrow);
	free(st[0].ring);
	free(st[0].oring);
	for (int i = 0; st[0].sscr && i < w->nthr; i++)
		free(st[0].sscr[i]);
	free(st[0].sscr);
	for (int b = 0; b < 2; b++) {
		free(st[b].l1);
		free(st[b].rt);
		free(st[b].er);
		free(st[b].vp);
		free(st[b].vr);
		free(st[b].dq);
		free(st[b].chisq);
		free(st[b].dumo);
	}
	free(w->lightbuf);
	free(w->light);
	free(w->pixarea);
	free(w->fluence);
	ramp_fit_plan_free(&w->fp);
}

/* The light of strip s's science rows and of the one row either side,
 * whose charge IPC shares with the strip's edge rows: the rendered rate
 * plus the background, into w->light (NULL off the array).  0 or -1 with
 * the message of rate_row. */
static int strip_light(struct sca_pass *w, struct strip *s, struct err *e)
{
	struct level_sca *L = s->L;

	for (int k = 0; k < s->ny + 2; k++) {
		int sy = s->sy0 - 1 + k;
		double *row = w->lightbuf + (size_t)k * WFS_NPIX;

		w->light[k] = NULL;
		if (sy < 0 || sy >= WFS_NPIX)
			continue;
		if (L->rate_row(L->arg, sy, row, e) < 0)
			return -1;
		if (L->geo && L->bkg_sky != 0) {
			/* the sky's part times each pixel's area, the
			 * thermal part as is (as detector.c's tiles) */
			double thermal = L->background - L->bkg_sky;

			geom_area_row(L->geo, sy, 0, WFS_NPIX, w->pixarea);
			for (int x = 0; x < WFS_NPIX; x++)
				row[x] += L->bkg_sky * w->pixarea[x] + thermal;
		} else {
			for (int x = 0; x < WFS_NPIX; x++)
				row[x] += L->background;
		}
		w->light[k] = row;
		/* the exposure's stimulus: the strip's own rows, once each,
		 * and the row either side of the part written (--rows), whose
		 * charge IPC shares with its edge rows, so that a part's
		 * afterglow is that of the whole SCA */
		if (L->persist && ((k >= 1 && k <= s->ny) || sy == L->ylo - 1 || sy == L->yhi)) {
			double T = L->pat->exptime, dark = L->det->dark;

			for (int x = 0; x < WFS_NPIX; x++)
				w->fluence[x] = (row[x] + dark) * T;
			if (persist_add(L->persist, L->key.sca, sy, 0, WFS_NPIX, w->fluence) < 0)
				return err_sys(e, "persistence state");
		}
	}
	return 0;
}

/* Compute strip s by bands of rows on the workers (strip_band) while this
 * thread writes the previous strip prev, if any.  The seconds spent
 * writing in *t_write.  0 or -1 with a message, the workers idle either
 * way. */
static int strip_compute(struct strip *s, const struct strip *prev, double *t_write,
			 struct err *e)
{
	struct level_sca *L = s->L;

	*t_write = 0;
	pool_start(L->pool, strip_band, s, (size_t)(s->ny + BAND - 1) / BAND);
	if (prev) {
		double t1 = now();

		if (strip_write(L, prev, e) < 0) {
			pool_wait(L->pool);
			return -1;
		}
		*t_write = now() - t1;
		L->t_write += *t_write;
	}
	pool_wait(L->pool);
	return 0;
}

int level_write_sca(struct level_sca *L, struct err *e)
{
	int flo = L->ylo == 0 ? 0 : L->ylo + BORDER;
	int fhi = L->yhi == WFS_NPIX ? FRAME : L->yhi + BORDER;
	struct sca_pass w = { 0 };
	struct strip *prev = NULL;
	int r = -1;

	const struct ramp_det *det0 = L->det;
	double read_noise = L->det->read_noise;

	if (L->correlated) {
		/* the white part per pixel; the fit's read noise that of a
		 * corrected read, the Project's CDS noise over sqrt 2 (the
		 * calibration of data/readnoise.tsv) */
		struct rnoise_par par;
		struct ramp_det fd = *L->det;

		if (rnoise_par_get(L->key.sca, &par, e) < 0)
			return -1;
		w.det = *L->det;
		w.det.read_noise = par.white;
		fd.read_noise = par.cds / sqrt(2);
		read_noise = fd.read_noise;
		if (rnoise_init(&w.rn, L->pat, &par, &L->key, 0, e) < 0)
			return -1;
		L->det = &w.det;
		if (L->level == LEVEL_2 &&
		    (rnoise_ref_init(&w.ref, &w.rn, L->pat, &w.det, &L->key, e) < 0 ||
		     ramp_fit_plan_init(&w.fp, L->pat, &fd) < 0)) {
			rnoise_free(&w.rn);
			rnoise_ref_free(&w.ref);
			L->det = det0;
			return err_sys(e, "detector level %d: memory", L->level);
		}
	} else if (L->level == LEVEL_2 && ramp_fit_plan_init(&w.fp, L->pat, L->det) < 0) {
		goto nomem;
	}
	if (sca_pass_alloc(&w, L) < 0)
		goto nomem;
	w.st[0].read_noise = w.st[1].read_noise = read_noise;
	for (int fy0 = flo, b = 0; fy0 < fhi; fy0 += w.S, b ^= 1) {
		struct strip *s = &w.st[b];
		double t0 = now(), t1;

		s->fy0 = fy0;
		s->ny = fhi - fy0 < w.S ? fhi - fy0 : w.S;
		s->sy0 = fy0 - BORDER;
		if (strip_light(&w, s, e) < 0 || strip_compute(s, prev, &t1, e) < 0)
			goto done;
		/* the wall time less the writing, which overlapped the ramp:
		 * the two add up to the wall time of the loop */
		L->t_ramp += now() - t0 - t1;
		prev = s;
	}
	if (prev) {
		double t1 = now();

		if (strip_write(L, prev, e) < 0)
			goto done;
		L->t_write += now() - t1;
	}
	r = 0;
	goto done;
nomem:
	err_sys(e, "detector level %d: memory", L->level);
done:
	sca_pass_free(&w);
	if (L->correlated) {
		rnoise_free(&w.rn);
		rnoise_ref_free(&w.ref);
		L->det = det0;
	}
	return r;
}
