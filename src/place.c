/*
 * place.c - rows to placements: the step between the catalog and rendering.
 *
 * For each chunk of rows: the model of each row's type and the columns it
 * reads, each row's reach (how far beyond an SCA edge it may still throw
 * light), which requested SCAs each sky row may reach (slot masks, so most
 * rows far from every SCA cost no projection), the exact pixel on each SCA,
 * the row's flux in counts/s there, the model's prepare() and footprint()
 * (on several threads for a model that allows it: see pend() below), and
 * finally the placements binned by the tiles their footprints touch, which
 * is what render.c draws.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "catalog.h"
#include "engine.h"
#include "err.h"
#include "motion.h"
#include "pool.h"
#include "source.h"
#include "spectrum.h"


static int grow(void **p, size_t *cap, size_t need, size_t size)
{
	size_t n = *cap ? *cap : 256;
	void *q;

	if (need <= *cap)
		return 0;
	while (n < need)
		n *= 2;
	if (!(q = pool_realloc_huge(*p, *cap * size, n * size)))
		return -1;
	*p = q;
	*cap = n;
	return 0;
}

/* *p resized to bytes; on failure -1 and *p left as it was (never
 * p = realloc(p, ...), which loses the block when realloc fails). */
static int resize(void **p, size_t bytes)
{
	void *q = realloc(*p, bytes);

	if (!q)
		return -1;
	*p = q;
	return 0;
}

/* The model drawing rows of type name: the model of that name, or, when
 * the scene has a setting of that name (--sersic, --set T=M), the model
 * name-setting of that family (model.h, "Resolving a catalog type"). */
static void type_model(struct engine *g, const char *name, char *real, size_t size)
{
	const char *method;

	if ((method = host_setting(g, name)) && *method)
		snprintf(real, size, "%s-%s", name, method);
	else
		snprintf(real, size, "%s", name);
}

/* The index of the model drawing rows of type name, loaded on first use;
 * or plugins_get()'s failure (-1 or PLUGIN_REFUSED_SETTING). */
static int resolve_type(struct engine *g, const char *name)
{
	char real[64];
	int m;

	for (int i = 0; i < g->ntypes; i++)
		if (!strcmp(g->types[i].name, name))
			return g->types[i].model;
	type_model(g, name, real, sizeof(real));
	if ((m = plugins_get(&g->plugins, real, g->e)) < 0)
		return m;
	if (g->ntypes < PLUGIN_MAX) {
		snprintf(g->types[g->ntypes].name, sizeof(g->types[0].name), "%s", name);
		g->types[g->ntypes++].model = m;
	}
	return m;
}

/* The spectra's tables (the colour terms, the spectral classes), made
 * before the first row with a spectrum is placed: 0, or -1 with the
 * error in g->e. */
static int place_colour_init(struct engine *g)
{
	const char *cc;

	if (g->colour)
		return 0;
	cc = host_setting(g, "colour-counts");
	if (cc && strcmp(cc, "pivot") && strcmp(cc, "band"))
		return err_set(g->e, EXIT_INPUT, "colour-counts: expected pivot or band, not '%s'",
			       cc);
	g->colour_band = cc && !strcmp(cc, "band");
	if (!(g->colour = colour_new(g->o->filter, g->e)) || psfgrids_colour_init(g) < 0)
		return -1;
	return 0;
}

/* The chunk's column index of each column model m reads (-1 if absent). */
static int model_columns(struct engine *g, const struct rows *r, int m)
{
	const struct plugin *pl = &g->plugins.p[m];
	const struct wfs_model *md = pl->m;

	if (g->colidx_rows[m] == r)
		return 0;
	if (md->ncolumns > MAX_COLUMNS)
		return err_set(g->e, EXIT_PLUGIN, "model '%s' reads %d columns; at most %d",
			       md->name, md->ncolumns, MAX_COLUMNS);
	for (int c = 0; c < md->ncolumns; c++) {
		const struct wfs_column *col = plugin_column(pl, c);

		g->colidx[m][c] = rows_column(r, col->name);
		if (g->colidx[m][c] < 0 && col->required)
			return err_set(g->e, EXIT_INPUT,
				       "%s: column '%s', required by model '%s', is missing",
				       r->file, col->name, md->name);
	}
	g->colidx_rows[m] = r;
	return 0;
}

/* A model's prepare() or reach() returned -1 for row i.  A refused row is
 * bad input; a refusal without a message is a broken plugin (silent is the
 * message then); a host service that failed under it (a PSF file that
 * cannot be read) keeps its own message and status.  Returns -1. */
static int row_refused(struct err *e, const struct rows *r, size_t i,
		       const struct wfs_model *md, const char *silent)
{
	if (e->code != EXIT_OK && e->code != EXIT_PLUGIN)
		return -1;
	if (e->code == EXIT_OK)
		err_set(e, EXIT_PLUGIN, "%s", silent);
	else
		e->code = EXIT_INPUT;
	err_prefix(e, "%s:%ld: model '%s'", r->file, r->line[i], md->name);
	return -1;
}

/* The model that draws the sources of row model m: m, or its drawn_by. */
static inline int drawer_of(const struct engine *g, int m)
{
	int d = g->plugins.p[m].drawer;

	return d >= 0 ? d : m;
}

/*
 * Fill src for row i on SCA sca at pixel (x, y); for a model drawn by
 * another (model.h, drawn_by), let it decide the source (its flux and
 * position at the exposure's date) and hand src the drawing model's
 * columns, which follow the model's own in param.  Returns 0 or -1.
 */
static int source_at(struct engine *g, const struct rows *r, size_t i, int m,
		     const double *param, int sca, double x, double y,
		     struct wfs_source *src)
{
	const struct plugin *pl = &g->plugins.p[m];
	double flux, mag;

	if (source_fill(g, r, i, param, sca, x, y, src, g->e) < 0)
		return -1;
	if (pl->drawer < 0)
		return 0;
	flux = src->flux;
	mag = src->mag;
	if (pl->m->prepare && pl->m->prepare(pl->state, src) < 0)
		return row_refused(g->e, r, i, pl->m, "prepare() failed" MODEL_SILENT);
	if (source_flux_check(g, r, i, src, pl->m->name, g->e) < 0)
		return -1;
	if (!isfinite(src->x) || !isfinite(src->y))
		return err_set(g->e, EXIT_PLUGIN, "%s:%ld: model '%s' moved the source to "
			       "(%g, %g)", r->file, r->line[i], pl->m->name, src->x, src->y);
	/* the magnitude of the flux the model left; the row's own where it
	 * left the flux as it was (source_fill: no round trip) */
	src->mag = src->flux != flux ? source_mag(g, sca, src->flux) : mag;
	src->psf_class = source_psf_class(g, src->mag);
	src->param = param + pl->m->ncolumns;
	return 0;
}

