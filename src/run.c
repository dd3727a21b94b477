/*
 * run.c - the run loop: catalogs in, one FITS file (or one per SCA) out per
 * exposure; see scene.h.
 *
 * scene_run() makes the exposures (exposure.c) and one engine per exposure,
 * then run_catalogs() streams the catalogs through them: each chunk of rows
 * is placed (place.c) by every engine and drawn (render.c) by the shared
 * worker pool while the main thread reads and places the next chunk.  After
 * the last chunk each exposure is written (write.c) with its side files
 * (report.c).  What does not fit the memory budget is drawn in more passes
 * over the catalogs: whole exposures, or groups of an exposure's SCAs
 * (plan_passes).
 */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "asdf.h"
#include "catalog.h"
#include "clock.h"
#include "detector.h"
#include "engine.h"
#include "err.h"
#include "options.h"
#include "fftconv.h"
#include "into.h"
#include "names.h"
#include "noise.h"
#include "persist.h"
#include "pool.h"
#include "product.h"
#include "psf.h"
#include "tempfile.h"
#include "tree.h"

/* An engine for exposure x: its sky geometry, its SCAs' tile grids, the
 * plugins (loaded by each engine: a plugin's state may hold per-exposure
 * values it read from host->setting), workers' state on the shared pool. */
static int engine_init(struct engine *g, const struct scene_opts *o, const struct exposure *x,
		       struct pool *pool, struct pool *place_pool, struct err *e)
{
	memset(g, 0, sizeof(*g));
	pthread_mutex_init(&g->grid_lock, NULL);
	g->o = o;
	g->x = x;
	g->e = e;
	g->main_thread = pthread_self();
	g->pass_slots = UINT32_MAX;
	g->npass = 1;
	settings_init(g);
	if (sky_init(&g->sky, x->ra, x->dec, x->pa, x->boresight, o->geometry, x->sca_mask, e) < 0 ||
	    sky_va_setting(&g->sky, host_setting(g, "velocity-aberration"), x->date, o->exptime,
			   e) < 0)
		return -1;
	g->tile = o->tile;
	g->ntx = g->nty = (WFS_NPIX + g->tile - 1) / g->tile;
	g->ntile = g->ntx * g->nty;
	g->ylo = o->row_first ? o->row_first - 1 : 0;
	g->yhi = o->row_first ? o->row_last : WFS_NPIX;
	for (int s = 0; s <= WFS_NSCA; s++)
		g->slot_of[s] = -1;
	for (int s = 1; s <= WFS_NSCA; s++)
		if (x->sca_mask & (1u << (s - 1))) {
			struct slot *sl = &g->slot[g->nslot];

			sl->sca = s;
			if (!(sl->tile = calloc(g->ntile, sizeof(*sl->tile))))
				return err_sys(e, "tiles");
			g->slot_of[s] = g->nslot++;
		}
	g->pbo.cache_dir = o->psf_cache;
	g->pbo.threads = o->threads;
	g->pbo.verbose = o->verbose;
	/* the SIAF's PSFs are sampled on each SCA's own pixels (psf.h) */
	g->pbo.pixgrid = o->geometry == GEOM_SIAF ? PSF_PIX_SIAF : PSF_PIX_SQUARE;
	host_init(g);
	if (plugins_init(&g->plugins, o->plugin_path, &g->host, e) < 0)
		return -1;
	if (!(g->fft = fftconv_new()))
		return err_sys(e, "FFT set-up");
	g->pool = pool;
	g->place_pool = place_pool;
	if (render_threads_init(g) < 0)
		return -1;
	if (place_pool) {
		g->npw = pool_threads(place_pool);
		if (!(g->pw = calloc(g->npw, sizeof(*g->pw))))
			return err_sys(e, "threads");
		for (int i = 0; i < g->npw; i++) {
			g->pw[i].g = g;
			g->pw[i].place = 1;
		}
	}
	return psfgrids_open_user(g);
}

/* The pool is the caller's; the workers must be idle. */
static void engine_free(struct engine *g)
{
	if (g->out)
		g->out->ops->abort(g->out);
	render_threads_stop(g);
	free(g->pw);
	plugins_free(&g->plugins);
	fftconv_free(g->fft);
	for (int s = 0; s < g->nslot; s++) {
		for (int t = 0; t < g->ntile; t++)
			tile_free(g->slot[s].tile[t], g->tile);
		free(g->slot[s].tile);
	}
	psfgrids_free(g);
	report_notes_free(g);
	for (int i = 0; i < 2; i++) {
		free(g->b[i].p);
		free(g->b[i].param);
		free(g->b[i].count);
		free(g->b[i].items);
		free(g->b[i].span);
		free(g->b[i].active);
	}
	free(g->fx); free(g->fy); free(g->px); free(g->py); free(g->reach); free(g->cand); free(g->mask);
	free(g->param); free(g->model);
	free(g->listed);
	free(g->mra); free(g->mdec); free(g->moved);
	sky_free(&g->sky);
	pthread_mutex_destroy(&g->grid_lock);
}

