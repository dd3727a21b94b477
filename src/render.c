/*
 * render.c - the workers: each draws whole tiles of one batch.
 *
 * place.c bins a chunk's placements by tile; each active tile is one task
 * of the pool, drawn by one worker, its placements in catalog order, so a
 * tile's pixels are the same sums in the same order whatever the number of
 * threads.  A worker keeps its own scratch memory, FFT buffers and each
 * model's per-thread state (thread_start() on its first source of that
 * model, thread_stop() when the exposure ends).
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>

#include "clock.h"
#include "engine.h"
#include "err.h"
#include "fftconv.h"
#include "pool.h"

/* A model failed in worker w on tile task: its record names the model (and
 * the source) after the plugin's message; what is the message when the
 * plugin recorded none, as it must.  The other workers stop at their next
 * tile. */
static void model_failed(struct worker *w, size_t task, const char *model, const char *what,
			 const struct wfs_source *src)
{
	err_set(&w->err, EXIT_PLUGIN, "%s" MODEL_SILENT, what);
	if (src)
		err_prefix(&w->err, "model '%s': source %lld on SCA %d", model, src->id,
			   src->sca);
	else
		err_prefix(&w->err, "model '%s'", model);
	w->err_task = task;
	atomic_store(&w->g->failed, 1);
}

void render_errors_collect(struct engine *g)
{
	struct worker *first = NULL;

	for (int i = 0; g->w && i < g->nworker; i++)
		if (g->w[i].err.code != EXIT_OK &&
		    (!first || g->w[i].err_task < first->err_task))
			first = &g->w[i];
	if (first && g->e->code == EXIT_OK)
		err_set(g->e, first->err.code, "%s", first->err.msg);
	for (int i = 0; g->w && i < g->nworker; i++)
		err_clear(&g->w[i].err);
}

/* Placements prefetched ahead of the one drawn, and the placement whose
 * tile rows are (only for windows of at most RENDER_ROWS_MAX rows: a
 * larger one streams, which the hardware prefetcher follows). */
#define RENDER_AHEAD 4
#define RENDER_ROWS_AHEAD 2
#define RENDER_ROWS_MAX 24

/* Worker: render every placement of one active tile, in placement order. */
void render_tile(void *arg, int wid, size_t task)
{
	struct engine *g = arg;
	const struct batch *b = g->rendering;
	struct worker *w = &g->w[wid];
	size_t t = b->active[task], lt = t % g->ntile;
	int T = g->tile, tx = lt % g->ntx, ty = lt / g->ntx;
	int x0 = tx * T, y0 = ty * T;
	double *tile = g->slot[t / g->ntile].tile[lt];

	double t0 = engine_clock();

	if (atomic_load(&g->failed))
		return;
	host_worker(w);
	for (uint32_t k = b->count[t]; k < b->count[t + 1]; k++) {
		const struct placement *p = &b->p[b->items[k]];
		struct plugin *pl = &g->plugins.p[p->model];
		struct wfs_window win;

		/* A tile's placements are scattered over the chunk's array
		 * (catalog order): fetch a few ahead, a placement is three
		 * cache lines. */
		if (k + RENDER_AHEAD < b->count[t + 1]) {
			const char *q = (const char *)&b->p[b->items[k + RENDER_AHEAD]];

			for (size_t c = 0; c < sizeof(*p); c += 64)
				__builtin_prefetch(q + c);
		}
		/* and the tile rows of the one after next (its placement came
		 * in two turns ago): a faint star's few short rows are too far
		 * apart for the hardware to see coming */
		if (k + RENDER_ROWS_AHEAD < b->count[t + 1]) {
			const struct placement *q = &b->p[b->items[k + RENDER_ROWS_AHEAD]];
			int qx0 = q->box.x0 > x0 ? q->box.x0 : x0, qy0 = q->box.y0 > y0 ? q->box.y0 : y0;
			int qx1 = q->box.x1 < x0 + T ? q->box.x1 : x0 + T;
			int qy1 = q->box.y1 < y0 + T ? q->box.y1 : y0 + T;

			if (qx0 < qx1 && qy1 - qy0 <= RENDER_ROWS_MAX)
				for (int y = qy0; y < qy1; y++) {
					const double *r = tile + (size_t)(y - y0) * T;

					__builtin_prefetch(r + (qx0 - x0), 1);
					__builtin_prefetch(r + (qx1 - 1 - x0), 1);
				}
		}

		if (!w->started[p->model]) {
			if (pl->m->thread_start &&
			    pl->m->thread_start(pl->state, &w->tstate[p->model]) < 0) {
				model_failed(w, task, pl->name, "thread_start() failed", NULL);
				host_worker(NULL);
				return;
			}
			w->started[p->model] = 1;
		}
		win.x0 = p->box.x0 > x0 ? p->box.x0 : x0;
		win.y0 = p->box.y0 > y0 ? p->box.y0 : y0;
		win.nx = (p->box.x1 < x0 + T ? p->box.x1 : x0 + T) - win.x0;
		win.ny = (p->box.y1 < y0 + T ? p->box.y1 : y0 + T) - win.y0;
		win.stride = T;
		win.pix = tile + (size_t)(win.y0 - y0) * T + (win.x0 - x0);
		if (pl->m->render(pl->state, w->tstate[p->model], w, &p->src, &win) < 0) {
			model_failed(w, task, pl->name, "render() failed", &p->src);
			host_worker(NULL);
			return;
		}
	}
	host_worker(NULL);
	g->t_render[wid] += engine_clock() - t0;
}