/*
 * Model d's prepare() and footprint() of src, the source of row i, on
 * whichever thread runs it (the main one, or place_pool's for a
 * WFS_PARALLEL_PREPARE model).  Returns 0, or -1 with the error in e.
 */
static int settle(struct engine *g, const struct rows *r, size_t i, int d,
		  struct wfs_source *src, struct wfs_box *box, struct err *e)
{
	const struct plugin *dp = &g->plugins.p[d];

	if (dp->m->prepare && dp->m->prepare(dp->state, src) < 0)
		return row_refused(e, r, i, dp->m, "prepare() failed" MODEL_SILENT);
	if (dp->m->footprint(dp->state, src, box) < 0) {
		err_set(e, EXIT_PLUGIN, "footprint() failed" MODEL_SILENT);
		err_prefix(e, "%s:%ld: model '%s'", r->file, r->line[i], dp->m->name);
		return -1;
	}
	return 0;
}

/*
 * The position angle, degrees east of north, of the detectors' +y axis at
 * (ra, dec) in exposure g: the direction of a short step north in the
 * focal-plane frame, whose +y is the detectors' +y and whose parity is
 * the sky's (east left when north is up).  A galaxy whose major axis lies
 * pa east of north then lies phi = pa - north_pa on the detector, in the
 * sense of the "phi" column (from +y toward -x).  0 when the row does not
 * project.
 */
static double north_pa(const struct engine *g, double ra, double dec)
{
	double h = dec > 89.0 ? -1e-4 : 1e-4;
	double rr[2] = { ra, ra }, dd[2] = { dec, dec + h }, fx[2], fy[2];
	double dx, dy;

	sky_to_focal(&g->sky, 2, rr, dd, INFINITY, fx, fy);
	dx = (fx[1] - fx[0]) * (h > 0 ? 1 : -1);
	dy = (fy[1] - fy[0]) * (h > 0 ? 1 : -1);
	if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0))
		return 0;
	return atan2(dx, dy) * (180.0 / M_PI);
}

/* The column of role k (model.h, enum wfs_column_role) of a row of model
 * pl, or fallback when the model has none. */
static double param_role(const struct plugin *pl, const double *param, int k, double fallback)
{
	return pl->role[k] >= 0 ? param[pl->role[k]] : fallback;
}

/* One row of a --placed list in romanisim's convention (see
 * wfiscene-catalog(5)): the source as a romanisim catalog would give it,
 * read back to the same image: under the model's roman_type when a row of
 * that type would be drawn by this model, its shape from the columns of
 * the shape roles.  Returns fprintf's sign. */
static int placed_roman_row(struct engine *g, const struct rows *r, size_t i,
			    const struct plugin *pl, const double *param,
			    const struct wfs_source *src)
{
	double maggies = pow(10.0, -0.4 * src->mag);
	const char *type = pl->m->name, *back;
	double n = -1, hlr = 0, pa = 0, ba = 1;
	char real[64];

	if (pl->roman_type && (back = catalog_roman_type(pl->roman_type))) {
		type_model(g, back, real, sizeof(real));
		if (!strcmp(real, pl->m->name))
			type = pl->roman_type;
	}
	if (pl->role[WFS_ROLE_SERSIC_INDEX] >= 0 || pl->role[WFS_ROLE_HALF_LIGHT] >= 0 ||
	    pl->role[WFS_ROLE_AXIS_RATIO] >= 0 || pl->role[WFS_ROLE_ANGLE] >= 0) {
		n = param_role(pl, param, WFS_ROLE_SERSIC_INDEX, -1);
		ba = param_role(pl, param, WFS_ROLE_AXIS_RATIO, 1);
		/* romanisim's half_light_radius is the circularised one,
		 * sqrt(a b), where re is along the major axis a */
		hlr = param_role(pl, param, WFS_ROLE_HALF_LIGHT, 0) * WFS_PIXSCALE *
		      sqrt(ba > 0 ? ba : 1);
		pa = param_role(pl, param, WFS_ROLE_ANGLE, 0);
		if (!isnan(r->ra[i]))
			pa += north_pa(g, r->ra[i], r->dec[i]);
		pa = fmod(pa, 360.0);
		if (pa < 0)
			pa += 360.0;
	}
	/* with SCA groups, the row for placed_merge() to list it once */
	if (g->npass > 1 && fprintf(g->placed, "%zu\t", i) < 0)
		return -1;
	return fprintf(g->placed, "%lld,%d,%.4f,%.4f,%.15g,%.15g,%s,%.17g,%.17g,%.17g,%.17g,%.17g\n",
		       src->id, src->sca, src->x + 1, src->y + 1, r->ra[i], r->dec[i], type,
		       n, hlr, pa, ba, maggies) < 0 ? -1 : 0;
}

/*
 * A galaxy given on the sky (romanisim's pa; re from half_light_radius at
 * 0.11" a pixel) on an SCA of the SIAF geometry: its re, ratio and phi
 * turned into that SCA's own pixels at (x, y) through the local Jacobian
 * (geom_sky_ellipse), into out.  0 when the row is not such a galaxy (its
 * pa turned into phi by north_pa alone is then exact or what it asks).
 */
static int sky_shape(struct engine *g, const struct rows *r, size_t i, int m,
		     const double *param, int sca, double x, double y, double *out)
{
	const struct plugin *pl = &g->plugins.p[m];
	struct geom_sca *geo = &g->sky.sca[sca - 1].geo;
	int cre = pl->role[WFS_ROLE_HALF_LIGHT], cq = pl->role[WFS_ROLE_AXIS_RATIO],
	    cphi = pl->role[WFS_ROLE_ANGLE];

	if (r->sky_angle_col < 0 || isnan(r->ra[i]) || geo->kind != GEOM_SIAF)
		return 0;
	if (cre < 0 || cq < 0 || cphi < 0 || g->colidx[m][cphi] != r->sky_angle_col)
		return 0;
	memcpy(out, param, pl->m->ncolumns * sizeof(double));
	geom_sky_ellipse(geo, x, y, param[cre] * WFS_PIXSCALE, param[cq],
			 param[cphi] + north_pa(g, r->ra[i], r->dec[i]),
			 &out[cre], &out[cq], &out[cphi]);
	return 1;
}

