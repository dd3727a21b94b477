/* scene.c - the streaming engine: catalogs in, FITS out; see scene.h. */
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <stdint.h>
#include <unistd.h>

#include "catalog.h"
#include "err.h"
#include "fftconv.h"
#include "fitsout.h"
#include "instrument.h"
#include "noise.h"
#include "plugin.h"
#include "pool.h"
#include "psf.h"
#include "scene.h"
#include "tempfile.h"
#include "sky.h"
#include "wfiscene/model.h"

/* Room beyond an SCA edge, in pixels, within which a point source may still
 * throw light onto it: the 176-pixel extra-bright box's half-width. */
#define POINT_REACH 88.0
#define MAX_COLUMNS PLUGIN_COLUMNS_MAX

/* One requested SCA: its image as a grid of tiles, allocated on first touch. */
struct slot {
	int sca;
	double **tile;          /* ntx * nty tiles, NULL until touched */
};

/* A source placed on one SCA. */
struct placement {
	struct wfs_source src;
	struct wfs_box box;     /* footprint clipped to the detector */
	int model;
	int slot;
	size_t param_off;       /* into batch.param */
};

/* The placements of one chunk, binned by tile. */
struct batch {
	struct placement *p;
	size_t n, cap;
	double *param;
	size_t nparam, capparam;
	uint32_t *count;        /* per global tile, then start offsets */
	uint32_t *items;        /* placement indices grouped by tile */
	size_t nitems, capitems;
	uint32_t *active;       /* global tiles with placements */
	size_t nactive;
};

/* Per worker thread: scratch memory, FFT buffers, models' thread state. */
struct worker {
	struct engine *g;
	void *scratch;
	size_t scratch_cap;
	struct fftconv_thread *fft;
	void *tstate[PLUGIN_MAX];
	unsigned char started[PLUGIN_MAX];
};

struct type_cache {
	char name[64];
	int model;
};

struct engine {
	const struct scene_opts *o;
	struct err *e;
	pthread_mutex_t err_mu;
	pthread_t main_thread;          /* the one that may load PSF grids */
	atomic_int failed;

	struct sky sky;
	int tile, ntx, nty, ntile;      /* tile side, tiles per axis, per SCA */
	int ylo, yhi;                   /* the rows drawn and written, [ylo, yhi) */
	int nslot;
	struct slot slot[WFS_NSCA];
	int slot_of[WFS_NSCA + 1];      /* SCA -> slot, or -1 */

	struct psf_grid *grid[WFS_NSCA][3];
	struct psf_grid *user_grid;     /* --psf FILE without %d: all SCAs */
	struct psf_build_opts pbo;

	struct plugins plugins;
	struct wfs_host host;
	struct fftconv *fft;
	struct pool *pool;
	struct worker *w;
	int nworker;

	char filter_name[16], exptime_str[32], seed_str[32];
	char bkg_str[32], readnoise_str[32], noise_str[64];
	const char *sersic_flux_now;    /* "total" or "ie" for the catalog being read */

	struct type_cache types[PLUGIN_MAX];
	int ntypes;
	int colidx[PLUGIN_MAX][MAX_COLUMNS];
	const struct rows *colidx_rows[PLUGIN_MAX];

	double *fx, *fy, *px, *py, *reach;
	uint32_t *cand;
	uint32_t *mask;                 /* slots the row may reach */
	size_t cap_rows;

	struct batch b[2];
	const struct batch *rendering;

	FILE *placed;
	char placed_tmp[PATH_MAX];
	int index;                      /* exposure number, 0-based */

	unsigned long long rows_read, placements, culled, offdet;
	unsigned long long tiles_drawn, tiles;  /* before noise, and in all */
	unsigned long long per_model[PLUGIN_MAX];
	double flux_requested[WFS_NSCA];        /* sum of placed sources' flux */
	unsigned long long placed_on[WFS_NSCA];
	double image_sum[WFS_NSCA];             /* drawn light, before noise */
	double t_read, t_place, t_wait, t_noise, t_write, t_total;
	double *t_render;                       /* per worker: busy seconds */
	struct timespec t_start, t_progress;
	int progress;                           /* stderr is a terminal */
};