/*
 * After the last chunk: the light the models gathered while their sources
 * were prepared (wfs_model gather and spread), added once per tile.  First
 * every (SCA, model) pair is gathered, a task each; then every tile of the
 * SCAs some model lit is spread, a task each (tiles no source touched are
 * allocated here), each tile's models in model order, so the sums are the
 * same for any number of threads.  The time counts as rendering.
 */
struct spread_job {
	struct engine *g;
	int nmodel;
	unsigned char has[PLUGIN_MAX];  /* the model spreads */
	unsigned char lit[WFS_NSCA][PLUGIN_MAX];
	int ntask;              /* the tiles of the lit SCAs: slot, then tile */
	int tslot[WFS_NSCA];    /* the lit slots */
};

static void gather_task(void *arg, int wid, size_t task)
{
	struct spread_job *j = arg;
	struct engine *g = j->g;
	struct worker *w = &g->w[wid];
	int s = (int)(task / j->nmodel), m = (int)(task % j->nmodel);
	struct plugin *pl = &g->plugins.p[m];
	double t0 = engine_clock();
	int r;

	/* an SCA is gathered in the pass that draws it (run.c) */
	if (atomic_load(&g->failed) || !j->has[m] || !(g->pass_slots >> s & 1))
		return;
	host_worker(w);
	if ((r = pl->m->gather(pl->state, w, g->slot[s].sca)) < 0)
		model_failed(w, task, pl->name, "gather() failed", NULL);
	else
		j->lit[s][m] = r > 0;
	host_worker(NULL);
	g->t_render[wid] += engine_clock() - t0;
}

static void spread_task(void *arg, int wid, size_t task)
{
	struct spread_job *j = arg;
	struct engine *g = j->g;
	struct worker *w = &g->w[wid];
	int s = j->tslot[task / g->ntile], lt = (int)(task % g->ntile);
	int T = g->tile, x0 = lt % g->ntx * T, y0 = lt / g->ntx * T;
	/* the rows drawn, and with the detector levels the row on either
	 * side of them (place.c's keep()) */
	int margin = g->o->level ? 1 : 0;
	int ya = y0 > g->ylo - margin ? y0 : g->ylo - margin;
	int yb = y0 + T < g->yhi + margin ? y0 + T : g->yhi + margin;
	double *tile = g->slot[s].tile[lt];
	double t0 = engine_clock();
	struct wfs_window win;

	if (atomic_load(&g->failed) || !tile)
		return;
	ya = ya > 0 ? ya : 0;
	yb = yb < WFS_NPIX ? yb : WFS_NPIX;
	win.x0 = x0;
	win.y0 = ya;
	win.nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;
	win.ny = yb - ya;
	win.stride = T;
	win.pix = tile + (size_t)(ya - y0) * T;
	if (win.ny <= 0)
		return;
	host_worker(w);
	for (int m = 0; m < j->nmodel; m++) {
		struct plugin *pl = &g->plugins.p[m];

		if (j->lit[s][m] && pl->m->spread(pl->state, w, g->slot[s].sca, &win) < 0) {
			model_failed(w, task, pl->name, "spread() failed", NULL);
			break;
		}
	}
	host_worker(NULL);
	g->t_render[wid] += engine_clock() - t0;
}