/*
 * Placing a chunk's rows takes three steps, so that the models' prepare()
 * and footprint() can run on several threads while the result stays that
 * of one thread going through the rows in order:
 *
 *   pend()     main thread, in order: the row's source on the slot (its
 *              flux, and a deciding model's say, source_at), appended to
 *              the batch
 *   settle()   the drawing model's prepare() and footprint(): on the main
 *              thread, or for a model that allows it (WFS_PARALLEL_PREPARE)
 *              on place_pool's threads, PLACE_PART placements a task
 *   keep()     main thread, in order: the counts, the --placed list, the
 *              rows drawn (--rows), and the batch closed up over the
 *              sources that light nothing
 *
 * A failure anywhere reports the first failing placement in that order, as
 * one pass would: the threads' errors carry their placement's index.
 */
#define PLACE_PART 512

/* Whether place_pool's threads may settle p (its model allows it). */
static int in_pool(const struct engine *g, const struct placement *p)
{
	return g->plugins.p[p->model].flags & WFS_PARALLEL_PREPARE;
}

static int pend(struct engine *g, struct batch *b, const struct rows *r, size_t i, int m,
		const double *param, int slot, double x, double y)
{
	const struct plugin *pl = &g->plugins.p[m];
	int d = drawer_of(g, m), nrow = pl->m->ncolumns;
	int n = nrow + (d != m ? g->plugins.p[d].m->ncolumns : 0);
	double shaped[MAX_COLUMNS], *v;
	struct placement *p;

	if (grow((void **)&b->p, &b->cap, b->n + 1, sizeof(*b->p)) < 0 ||
	    grow((void **)&b->param, &b->capparam, b->nparam + n + 1, sizeof(double)) < 0)
		return err_sys(g->e, "placements");
	/* the row's columns, then its drawing model's (model.h, drawn_by) */
	v = b->param + b->nparam;
	memcpy(v, param, n * sizeof(double));
	if (sky_shape(g, r, i, m, param, g->slot[slot].sca, x, y, shaped))
		memcpy(v, shaped, nrow * sizeof(double));
	p = &b->p[b->n];
	if (d != m) {
		/* the deciding model's prepare(), here in order */
		if (source_at(g, r, i, m, v, g->slot[slot].sca, x, y, &p->src) < 0)
			return -1;
	} else {
		/* filled by settle() */
		p->src.x = x;
		p->src.y = y;
		p->src.param = v;
	}
	p->model = d;
	p->from = m;
	b->nserial += !in_pool(g, p);
	p->slot = slot;
	p->row = i;
	p->param_off = b->nparam + (size_t)(p->src.param - v);
	b->nparam += n;
	b->n++;
	return 0;
}

/* settle() of placement p of batch b, its source filled first unless
 * pend() did; its columns' address set here, on the thread that settles
 * it, now that b->param has stopped moving. */
static int place_settle(struct engine *g, const struct rows *r, struct batch *b,
			struct placement *p, struct err *e)
{
	p->src.param = b->param + p->param_off;
	if (p->from == p->model &&
	    source_fill(g, r, p->row, p->src.param, g->slot[p->slot].sca, p->src.x, p->src.y,
			&p->src, e) < 0)
		return -1;
	return settle(g, r, p->row, p->model, &p->src, &p->box, e);
}

/* The threads' share of settle(): the placements of task part that
 * place_pool takes (their drawing model allows it), in order, each
 * thread stopping at its first failure. */
struct settle_job {
	struct engine *g;
	const struct rows *r;
	struct batch *b;
	const size_t *order;    /* the placements in the order taken (NULL:
				 * the batch's own), settle_order() */
	atomic_size_t failed;   /* the lowest failing placement, or SIZE_MAX */
};

/* Lower j->failed to placement k if k comes before it. */
static void settle_failed(struct settle_job *j, size_t k)
{
	size_t f = atomic_load(&j->failed);

	while (k < f && !atomic_compare_exchange_weak(&j->failed, &f, k))
		;
}

/* settle_order()'s placements are scattered over the batch and their rows
 * over the chunk's columns: fetch the placement SETTLE_AHEAD * 2 ahead,
 * and the row columns source_fill() reads of the one SETTLE_AHEAD ahead
 * (its placement came in by then).  In the batch's own order the hardware
 * sees the streams. */
#define SETTLE_AHEAD 10

/* (always inlined: GCC 12 finds a function of prefetches alone pure and
 * drops its calls) */
static inline __attribute__((always_inline)) void settle_prefetch(const struct settle_job *j,
								   size_t n, size_t end)
{
	const struct rows *r = j->r;

	if (n + 2 * SETTLE_AHEAD < end) {
		const char *q = (const char *)&j->b->p[j->order[n + 2 * SETTLE_AHEAD]];

		for (size_t c = 0; c < sizeof(struct placement); c += 64)
			__builtin_prefetch(q + c);
	}
	if (n + SETTLE_AHEAD < end) {
		const struct placement *p = &j->b->p[j->order[n + SETTLE_AHEAD]];
		size_t i = p->row;

		/* its columns (src.param is set when it is settled) */
		__builtin_prefetch(j->b->param + p->param_off);
		__builtin_prefetch(r->flux + i);
		__builtin_prefetch(r->unit + i);
		__builtin_prefetch(r->id + i);
		if (r->spec_kind) {
			__builtin_prefetch(r->spec_kind + i);
			__builtin_prefetch(r->spec_value + i);
		}
	}
}