static double now(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* A progress line on a terminal, at most a few times a second. */
static void progress(struct engine *g, const char *stage, int force)
{
	double t = now(), since = t - (g->t_progress.tv_sec + 1e-9 * g->t_progress.tv_nsec);
	double el = t - (g->t_start.tv_sec + 1e-9 * g->t_start.tv_nsec);

	if (!g->progress || (!force && since < 0.25))
		return;
	clock_gettime(CLOCK_MONOTONIC, &g->t_progress);
	fprintf(stderr, "\rwfiscene: %llu rows, %.0f rows/s, %.1f s, %-10s", g->rows_read,
		el > 0 ? g->rows_read / el : 0.0, el, stage);
	fflush(stderr);
}

/* Names of the --placed temporary files (one per exposure), for the signal
 * handler: the one piece of global state, because a handler has no context. */
#define MAX_EXPOSURES 64
static char placed_tmp_signal[MAX_EXPOSURES][PATH_MAX];

/* ---- host services lent to plugins ---- */

/* Said of a plugin callback that returned -1 without host->error(). */
#define MODEL_SILENT ", with no message (the plugin must give one with host->error())"

static int host_error(void *ctx, const char *fmt, ...)
{
	struct engine *g = ctx;
	char msg[1024];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	pthread_mutex_lock(&g->err_mu);
	err_set(g->e, EXIT_PLUGIN, "%s", msg);
	pthread_mutex_unlock(&g->err_mu);
	return -1;
}

static void host_log(void *ctx, int level, const char *fmt, ...)
{
	struct engine *g = ctx;
	va_list ap;

	if (level > g->o->verbose)
		return;
	va_start(ap, fmt);
	fputs("wfiscene: ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

static const char *host_setting(void *ctx, const char *key)
{
	struct engine *g = ctx;

	if (!strcmp(key, "filter"))
		return g->filter_name;
	if (!strcmp(key, "exptime"))
		return g->exptime_str;
	if (!strcmp(key, "seed"))
		return g->seed_str;
	if (!strcmp(key, "sersic-flux"))
		return g->sersic_flux_now;
	if (!strcmp(key, "sersic"))
		return g->o->sersic;
	if (!strcmp(key, "background"))
		return g->bkg_str;
	if (!strcmp(key, "readnoise"))
		return g->readnoise_str;
	if (!strcmp(key, "noise"))
		return g->noise_str;
	/* --set key=value: the last one given wins */
	const char *hit = NULL;
	size_t n = strlen(key);

	for (const char *const *kv = g->o->settings; kv && *kv; kv++)
		if (!strncmp(*kv, key, n) && (*kv)[n] == '=')
			hit = *kv + n + 1;
	return hit;
}

static const struct psf_grid *grid_for(const struct engine *g, int sca, int cls)
{
	if (g->user_grid)
		return g->user_grid;
	return g->grid[sca - 1][cls];
}

static int need_grid(struct engine *g, int sca, int cls);

/* Grids are loaded (or built) the first time a model asks for one from the
 * main thread, in prepare() or footprint(): a scene whose models never draw
 * with the ePSF builds none.  Workers only read grids already loaded. */
static int host_epsf(void *ctx, int sca, double x, double y, int cls,
		     struct wfs_epsf *out)
{
	struct engine *g = ctx;
	const struct psf_grid *grid;

	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > 2)
		return host_error(ctx, "no ePSF for SCA %d class %d", sca, cls);
	if (!(grid = grid_for(g, sca, cls))) {
		if (!pthread_equal(pthread_self(), g->main_thread))
			return host_error(ctx, "ePSF of SCA %d class %d asked for in render() "
					  "but not in prepare() or footprint()", sca, cls);
		if (need_grid(g, sca, cls) < 0)
			return -1;
		grid = grid_for(g, sca, cls);
	}
	psf_grid_at(grid, x, y, out);
	return 0;
}

static void *host_scratch(void *thread, size_t bytes)
{
	struct worker *w = thread;

	if (bytes > w->scratch_cap) {
		size_t cap = bytes + bytes / 4 + 4096;

		free(w->scratch);
		w->scratch_cap = 0;
		if (posix_memalign(&w->scratch, 64, cap))
			return w->scratch = NULL;
		w->scratch_cap = cap;
	}
	return w->scratch;
}

static int host_convolve(void *ctx, void *thread, double *img, int nx, int ny,
			 const double *kernel, int kn)
{
	struct engine *g = ctx;
	struct worker *w = thread;

	if (!w->fft && !(w->fft = fftconv_thread_new()))
		return host_error(ctx, "out of memory for FFT buffers");
	if (fftconv_convolve(g->fft, w->fft, img, nx, ny, kernel, kn) < 0)
		return host_error(ctx, "FFT convolution of a %d x %d image failed", nx, ny);
	return 0;
}

/* ---- PSF grids ---- */

/* Make sure the ePSF grid of (sca, cls) is loaded.  Main thread only. */
/* A --psf file made for another filter or (with %d) another SCA than it
 * serves is most likely a mistake, but not certainly one: say so. */
static void psf_file_warn(struct engine *g, const struct psf_grid *grid,
			  const char *path, int sca)
{
	if (grid->filter >= 0 && grid->filter != g->o->filter)
		host_log(g, 0, "warning: %s: PSF for filter %s, the scene's is %s",
			 path, filter_get(grid->filter)->name, g->filter_name);
	if (sca && grid->sca && grid->sca != sca)
		host_log(g, 0, "warning: %s: PSF for SCA %d serves SCA %d", path,
			 grid->sca, sca);
}

static int need_grid(struct engine *g, int sca, int cls)
{
	const struct scene_opts *o = g->o;
	struct psf_grid *grid;

	if (grid_for(g, sca, cls))
		return 0;
	if (strcmp(o->psf, "builtin")) {
		/* A user file: per SCA when the name holds %d, and then its one
		 * size serves every brightness class. */
		char path[PATH_MAX];

		if (g->grid[sca - 1][0]) {
			g->grid[sca - 1][cls] = g->grid[sca - 1][0];
			return 0;
		}
		snprintf(path, sizeof(path), o->psf, sca);
		if (!(grid = psf_grid_read(path, g->e)))
			return -1;
		psf_file_warn(g, grid, path, sca);
		if (grid->kind == PSF_OPTICAL && psf_make_epsf(grid, g->e) < 0) {
			psf_grid_free(grid);
			return -1;
		}
		g->grid[sca - 1][0] = grid;
		g->grid[sca - 1][cls] = grid;
		return 0;
	}
	host_log(g, 1, "ePSF grid for %s SCA %d, %d samples: building or loading",
		 g->filter_name, sca, psf_class_n[cls]);
	if (!(grid = psf_builtin(o->filter, sca, cls, PSF_EPSF, &g->pbo, g->e)))
		return -1;
	g->grid[sca - 1][cls] = grid;
	return 0;
}

/* ---- reading rows into placements ---- */

/*
 * A zeroed tile.  Tiles are mapped from the kernel directly: its pages come
 * zeroed and are only touched by the worker that first draws on them,
 * whereas calloc() would zero them with memset in the main thread once
 * glibc's mmap threshold has risen above a tile's size (it does after the
 * first large free).  18 SCAs of 512-pixel tiles are 2.4 GB of doubles.
 */
static double *tile_alloc(int T)
{
	void *p = mmap(NULL, (size_t)T * T * sizeof(double), PROT_READ | PROT_WRITE,
		       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);

	return p == MAP_FAILED ? NULL : p;
}

static void tile_free(double *p, int T)
{
	if (p)
		munmap(p, (size_t)T * T * sizeof(double));
}

static int grow(void **p, size_t *cap, size_t need, size_t size)
{
	size_t n = *cap ? *cap : 256;
	void *q;

	if (need <= *cap)
		return 0;
	while (n < need)
		n *= 2;
	if (!(q = realloc(*p, n * size)))
		return -1;
	*p = q;
	*cap = n;
	return 0;
}

/* The model drawing rows of type name ("sersic" picks the scene's method). */
static int resolve_type(struct engine *g, const char *name)
{
	char real[64];
	int m;

	for (int i = 0; i < g->ntypes; i++)
		if (!strcmp(g->types[i].name, name))
			return g->types[i].model;
	if (!strcmp(name, "sersic"))
		snprintf(real, sizeof(real), "sersic-%s", g->o->sersic);
	else
		snprintf(real, sizeof(real), "%s", name);
	if ((m = plugins_get(&g->plugins, real, g->e)) < 0)
		return -1;
	if (g->ntypes < PLUGIN_MAX) {
		snprintf(g->types[g->ntypes].name, sizeof(g->types[0].name), "%s", name);
		g->types[g->ntypes++].model = m;
	}
	return m;
}

/* The chunk's column index of each column model m reads (-1 if absent). */
static int model_columns(struct engine *g, const struct rows *r, int m)
{
	const struct wfs_model *md = g->plugins.p[m].m;

	if (g->colidx_rows[m] == r)
		return 0;
	if (md->ncolumns > MAX_COLUMNS)
		return err_set(g->e, EXIT_PLUGIN, "model '%s' reads %d columns; at most %d",
			       md->name, md->ncolumns, MAX_COLUMNS);
	for (int c = 0; c < md->ncolumns; c++) {
		g->colidx[m][c] = rows_column(r, md->columns[c].name);
		if (g->colidx[m][c] < 0 && md->columns[c].required)
			return err_set(g->e, EXIT_INPUT,
				       "%s: column '%s', required by model '%s', is missing",
				       r->file, md->columns[c].name, md->name);
	}
	g->colidx_rows[m] = r;
	return 0;
}

static double zeropoint(const struct engine *g, int sca)
{
	return g->o->zp_stips ? filter_stips_zp(g->o->filter)
			      : filter_get(g->o->filter)->zp_ab[sca - 1];
}

/* The row's flux in counts/s on SCA sca. */
static double counts_on(const struct engine *g, const struct rows *r, size_t i, int sca)
{
	double v = r->flux[i];

	switch (r->unit[i]) {
	case UNIT_COUNTS:
		return v;
	case UNIT_ABMAG:
		return pow(10.0, -0.4 * (v - zeropoint(g, sca)));
	default:
		/* unit_to_counts() goes through the SCA's RTI zeropoint, as
		 * 1 / PHOTFNU; STIPS's fixed zeropoint zs gives PHOTFNU's
		 * ratio 10^(0.4 (zs - z_rti)) on top of it. */
		if (g->o->zp_stips)
			return v * unit_to_counts(g->o->filter, sca, r->unit[i]) *
			       pow(10.0, 0.4 * (filter_stips_zp(g->o->filter) -
						filter_get(g->o->filter)->zp_ab[sca - 1]));
		return v * unit_to_counts(g->o->filter, sca, r->unit[i]);
	}
}

/* Bright sources get the bigger ePSF boxes; a magnitude equal to a limit
 * counts as the brighter class (STIPS drops such sources). */
static int psf_class_of(const struct engine *g, double mag)
{
	if (mag <= g->o->xbright_limit)
		return WFS_PSF_XBRIGHT;
	if (mag <= g->o->bright_limit)
		return WFS_PSF_BRIGHT;
	return WFS_PSF_NORMAL;
}

/* Fill src for row i on SCA sca at pixel (x, y), load its ePSF class and let
 * the model check and prepare it.  Returns 0 or -1. */
static int make_source(struct engine *g, const struct rows *r, size_t i, int m,
		       const double *param, int sca, double x, double y,
		       struct wfs_source *src)
{
	const struct wfs_model *md = g->plugins.p[m].m;

	memset(src, 0, sizeof(*src));
	src->x = x;
	src->y = y;
	src->sca = sca;
	src->flux = counts_on(g, r, i, sca);
	src->mag = zeropoint(g, sca) - 2.5 * log10(src->flux);
	src->psf_class = psf_class_of(g, src->mag);
	src->id = r->id[i];
	src->param = param;
	if (!isfinite(src->flux) || src->flux <= 0)
		return err_set(g->e, EXIT_INPUT, "%s:%ld: flux %g converts to %g counts/s "
			       "on SCA %d: not a positive finite number", r->file,
			       r->line[i], r->flux[i], src->flux, sca);
	/* The image is float32 (at most 3.4e38): one source may bring up to
	 * 1e32 in the image's unit, so no sum of sources can overflow it. */
	if (src->flux * (g->o->bunit_counts ? g->o->exptime : 1) > 1e32)
		return err_set(g->e, EXIT_INPUT, "%s:%ld: flux %g gives %g %s on SCA %d, "
			       "more than the 1e32 that one source may put in a "
			       "float32 image", r->file, r->line[i], r->flux[i],
			       src->flux * (g->o->bunit_counts ? g->o->exptime : 1),
			       g->o->bunit_counts ? "counts" : "counts/s", sca);
	if (md->prepare && md->prepare(g->plugins.p[m].state, src) < 0) {
		/* A refused row is bad input; a refusal without a message is
		 * a broken plugin; a host service that failed under it (a
		 * PSF file that cannot be read) keeps its own message and
		 * status. */
		if (g->e->code != EXIT_OK && g->e->code != EXIT_PLUGIN)
			return -1;
		if (g->e->code == EXIT_OK)
			err_set(g->e, EXIT_PLUGIN, "prepare() failed" MODEL_SILENT);
		else
			g->e->code = EXIT_INPUT;
		err_prefix(g->e, "%s:%ld: model '%s'", r->file, r->line[i], md->name);
		return -1;
	}
	return 0;
}

static int footprint(struct engine *g, const struct rows *r, size_t i, int m,
		     const struct wfs_source *src, struct wfs_box *box)
{
	const struct wfs_model *md = g->plugins.p[m].m;

	if (md->footprint(g->plugins.p[m].state, src, box) < 0) {
		err_set(g->e, EXIT_PLUGIN, "footprint() failed" MODEL_SILENT);
		err_prefix(g->e, "%s:%ld: model '%s'", r->file, r->line[i], md->name);
		return -1;
	}
	return 0;
}

static int add_placement(struct engine *g, struct batch *b, const struct rows *r,
			 size_t i, int m, const double *param, int slot, double x,
			 double y)
{
	const struct wfs_model *md = g->plugins.p[m].m;
	struct placement *p;
	struct wfs_source src;
	struct wfs_box box;

	if (make_source(g, r, i, m, param, g->slot[slot].sca, x, y, &src) < 0 ||
	    footprint(g, r, i, m, &src, &box) < 0)
		return -1;
	if (box.x0 < 0) box.x0 = 0;
	if (box.y0 < 0) box.y0 = 0;
	if (box.x1 > WFS_NPIX) box.x1 = WFS_NPIX;
	if (box.y1 > WFS_NPIX) box.y1 = WFS_NPIX;
	if (box.x0 >= box.x1 || box.y0 >= box.y1) {
		g->offdet++;    /* all its light misses this SCA */
		return 0;
	}
	g->placements++;
	g->per_model[m]++;
	g->flux_requested[src.sca - 1] += src.flux;
	g->placed_on[src.sca - 1]++;
	if (g->placed &&
	    fprintf(g->placed, "%lld,%d,%.4f,%.4f,%.6g,%.4f,%s\n", src.id, src.sca,
		    src.x + 1, src.y + 1, src.flux, src.mag, md->name) < 0)
		return err_sys(g->e, "%s", g->o->placed);
	/* With --rows, counted and listed as in a run of the whole SCA (the
	 * part's header is that run's), but drawn only in the rows written:
	 * the windows are cut there, and a model gives the same pixels for
	 * any windows. */
	if (box.y0 < g->ylo)
		box.y0 = g->ylo;
	if (box.y1 > g->yhi)
		box.y1 = g->yhi;
	if (box.y0 >= box.y1)
		return 0;
	if (grow((void **)&b->p, &b->cap, b->n + 1, sizeof(*b->p)) < 0 ||
	    grow((void **)&b->param, &b->capparam, b->nparam + md->ncolumns + 1,
		 sizeof(double)) < 0)
		return err_sys(g->e, "placements");
	p = &b->p[b->n++];
	p->src = src;
	p->box = box;
	p->model = m;
	p->slot = slot;
	p->param_off = b->nparam;
	memcpy(b->param + b->nparam, param, md->ncolumns * sizeof(double));
	b->nparam += md->ncolumns;
	return 0;
}

/* How far (arcsec) beyond an SCA edge row i can still send light: its
 * footprint's extent for a provisional placement at the origin. */
static int row_reach(struct engine *g, const struct rows *r, size_t i, int m,
		     const double *param, double *reach)
{
	struct wfs_source src;
	struct wfs_box box;
	double ext;

	if (!strcmp(g->plugins.p[m].name, "point")) {
		*reach = POINT_REACH * WFS_PIXSCALE;
		return 0;
	}
	if (make_source(g, r, i, m, param, g->slot[0].sca, 0, 0, &src) < 0 ||
	    footprint(g, r, i, m, &src, &box) < 0)
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

static void slot_masks(struct engine *g, const struct rows *r, double maxreach)
{
	uint32_t xm[SLOT_BINS], ym[SLOT_BINS];
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
	memset(xm, 0, sizeof(xm));
	memset(ym, 0, sizeof(ym));
	for (int s = 0; s < g->nslot; s++) {
		const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
		double lim = LIM(ss);
		int a = (int)((ss->fx - lim - x0) / wx), b = (int)((ss->fx + lim - x0) / wx);
		int c = (int)((ss->fy - lim - y0) / wy), d = (int)((ss->fy + lim - y0) / wy);

		for (int k = a < 0 ? 0 : a; k <= b && k < SLOT_BINS; k++)
			xm[k] |= 1u << s;
		for (int k = c < 0 ? 0 : c; k <= d && k < SLOT_BINS; k++)
			ym[k] |= 1u << s;
	}
	for (size_t i = 0; i < r->n; i++) {
		double fx = g->fx[i], fy = g->fy[i];
		uint32_t m = 0, c;

		/* also false for NaN: x/y rows and rows far from the pointing */
		if (fx >= x0 && fx < x1 && fy >= y0 && fy < y1) {
			int bx = (int)((fx - x0) / wx), by = (int)((fy - y0) / wy);

			c = xm[bx < SLOT_BINS ? bx : SLOT_BINS - 1] &
			    ym[by < SLOT_BINS ? by : SLOT_BINS - 1];
			while (c) {
				int s = __builtin_ctz(c);
				const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
				double l = ss->half + g->reach[i] + 2.0;

				c &= c - 1;
				if (fabs(fx - ss->fx) < l && fabs(fy - ss->fy) < l)
					m |= 1u << s;
			}
		}
		g->mask[i] = m;
		g->culled += !isnan(r->ra[i]) && !m;
	}
}

/* Turn one chunk of rows into the placements of batch b. */
static int build_batch(struct engine *g, const struct rows *r, struct batch *b)
{
	double *param = NULL, maxreach = 0, band = 0;
	size_t nparam_row = 0, nxy = 0;
	int rc = -1, last_m = -1;
	const char *last_type = NULL;

	b->n = b->nparam = 0;
	if (grow((void **)&g->fx, &g->cap_rows, r->n, sizeof(double)) < 0)
		return err_sys(g->e, "rows");
	/* all per-row arrays share cap_rows: grow them together */
	if (!(g->fy = realloc(g->fy, g->cap_rows * sizeof(double))) ||
	    !(g->px = realloc(g->px, g->cap_rows * sizeof(double))) ||
	    !(g->py = realloc(g->py, g->cap_rows * sizeof(double))) ||
	    !(g->reach = realloc(g->reach, g->cap_rows * sizeof(double))) ||
	    !(g->cand = realloc(g->cand, g->cap_rows * sizeof(uint32_t))) ||
	    !(g->mask = realloc(g->mask, g->cap_rows * sizeof(uint32_t))))
		return err_sys(g->e, "rows");
	g->sersic_flux_now = g->o->sersic_flux ? g->o->sersic_flux
			   : r->sersic_ie ? "ie" : "total";

	/* Resolve models, read their columns, and work out each row's reach.
	 * Parameters of all rows are kept in one array, MAX_COLUMNS a row. */
	nparam_row = MAX_COLUMNS;
	if (!(param = malloc(r->n * nparam_row * sizeof(double))))
		return err_sys(g->e, "rows");
	int *model = malloc(r->n * sizeof(int));
	if (!model) {
		free(param);
		return err_sys(g->e, "rows");
	}
	for (size_t i = 0; i < r->n; i++) {
		int m;
		const struct wfs_model *md;

		/* Rows of one catalog mostly share one type string ("point"
		 * when there is no type column). */
		if (r->type[i] == last_type) {
			m = last_m;
		} else if ((m = resolve_type(g, r->type[i])) < 0) {
			err_prefix(g->e, "%s:%ld", r->file, r->line[i]);
			goto out;
		}
		last_type = r->type[i];
		last_m = m;
		md = g->plugins.p[m].m;
		model[i] = m;
		if (model_columns(g, r, m) < 0)
			goto out;
		for (int c = 0; c < md->ncolumns; c++) {
			double *v = &param[i * nparam_row + c];

			/* an empty cell is the fallback, but for a required
			 * column (no number parses to NaN) */
			if (g->colidx[m][c] < 0)
				*v = md->columns[c].fallback;
			else if (rows_number(r, g->colidx[m][c], i, md->columns[c].required ? NAN :
					     md->columns[c].fallback, v, g->e) < 0)
				goto out;
			else if (md->columns[c].required && isnan(*v)) {
				err_set(g->e, EXIT_INPUT, "%s:%ld: model '%s': column '%s': empty value",
					r->file, r->line[i], md->name, md->columns[c].name);
				goto out;
			}
		}
		g->reach[i] = 0;
		if (isnan(r->ra[i]))
			nxy++;
		else if (row_reach(g, r, i, m, &param[i * nparam_row], &g->reach[i]) < 0)
			goto out;
		else if (g->reach[i] > maxreach)
			maxreach = g->reach[i];
	}

	/* Rows farther in declination from the pointing than any SCA's
	 * window reaches are on no SCA: a row near slot s lies within
	 * rho = |(fx, fy)| of the reference in the focal plane, i.e. at an
	 * angle atan(rho) <= rho, which is at least its declination offset.
	 * Those rows skip the trigonometry of the projection. */
	for (int s = 0; s < g->nslot; s++) {
		const struct sky_sca *ss = &g->sky.sca[g->slot[s].sca - 1];
		double lim = ss->half + maxreach + 2.0;

		band = fmax(band, hypot(fabs(ss->fx) + lim, fabs(ss->fy) + lim));
	}
	band = band / 3600 * (1 + 1e-9) + 1e-9;
	sky_to_focal(&g->sky, r->n, r->ra, r->dec, band, g->fx, g->fy);
	slot_masks(g, r, maxreach);

	for (int s = 0; s < g->nslot; s++) {
		size_t nc = 0, k = 0;

		/* Sky rows whose reach touches this SCA, then their exact pixels. */
		for (size_t i = 0; i < r->n; i++)
			if (g->mask[i] >> s & 1)
				g->cand[nc++] = i;
		for (k = 0; k < nc; k++) {
			g->px[k] = r->ra[g->cand[k]];
			g->py[k] = r->dec[g->cand[k]];
		}
		if (sky_to_pixel(&g->sky, g->slot[s].sca, nc, g->px, g->py, g->px, g->py,
				 g->e) < 0)
			goto out;
		if (!nxy) {
			for (k = 0; k < nc; k++) {
				size_t i = g->cand[k];

				if (!isnan(g->px[k]) &&
				    add_placement(g, b, r, i, model[i], &param[i * nparam_row], s,
						  g->px[k], g->py[k]) < 0)
					goto out;
			}
			continue;
		}
		/* Pixel rows for this SCA are merged in catalog order. */
		k = 0;
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
			if (add_placement(g, b, r, i, model[i], &param[i * nparam_row], s,
					  x, y) < 0)
				goto out;
		}
	}
	for (size_t i = 0; i < b->n; i++)
		b->p[i].src.param = b->param + b->p[i].param_off;
	rc = 0;
out:
	free(param);
	free(model);
	return rc;
}

/* Bin the placements of b by the tiles their boxes touch, in placement
 * order, and allocate the tiles they need. */
static int bin_batch(struct engine *g, struct batch *b)
{
	size_t ntot = (size_t)g->nslot * g->ntile, total = 0;
	int T = g->tile;

	if (!b->count && !(b->count = calloc(ntot + 1, sizeof(*b->count))))
		return err_sys(g->e, "tiles");
	memset(b->count, 0, (ntot + 1) * sizeof(*b->count));
	for (size_t i = 0; i < b->n; i++) {
		const struct wfs_box *bx = &b->p[i].box;
		size_t base = (size_t)b->p[i].slot * g->ntile;

		for (int ty = bx->y0 / T; ty <= (bx->y1 - 1) / T; ty++)
			for (int tx = bx->x0 / T; tx <= (bx->x1 - 1) / T; tx++) {
				b->count[base + ty * g->ntx + tx]++;
				total++;
			}
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
		if (c) {
			struct slot *sl = &g->slot[t / g->ntile];
			size_t lt = t % g->ntile;

			b->active[b->nactive++] = t;
			if (!sl->tile[lt] && !(sl->tile[lt] = tile_alloc(T)))
				return err_sys(g->e, "tile memory");
		}
		run += c;
	}
	b->count[ntot] = run;
	/* fill: count[t] advances to the end of tile t's range */
	for (size_t i = 0; i < b->n; i++) {
		const struct wfs_box *bx = &b->p[i].box;
		size_t base = (size_t)b->p[i].slot * g->ntile;

		for (int ty = bx->y0 / T; ty <= (bx->y1 - 1) / T; ty++)
			for (int tx = bx->x0 / T; tx <= (bx->x1 - 1) / T; tx++)
				b->items[b->count[base + ty * g->ntx + tx]++] = i;
	}
	/* shift back so count[t] is tile t's start again */
	for (size_t t = ntot; t > 0; t--)
		b->count[t] = b->count[t - 1];
	b->count[0] = 0;
	b->nitems = total;
	return 0;
}

/* A model failed in a worker: the first failure names the model (and the
 * source), later ones on other threads add nothing.  what is the message
 * when the plugin recorded none, as it must. */
static void model_failed(struct engine *g, const char *model, const char *what,
			 const struct wfs_source *src)
{
	pthread_mutex_lock(&g->err_mu);
	if (!atomic_exchange(&g->failed, 1)) {
		err_set(g->e, EXIT_PLUGIN, "%s" MODEL_SILENT, what);
		if (src)
			err_prefix(g->e, "model '%s': source %lld on SCA %d", model,
				   src->id, src->sca);
		else
			err_prefix(g->e, "model '%s'", model);
	}
	pthread_mutex_unlock(&g->err_mu);
}

/* Worker: render every placement of one active tile, in placement order. */
static void render_tile(void *arg, int wid, size_t task)
{
	struct engine *g = arg;
	const struct batch *b = g->rendering;
	struct worker *w = &g->w[wid];
	size_t t = b->active[task], lt = t % g->ntile;
	int T = g->tile, tx = lt % g->ntx, ty = lt / g->ntx;
	int x0 = tx * T, y0 = ty * T;
	double *tile = g->slot[t / g->ntile].tile[lt];

	double t0 = now();

	if (atomic_load(&g->failed))
		return;
	for (uint32_t k = b->count[t]; k < b->count[t + 1]; k++) {
		const struct placement *p = &b->p[b->items[k]];
		struct plugin *pl = &g->plugins.p[p->model];
		struct wfs_window win;

		if (!w->started[p->model]) {
			if (pl->m->thread_start &&
			    pl->m->thread_start(pl->state, &w->tstate[p->model]) < 0) {
				model_failed(g, pl->name, "thread_start() failed", NULL);
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
			model_failed(g, pl->name, "render() failed", &p->src);
			return;
		}
	}
	g->t_render[wid] += now() - t0;
}

/* ---- output ---- */

struct strip_job {
	struct engine *g;
	struct noise_opts *no;
	int slot, ty;
};

static void noise_strip_tile(void *arg, int wid, size_t tx)
{
	struct strip_job *j = arg;
	struct engine *g = j->g;
	int T = g->tile, x0 = tx * T, y0 = j->ty * T;
	int nx = x0 + T > WFS_NPIX ? WFS_NPIX - x0 : T;
	int ny = y0 + T > WFS_NPIX ? WFS_NPIX - y0 : T;
	double *tile = g->slot[j->slot].tile[j->ty * g->ntx + tx];
	const struct geom_sca *geo = &g->sky.sca[g->slot[j->slot].sca - 1].geo;
	struct noise_opts no = *j->no;

	/* The SIAF geometry: the background is per nominal 0.11" pixel, and
	 * each pixel gets it times its own area (before the noise stages, as
	 * noise_tile would add it).  stips: noise_tile adds it, as before. */
	if (geo->kind == GEOM_SIAF && no.background != 0 && tile) {
		enum { SPAN = 256 };
		double area[SPAN];

		for (int y = 0; y < ny; y++)
			for (int x = 0; x < nx; x += SPAN) {
				int m = nx - x < SPAN ? nx - x : SPAN;
				double *r = tile + (size_t)y * T + x;

				geom_area_row(geo, y0 + y, x0 + x, m, area);
				for (int i = 0; i < m; i++)
					r[i] += no.background * area[i];
			}
		no.background = 0;
	}
	if (noise_tile(&no, g->slot[j->slot].sca, x0, y0, nx, ny, tile, T) < 0)
		atomic_store(&g->failed, 1);
}

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
	CARD(fits_card_str, "POINTREF", o->boresight ? "BORESIGHT" : "WFI01",
	     "what RA_TARG/DEC_TARG point at");
	CARD(fits_card_str, "GEOMETRY", geom_name(o->geometry),
	     o->geometry == GEOM_STIPS ? "0.11\" square aligned SCAs, TAN" : "Roman SIAF, TAN-SIP");
	CARD(fits_card_int, "SEED", (long long)o->seed, "random seed");
	CARD(fits_card_str, "PSFSRC", o->psf, "PSF source");
	CARD(fits_card_str, "BUNIT", o->bunit_counts ? "counts" : "counts/s", NULL);
	CARD(fits_card_str, "BKGRND", o->background_arg ? o->background_arg : "none",
	     "background setting");
	CARD(fits_card_dbl, "BKGRATE", o->background, "background (counts/s/pixel)");
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
	CARD(fits_card_dbl, "PHOTZPAB", zeropoint(g, sca), "AB mag of 1 count/s");
	CARD(fits_card_dbl, "PA_APER", g->sky.sca[sca - 1].pa, "position angle of +y (deg)");
	CARD(fits_card_dbl, "RA_APER", g->sky.sca[sca - 1].ra, "detector centre RA");
	CARD(fits_card_dbl, "DEC_APER", g->sky.sca[sca - 1].dec, "detector centre Dec");
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
static ptrdiff_t first_nonfinite(const float *a, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (!isfinite(a[i]))
			return (ptrdiff_t)i;
	return -1;
}

static int write_slot(struct engine *g, struct fitsout *f, int s, struct noise_opts *no,
		      int apply_noise, float *strip)
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

			for (int y = ya; row[tx] && y < yb; y++)
				for (int x = 0; x < nx; x++)
					g->image_sum[g->slot[s].sca - 1] += row[tx][(size_t)y * T + x];
		}
		for (int tx = 0; tx < g->ntx; tx++)
			g->tiles_drawn += row[tx] != NULL;
		g->tiles += g->ntx;
		t0 = now();
		if (apply_noise) {
			struct strip_job j = { g, no, s, ty };

			for (int tx = 0; tx < g->ntx; tx++)
				if (!row[tx] && !(row[tx] = tile_alloc(T)))
					return err_sys(g->e, "tile memory");
			pool_run(g->pool, noise_strip_tile, &j, g->ntx);
			if (atomic_load(&g->failed))
				return err_set(g->e, EXIT_SYSTEM, "noise stage failed");
		}
		g->t_noise += now() - t0;
		t0 = now();
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
		g->t_write += now() - t0;
		progress(g, "writing", 0);
	}
	return fitsout_image_end(f, g->e);
}