/*
 * Stream the catalogs through the engines g[0 .. ng-1] (one per exposure).
 *
 * The main thread and the worker pool work as a two-stage pipeline, one
 * chunk apart:
 *
 *   main thread:  read chunk k | place k for g[0] | place k for g[1] | ...
 *   workers:      ... draw chunk k-1 of g[ng-1]   | draw k of g[0]  | ...
 *
 * For each chunk and each engine in turn, the main thread builds that
 * engine's placements into batch b[cur] (place_batch: the models' prepare()
 * and footprint(), and PSF grids loaded on first use, all on the main
 * thread) while the pool still draws the batch started last, the
 * "pending" one: the previous engine's for this chunk, or the last
 * engine's for the previous chunk, and bins the new batch by tile.  Only
 * then does it wait for the pool (pool_wait), allocate the tiles the new
 * batch touches first and start it.  So reading and
 * placing overlap with rendering, and the pool is never given two loops at
 * once.
 *
 * Why two batches per engine: with one exposure the pending batch is the
 * same engine's batch of the previous chunk, whose placements and tile
 * lists must stay intact until pool_wait() returns.  The batches alternate
 * (cur ^= 1 per chunk), so placing writes into the one not being drawn.
 * (With several exposures the pending batch is another engine's, and the
 * alternation costs nothing.)  The tiles themselves are
 * shared by both batches; they are only written by workers, and a tile is
 * drawn by one worker at a time because only one batch is drawn at a time.
 * Tiles a batch needs are allocated in place_tiles(), after the wait, so the
 * pool never sees a tile array change under it.
 *
 * A failure in the main thread stops the run after the pending batch
 * finishes (a worker may be writing into the tiles); a failure in a worker
 * is seen at the next wait.
 */
/*
 * The region a catalog tree must cover: a disc about each SCA of each
 * exposure, of the SCA's half diagonal plus a margin for the light of
 * sources centred outside it (--set tree-margin=ARCSEC, default 30: the
 * largest ePSF box reaches 9.7 arcsec; galaxies reach farther).
 */
static int tree_region(struct engine **g, int ng, struct tree_disc **out, int *nout,
		       struct err *e)
{
	const char *m = host_setting(g[0], "tree-margin");
	double margin = 30;
	int n = 0;

	if (m) {
		char *end;

		margin = strtod(m, &end);
		if (end == m || *end || !(margin >= 0) || margin > 648000)
			return err_set(e, EXIT_INPUT, "--set tree-margin=%s: want arcseconds "
				       "from 0 to 648000", m);
	}
	for (int i = 0; i < ng; i++)
		n += g[i]->nslot;
	if (!(*out = malloc((size_t)(n ? n : 1) * sizeof(**out))))
		return err_sys(e, "tree region");
	n = 0;
	for (int i = 0; i < ng; i++)
		for (int s = 0; s < g[i]->nslot; s++) {
			const struct sky_sca *ss = &g[i]->sky.sca[g[i]->slot[s].sca - 1];

			(*out)[n].ra = ss->ra;
			(*out)[n].dec = ss->dec;
			(*out)[n++].radius = (SKY_SCA_HALF * M_SQRT2 + margin) / 3600.0;
		}
	*nout = n;
	return 0;
}

/* A catalog tree's counts, into the engines' (and -v's) once per run:
 * by the first pass over the catalogs. */
static void tree_note(struct engine **g, int ng, struct catalog *c, const char *cat)
{
	struct tree_counts tc;

	if (g[0]->pass || !catalog_tree_counts(c, &tc))
		return;
	host_log(g[0], 1, "%s: catalog tree: %llu of %llu files read; %llu skipped unread "
		 "(%llu bytes, %llu rows counted, %llu files uncounted)", cat,
		 tc.files - tc.skipped, tc.files, tc.skipped, tc.bytes_skipped,
		 tc.rows_skipped, tc.rows_uncounted);
	for (int i = 0; i < ng; i++) {
		g[i]->tree_files += tc.files;
		g[i]->tree_skipped += tc.skipped;
		g[i]->tree_bytes_skipped += tc.bytes_skipped;
		g[i]->tree_rows_skipped += tc.rows_skipped;
		g[i]->tree_rows_uncounted += tc.rows_uncounted;
		g[i]->trees++;
	}
}