static void settle_part(void *arg, int wid, size_t part)
{
	struct settle_job *j = arg;
	struct engine *g = j->g;
	struct worker *w = &g->pw[wid];
	size_t end = (part + 1) * PLACE_PART;

	if (end > j->b->n)
		end = j->b->n;
	host_worker(w);
	for (size_t n = part * PLACE_PART; n < end; n++) {
		size_t k = j->order ? j->order[n] : n;
		int had = w->err.code != EXIT_OK;
		struct err was;

		if (k > atomic_load_explicit(&j->failed, memory_order_relaxed)) {
			if (j->order)
				continue;
			break;  /* an earlier placement failed: this one is moot */
		}
		if (j->order)
			settle_prefetch(j, n, end);
		if (!in_pool(g, &j->b->p[k]))
			continue;
		/* out of order, a placement before the thread's failure: its
		 * own error replaces that one if it fails too */
		if (had) {
			was = w->err;
			err_clear(&w->err);
		}
		if (place_settle(g, j->r, j->b, &j->b->p[k], &w->err) < 0) {
			w->err_task = k;
			settle_failed(j, k);
			if (!j->order)
				break;
		} else if (had) {
			w->err = was;
		}
	}
	host_worker(NULL);
}

/* The order place_pool settles a batch in: by slot and 512-pixel block (a
 * stable counting sort), so that what point.so's prepare() reads and adds
 * to by position is met a position at a time, from cache rather than
 * memory: its blended cells and their summed-area tables (with spectra,
 * four to seven cells of 0.3 MB per position) and its grid of far light
 * (1.8 MB a thread and SCA).  First for scenes with spectra only; for
 * every scene since: 10^6 faint stars without spectra take 0.88-0.98x
 * the CPU (F129, F146).  prepare() gives the same result in any order
 * (model.h).  NULL: the batch's own order. */
#define ORDER_BLOCK 512
#define ORDER_SIDE ((WFS_NPIX + ORDER_BLOCK - 1) / ORDER_BLOCK + 2)

static size_t *settle_order(const struct engine *g, const struct batch *b)
{
	size_t nkey = (size_t)g->nslot * ORDER_SIDE * ORDER_SIDE, *order, *at;
	unsigned *key;

	if (b->n < 2 * PLACE_PART)
		return NULL;
	order = malloc(b->n * sizeof(*order));
	key = malloc(b->n * sizeof(*key));
	if (!(at = calloc(nkey + 1, sizeof(*at))) || !order || !key)
		goto out;
	for (size_t k = 0; k < b->n; k++) {
		const struct placement *p = &b->p[k];
		double bx = floor(p->src.x / ORDER_BLOCK) + 1, by = floor(p->src.y / ORDER_BLOCK) + 1;

		bx = bx < 0 ? 0 : bx > ORDER_SIDE - 1 ? ORDER_SIDE - 1 : bx;
		by = by < 0 ? 0 : by > ORDER_SIDE - 1 ? ORDER_SIDE - 1 : by;
		key[k] = (unsigned)((p->slot * ORDER_SIDE + by) * ORDER_SIDE + bx);
		at[key[k] + 1]++;
	}
	for (size_t q = 0; q < nkey; q++)
		at[q + 1] += at[q];
	for (size_t k = 0; k < b->n; k++)
		order[at[key[k]]++] = k;
	free(key);
	free(at);
	return order;
out:
	free(order);
	free(key);
	free(at);
	return NULL;
}

/*
 * settle() for the batch's placements: place_pool's threads take those
 * whose model allows it (in settle_order()'s order), when there are
 * enough of them to share, while the main thread takes the rest in order.
 * Returns 0, or -1 with the first failing placement's error in g->e.
 */
static int settle_all(struct engine *g, const struct rows *r, struct batch *b)
{
	struct settle_job j = { .g = g, .r = r, .b = b };
	size_t npool = 0, failed = SIZE_MAX, parts = (b->n + PLACE_PART - 1) / PLACE_PART;
	struct worker *first = NULL;

	atomic_init(&j.failed, SIZE_MAX);
	if (g->place_pool)
		npool = b->n - b->nserial;
	if (npool < 2 * PLACE_PART)
		npool = 0;
	if (npool)
		j.order = settle_order(g, b);
	if (npool)
		pool_start(g->place_pool, settle_part, &j, parts);
	/* (none when every placement is the pool's) */
	for (size_t k = 0; (!npool || b->nserial) && k < b->n && k < failed &&
	     k <= atomic_load_explicit(&j.failed, memory_order_relaxed); k++)
		if ((!npool || !in_pool(g, &b->p[k])) && place_settle(g, r, b, &b->p[k], g->e) < 0) {
			failed = k;
			settle_failed(&j, k);   /* the threads need not go past it */
		}
	if (!npool)
		return failed == SIZE_MAX ? 0 : -1;
	pool_wait(g->place_pool);
	free((void *)j.order);
	for (int t = 0; t < g->npw; t++)
		if (g->pw[t].err.code != EXIT_OK && g->pw[t].err_task < failed) {
			first = &g->pw[t];
			failed = first->err_task;
		}
	if (first) {
		err_clear(g->e);
		err_set(g->e, first->err.code, "%s", first->err.msg);
	}
	for (int t = 0; t < g->npw; t++)
		err_clear(&g->pw[t].err);
	return failed == SIZE_MAX ? 0 : -1;
}

/* The counts and the --placed list of placement k, in order; *kept tells
 * whether the batch keeps it (it lights a pixel drawn). */
static int keep(struct engine *g, struct batch *b, const struct rows *r, size_t k, int *kept)
{
	struct placement *p = &b->p[k];
	const struct wfs_source *src = &p->src;
	const struct wfs_model *md = g->plugins.p[p->from].m;
	struct wfs_box *box = &p->box;
	size_t i = p->row;

	*kept = 0;
	if (box->x0 < 0) box->x0 = 0;
	if (box->y0 < 0) box->y0 = 0;
	if (box->x1 > WFS_NPIX) box->x1 = WFS_NPIX;
	if (box->y1 > WFS_NPIX) box->y1 = WFS_NPIX;
	if (box->x0 >= box->x1 || box->y0 >= box->y1) {
		g->offdet++;    /* all its light misses this SCA */
		return 0;
	}
	g->placements++;
	g->per_model[p->from]++;
	g->flux_requested[src->sca - 1] += src->flux;
	g->placed_on[src->sca - 1]++;
	if (g->placed && !g->placed_roman &&
	    fprintf(g->placed, "%lld,%d,%.4f,%.4f,%.6g,%.4f,%s\n", src->id, src->sca,
		    src->x + 1, src->y + 1, src->flux, src->mag, md->name) < 0)
		return err_sys(g->e, "%s", g->o->placed);
	if (g->placed && g->placed_roman && !g->listed[i]) {
		/* the row's own columns come first (pend) */
		const double *param = b->param + p->param_off -
				      (p->from != p->model ? md->ncolumns : 0);

		g->listed[i] = 1;
		if (placed_roman_row(g, r, i, &g->plugins.p[p->from], param, src) < 0)
			return err_sys(g->e, "%s", g->o->placed);
	}
	/* With --rows, counted and listed as in a run of the whole SCA (the
	 * part's header is that run's), but drawn only in the rows written:
	 * the windows are cut there, and a model gives the same pixels for
	 * any windows.  The detector levels also need the row on either side
	 * of the part, whose light IPC brings into it. */
	{
		int margin = g->o->level ? 1 : 0;

		if (box->y0 < g->ylo - margin)
			box->y0 = g->ylo - margin;
		if (box->y1 > g->yhi + margin)
			box->y1 = g->yhi + margin;
	}
	*kept = box->y0 < box->y1;
	return 0;
}