static int write_output(struct engine *g)
{
	const struct scene_opts *o = g->o;
	struct noise_opts no = {
		.stages = o->noise, .background = o->background, .exptime = o->exptime,
		.readnoise = o->readnoise, .dark_current = o->dark_current,
		.cosmic_rate = o->cosmic_rate, .cosmic_residual = o->cosmic_residual,
		.seed = o->seed, .filter = o->filter, .counts = o->bunit_counts,
	};
	int apply_noise = o->noise || o->background != 0 || o->bunit_counts;
	int per_sca = strstr(o->output, "%") != NULL;
	float *strip = malloc((size_t)g->tile * WFS_NPIX * sizeof(float));
	struct fitsout *f = NULL;
	char *cards = NULL;
	int ncards;

	if (!strip)
		return err_sys(g->e, "output buffer");
	if (primary_cards(g, &cards, &ncards) < 0) {
		err_sys(g->e, "header");
		goto fail;
	}
	for (int s = 0; s < g->nslot; s++) {
		if (!f || per_sca) {
			char path[PATH_MAX];

			snprintf(path, sizeof(path), o->output, g->slot[s].sca);
			if (!(f = fitsout_open(path, o->compress, g->e)) ||
			    fitsout_primary(f, cards, ncards, g->e) < 0)
				goto fail;
		}
		if (write_slot(g, f, s, &no, apply_noise, strip) < 0)
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

/* ---- the run ---- */

static int engine_init(struct engine *g, const struct scene_opts *o, struct pool *pool,
		       struct err *e)
{
	memset(g, 0, sizeof(*g));
	g->o = o;
	g->e = e;
	g->main_thread = pthread_self();
	pthread_mutex_init(&g->err_mu, NULL);
	snprintf(g->filter_name, sizeof(g->filter_name), "%s", filter_get(o->filter)->name);
	snprintf(g->exptime_str, sizeof(g->exptime_str), "%.17g", o->exptime);
	snprintf(g->seed_str, sizeof(g->seed_str), "%llu", (unsigned long long)o->seed);
	snprintf(g->bkg_str, sizeof(g->bkg_str), "%.17g", o->background);
	snprintf(g->readnoise_str, sizeof(g->readnoise_str), "%.17g",
		 o->noise & NOISE_READ ? o->readnoise : 0.0);
	snprintf(g->noise_str, sizeof(g->noise_str), "%s%s%s%s%s",
		 o->noise & NOISE_POISSON ? "poisson," : "", o->noise & NOISE_READ ? "readnoise," : "",
		 o->noise & NOISE_DARK ? "dark," : "", o->noise & NOISE_FLAT ? "flat," : "",
		 o->noise & NOISE_COSMIC ? "cosmic," : "");
	g->sersic_flux_now = o->sersic_flux ? o->sersic_flux : "total";
	if (sky_init(&g->sky, o->ra, o->dec, o->pa, o->boresight, o->geometry, o->sca_mask, e) < 0)
		return -1;
	g->tile = o->tile;
	g->ntx = g->nty = (WFS_NPIX + g->tile - 1) / g->tile;
	g->ntile = g->ntx * g->nty;
	g->ylo = o->row_first ? o->row_first - 1 : 0;
	g->yhi = o->row_first ? o->row_last : WFS_NPIX;
	for (int s = 0; s <= WFS_NSCA; s++)
		g->slot_of[s] = -1;
	for (int s = 1; s <= WFS_NSCA; s++)
		if (o->sca_mask & (1u << (s - 1))) {
			struct slot *sl = &g->slot[g->nslot];

			sl->sca = s;
			if (!(sl->tile = calloc(g->ntile, sizeof(*sl->tile))))
				return err_sys(e, "tiles");
			g->slot_of[s] = g->nslot++;
		}
	g->pbo.cache_dir = o->psf_cache;
	g->pbo.threads = o->threads;
	g->pbo.verbose = o->verbose;
	g->host = (struct wfs_host){
		.abi = WFS_ABI_VERSION, .size = sizeof(struct wfs_host), .ctx = g,
		.error = host_error, .log = host_log, .setting = host_setting,
		.epsf = host_epsf, .scratch = host_scratch, .convolve = host_convolve,
	};
	if (plugins_init(&g->plugins, o->plugin_path, &g->host, e) < 0)
		return -1;
	if (!(g->fft = fftconv_new()))
		return err_sys(e, "FFT set-up");
	g->pool = pool;
	g->nworker = pool_threads(pool);
	if (!(g->w = calloc(g->nworker, sizeof(*g->w))) ||
	    !(g->t_render = calloc(g->nworker, sizeof(*g->t_render))))
		return err_sys(e, "threads");
	for (int i = 0; i < g->nworker; i++)
		g->w[i].g = g;
	if (o->psf && strcmp(o->psf, "builtin") && !strstr(o->psf, "%")) {
		if (!(g->user_grid = psf_grid_read(o->psf, e)))
			return -1;
		psf_file_warn(g, g->user_grid, o->psf, 0);
		if (g->user_grid->kind == PSF_OPTICAL && psf_make_epsf(g->user_grid, e) < 0)
			return -1;
	}
	return 0;
}

/* The pool is the caller's; the workers must be idle. */
static void engine_free(struct engine *g)
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
	plugins_free(&g->plugins);
	fftconv_free(g->fft);
	for (int s = 0; s < g->nslot; s++) {
		for (int t = 0; t < g->ntile; t++)
			tile_free(g->slot[s].tile[t], g->tile);
		free(g->slot[s].tile);
	}
	for (int s = 0; s < WFS_NSCA; s++)
		for (int c = 0; c < 3; c++)
			if (g->grid[s][c] && (c == 0 || g->grid[s][c] != g->grid[s][0]))
				psf_grid_free(g->grid[s][c]);
	psf_grid_free(g->user_grid);
	for (int i = 0; i < 2; i++) {
		free(g->b[i].p);
		free(g->b[i].param);
		free(g->b[i].count);
		free(g->b[i].items);
		free(g->b[i].active);
	}
	free(g->fx); free(g->fy); free(g->px); free(g->py); free(g->reach); free(g->cand); free(g->mask);
	sky_free(&g->sky);
	pthread_mutex_destroy(&g->err_mu);
}

/* Before a run: a side file that could not be written at its end (a
 * directory, a directory that is not writable) is refused up front, so
 * that no image is written for a run whose --report must fail. */
static int side_check(const char *path, struct err *e)
{
	const char *slash = strrchr(path, '/');
	char dir[PATH_MAX];
	struct stat st;

	if (stat(path, &st) == 0 && !S_ISREG(st.st_mode))
		return S_ISDIR(st.st_mode) ?
		       err_set(e, EXIT_INPUT, "%s: is a directory", path) : 0;
	snprintf(dir, sizeof(dir), "%.*s", slash ? (int)(slash - path + 1) : 1,
		 slash ? path : ".");
	if (access(dir, W_OK | X_OK))
		return err_sys(e, "%s: cannot write in '%s'", path, dir);
	return 0;
}

/* Finish a side file opened by side_open: flush, fsync and rename a
 * temporary file (keep) or remove it; a file written in place is only
 * flushed.  Closes f.  Returns 0 or -1 (errno set). */
static int side_close(FILE *f, const char *path, const char *tmp, int keep)
{
	int bad = fflush(f) != 0 || ferror(f);

	if (!bad && tmp[0] && keep)
		bad = fsync(fileno(f)) != 0;
	bad |= fclose(f) != 0;
	if (!tmp[0])
		return bad ? -1 : 0;
	if (keep && !bad && rename(tmp, path) == 0)
		return 0;
	int saved = errno;
	unlink(tmp);
	errno = saved;
	return keep ? -1 : 0;
}

static int open_placed(struct engine *g)
{
	const char *path = g->o->placed;
	int fd;

	if ((fd = tempfile_open_output(path, g->placed_tmp, sizeof(g->placed_tmp), g->e)) < 0)
		return -1;
	memcpy(placed_tmp_signal[g->index], g->placed_tmp, sizeof(placed_tmp_signal[0]));
	if (!(g->placed = fdopen(fd, "w"))) {
		close(fd);
		if (g->placed_tmp[0])
			unlink(g->placed_tmp);
		placed_tmp_signal[g->index][0] = 0;
		return err_sys(g->e, "%s", path);
	}
	fputs("id,sca,x,y,flux,mag,model\n", g->placed);
	return 0;
}

static int close_placed(struct engine *g, int keep)
{
	int r;

	if (!g->placed)
		return 0;
	r = side_close(g->placed, g->o->placed, g->placed_tmp, keep);
	g->placed = NULL;
	placed_tmp_signal[g->index][0] = 0;
	return keep && r < 0 ? err_sys(g->e, "%s", g->o->placed) : 0;
}

/* A JSON string: quotes, backslashes and control bytes escaped (--set
 * values reach the report as the user typed them). */
static void report_string(FILE *f, const char *s)
{
	fputc('"', f);
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;

		if (c == '"' || c == '\\')
			fprintf(f, "\\%c", c);
		else if (c < 0x20)
			fprintf(f, "\\u%04x", c);
		else
			fputc(c, f);
	}
	fputc('"', f);
}