int render_spread(struct engine *g)
{
	struct spread_job *j;
	int any = 0, T = g->tile;

	if (!g->nslot || !(j = calloc(1, sizeof(*j))))
		return g->nslot ? err_sys(g->e, "memory") : 0;
	j->g = g;
	j->nmodel = g->plugins.n;
	for (int m = 0; m < g->plugins.n; m++) {
		const struct plugin *pl = &g->plugins.p[m];

		j->has[m] = pl->ready && WFS_HAS(pl->m->size, struct wfs_model, spread) &&
			    pl->m->gather && pl->m->spread;
		any |= j->has[m];
	}
	if (!any) {
		free(j);
		return 0;
	}
	pool_run_timed(g->pool, gather_task, j, (size_t)g->nslot * j->nmodel, g->t_render_cpu);
	render_errors_collect(g);
	if (atomic_load(&g->failed) || g->e->code != EXIT_OK)
		goto fail;
	for (int s = 0; s < g->nslot; s++) {
		int lit = 0;

		for (int m = 0; m < j->nmodel; m++)
			lit |= j->lit[s][m];
		if (!lit)
			continue;
		/* the tiles of the rows drawn that a model lights */
		for (int lt = 0; lt < g->ntile; lt++) {
			int x0 = lt % g->ntx * T, y0 = lt / g->ntx * T, want = 0;
			struct wfs_window q = { NULL, T, x0, y0,
						x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T,
						y0 + T > WFS_NPIX ? WFS_NPIX - y0 : T };

			if (!(y0 + T > g->ylo - 1 && y0 < g->yhi + 1) || g->slot[s].tile[lt])
				continue;
			for (int m = 0; m < j->nmodel && !want; m++)
				want = j->lit[s][m] && g->plugins.p[m].m->spread(g->plugins.p[m].state,
										  NULL, g->slot[s].sca, &q) > 0;
			if (want && !(g->slot[s].tile[lt] = tile_alloc(T))) {
				free(j);
				return err_sys(g->e, "tile memory");
			}
		}
		j->tslot[j->ntask++] = s;
	}
	if (j->ntask) {
		pool_run_timed(g->pool, spread_task, j, (size_t)j->ntask * g->ntile,
			       g->t_render_cpu);
		render_errors_collect(g);
	}
fail:
	free(j);
	return atomic_load(&g->failed) || g->e->code != EXIT_OK ? -1 : 0;
}

int render_threads_init(struct engine *g)
{
	g->nworker = pool_threads(g->pool);
	if (!(g->w = calloc(g->nworker, sizeof(*g->w))) ||
	    !(g->t_render = calloc(g->nworker, sizeof(*g->t_render))) ||
	    !(g->t_render_cpu = calloc(g->nworker, sizeof(*g->t_render_cpu))))
		return err_sys(g->e, "threads");
	for (int i = 0; i < g->nworker; i++)
		g->w[i].g = g;
	return 0;
}

/* The models' thread_stop() and the workers' memory.  The workers must be
 * idle. */
void render_threads_stop(struct engine *g)
{
	for (int i = 0; g->w && i < g->nworker; i++) {
		for (int m = 0; m < g->plugins.n; m++)
			if (g->w[i].started[m] && g->plugins.p[m].m->thread_stop)
				g->plugins.p[m].m->thread_stop(g->plugins.p[m].state,
							       g->w[i].tstate[m]);
		free(g->w[i].scratch);
		fftconv_thread_free(g->w[i].fft);
	}
	free(g->w);
	free(g->t_render);
	free(g->t_render_cpu);
	g->w = NULL;
	g->t_render = NULL;
	g->t_render_cpu = NULL;
}