/*
 * How far (arcsec) beyond an SCA edge row i can still send light, from the
 * model's reach() (model.h), given the row as on the scene's first SCA at
 * its centre.  A model without reach() (built against an older model.h)
 * gets what older hosts did: one more prepare() and footprint(), at the
 * origin of the first SCA, and the footprint's extent plus 2 pixels.
 */
static int row_reach(struct engine *g, const struct rows *r, size_t i, int m,
		     const double *param, double *reach)
{
	const struct plugin *pl = &g->plugins.p[drawer_of(g, m)];
	struct wfs_source src;
	struct wfs_box box;
	double ext;

	if (pl->reach) {
		double centre = (WFS_NPIX - 1) / 2.0;

		if (source_at(g, r, i, m, param, g->slot[0].sca, centre, centre, &src) < 0)
			return -1;
		if (pl->reach(pl->state, &src, &ext) < 0)
			return row_refused(g->e, r, i, pl->m, "reach() failed" MODEL_SILENT);
		if (!(ext >= 0) || isinf(ext))
			return err_set(g->e, EXIT_PLUGIN, "%s:%ld: model '%s': reach() gave %g "
				       "pixels, not a finite number >= 0", r->file, r->line[i],
				       pl->m->name, ext);
		*reach = ext * WFS_PIXSCALE;
		return 0;
	}
	if (source_at(g, r, i, m, param, g->slot[0].sca, 0, 0, &src) < 0 ||
	    settle(g, r, i, drawer_of(g, m), &src, &box, g->e) < 0)
		return -1;
	ext = fmax(fmax(-box.x0, box.x1), fmax(-box.y0, box.y1));
	*reach = (ext + 2) * WFS_PIXSCALE;
	return 0;
}

/*
 * Which requested SCAs each sky row may reach, as a bit mask per row (bit s
 * for slot s), and the rows near none of them counted as culled.  A row is
 * a candidate for slot s when its focal-plane position is within
 * the SCA's half extent + its reach + 2" of the SCA centre along both axes.  Rather
 * than test every slot for every row, a per-axis table gives the slots
 * whose window, widened by the largest reach in the chunk, covers a band of
 * the focal plane; only those slots get the exact test.  The table is a
 * superset by construction (a monotone bin index of a position inside a
 * window lies within the window's bins, and the windows are widened by a
 * margin for rounding), so the masks are exactly what testing every slot
 * gives.
 */
#define SLOT_BINS 64
#define ROW_PART 16384          /* rows a task of the parallel steps */

/* The focal-plane map of a chunk's slots: the slot_masks() tables. */
struct slot_map {
	struct engine *g;
	const struct rows *r;
	double band;                    /* focal_band() */
	double x0, x1, y0, y1, wx, wy;
	uint32_t xm[SLOT_BINS], ym[SLOT_BINS];
	unsigned long long *culled;     /* per task */
};

static void slot_map_init(struct engine *g, struct slot_map *sm, double maxreach)
{
	/* widened a little, so that a row passing the exact test within an
	 * ulp of a window's edge is still inside the window's bins */
#define LIM(ss) (((ss)->half + maxreach + 2.0) * (1 + 1e-9) + 1e-6)
	double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY, wx, wy;

	for (int s = 0; s < g->nslot; s++) {
		const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
		double lim = LIM(ss);

		x0 = fmin(x0, ss->fx - lim);
		x1 = fmax(x1, ss->fx + lim);
		y0 = fmin(y0, ss->fy - lim);
		y1 = fmax(y1, ss->fy + lim);
	}
	wx = (x1 - x0) / SLOT_BINS;
	wy = (y1 - y0) / SLOT_BINS;
	memset(sm->xm, 0, sizeof(sm->xm));
	memset(sm->ym, 0, sizeof(sm->ym));
	for (int s = 0; s < g->nslot; s++) {
		const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
		double lim = LIM(ss);
		int a = (int)((ss->fx - lim - x0) / wx), b = (int)((ss->fx + lim - x0) / wx);
		int c = (int)((ss->fy - lim - y0) / wy), d = (int)((ss->fy + lim - y0) / wy);

		for (int k = a < 0 ? 0 : a; k <= b && k < SLOT_BINS; k++)
			sm->xm[k] |= 1u << s;
		for (int k = c < 0 ? 0 : c; k <= d && k < SLOT_BINS; k++)
			sm->ym[k] |= 1u << s;
	}
	sm->x0 = x0; sm->x1 = x1; sm->y0 = y0; sm->y1 = y1; sm->wx = wx; sm->wy = wy;
#undef LIM
}

