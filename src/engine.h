/*
 * engine.h - the engine's private state, shared by the files of one run.
 *
 * scene.h is the engine's public face (scene_run); this header is what its
 * files share.  One struct engine simulates one exposure; a run with
 * --pointings has one engine per exposure, all fed the same chunks of rows.
 * The files, in the order the data flows through them:
 *
 *   run.c        the run loop: exposures set up, catalogs read in chunks,
 *                each chunk placed while the previous one renders
 *   clock.c      the run's clock and progress line (clock.h)
 *   exposure.c   the exposures: one from the options, or --pointings
 *   place.c      rows to placements: models, columns, fluxes, reach,
 *                which SCAs a row may reach, pixels, binning by tile
 *   tile.c       the tiles' memory, allocated when first touched
 *   settings.c   the engine's messages and settings, lent to models by host.c
 *   host.c       the services the host lends to every model (struct wfs_host)
 *   psfgrids.c   the ePSF grids the scene's models ask for
 *   render.c     worker threads drawing whole tiles
 *   detector.c   the detector stage after rendering (detector.h)
 *   write.c      FITS header cards and the image written strip by strip
 *   report.c     the --placed list and the --report JSON
 */
#ifndef WFS_ENGINE_H
#define WFS_ENGINE_H

#include <limits.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdint.h>
#include <time.h>

#include "err.h"
#include "exposure.h"
#include "instrument.h"
#include "plugin.h"
#include "psf.h"
#include "scene.h"
#include "sky.h"
#include "wfiscene/model.h"

struct catalog;
struct fftconv;
struct fftconv_thread;
struct pool;
struct rows;

#define MAX_COLUMNS PLUGIN_COLUMNS_MAX

/* Said of a plugin callback that returned -1 without host->error(). */
#define MODEL_SILENT ", with no message (the plugin must give one with host->error())"

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
	size_t row;             /* the row of the chunk */
	int from;               /* the row's own model (model[row]) */
};


/* The tiles a placement's box meets: nx x ny of them from global tile
 * t0 (place_bin's first pass, read again by its second). */
struct tile_span {
	uint32_t t0;
	uint16_t nx, ny;
};

/* The placements of one chunk, binned by tile. */
struct batch {
	struct placement *p;
	size_t n, cap;
	size_t nserial;         /* placements whose model's prepare() is
				   not WFS_PARALLEL_PREPARE */
	double *param;
	size_t nparam, capparam;
	uint32_t *count;        /* per global tile, then start offsets */
	uint32_t *items;        /* placement indices grouped by tile */
	size_t nitems, capitems;
	struct tile_span *span; /* each placement's tiles (place_bin) */
	size_t capspan;
	uint32_t *active;       /* global tiles with placements */
	size_t nactive;
};

/* Per worker thread: scratch memory, FFT buffers, models' thread state. */
struct worker {
	struct engine *g;
	/* The worker's own error record, written only by its thread while
	 * the pool runs and read by the main thread after pool_wait()
	 * (render_errors_collect); err_task is the tile it failed on, or for
	 * a thread of place_pool the placement. */
	struct err err;
	size_t err_task;
	int place;              /* a thread of place_pool: may load PSF grids */
	void *scratch;
	size_t scratch_cap;
	struct fftconv_thread *fft;
	void *tstate[PLUGIN_MAX];
	unsigned char started[PLUGIN_MAX];
};

/* A catalog's type string and the model that draws it. */
struct type_cache {
	char name[64];
	int model;
};

struct engine {
	const struct scene_opts *o;     /* what all exposures share */
	const struct exposure *x;       /* this exposure */
	struct err *e;                  /* the main thread's only (workers: struct worker) */
	pthread_t main_thread;          /* the one that may load PSF grids */
	atomic_int failed;

	struct sky sky;
	int tile, ntx, nty, ntile;      /* tile side, tiles per axis, per SCA */
	int ylo, yhi;                   /* the rows drawn and written, [ylo, yhi) */
	int nslot;
	struct slot slot[WFS_NSCA];
	int slot_of[WFS_NSCA + 1];      /* SCA -> slot, or -1 */