static int run_catalogs(struct engine **g, int ng, char *const *catalogs,
			const struct scene_opts *o, struct err *e)
{
	struct catalog_opts co = { .filter = o->filter, .flux_unit = o->flux_unit,
				   .chunk_rows = o->chunk, .settings = o->settings,
				   .epoch = o->epoch, .pool = g[0]->place_pool };
	struct engine *pending = NULL;  /* whose batch the pool is drawing */
	struct tree_disc *disc = NULL;
	int cur = 0, rc = -1;

	if (tree_region(g, ng, &disc, &co.ndisc, e) < 0)
		return -1;
	co.disc = disc;

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
			double ta = engine_clock(), tb;

			if ((n = catalog_read(c, &rows, e)) <= 0)
				break;
			tb = engine_clock();
			g[0]->t_read += tb - ta;
			for (int i = 0; i < ng; i++) {
				struct batch *b = &g[i]->b[cur];

				/* rows read and culled: counted by the first pass */
				if (!g[i]->pass)
					g[i]->rows_read += n;
				/* placed while the pool draws the pending batch */
				if (place_batch(g[i], &rows, b) < 0 || placed_chunk_end(g[i]) < 0 ||
				    place_bin(g[i], b) < 0) {
					/* Never a silent end of the run. */
					err_set(e, EXIT_SYSTEM, "placing the rows of %s failed", *cat);
					break;
				}
				ta = engine_clock();
				g[i]->t_place += ta - tb;
				if (pending) {
					pool_wait(g[i]->pool);
					pending->t_wait += engine_clock() - ta;
					render_errors_collect(pending);
					if (atomic_load(&pending->failed)) {
						err_set(e, EXIT_PLUGIN, "rendering failed");
						pending = NULL;
						break;
					}
					pending = NULL;
				}
				/* the pool is idle: allocate tiles, start */
				engine_progress(g[i], "rendering", 0);
				if (place_tiles(g[i], b) < 0)
					break;
				g[i]->rendering = b;
				pool_start_timed(g[i]->pool, render_tile, g[i], b->nactive,
						 g[i]->t_render_cpu);
				pending = g[i];
				tb = engine_clock();
			}
			if (e->code != EXIT_OK)
				break;
			cur ^= 1;
		}
		tree_note(g, ng, c, *cat);
		catalog_close(c);
		if (n < 0 || e->code != EXIT_OK)
			break;
	}
	rc = 0;
out:
	free(disc);
	if (pending) {
		double ta = engine_clock();

		pool_wait(pending->pool);
		pending->t_wait += engine_clock() - ta;
		render_errors_collect(pending);
	}
	for (int i = 0; i < ng; i++)
		if (atomic_load(&g[i]->failed) && e->code == EXIT_OK)
			err_set(e, EXIT_PLUGIN, "rendering failed");
	return rc < 0 || e->code != EXIT_OK ? -1 : 0;
}

/*
 * Between SCA groups, the pool idle: the models started afresh (their
 * threads' states stopped, fini() and init() again), so that what they
 * hold for the SCAs written (halos, the diffuse light, polyphase copies of
 * ePSF nodes) goes, and then those SCAs' PSF grids are freed.  In that
 * order: a model may know a grid by its address, which a grid loaded
 * later could take.  The report's figures of the grids are kept first.
 */
static int models_restart(struct engine *g)
{
	for (int i = 0; i < g->nworker; i++)
		for (int m = 0; m < g->plugins.n; m++) {
			struct plugin *pl = &g->plugins.p[m];

			if (g->w[i].started[m] && pl->m->thread_stop)
				pl->m->thread_stop(pl->state, g->w[i].tstate[m]);
			g->w[i].started[m] = 0;
			g->w[i].tstate[m] = NULL;
		}
	for (int m = 0; m < g->plugins.n; m++) {
		struct plugin *pl = &g->plugins.p[m];

		if (!pl->ready)
			continue;
		if (pl->m->fini)
			pl->m->fini(pl->state);
		pl->state = NULL;
		if (pl->m->init && pl->m->init(&g->host, &pl->state) < 0) {
			pl->ready = 0;
			if (g->e->code == EXIT_OK)
				err_set(g->e, EXIT_PLUGIN, "model '%s' (%s): set-up failed",
					pl->name, pl->path);
			return -1;
		}
	}
	/* (not the first SCA's, its spectral classes' and galaxies' blends
	 * too: every pass measures the reach of sky rows on it, place.c,
	 * which would make them again; run_first_bytes() counts them) */
	for (int s = 1; s < g->nslot; s++)
		if (g->pass_slots >> s & 1) {
			if (g->x->report && report_grids_note(g, g->slot[s].sca) < 0)
				return -1;
			psfgrids_drop(g, g->slot[s].sca);
		}
	return 0;
}

/* The end of a pass for one exposure: the light its models gathered
 * spread, its SCAs through the detector stage and written, and before
 * another SCA group the memory of these SCAs freed. */
static int finish_pass(struct engine *g)
{
	if (render_spread(g) < 0 || write_exposure(g) < 0)
		return -1;
	return g->pass + 1 < g->npass ? models_restart(g) : 0;
}

/* After the exposure's last pass: its --placed list, persistence, report. */
static int finish(struct engine *g, struct timespec t0)
{
	struct timespec t1;

	if (placed_merge(g) < 0 || placed_close(g, 1) < 0 ||
	    (g->x->persist && persist_end(g->x->persist, g->e) < 0))
		return -1;
	clock_gettime(CLOCK_MONOTONIC, &t1);
	g->t_total = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
	if (g->progress)
		fputs("\r\033[K", stderr);
	if (g->x->report && report_write(g) < 0)
		return -1;
	host_log(g, 1, "%s%s%llu rows read, %llu culled far from every SCA, %llu placements "
		 "on %d SCA%s, %.3f s", g->o->pointings ? g->x->name : "",
		 g->o->pointings ? ": " : "", g->rows_read, g->culled, g->placements, g->nslot,
		 g->nslot == 1 ? "" : "s", g->t_total);
	return 0;
}