/* "name": "value of --set key, or fallback", */
static void report_setting(FILE *f, struct engine *g, const char *name, const char *key,
			   const char *fallback)
{
	const char *v = host_setting(g, key);

	fprintf(f, "\"%s\": ", name);
	report_string(f, v && *v ? v : fallback);
	fputs(", ", f);
}

/* The per-run report: what was done, how long each stage took, what the
 * chosen settings cost in accuracy.  JSON, written atomically. */
static int write_report(struct engine *g)
{
	const struct scene_opts *o = g->o;
	char tmp[PATH_MAX];
	double render = 0, worst_loss = 0;
	FILE *f;
	int fd, first;

	if ((fd = tempfile_open_output(o->report, tmp, sizeof(tmp), g->e)) < 0)
		return -1;
	if (!(f = fdopen(fd, "w"))) {
		close(fd);
		if (tmp[0])
			unlink(tmp);
		return err_sys(g->e, "%s", o->report);
	}
	for (int i = 0; i < g->nworker; i++)
		render += g->t_render[i];
	fprintf(f, "{\n  \"wfiscene\": \"%s\",\n", WFS_VERSION);
	fprintf(f, "  \"settings\": {\"filter\": \"%s\", \"scas\": [", g->filter_name);
	for (int s = 0; s < g->nslot; s++)
		fprintf(f, "%s%d", s ? ", " : "", g->slot[s].sca);
	fprintf(f, "], \"ra\": %.10g, \"dec\": %.10g, \"pa\": %.10g, \"geometry\": \"%s\", "
		"\"exptime\": %.10g, "
		"\"psf\": \"%s\", \"threads\": %d, \"tile\": %d, \"chunk\": %zu, "
		"\"seed\": %llu, \"noise\": %u, \"background\": %.10g},\n",
		g->sky.ra0, g->sky.dec0, g->sky.pa0, geom_name(o->geometry), o->exptime, o->psf, g->nworker, g->tile,
		o->chunk, (unsigned long long)o->seed, o->noise, o->background);
	fprintf(f, "  \"seconds\": {\"total\": %.6f, \"read_parse\": %.6f, "
		"\"project_place\": %.6f, \"render_busy\": %.6f, \"render_wait\": %.6f, "
		"\"noise\": %.6f, \"write\": %.6f},\n", g->t_total, g->t_read, g->t_place,
		render, g->t_wait, g->t_noise, g->t_write);
	fprintf(f, "  \"rows\": {\"read\": %llu, \"culled_far\": %llu, "
		"\"off_detector\": %llu, \"placements\": %llu, \"by_model\": {",
		g->rows_read, g->culled, g->offdet, g->placements);
	first = 1;
	for (int m = 0; m < g->plugins.n; m++)
		if (g->plugins.p[m].ready) {
			fprintf(f, "%s\"%s\": %llu", first ? "" : ", ", g->plugins.p[m].name,
				g->per_model[m]);
			first = 0;
		}
	fprintf(f, "}},\n  \"flux\": [");
	for (int s = 0; s < g->nslot; s++) {
		int sca = g->slot[s].sca;

		fprintf(f, "%s\n    {\"sca\": %d, \"requested\": %.10g, \"placed\": %.10g}",
			s ? "," : "", sca, g->flux_requested[sca - 1], g->image_sum[sca - 1]);
	}
	/* What the scene needed and so did: the models loaded, the FFT sizes
	 * planned (Sersic convolution), the tiles drawn on before noise (the
	 * rest were never allocated), the noise stages that drew random
	 * numbers (none: the random number code never ran). */
	fprintf(f, "\n  ],\n  \"work\": {\"models\": [");
	first = 1;
	for (int m = 0; m < g->plugins.n; m++)
		if (g->plugins.p[m].ready) {
			fprintf(f, "%s\"%s\"", first ? "" : ", ", g->plugins.p[m].name);
			first = 0;
		}
	fprintf(f, "], \"fft_plans\": %d, \"tiles_drawn\": %llu, \"tiles\": %llu, "
		"\"noise_stages\": [", fftconv_nplans(g->fft), g->tiles_drawn, g->tiles);
	first = 1;
	for (int k = 0; k < 5; k++)
		if (o->noise & (1u << k)) {
			static const char *const stage[] = { "poisson", "readnoise", "dark", "flat",
							     "cosmic" };

			fprintf(f, "%s\"%s\"", first ? "" : ", ", stage[k]);
			first = 0;
		}
	fprintf(f, "]},\n  \"psf_grids\": {\"built\": %d, \"loaded\": %d, \"boxes\": [",
		g->pbo.built, g->pbo.loaded);
	/* The light a point source's box leaves out, at the grid's worst node
	 * and phase: the largest truncation loss of the settings. */
	first = 1;
	for (int s = 0; s < WFS_NSCA; s++)
		for (int c = 0; c < 3; c++) {
			const struct psf_grid *gr = grid_for(g, s + 1, c);
			double lo = 1;

			if (!gr || (c > 0 && gr == grid_for(g, s + 1, c - 1)))
				continue;
			for (int k = 0; k < gr->nx * gr->ny; k++)
				for (int p = 0; p < gr->over * gr->over; p++)
					lo = fmin(lo, psf_enclosed(gr, k, p % gr->over, p / gr->over));
			worst_loss = fmax(worst_loss, 1 - lo);
			fprintf(f, "%s\n    {\"sca\": %d, \"class\": %d, \"samples\": %d, "
				"\"min_enclosed\": %.8f}", first ? "" : ",", s + 1, c, gr->n, lo);
			first = 0;
		}
	fprintf(f, "\n  ]},\n  \"error_budget\": {\"largest_truncation_loss\": %.8f, "
		"\"psf_grid\": \"%dx%d nodes, bilinear in position\", ",
		worst_loss, g->user_grid ? g->user_grid->nx : 3, g->user_grid ? g->user_grid->ny : 3);
	/* The point model's approximations as --set chose them (its defaults
	 * otherwise), so that a report says which evaluation made the image. */
	report_setting(f, g, "interpolation", "psf-interp", "core");
	report_setting(f, g, "core_halfwidth_px", "psf-core", "4");
	report_setting(f, g, "wing_halfwidth_px", "psf-wing", "8");
	report_setting(f, g, "box", "psf-box", "fixed");
	report_setting(f, g, "box_noise_fraction", "psf-box-noise", "0.1");
	report_setting(f, g, "blend", "psf-blend", "core");
	fprintf(f, "\"blend_cell_px\": ");
	report_string(f, host_setting(g, "psf-cell") ? host_setting(g, "psf-cell") : "512");
	fprintf(f, "}\n}\n");
	if (side_close(f, o->report, tmp, 1) < 0)
		return err_sys(g->e, "%s", o->report);
	return 0;
}