/* Rows [a, b) of the chunk: their masks (g->fx, g->fy set). */
static unsigned long long slot_masks(const struct slot_map *sm, size_t a, size_t b)
{
	struct engine *g = sm->g;
	const struct rows *r = sm->r;
	unsigned long long culled = 0;

	for (size_t i = a; i < b; i++) {
		double fx = g->fx[i], fy = g->fy[i];
		uint32_t m = 0, c;

		/* also false for NaN: x/y rows and rows far from the pointing */
		if (fx >= sm->x0 && fx < sm->x1 && fy >= sm->y0 && fy < sm->y1) {
			int bx = (int)((fx - sm->x0) / sm->wx), by = (int)((fy - sm->y0) / sm->wy);

			c = sm->xm[bx < SLOT_BINS ? bx : SLOT_BINS - 1] &
			    sm->ym[by < SLOT_BINS ? by : SLOT_BINS - 1];
			while (c) {
				int s = __builtin_ctz(c);
				const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
				double l = ss->half + g->reach[i] + 2.0;

				c &= c - 1;
				if (fabs(fx - ss->fx) < l && fabs(fy - ss->fy) < l)
					m |= 1u << s;
			}
		}
		/* culled near no slot; placed on this pass's (run.c) */
		g->mask[i] = m & g->pass_slots;
		culled += !isnan(r->ra[i]) && !m;
	}
	return culled;
}

/* Task part of the focal-plane step: sky to focal plane (focal_band()
 * below), then the slot masks, for ROW_PART rows.  Each row's result is its
 * own, so any split gives the same masks. */
static void focal_part(void *arg, int wid, size_t part)
{
	struct slot_map *sm = arg;
	size_t a = part * ROW_PART, b = a + ROW_PART;

	(void)wid;
	if (b > sm->r->n)
		b = sm->r->n;
	sky_to_focal(&sm->g->sky, b - a, sm->r->ra + a, sm->r->dec + a, sm->band,
		     sm->g->fx + a, sm->g->fy + a);
	sm->culled[part] = slot_masks(sm, a, b);
}

/* fn for tasks 0 .. ntasks-1: on place_pool's threads when there is one
 * and more than one task, else here in order. */
static void place_parallel(struct engine *g, pool_fn fn, void *arg, size_t ntasks)
{
	if (g->place_pool && ntasks > 1)
		pool_run(g->place_pool, fn, arg, ntasks);
	else
		for (size_t t = 0; t < ntasks; t++)
			fn(arg, 0, t);
}

/* The values of the columns model m reads for row i, into v. */
static int read_params(struct engine *g, const struct rows *r, size_t i, int m, double *v)
{
	const struct wfs_model *md = g->plugins.p[m].m;

	if (model_columns(g, r, m) < 0)
		return -1;
	for (int c = 0; c < md->ncolumns; c++) {
		const struct wfs_column *col = plugin_column(&g->plugins.p[m], c);

		/* an empty cell is the fallback, but for a required column
		 * (no number parses to NaN) */
		if (g->colidx[m][c] < 0)
			v[c] = col->fallback;
		else if (rows_number(r, g->colidx[m][c], i, col->required ? NAN :
				     col->fallback, &v[c], g->e) < 0)
			return -1;
		else if (col->required && isnan(v[c]))
			return err_set(g->e, EXIT_INPUT, "%s:%ld: model '%s': column '%s': "
				       "empty value", r->file, r->line[i], md->name, col->name);
		else if (g->colidx[m][c] == r->sky_angle_col && !isnan(r->ra[i]))
			v[c] -= north_pa(g, r->ra[i], r->dec[i]);   /* romanisim's pa */
	}
	return 0;
}

/* The model of each row (model[i]), the values of the columns it reads
 * (param, MAX_COLUMNS a row), and each sky row's reach (g->reach); the
 * count of x/y rows in *nxy and the largest reach in *maxreach. */
static int read_models(struct engine *g, const struct rows *r, int *model, double *param,
		       size_t *nxy, double *maxreach)
{
	const char *last_type = NULL;
	int last_m = -1;

	for (size_t i = 0; i < r->n; i++) {
		int m;

		/* Rows of one catalog mostly share one type string ("point"
		 * when there is no type column). */
		if (r->type[i] == last_type) {
			m = last_m;
		} else if ((m = resolve_type(g, r->type[i])) < 0) {
			/* the row that first needed the model, unless a value
			 * the run was given is what it refused */
			if (m != PLUGIN_REFUSED_SETTING)
				err_prefix(g->e, "%s:%ld", r->file, r->line[i]);
			return -1;
		}
		last_type = r->type[i];
		last_m = m;
		model[i] = m;
		if (read_params(g, r, i, m, &param[i * MAX_COLUMNS]) < 0)
			return -1;
		if (g->plugins.p[m].drawer >= 0 &&
		    read_params(g, r, i, g->plugins.p[m].drawer,
				&param[i * MAX_COLUMNS + g->plugins.p[m].m->ncolumns]) < 0)
			return -1;
		g->reach[i] = 0;
		if (isnan(r->ra[i]))
			(*nxy)++;
		else if (row_reach(g, r, i, m, &param[i * MAX_COLUMNS], &g->reach[i]) < 0)
			return -1;
		else if (g->reach[i] > *maxreach)
			*maxreach = g->reach[i];
	}
	return 0;
}

/*
 * The declination band (degrees) for sky to focal plane: sky_to_focal()
 * gives every sky row of the chunk g->fx, g->fy in arcsec from the
 * pointing's reference (NaN for x/y rows and for rows that cannot reach
 * any requested SCA).
 *
 * Rows farther in declination from the pointing than any SCA's window
 * reaches are on no SCA: a row near slot s lies within rho = |(fx, fy)| of
 * the reference in the focal plane, i.e. at an angle atan(rho) <= rho,
 * which is at least its declination offset.  Those rows skip the
 * trigonometry of the projection.
 */
static double focal_band(struct engine *g, double maxreach)
{
	double band = 0;

	for (int s = 0; s < g->nslot; s++) {
		const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
		double lim = ss->half + maxreach + 2.0;

		band = fmax(band, hypot(fabs(ss->fx) + lim, fabs(ss->fy) + lim));
	}
	return band / 3600 * (1 + 1e-9) + 1e-9;
}

/*
 * The focal-plane step for the whole chunk: g->fx, g->fy (above) and the
 * slot masks, ROW_PART rows a task on place_pool's threads, and the rows
 * near no slot counted as culled.
 */
static int focal_step(struct engine *g, const struct rows *r, double maxreach)
{
	size_t parts = (r->n + ROW_PART - 1) / ROW_PART;
	struct slot_map sm = { .g = g, .r = r, .band = focal_band(g, maxreach) };

	if (!(sm.culled = malloc((parts ? parts : 1) * sizeof(*sm.culled))))
		return err_sys(g->e, "rows");
	slot_map_init(g, &sm, maxreach);
	place_parallel(g, focal_part, &sm, parts);
	for (size_t t = 0; t < parts; t++)
		g->culled += sm.culled[t];
	free(sm.culled);
	return 0;
}