/*
 * The memory a run holds while it draws, measured with /usr/bin/time's
 * peak (BENCHMARKS.md, "Memory in passes"): for every SCA drawn at once,
 * 4088 columns of doubles for each row drawn (its tiles: a crowded field
 * touches every one) and SCA_BYTES more for its PSF grids, the models'
 * state for it and its placements; and run_bytes() once, the catalog's
 * chunks and the program (more at levels 1 and 2: the ramps of the SCA
 * being written).  Measured on 10^6 sky rows over the focal plane: 172 MiB
 * an SCA at the scene level and 183 MiB at level 2, of which 127.5 MiB
 * are tiles; 33 and 104 MiB besides.  A chunk's rows, every one placed,
 * hold some 510 bytes each (10^6 faint stars on one SCA: 230 MiB at the
 * 65536 rows of --chunk, 327 MiB at 262144): 512 a row of --chunk.
 */
#define MIB (1024.0 * 1024.0)
#define SCA_BYTES (56.0 * MIB)

static double run_bytes(const struct scene_opts *o)
{
	return (o->level ? 78.0 : 8.0) * MIB + 512.0 * (double)o->chunk;
}

/* What each exposure drawn at once beyond the first adds for a chunk of
 * --chunk rows: its engine's own two batches (engine.h), a placement and
 * its tile index for every row at most; run_bytes() counts the first's. */
static double batch_bytes(const struct scene_opts *o)
{
	return 2.0 * (sizeof(struct placement) + sizeof(uint32_t)) * (double)o->chunk;
}

/* Every ASDF file the run will write, each exposure's of each SCA, checked
 * (asdf_out_target) before anything is drawn: a name with an exposure's
 * %s is known only once the exposures are read, and a run whose later
 * file names a device must leave no earlier file behind. */
static int asdf_names(const struct scene_opts *o, const struct exposure *x, int n,
		      struct err *e)
{
	char name[4096];

	if (o->format != FORMAT_ASDF)
		return 0;
	for (int i = 0; i < n; i++)
		for (int sca = 1; sca <= WFS_NSCA; sca++)
			if ((x[i].sca_mask >> (sca - 1) & 1) &&
			    (name_expand(name, sizeof(name), "-o", o->output, sca,
					 x[i].name[0] ? x[i].name : NULL, e) < 0 ||
			     asdf_out_target(name, e) < 0))
				return -1;
	return 0;
}

/* Whether catalog path can be read only once: stdin ('-'), a named pipe
 * or a device (not a regular file nor a tree's directory). */
static int read_once(const char *path)
{
	struct stat st;

	return !strcmp(path, "-") ||
	       (stat(path, &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode));
}

/* The families of spectra a catalog (not stdin, which is read once) names
 * (catalog_spectral), from its header (a tree's: its first file's), no row
 * read; a catalog that cannot be opened counts as none (the pass reports
 * it), and so do stdin and a named pipe or device, which opening here
 * would drain (wfiscene(1), --memory). */
static int catalog_families(const struct scene_opts *o, const char *path)
{
	struct catalog_opts co = { .filter = o->filter, .flux_unit = o->flux_unit,
				   .chunk_rows = o->chunk, .settings = o->settings,
				   .epoch = o->epoch };
	struct err e = { 0 };
	struct catalog *c;
	int fam;

	if (read_once(path) || !(c = catalog_open(path, &co, &e)))
		return 0;
	fam = catalog_spectral(c);
	catalog_close(c);
	return fam;
}

/* A --set key's last value, NULL when unset or empty (point.so then takes
 * its default; the host refuses an empty psf-colour-classes,
 * psf-colour-galaxy-steps or psf-halo-radius when the run starts). */
static const char *set_value(const struct scene_opts *o, const char *key)
{
	const char *v = setting_last(o->settings, key);

	return v && *v ? v : NULL;
}

/* set_value() as a number, or dflt. */
static double set_number(const struct scene_opts *o, const char *key, double dflt)
{
	const char *v = set_value(o, key);

	return v ? atof(v) : dflt;
}

/* What point.so adds to a halo of psf-halo-radius R (4 R + 1 samples a
 * side, two a pixel) when it draws with psf-halo-near (above 0, as by
 * default): its step map ((2 R + 3)^2 int16); its runs and, with
 * AVX-512, their chunks, two int32 a row and level (103-109 levels in
 * F129-F213 at the default radius, up to 147 at 1024: 170 here) and some
 * 3 bytes an offset (measured: 1.03-1.05 MB in all at the default radius,
 * 0.25 MB at 100, up to 14.4 MB at 1024 in F062-F213; 3.5 here); and the
 * array split by phase (two planes of 4 R + 1 rows of 2 R + 17 floats). */
static double halo_near_bytes(const struct scene_opts *o, double R)
{
	double n = 4 * R + 1, side = 2 * R + 3;

	if (!(set_number(o, "psf-halo-near", 1) > 0))
		return 0;
	return side * side * (2 + 3.5) + side * 170 * 2 * sizeof(int32_t) +
	       2 * n * (ceil(n / 2) + 16) * sizeof(float);
}

/* The default spectrum's halo of an SCA beyond what SCA_BYTES holds (its
 * array at the default psf-halo-radius 256): its near lists, and its
 * array's growth at a larger radius (built-in PSF, psf-extent=noise). */