void scene_remove_temporaries(void)
{
	for (int i = 0; i < MAX_EXPOSURES; i++)
		if (placed_tmp_signal[i][0])
			unlink(placed_tmp_signal[i]);
}

/* ---- several exposures: --pointings ---- */

struct pointing {
	double ra, dec, pa;
	uint64_t seed;
	char name[64];
};

static int is_number(const char *s, double *v)
{
	char *end;

	*v = strtod(s, &end);
	return end != s && !*end && isfinite(*v);
}

/*
 * A pointings file: one exposure a line, "ra dec pa [name [seed]]", fields
 * separated by blanks or commas; '#' starts a comment; a first line whose
 * first field is not a number is a header.  Exposure k (from 1) is named
 * k with three digits unless named, and has seed --seed + k - 1 unless given,
 * so that a single run of that pointing with that seed gives the same image.
 */
static int read_pointings(const struct scene_opts *o, struct pointing **out, int *nout,
			  struct err *e)
{
	FILE *f = fopen(o->pointings, "r");
	char line[4096];
	struct pointing *p = NULL;
	int n = 0, lineno = 0, seen_data = 0;

	if (!f)
		return err_sys(e, "%s", o->pointings);
	if (!(p = calloc(MAX_EXPOSURES, sizeof(*p)))) {
		fclose(f);
		return err_sys(e, "pointings");
	}
	while (fgets(line, sizeof(line), f)) {
		char *field[6], *save = NULL, *tok, *hash = strchr(line, '#');
		int nf = 0;
		double v[3];

		lineno++;
		if (!strchr(line, '\n') && !feof(f)) {
			err_set(e, EXIT_INPUT, "%s:%d: line too long", o->pointings, lineno);
			goto fail;
		}
		if (hash)
			*hash = 0;
		for (tok = strtok_r(line, " \t\r\n,", &save); tok && nf < 6;
		     tok = strtok_r(NULL, " \t\r\n,", &save))
			field[nf++] = tok;
		if (nf == 0)
			continue;
		if (!seen_data++ && !is_number(field[0], &v[0]))
			continue;       /* a header line */
		if (nf < 3 || nf > 5) {
			err_set(e, EXIT_INPUT, "%s:%d: expected 'ra dec pa [name [seed]]', got %d "
				"field%s", o->pointings, lineno, nf, nf == 1 ? "" : "s");
			goto fail;
		}
		for (int k = 0; k < 3; k++)
			if (!is_number(field[k], &v[k])) {
				err_set(e, EXIT_INPUT, "%s:%d: %s: not a number: '%s'", o->pointings,
					lineno, k == 0 ? "ra" : k == 1 ? "dec" : "pa", field[k]);
				goto fail;
			}
		if (v[1] < -90 || v[1] > 90) {
			err_set(e, EXIT_INPUT, "%s:%d: dec %g is outside [-90, 90]", o->pointings,
				lineno, v[1]);
			goto fail;
		}
		if (n == MAX_EXPOSURES) {
			err_set(e, EXIT_INPUT, "%s:%d: more than %d pointings", o->pointings, lineno,
				MAX_EXPOSURES);
			goto fail;
		}
		p[n].ra = v[0];
		p[n].dec = v[1];
		p[n].pa = v[2];
		p[n].seed = o->seed + n;
		snprintf(p[n].name, sizeof(p[n].name), "%03d", n + 1);
		if (nf >= 4) {
			if (strlen(field[3]) >= sizeof(p[n].name) ||
			    strspn(field[3], "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
				   "0123456789_.-") != strlen(field[3])) {
				err_set(e, EXIT_INPUT, "%s:%d: name '%s': use letters, digits, '_', "
					"'.' and '-' (at most 63)", o->pointings, lineno, field[3]);
				goto fail;
			}
			strcpy(p[n].name, field[3]);
			for (int k = 0; k < n; k++)
				if (!strcmp(p[k].name, p[n].name)) {
					err_set(e, EXIT_INPUT, "%s:%d: name '%s' is used twice",
						o->pointings, lineno, p[n].name);
					goto fail;
				}
		}
		if (nf == 5) {
			char *end;

			errno = 0;
			p[n].seed = strtoull(field[4], &end, 10);
			if (*end || errno || field[4][0] == '-') {
				err_set(e, EXIT_INPUT, "%s:%d: seed: not an integer: '%s'",
					o->pointings, lineno, field[4]);
				goto fail;
			}
		}
		n++;
	}
	if (ferror(f)) {
		err_sys(e, "%s", o->pointings);
		goto fail;
	}
	if (n == 0) {
		err_set(e, EXIT_INPUT, "%s: no pointings", o->pointings);
		goto fail;
	}
	fclose(f);
	*out = p;
	*nout = n;
	return 0;
fail:
	fclose(f);
	free(p);
	return -1;
}