/*
 * Sky to pixels, slot by slot: the candidates of all slots in one pass over
 * the masks (slot s's rows, in catalog order, at g->cand[off[s] ..
 * off[s + 1]]), then each slot's exact pixels (g->px, g->py; NaN off the
 * projection), one slot a task.  sky_to_pixel() of a slot's rows is the
 * one place the engine turns sky positions into detector pixels; a slot's
 * failure is kept in its own err, reported when placing reaches it.
 */
struct pixel_job {
	struct engine *g;
	const size_t *off;
	struct err *err;                /* per slot */
};

static void pixel_part(void *arg, int wid, size_t s)
{
	struct pixel_job *j = arg;
	struct engine *g = j->g;
	size_t a = j->off[s], n = j->off[s + 1] - a;

	(void)wid;
	sky_to_pixel(&g->sky, g->slot[s].sca, n, g->px + a, g->py + a, g->px + a, g->py + a,
		     &j->err[s]);
}

static int pixel_step(struct engine *g, const struct rows *r, size_t *off, struct err *err)
{
	struct pixel_job j = { .g = g, .off = off, .err = err };
	int wcs = 0;

	memset(off, 0, (g->nslot + 1) * sizeof(*off));
	for (size_t i = 0; i < r->n; i++)
		for (uint32_t m = g->mask[i]; m; m &= m - 1)
			off[__builtin_ctz(m) + 1]++;
	for (int s = 0; s < g->nslot; s++)
		off[s + 1] += off[s];
	if (grow((void **)&g->cand, &g->cap_cand, off[g->nslot] + 1, sizeof(uint32_t)) < 0 ||
	    resize((void **)&g->px, g->cap_cand * sizeof(double)) < 0 ||
	    resize((void **)&g->py, g->cap_cand * sizeof(double)) < 0)
		return err_sys(g->e, "rows");
	{
		size_t at[32];

		memcpy(at, off, g->nslot * sizeof(*at));
		for (size_t i = 0; i < r->n; i++)
			for (uint32_t m = g->mask[i]; m; m &= m - 1) {
				size_t k = at[__builtin_ctz(m)]++;

				g->cand[k] = i;
				g->px[k] = r->ra[i];
				g->py[k] = r->dec[i];
			}
	}
	for (int s = 0; s < g->nslot; s++) {
		err_clear(&err[s]);
		wcs |= g->sky.sca[g->slot[s].sca - 1].geo.kind != GEOM_SIAF;
	}
	/* wcslib's projection (STIPS's geometry) sets itself up on first use:
	 * on this thread then */
	if (wcs)
		for (int s = 0; s < g->nslot; s++)
			pixel_part(&j, 0, s);
	else
		place_parallel(g, pixel_part, &j, g->nslot);
	return 0;
}

/* The placements of the chunk's rows on slot s, in catalog order: sky rows
 * whose mask names s at their exact pixels (pixel_step), x/y rows of its
 * SCA as given. */
static int place_on_slot(struct engine *g, const struct rows *r, struct batch *b, int s,
			 const int *model, const double *param, size_t nxy, const size_t *off,
			 struct err *err)
{
	size_t k = off[s], nc = off[s + 1];

	if (err[s].code != EXIT_OK) {
		*g->e = err[s];
		return -1;
	}
	if (!nxy) {
		for (; k < nc; k++) {
			size_t i = g->cand[k];

			if (!isnan(g->px[k]) &&
			    pend(g, b, r, i, model[i], &param[i * MAX_COLUMNS], s,
				  g->px[k], g->py[k]) < 0)
				return -1;
		}
		return 0;
	}
	/* Pixel rows for this SCA are merged in catalog order. */
	for (size_t i = 0; i < r->n; i++) {
		double x, y;

		if (isnan(r->ra[i])) {
			int sca = r->sca[i] ? r->sca[i] : g->slot[0].sca;

			if (sca != g->slot[s].sca)
				continue;
			x = r->x[i];
			y = r->y[i];
		} else {
			if (k >= nc || g->cand[k] != i)
				continue;
			x = g->px[k];
			y = g->py[k];
			k++;
			if (isnan(x))
				continue;
		}
		if (pend(g, b, r, i, model[i], &param[i * MAX_COLUMNS], s, x, y) < 0)
			return -1;
	}
	return 0;
}

/*
 * The chunk as seen at the exposure's date: its sky rows moved by their
 * proper motion and parallax (motion.h) into g->mra, g->mdec, and a copy of
 * r pointing at them (kept in the engine, so that its address, which
 * caches the models' column indices, is the same for every chunk).  An
 * exposure without a date sees the catalog's positions.
 */
static const struct rows *moved_rows(struct engine *g, const struct rows *r)
{
	if (!g->moved) {
		if (!(g->moved = malloc(sizeof(*g->moved)))) {
			err_sys(g->e, "rows");
			return NULL;
		}
		motion_observer(g->x->date, g->observer);
	}
	motion_apply(g->x->date, g->observer, r->n, r->ra, r->dec, r->pmra, r->pmdec,
		     r->parallax, r->epoch, g->mra, g->mdec);
	*g->moved = *r;
	g->moved->ra = g->mra;
	g->moved->dec = g->mdec;
	return g->moved;
}