static double default_halo_bytes(const struct scene_opts *o)
{
	const char *v = set_value(o, "psf-extent");
	double R = set_number(o, "psf-halo-radius", 256);

	if (strcmp(o->psf, "builtin") || (v && strcmp(v, "noise")) || !(R > 0))
		return 0;
	return halo_near_bytes(o, R) +
	       (R > 256 ? ((4 * R + 1) * (4 * R + 1) - (4 * 256 + 1.0) * (4 * 256 + 1)) *
				  sizeof(float) : 0);
}

/*
 * The colour halos an SCA may hold (point.so, psf-extent=noise with the
 * built-in PSF) when a catalog has a spectrum column, an upper bound: the
 * class halos the host builds ((4 R + 1)^2 floats for psf-halo-radius R,
 * 2 n of them for psf-colour-classes n a family) and, for every class pair
 * of both families and every step of psf-halo-colour-steps N, the blend
 * (one more array) with its step map, runs and chunks and the array
 * again split by phase (halo_near_bytes) and halo tables (some 40 kB):
 * 2 ((n - 1) N + 1) of them.  The diffuse grid builds a halo's kernels while it
 * gathers the SCA, one halo's at a time, in the buffers of the default
 * halo's (counted in SCA_BYTES).  Measured: 1000 bright stars of every
 * temperature on one SCA held 61 MB more with 4 steps, against this
 * bound's 158 MB (both families).
 */
static double colour_halo_bytes(const struct scene_opts *o)
{
	const char *v = set_value(o, "psf-extent");
	double N = set_number(o, "psf-halo-colour-steps", 4);
	double R = set_number(o, "psf-halo-radius", 256);
	double n = set_number(o, "psf-colour-classes", psf_default_classes(o->filter)), arr;

	if (strcmp(o->psf, "builtin") || (v && strcmp(v, "noise")))
		return 0;
	if (!(N > 0) || !(R > 0) || !(n >= 2))
		return 0;
	arr = (4 * R + 1) * (4 * R + 1) * sizeof(float);
	return 2 * n * arr + 2 * ((n - 1) * N + 1) * (arr + halo_near_bytes(o, R) + 40e3);
}

/*
 * What spectra add to an SCA (built-in PSF) when the catalogs name the
 * spectral families fam (catalog_spectral), an upper bound, for each
 * family of n classes (psf-colour-classes): the classes' grids of the
 * faint size class (n grids of 9 nodes of 177^2 floats) and point.so's
 * 9 n copies of their nodes, each a polyphase copy with its summed-area
 * tables (PSF_OVER^2 (m^2 + (m + 1)^2) floats, m = ceil(177 / PSF_OVER) +
 * 5); its colour cells, as large each (psf-blend core or cell, and
 * psf-colour-steps M at least 1): at each of the (ceil(4088 / C) + 2)^2
 * positions of psf-cell C, the cells of the (n - 1) M + 1 steps between
 * the classes (the n class cells among them); and
 * when rows may name their model (SPECTRAL_TYPED), the grids galaxies are
 * convolved with, the (n - 1)(G - 1) blends between the classes at
 * psf-colour-galaxy-steps G, 9 nodes of 177^2 floats each.  The bright
 * size classes are left out: a bright source makes its own position's
 * cells and its own step's blend only.  Measured (BENCHMARKS.md, "Seventh
 * sitting"): 10^6 faint stars of random teff on one SCA held 32 MB more
 * than without the column in F158 and 93 MB in F146, against this
 * bound's 73 and 147 MB; 10^4 faint galaxies of random beta in F146 108
 * MB more, against the 110 MB of its grids and blends.  Without cells,
 * the host's grids and blends alone (what the first SCA keeps all run).
 */
static double colour_cell_bytes(const struct scene_opts *o, int fam, int cells)
{
	const char *v = set_value(o, "psf-blend");
	double C = set_number(o, "psf-cell", 512), M = set_number(o, "psf-colour-steps", 1);
	double G = set_number(o, "psf-colour-galaxy-steps", 32);
	double n = set_number(o, "psf-colour-classes", psf_default_classes(o->filter));
	double nn = psf_class_n[0], grid = 9 * nn * nn * sizeof(float), side, m, poly, b;
	int nf = !!(fam & SPECTRAL_BLACKBODY) + !!(fam & SPECTRAL_POWER);

	if (strcmp(o->psf, "builtin") || !nf || !(n >= 2))
		return 0;
	m = ceil(nn / PSF_OVER) + 5;
	poly = PSF_OVER * PSF_OVER * (m * m + (m + 1) * (m + 1)) * sizeof(float);
	b = n * grid + (cells ? 9 * n * poly : 0);
	if (fam & SPECTRAL_TYPED && G > 1)
		b += (n - 1) * (G - 1) * grid;
	if (cells && C >= 1 && M >= 1 && !(v && !strcmp(v, "source"))) {
		side = ceil(WFS_NPIX / C) + 2;
		b += side * side * ((n - 1) * M + 1) * poly;
	}
	return nf * b;
}

/* An SCA's bytes; colour, its colour halos' and cells' (colour_halo_bytes,
 * colour_cell_bytes). */
static double sca_bytes(const struct scene_opts *o, double colour)
{
	double rows = o->row_first ? o->row_last - o->row_first + 1 : WFS_NPIX;

	return rows * WFS_NPIX * sizeof(double) + SCA_BYTES + default_halo_bytes(o) + colour;
}