/* tmpl with its "%s" replaced by name (a word of safe characters). */
static char *expand_name(const char *tmpl, const char *name)
{
	const char *at = strstr(tmpl, "%s");
	size_t n;
	char *out;

	if (!tmpl)
		return NULL;
	if (!at)
		return strdup(tmpl);
	n = strlen(tmpl) + strlen(name);
	if (!(out = malloc(n + 1)))
		return NULL;
	snprintf(out, n + 1, "%.*s%s%s", (int)(at - tmpl), tmpl, name, at + 2);
	return out;
}

/* Read the next chunk into every exposure's engine: each builds its
 * placements while the workers draw the previous engine's, one loop at a
 * time on the shared pool. */
static int run_catalogs(struct engine **g, int ng, char *const *catalogs,
			const struct scene_opts *o, struct err *e)
{
	struct catalog_opts co = { .filter = o->filter, .flux_unit = o->flux_unit,
				   .chunk_rows = o->chunk };
	struct engine *pending = NULL;
	int cur = 0, rc = -1;

	for (char *const *cat = catalogs; *cat; cat++) {
		struct catalog *c = catalog_open(*cat, &co, e);
		struct rows rows;
		long n = 0;

		if (!c)
			goto out;
		/* Column indices belong to a catalog: the next one may order
		 * its columns differently (rows lives at the same address). */
		for (int i = 0; i < ng; i++)
			memset(g[i]->colidx_rows, 0, sizeof(g[i]->colidx_rows));
		for (;;) {
			double ta = now(), tb;

			if ((n = catalog_read(c, &rows, e)) <= 0)
				break;
			tb = now();
			g[0]->t_read += tb - ta;
			for (int i = 0; i < ng; i++) {
				struct batch *b = &g[i]->b[cur];

				g[i]->rows_read += n;
				if (build_batch(g[i], &rows, b) < 0) {
					/* Never a silent end of the run. */
					err_set(e, EXIT_SYSTEM, "placing the rows of %s failed", *cat);
					break;
				}
				ta = now();
				g[i]->t_place += ta - tb;
				if (pending) {
					pool_wait(g[i]->pool);
					pending->t_wait += now() - ta;
					if (atomic_load(&pending->failed)) {
						err_set(e, EXIT_PLUGIN, "rendering failed");
						pending = NULL;
						break;
					}
					pending = NULL;
				}
				progress(g[i], "rendering", 0);
				if (bin_batch(g[i], b) < 0)
					break;
				g[i]->rendering = b;
				pool_start(g[i]->pool, render_tile, g[i], b->nactive);
				pending = g[i];
				tb = now();
			}
			if (e->code != EXIT_OK)
				break;
			cur ^= 1;
		}
		catalog_close(c);
		if (n < 0 || e->code != EXIT_OK)
			break;
	}
	rc = 0;
out:
	if (pending) {
		double ta = now();

		pool_wait(pending->pool);
		pending->t_wait += now() - ta;
	}
	for (int i = 0; i < ng; i++)
		if (atomic_load(&g[i]->failed) && e->code == EXIT_OK)
			err_set(e, EXIT_PLUGIN, "rendering failed");
	return rc < 0 || e->code != EXIT_OK ? -1 : 0;
}