/* Turn one chunk of rows into the placements of batch b. */
int place_batch(struct engine *g, const struct rows *r, struct batch *b)
{
	double *param, maxreach = 0;
	size_t nxy = 0, n = 0, off[33];
	int *model, rc = -1, pended = 0;
	struct err stopped, *perr;

	b->n = b->nparam = b->nserial = 0;
	if (r->spec_kind && place_colour_init(g) < 0)
		return -1;
	if (grow((void **)&g->fx, &g->cap_rows, r->n, sizeof(double)) < 0)
		return err_sys(g->e, "rows");
	/* all per-row arrays share cap_rows: grow them together (a failed
	 * one keeps its block, which engine_free() releases) */
	if (resize((void **)&g->fy, g->cap_rows * sizeof(double)) < 0 ||
	    resize((void **)&g->reach, g->cap_rows * sizeof(double)) < 0 ||
	    resize((void **)&g->mask, g->cap_rows * sizeof(uint32_t)) < 0 ||
	    resize((void **)&g->model, g->cap_rows * sizeof(int)) < 0 ||
	    resize((void **)&g->param, g->cap_rows * MAX_COLUMNS * sizeof(double)) < 0 ||
	    resize((void **)&g->listed, g->cap_rows) < 0 ||
	    resize((void **)&g->mra, g->cap_rows * sizeof(double)) < 0 ||
	    resize((void **)&g->mdec, g->cap_rows * sizeof(double)) < 0)
		return err_sys(g->e, "rows");
	if (r->pmra && !isnan(g->x->date) && (r = moved_rows(g, r)) == NULL)
		return -1;
	memset(g->listed, 0, r->n);
	/* a catalog fact, for models with a half-light radius */
	g->flux_meaning = g->o->sersic_flux ? strcmp(g->o->sersic_flux, "ie") == 0
			: r->sersic_ie;

	/* Parameters of all rows are kept in one array, MAX_COLUMNS a row;
	 * kept from chunk to chunk (a fresh block each chunk costs the kernel
	 * zeroing its pages every time). */
	param = g->param;
	model = g->model;
	if (!(perr = malloc(g->nslot * sizeof(*perr))))
		return err_sys(g->e, "rows");
	if (read_models(g, r, model, param, &nxy, &maxreach) < 0 ||
	    focal_step(g, r, maxreach) < 0 || pixel_step(g, r, off, perr) < 0)
		goto out;
	for (int s = 0; s < g->nslot && !pended; s++)
		if ((g->pass_slots >> s & 1) &&
		    place_on_slot(g, r, b, s, model, param, nxy, off, perr) < 0) {
			/* reported only if no placement before it fails */
			pended = -1;
			stopped = *g->e;
			err_clear(g->e);
		}
	if (settle_all(g, r, b) < 0)
		goto out;
	if (pended < 0) {
		*g->e = stopped;
		goto out;
	}
	for (size_t k = 0; k < b->n; k++) {
		int kept;

		if (keep(g, b, r, k, &kept) < 0)
			goto out;
		if (kept && n != k)
			b->p[n] = b->p[k];
		n += kept;
	}
	b->n = n;
	rc = 0;
out:
	free(perr);
	return rc;
}

/* Bin the placements of b by the tiles their boxes touch, in placement
 * order, and list the tiles they touch.  Only b is written, so this runs
 * while the pool draws another batch; place_tiles() then allocates. */

int place_bin(struct engine *g, struct batch *b)
{
	size_t ntot = (size_t)g->nslot * g->ntile, total = 0;
	/* x / T as (x m) >> 40, exact for every pixel index x and side T
	 * (the error, under x / 2^40, cannot reach the next multiple of 1 / T):
	 * a division per box edge was most of the binning's time */
	uint64_t m = ((uint64_t)1 << 40) / (uint64_t)g->tile + 1;
	int ntx = g->ntx;

	if (!b->count && !(b->count = calloc(ntot + 1, sizeof(*b->count))))
		return err_sys(g->e, "tiles");
	memset(b->count, 0, (ntot + 1) * sizeof(*b->count));
	if (grow((void **)&b->span, &b->capspan, b->n + 1, sizeof(*b->span)) < 0)
		return err_sys(g->e, "tiles");
	/* count, keeping each placement's span, so that the fill below reads
	 * 8 bytes a placement rather than its 200 again */
	for (size_t i = 0; i < b->n; i++) {
		const struct wfs_box *bx = &b->p[i].box;
		uint32_t tx0 = (uint32_t)((uint64_t)bx->x0 * m >> 40);
		uint32_t ty0 = (uint32_t)((uint64_t)bx->y0 * m >> 40);
		uint32_t nx = (uint32_t)((uint64_t)(bx->x1 - 1) * m >> 40) - tx0 + 1;
		uint32_t ny = (uint32_t)((uint64_t)(bx->y1 - 1) * m >> 40) - ty0 + 1;
		uint32_t t0 = (uint32_t)((size_t)b->p[i].slot * g->ntile) + ty0 * ntx + tx0;

		b->span[i] = (struct tile_span){ t0, (uint16_t)nx, (uint16_t)ny };
		for (uint32_t y = 0; y < ny; y++)
			for (uint32_t x = 0; x < nx; x++)
				b->count[t0 + y * ntx + x]++;
		total += (size_t)nx * ny;
	}
	if (total > UINT32_MAX)
		return err_set(g->e, EXIT_SYSTEM, "too many placements in one chunk");
	if (grow((void **)&b->items, &b->capitems, total + 1, sizeof(*b->items)) < 0)
		return err_sys(g->e, "tiles");
	if (!b->active && !(b->active = malloc(ntot * sizeof(*b->active))))
		return err_sys(g->e, "tiles");
	/* counts -> start offsets, and the list of active tiles */
	b->nactive = 0;
	uint32_t run = 0;
	for (size_t t = 0; t < ntot; t++) {
		uint32_t c = b->count[t];

		b->count[t] = run;
		if (c)
			b->active[b->nactive++] = t;
		run += c;
	}
	b->count[ntot] = run;
	/* fill: count[t] advances to the end of tile t's range */
	for (size_t i = 0; i < b->n; i++) {
		struct tile_span sp = b->span[i];

		for (uint32_t y = 0; y < sp.ny; y++)
			for (uint32_t x = 0; x < sp.nx; x++)
				b->items[b->count[sp.t0 + y * ntx + x]++] = (uint32_t)i;
	}
	/* shift back so count[t] is tile t's start again */
	for (size_t t = ntot; t > 0; t--)
		b->count[t] = b->count[t - 1];
	b->count[0] = 0;
	b->nitems = total;
	return 0;
}

/* Allocate the tiles b's list names that no batch has touched yet: after
 * the pool's wait, so that no worker sees the tile arrays change. */
int place_tiles(struct engine *g, struct batch *b)
{
	for (size_t k = 0; k < b->nactive; k++) {
		size_t t = b->active[k];
		struct slot *sl = &g->slot[t / g->ntile];
		size_t lt = t % g->ntile;

		if (!sl->tile[lt] && !(sl->tile[lt] = tile_alloc(g->tile)))
			return err_sys(g->e, "tile memory");
	}
	return 0;
}