static double exposure_bytes(const struct scene_opts *o, const struct exposure *x, double colour)
{
	return __builtin_popcount(x->sca_mask) * sca_bytes(o, colour);
}

/* The smallest of the machine's physical memory and the memory limit of
 * the control group the process runs in (cgroup v2, else v1), bytes. */
static double memory_available(void)
{
	static const char *const limit[2] = { "/sys/fs/cgroup/memory.max",
					      "/sys/fs/cgroup/memory/memory.limit_in_bytes" };
	long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
	double have = pages > 0 && size > 0 ? (double)pages * size : 8e9;

	for (int k = 0; k < 2; k++) {
		FILE *f = fopen(limit[k], "r");
		double v;

		if (!f)
			continue;
		if (fscanf(f, "%lf", &v) == 1 && v > 0 && v < have)
			have = v;
		fclose(f);
		break;
	}
	return have;
}

/*
 * The budget without --memory: half of memory_available(), the other half
 * left to the page cache the outputs go through and to other programs; at
 * levels 1 and 2 at most LEVEL_BUDGET.  There the ramps take most of the
 * run (some 35 of the 38 s of 10^7 sky rows on 18 SCAs), so a second pass
 * over the catalogs costs a few per cent for half the peak: 1.7 GB instead
 * of 3.3 (BENCHMARKS.md, "Tenth sitting").  At the scene level a pass is
 * most of the run, and memory is spent first.
 */
#define LEVEL_BUDGET (2000.0 * MIB)

static double default_budget(const struct scene_opts *o)
{
	double half = 0.5 * memory_available();

	return o->level ? fmin(half, LEVEL_BUDGET) : half;
}

/*
 * --chunk's default.  Each chunk's tile tasks, sorts and bins cost the same
 * however few of its rows land in a tile, and each tile a chunk touches is
 * fetched from memory once a chunk: the larger the chunk, the less both
 * cost (against 65536 rows, 262144 took 0.8 of the CPU for 10^7 sky rows
 * on 18 SCAs and 0.92 for 10^6 faint stars on one; BENCHMARKS.md,
 * "Seventh" and "Eleventh sitting").  So 262144 rows; but in a series 16384
 * an SCA, at least 65536, since each exposure drawn at once beyond the
 * first holds its own placements of a chunk (batch_bytes()).  Not from
 * --memory: the order of --placed goes chunk by chunk, and a run's files
 * do not depend on its budget.
 */
size_t scene_default_chunk(const struct scene_opts *o)
{
	size_t n = (size_t)16384 * __builtin_popcount(o->sca_mask);

	if (!o->pointings || n >= 262144)
		return 262144;
	return n < 65536 ? 65536 : n;
}

/*
 * How a run's exposures are drawn: as many exposures at once as the memory
 * budget (--memory, by default default_budget()) holds at
 * exposure_bytes() each (and batch_bytes() for each but the first)
 * besides run_bytes(); the others wait for later
 * passes over the catalogs, so a series of hundreds of exposures of one
 * field needs the memory of a few.  When not even one exposure fits, each
 * is drawn alone in groups of SCAs, as many at once as fit (at least one),
 * one pass over the catalogs a group: every SCA of a group is finished,
 * written and freed before the next group is drawn.
 */
struct plan {
	int per;                /* exposures drawn at once */
	int groups;             /* SCA groups of each exposure (per is 1) */
	int passes;             /* over the catalogs in all */
	double budget;          /* bytes */
	double colour;          /* an SCA's colour halos and cells, bytes */
	double first;           /* the first SCA's colour grids, kept all run
				 * (models_restart), bytes */
};

/* p's colour and first for the spectral families fam (none: 0). */
#define SPECTRAL_ALL (SPECTRAL_BLACKBODY | SPECTRAL_POWER | SPECTRAL_TYPED)

static void plan_colour(const struct scene_opts *o, int fam, struct plan *p)
{
	double halos = fam ? colour_halo_bytes(o) : 0;

	p->colour = halos + colour_cell_bytes(o, fam, 1);
	p->first = halos + colour_cell_bytes(o, fam, 0);
}

static void plan_passes(const struct scene_opts *o, const struct exposure *x, int n,
			struct plan *p)
{
	double each = 0, k;
	int nsca = __builtin_popcount(x[0].sca_mask);

	p->budget = o->memory_mb > 0 ? o->memory_mb * MIB : default_budget(o);
	for (int i = 0; i < n; i++)
		each = fmax(each, exposure_bytes(o, &x[i], p->colour));
	k = floor((p->budget - run_bytes(o) - p->first + batch_bytes(o)) / (each + batch_bytes(o)));
	p->per = k < 1 ? 1 : k >= n ? n : (int)k;
	p->groups = 1;
	if (k < 1 && nsca > 1) {
		double fit = floor((p->budget - run_bytes(o) - p->first) / sca_bytes(o, p->colour));
		int at_once = fit < 1 ? 1 : fit >= nsca ? nsca : (int)fit;

		p->groups = (nsca + at_once - 1) / at_once;
	}
	p->passes = (n + p->per - 1) / p->per * p->groups;
}