	/* per SCA, the size classes of model.h's enum wfs_psf_class and last
	 * the halo's (psf.h); published under grid_lock (psfgrids.c) */
	struct psf_grid *grid[WFS_NSCA][WFS_PSF_HALO + 1];
	pthread_mutex_t grid_lock;
	struct psf_grid *user_grid;     /* --psf FILE without %d: all SCAs */
	struct psf_build_opts pbo;
	/* colour (spectrum.h): the filter's colour tables, made for the
	 * first chunk with a spectrum column */
	struct colour *colour;
	int colour_band;                /* --set colour-counts=band: no colour term */
	/* the spectral classes of the built-in PSF (psf.h), NULL for none
	 * (no spectrum yet, or --psf FILE), and their grids: cgrid[((sca -
	 * 1) * 4 + cls) * ncgrid + k] for spectral class k (cls 3: its
	 * halo), published under grid_lock as the others (psfgrids.c) */
	struct psf_classes *classes;
	struct psf_grid **cgrid;
	char classes_str[16];           /* setting "spectral-classes": 2 n */
	int ncgrid;

	struct plugins plugins;
	struct wfs_host host;
	struct fftconv *fft;
	struct pool *pool;
	struct worker *w;
	int nworker;
	/* prepare() and footprint() of WFS_PARALLEL_PREPARE models (place.c):
	 * a second pool, as the first draws the previous chunk meanwhile,
	 * and its threads' records (only err and place used) */
	struct pool *place_pool;
	struct worker *pw;
	int npw;

	char filter_name[16], exptime_str[32], seed_str[32];
	char bkg_str[32], readnoise_str[32], noise_str[64], sigma_str[32], mjd_str[32];
	int flux_meaning;               /* enum wfs_flux_meaning of the catalog being read */

	struct type_cache types[PLUGIN_MAX];
	int ntypes;
	int colidx[PLUGIN_MAX][MAX_COLUMNS];
	const struct rows *colidx_rows[PLUGIN_MAX];

	/* per row of the chunk being placed; all share cap_rows */
	double *fx, *fy, *px, *py, *reach;
	uint32_t *cand;
	uint32_t *mask;                 /* slots the row may reach */
	double *param;                  /* the row's columns, MAX_COLUMNS a row */
	int *model;                     /* the row's model */
	size_t cap_cand;                /* cand, px, py: all slots' candidates */
	unsigned char *listed;          /* row already in a romanisim --placed */
	double *mra, *mdec;             /* rows moved to the exposure's date */
	size_t cap_rows;
	struct rows *moved;             /* the chunk with mra, mdec (place.c) */
	double observer[3];             /* Roman at the date (motion.h) */

	struct batch b[2];              /* double buffer: see run_catalogs() */
	const struct batch *rendering;

	FILE *placed;
	int placed_roman;               /* --placed in romanisim's convention */
	char placed_tmp[PATH_MAX];

	unsigned long long rows_read, placements, culled, offdet;
	/* catalog trees: files in them, skipped unread, what those held */
	unsigned long long trees, tree_files, tree_skipped, tree_bytes_skipped;
	unsigned long long tree_rows_skipped, tree_rows_uncounted;
	unsigned long long tiles_drawn, tiles;  /* before noise, and in all */
	unsigned long long per_model[PLUGIN_MAX];
	double flux_requested[WFS_NSCA];        /* sum of placed sources' flux */
	unsigned long long placed_on[WFS_NSCA];
	double image_sum[WFS_NSCA];             /* drawn light, before noise */
	double t_read, t_place, t_wait, t_noise, t_write, t_total;
	double *t_render;                       /* per worker: busy seconds */
	double *t_render_cpu;                   /* per worker: CPU seconds drawing */
	struct timespec t_start, t_progress;
	int progress;                           /* stderr is a terminal */

	/* SCA groups (run.c): an exposure whose SCAs do not fit --memory
	 * is drawn in npass passes over the catalogs, pass_slots the bits of
	 * the slots drawn in pass number pass (all bits set in a run of one
	 * pass).  A file of several SCAs stays open across them (out,
	 * write.c); each pass's --placed list is kept apart (placed_part)
	 * and merged into placed_out in the order of one pass (report.c). */
	uint32_t pass_slots;
	int pass, npass;
	struct writer *out;
	FILE *placed_out, *placed_part[WFS_NSCA];
	struct grid_note *grid_note;    /* the report's PSF grids of SCAs done */
	char *written[WFS_NSCA];        /* files committed by passes before the last */
	int nwritten;
};