/* Write one exposure's image, --placed list and report. */
static int finish(struct engine *g, struct timespec t0)
{
	struct timespec t1;

	if (write_output(g) < 0 || close_placed(g, 1) < 0)
		return -1;
	clock_gettime(CLOCK_MONOTONIC, &t1);
	g->t_total = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
	if (g->progress)
		fputs("\r\033[K", stderr);
	if (g->o->report && write_report(g) < 0)
		return -1;
	host_log(g, 1, "%s%s%llu rows read, %llu culled far from every SCA, %llu placements "
		 "on %d SCA%s, %.3f s", g->o->pointings ? g->o->output : "",
		 g->o->pointings ? ": " : "", g->rows_read, g->culled, g->placements, g->nslot,
		 g->nslot == 1 ? "" : "s", g->t_total);
	return 0;
}

int scene_run(const struct scene_opts *o, char *const *catalogs, struct err *e)
{
	struct pointing one = { o->ra, o->dec, o->pa, o->seed, "" }, *pt = &one;
	struct scene_opts *opts = NULL;
	struct engine **g = NULL;
	struct pool *pool = NULL;
	struct timespec t0;
	int n = 1, made = 0, rc = -1;

	clock_gettime(CLOCK_MONOTONIC, &t0);
	if (o->pointings && read_pointings(o, &pt, &n, e) < 0)
		return -1;
	if (!(opts = calloc(n, sizeof(*opts))) || !(g = calloc(n, sizeof(*g))) ||
	    !(pool = pool_new(o->threads > 0 ? o->threads : pool_cpus()))) {
		err_sys(e, "memory");
		goto out;
	}
	for (int i = 0; i < n; i++) {
		opts[i] = *o;
		opts[i].ra = pt[i].ra;
		opts[i].dec = pt[i].dec;
		opts[i].pa = pt[i].pa;
		opts[i].seed = pt[i].seed;
		if (o->pointings &&
		    (!(opts[i].output = expand_name(o->output, pt[i].name)) ||
		     (o->placed && !(opts[i].placed = expand_name(o->placed, pt[i].name))) ||
		     (o->report && !(opts[i].report = expand_name(o->report, pt[i].name))))) {
			err_sys(e, "memory");
			goto out;
		}
	}
	for (int i = 0; i < n; i++) {
		if (!(g[i] = malloc(sizeof(*g[i])))) {
			err_sys(e, "memory");
			goto out;
		}
		made++;
		if (engine_init(g[i], &opts[i], pool, e) < 0)
			goto out;
		g[i]->index = i;
		if ((opts[i].placed && open_placed(g[i]) < 0) ||
		    (opts[i].report && side_check(opts[i].report, e) < 0))
			goto out;
		g[i]->t_start = g[i]->t_progress = t0;
		g[i]->progress = i == 0 && o->verbose >= 0 && isatty(2);
	}
	if (run_catalogs(g, n, catalogs, o, e) < 0)
		goto out;
	for (int i = 0; i < n; i++)
		if (finish(g[i], t0) < 0)
			goto out;
	rc = 0;
out:
	for (int i = 0; i < made; i++) {
		close_placed(g[i], 0);
		engine_free(g[i]);
		free(g[i]);
	}
	pool_free(pool);
	if (o->pointings) {
		for (int i = 0; opts && i < n; i++) {
			free((char *)opts[i].output);
			free((char *)opts[i].placed);
			free((char *)opts[i].report);
		}
		free(pt);
	}
	free(opts);
	free(g);
	return rc;
}