/* The bits of the slots of group j of k among nslot slots: consecutive
 * slots, the groups as even as can be. */
static uint32_t group_slots(int nslot, int j, int k)
{
	int lo = j * nslot / k, hi = (j + 1) * nslot / k;

	return (uint32_t)(((1ull << hi) - 1) & ~((1ull << lo) - 1));
}

/* -v: how the run's exposures are drawn. */
static void plan_say(const struct scene_opts *o, const struct exposure *x, int n,
		     const struct plan *p)
{
	int nsca = __builtin_popcount(x[0].sca_mask);

	if (o->verbose < 1 || p->passes < 2)
		return;
	if (p->groups > 1)
		fprintf(stderr, "wfiscene: %d SCAs in %d passes over the catalogs%s, %d at most at "
			"a time (%.0f MB each, %.0f MB of memory)\n", nsca, p->groups,
			n > 1 ? " per exposure" : "", (nsca + p->groups - 1) / p->groups,
			sca_bytes(o, p->colour) / MIB, p->budget / MIB);
	else
		fprintf(stderr, "wfiscene: %d exposures in %d passes over the catalogs, "
			"at most %d at a time (%.0f MB each)\n", n, p->passes, p->per,
			exposure_bytes(o, &x[0], p->colour) / MIB);
}

/* Engine g[i] for exposure x[i], ready for the catalogs. */
static int pass_engine(struct engine *g, const struct scene_opts *o, struct exposure *x,
		       int groups, struct pool *pool, struct pool *place_pool,
		       struct into *into, struct timespec t0, int first, struct err *e)
{
	if (engine_init(g, o, x, pool, place_pool, e) < 0 ||
	    (into && into_apply(into, &g->sky, o, e) < 0))
		return -1;
	if ((x->placed && placed_open(g) < 0) || (x->report && side_check(x->report, e) < 0))
		return -1;
	g->npass = groups;
	g->t_start = g->t_progress = t0;
	g->progress = first && o->verbose >= 0 && isatty(2);
	return 0;
}

/* Exposures x[0 .. n-1] drawn in plan->groups passes over the catalogs (one
 * but with SCA groups): an engine each, the catalogs streamed through them
 * once a group, each group finished, the exposures' side files at the end.
 * A catalog on stdin has been spooled (stdin_copy) and is read again from
 * its start each pass. */
static int run_pass(const struct scene_opts *o, char *const *catalogs, struct exposure *x,
		    int n, int groups, struct pool *pool, struct pool *place_pool,
		    struct into *into, struct timespec t0, int stdin_copy, struct err *e)
{
	struct engine **g = calloc(n, sizeof(*g));
	unsigned long long *culled = calloc(n, sizeof(*culled));
	int made = 0, rc = -1;

	if (!g || !culled) {
		err_sys(e, "memory");
		goto out;
	}
	for (int i = 0; i < n; i++) {
		if (!(g[i] = malloc(sizeof(*g[i])))) {
			err_sys(e, "memory");
			goto out;
		}
		made++;
		if (pass_engine(g[i], o, &x[i], groups, pool, place_pool, into, t0, i == 0, e) < 0)
			goto out;
	}
	for (int j = 0; j < groups; j++) {
		if (stdin_copy && lseek(0, 0, SEEK_SET) < 0) {
			err_sys(e, "<stdin>: its temporary copy");
			goto out;
		}
		for (int i = 0; i < n; i++) {
			g[i]->pass = j;
			g[i]->pass_slots = groups > 1 ? group_slots(g[i]->nslot, j, groups) : UINT32_MAX;
			culled[i] = g[i]->culled;
			if (placed_pass_begin(g[i]) < 0)
				goto out;
		}
		if (run_catalogs(g, n, catalogs, o, e) < 0)
			goto out;
		for (int i = 0; i < n; i++) {
			/* culled near every SCA: counted by the first pass */
			if (j)
				g[i]->culled = culled[i];
			if (finish_pass(g[i]) < 0 || (j == groups - 1 && finish(g[i], t0) < 0))
				goto out;
		}
	}
	rc = 0;
out:
	for (int i = 0; i < made; i++) {
		placed_close(g[i], 0);
		/* a failed run leaves no file behind, as one pass would not */
		for (int k = 0; k < g[i]->nwritten; k++) {
			if (rc < 0)
				unlink(g[i]->written[k]);
			free(g[i]->written[k]);
		}
		engine_free(g[i]);
		free(g[i]);
	}
	free(g);
	free(culled);
	return rc;
}

/* A run of several passes over a catalog given as '-': stdin copied to a
 * temporary once (tempfile.h), read from its start by each pass.  A named
 * pipe or a device can be read only once: refused (a second pass opened a
 * pipe whose writer had gone, and waited for ever). */