/* host.c: the struct wfs_host lent to plugins. */
void host_init(struct engine *g);

/* settings.c: the engine's messages and settings, which host.c also lends
 * to plugins (errors from any thread, -v logging, a setting's value).
 * settings_init() fixes the scene's settings as text for the exposure.
 * host_worker() says which worker the calling thread is drawing for (NULL:
 * the main thread), so that host_error() writes that worker's record;
 * host_current() is that worker if it is one of g's, else NULL. */
void settings_init(struct engine *g);
void host_worker(struct worker *w);
struct worker *host_current(const struct engine *g);
int host_error(void *ctx, const char *fmt, ...) WFS_PRINTF(2, 3);
void host_log(void *ctx, int level, const char *fmt, ...) WFS_PRINTF(3, 4);
const char *host_setting(void *ctx, const char *key);

/* psfgrids.c */
const struct psf_grid *psfgrids_get(const struct engine *g, int sca, int cls);
int psfgrids_need(struct engine *g, int sca, int cls, struct err *e);
int psfgrids_open_user(struct engine *g);
void psfgrids_free(struct engine *g);
/* SCA groups (run.c): the grids of SCA sca freed, its spectral classes'
 * and galaxies' blends too, once it is written and its light gathered
 * (the pool idle); report_grids_note() first. */
void psfgrids_drop(struct engine *g, int sca);
/* The spectral classes for a scene with spectra (the builtin PSF only):
 * made once, from the setting psf-colour-classes.
 * Returns 0 or -1. */
int psfgrids_colour_init(struct engine *g);
const struct psf_grid *psfgrids_colour_get(const struct engine *g, int sca, int cls, int k);
int psfgrids_colour_need(struct engine *g, int sca, int cls, int k, struct err *e);
/* The grid galaxies of spectral class colour are drawn with (host->
 * epsf_blend): loaded or made when load is set, else NULL when not made
 * yet.  NULL with an error in e when it fails. */
const struct psf_grid *psfgrids_blend(struct engine *g, int sca, int cls, double colour,
				      int load, struct err *e);

/* tile.c: the memory of one tile of T x T doubles, zeroed */
double *tile_alloc(int T);
void tile_free(double *p, int T);

/* place.c */
int place_batch(struct engine *g, const struct rows *r, struct batch *b);
/* b binned by tile (only b written: while the pool draws another batch),
 * then, the pool idle, its new tiles allocated */
int place_bin(struct engine *g, struct batch *b);
int place_tiles(struct engine *g, struct batch *b);

/* render.c */
void render_tile(void *arg, int wid, size_t task);
/* After pool_wait(): the workers' errors into g->e (the failure on the
 * lowest tile, unless the main thread recorded one first), records
 * cleared.  Main thread only. */
void render_errors_collect(struct engine *g);
int render_threads_init(struct engine *g);
/* After the last chunk, before the detector stage: the light the models
 * gathered (wfs_model gather, spread) added to every tile of the rows
 * drawn.  Main thread, pool idle.  Returns 0 or -1. */
int render_spread(struct engine *g);
void render_threads_stop(struct engine *g);

/* write.c */
int write_exposure(struct engine *g);

/* report.c: whether a side file (--report, the persistence state) can be
 * written at path, checked before the run draws anything: a directory is
 * refused (exit 1), a device taken as it is, and otherwise the temporary
 * it will be written through is made beside it and removed (exit 2). */
int side_check(const char *path, struct err *e);
int placed_open(struct engine *g);
int placed_close(struct engine *g, int keep);
/* With SCA groups: the --placed list of the pass begins (a temporary of
 * its own), a chunk of it ends, and after the last pass the lists are
 * merged in one pass's order.  0 or -1 with the message in g->e. */
int placed_pass_begin(struct engine *g);
int placed_chunk_end(struct engine *g);
int placed_merge(struct engine *g);
int report_write(struct engine *g);
/* What the report says of SCA sca's PSF grids, kept before they are freed
 * (psfgrids_drop); its memory freed by report_notes_free.  0 or -1. */
int report_grids_note(struct engine *g, int sca);
void report_notes_free(struct engine *g);

#endif