static int stdin_for_passes(const struct scene_opts *o, char *const *catalogs,
			    const struct plan *p, int *copied, struct err *e)
{
	long long bytes;

	*copied = 0;
	if (p->passes < 2)
		return 0;
	for (char *const *cat = catalogs; *cat; cat++)
		if (strcmp(*cat, "-") && read_once(*cat))
			return err_set(e, EXIT_INPUT, "%s: not a regular file, so read only once, "
				       "and this run makes %d passes over the catalogs "
				       "(--memory): give a file, or pipe it to stdin ('-'), "
				       "which is kept in a temporary file", *cat, p->passes);
	for (char *const *cat = catalogs; *cat; cat++)
		if (!strcmp(*cat, "-")) {
			if ((bytes = tempfile_spool_stdin(e)) < 0) {
				err_prefix(e, "%d passes over the catalogs (--memory)", p->passes);
				return -1;
			}
			if (o->verbose >= 1)
				fprintf(stderr, "wfiscene: <stdin>: %lld bytes kept in a temporary "
					"file for %d passes\n", bytes, p->passes);
			*copied = 1;
			return 0;
		}
	return 0;
}

int scene_run(const struct scene_opts *o, char *const *catalogs, struct err *e)
{
	struct exposure *x = NULL;
	struct pool *pool = NULL, *place_pool = NULL;
	struct into *into = NULL;
	struct persist *persist = NULL;
	struct timespec t0;
	struct plan plan;
	int n = 0, nthreads, rc = -1, acomp, stdin_copy;

	clock_gettime(CLOCK_MONOTONIC, &t0);
	/* a setting the writers read at the end, checked before any work */
	if (asdf_compression_setting(o->settings, &acomp, e) < 0)
		return -1;
	if (o->into && (o->pointings || o->row_first || !strcmp(o->output, "-") ||
			strstr(o->output, "%d")))
		return err_set(e, EXIT_INPUT, "--into: one output file, without "
			       "--pointings, --rows, '-' or '%%d'");
	if (o->into && !(into = into_open(o->into, o->sca_mask, e)))
		return -1;
	if (into)
		into_catalogs(into, catalogs);
	if (into && into_check_output(into, o->output, e) < 0) {
		into_free(into);
		return -1;
	}
	if (exposures_make(o, &x, &n, e) < 0) {
		into_free(into);
		return -1;
	}
	if (asdf_names(o, x, n, e) < 0)
		goto out;
	/* With --into, the image says where the SCAs look (into.h). */
	if (into)
		into_pointing(into, &x[0].ra, &x[0].dec, &x[0].pa, &x[0].boresight);
	/* Persistence: one state for the run's exposures, taken in their
	 * order (persist.h); needless for one exposure without a state to
	 * carry on. */
	if ((o->detector & DETECTOR_PERSISTENCE) && (n > 1 || o->persistence_state)) {
		unsigned mask = 0;

		for (int i = 0; i < n; i++)
			mask |= x[i].sca_mask;
		if (!(persist = persist_new(mask, o->row_first ? o->row_first - 1 : 0,
					    o->row_first ? o->row_last : WFS_NPIX, o->settings, e)) ||
		    (o->persistence_state && persist_load(persist, o->persistence_state, e) < 0) ||
		    persist_check_dates(persist, x, n, o->exptime, e) < 0)
			goto out;
		/* the state is saved after the images are written: a place it
		 * cannot be saved in is refused now, before any image is */
		if (o->persistence_state && side_check(o->persistence_state, e) < 0)
			goto out;
		for (int i = 0; i < n; i++)
			x[i].persist = persist;
	}
	/* the colour halos and cells counted only where they could change
	 * the plan (both families), and then for the families the catalogs'
	 * spectrum columns name (opening each catalog to see costs some MB of
	 * buffers, left unspent otherwise) */
	plan_colour(o, SPECTRAL_ALL, &plan);
	if (plan.colour > 0) {
		struct plan with = plan, without = plan;

		plan_colour(o, 0, &without);
		plan_passes(o, x, n, &with);
		plan_passes(o, x, n, &without);
		if (with.passes == without.passes && with.groups == without.groups &&
		    with.per == without.per) {
			plan_colour(o, 0, &plan);
		} else {
			int fam = 0;

			for (char *const *cat = catalogs; *cat && fam != SPECTRAL_ALL; cat++)
				fam |= catalog_families(o, *cat);
			plan_colour(o, fam, &plan);
		}
	}
	plan_passes(o, x, n, &plan);
	plan_say(o, x, n, &plan);
	if (stdin_for_passes(o, catalogs, &plan, &stdin_copy, e) < 0)
		goto out;
	nthreads = o->threads > 0 ? o->threads : pool_cpus();
	/* the models' prepare() on as many threads, beside the render pool's
	 * (place.c): one thread would only stand in for the main one */
	if (!(pool = pool_new(nthreads)) ||
	    (nthreads > 1 && !(place_pool = pool_new(nthreads)))) {
		err_sys(e, "memory");
		goto out;
	}
	for (int i = 0; i < n; i += plan.per)
		if (run_pass(o, catalogs, x + i, n - i < plan.per ? n - i : plan.per, plan.groups,
			     pool, place_pool, into, t0, stdin_copy, e) < 0)
			goto out;
	if (into && into_compose(into, x[0].output, acomp, pool, e) < 0)
		goto out;
	if (persist && o->persistence_state && persist_save(persist, o->persistence_state, e) < 0)
		goto out;
	rc = 0;
out:
	persist_free(persist);
	into_free(into);
	pool_free(pool);
	pool_free(place_pool);
	exposures_free(x, n);
	return rc;
}
