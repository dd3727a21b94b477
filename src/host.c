/*
 * host.c - the plugin host: the services lent to every model through
 * struct wfs_host (include/wfiscene/model.h).
 *
 * Errors from any thread (a worker's go to its own record, merged by the
 * main thread after the pool waits; the main thread's to the run's), -v
 * logging, settings by key (the scene's own, then --set), ePSF
 * samples (grids loaded by the threads that prepare, see psfgrids.c), per-worker
 * scratch memory and FFT convolution.  The engine uses host_error, host_log
 * and host_setting itself too.
 */
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "err.h"
#include "fftconv.h"


/*
 * The worker the calling thread draws for.  Thread-local because
 * host->error() has no thread argument (model.h): a model calls it with the
 * host's ctx from render() on any worker.  Set by render_tile() around its
 * work, and by place.c's threads of place_pool around theirs; NULL on the
 * main thread.
 */
static _Thread_local struct worker *current_worker;

void host_worker(struct worker *w)
{
	current_worker = w;
}

int host_error(void *ctx, const char *fmt, ...)
{
	struct engine *g = ctx;
	struct worker *w = current_worker;
	char msg[1024];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	err_set(w && w->g == g ? &w->err : g->e, EXIT_PLUGIN, "%s", msg);
	return -1;
}

/* A line at a time, written whole (threads that prepare may log at once). */
void host_log(void *ctx, int level, const char *fmt, ...)
{
	struct engine *g = ctx;
	char line[2048];
	va_list ap;
	int n;

	if (level > g->o->verbose)
		return;
	va_start(ap, fmt);
	n = snprintf(line, sizeof(line), "wfiscene: ");
	vsnprintf(line + n, sizeof(line) - n - 1, fmt, ap);
	va_end(ap);
	strcat(line, "\n");
	fputs(line, stderr);
}

const char *host_setting(void *ctx, const char *key)
{
	struct engine *g = ctx;

	if (!strcmp(key, "filter"))
		return g->filter_name;
	if (!strcmp(key, "exptime"))
		return g->exptime_str;
	if (!strcmp(key, "seed"))
		return g->seed_str;
	if (!strcmp(key, "sersic"))
		return g->o->sersic;
	if (!strcmp(key, "background"))
		return g->bkg_str;
	if (!strcmp(key, "readnoise"))
		return g->readnoise_str;
	if (!strcmp(key, "noise"))
		return g->noise_str;
	if (!strcmp(key, "pixel-sigma"))
		return g->sigma_str;
	if (!strcmp(key, "mjd"))
		return isnan(g->x->date) ? NULL : g->mjd_str;
	if (!strcmp(key, "spectral-classes"))
		return g->classes ? g->classes_str : NULL;
	/* --set key=value: the last one given wins */
	const char *hit = NULL;
	size_t n = strlen(key);

	for (const char *const *kv = g->o->settings; kv && *kv; kv++)
		if (!strncmp(*kv, key, n) && (*kv)[n] == '=')
			hit = *kv + n + 1;
	return hit;
}

/* Grids are loaded (or built) the first time a model asks for one in
 * prepare() or footprint(), on the main thread or a thread of place_pool:
 * a scene whose models never draw with the ePSF builds none.  Render
 * workers only read grids already loaded. */
static int host_epsf(void *ctx, int sca, double x, double y, int cls,
		     struct wfs_epsf *out)
{
	struct engine *g = ctx;
	/* the calling thread's worker of this engine, NULL on the main thread */
	struct worker *w = current_worker && current_worker->g == g ? current_worker : NULL;
	const struct psf_grid *grid;

	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > 3)
		return host_error(ctx, "no ePSF for SCA %d class %d", sca, cls);
	if (!(grid = psfgrids_get(g, sca, cls))) {
		if (w ? !w->place : !pthread_equal(pthread_self(), g->main_thread))
			return host_error(ctx, "ePSF of SCA %d class %d asked for in render() "
					  "but not in prepare() or footprint()", sca, cls);
		if (psfgrids_need(g, sca, cls, w ? &w->err : g->e) < 0)
			return -1;
		grid = psfgrids_get(g, sca, cls);
	}
	psf_grid_at(grid, x, y, out);
	return 0;
}

/* The ePSF of spectral class k (psfgrids.c), loaded as host_epsf() loads
 * the default's; the halo is the default's. */
static int host_epsf_colour(void *ctx, int sca, double x, double y, int cls, int k,
			    struct wfs_epsf *out)
{
	struct engine *g = ctx;
	struct worker *w = current_worker && current_worker->g == g ? current_worker : NULL;
	const struct psf_grid *grid;

	if (cls == 3)
		return host_epsf(ctx, sca, x, y, cls, out);
	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > 2 || !g->classes || k < 0 ||
	    k >= g->ncgrid)
		return host_error(ctx, "no ePSF for SCA %d class %d spectral class %d", sca,
				  cls, k);
	if (!(grid = psfgrids_colour_get(g, sca, cls, k))) {
		if (w ? !w->place : !pthread_equal(pthread_self(), g->main_thread))
			return host_error(ctx, "ePSF of SCA %d class %d spectral class %d asked "
					  "for in render() but not in prepare() or footprint()",
					  sca, cls, k);
		if (psfgrids_colour_need(g, sca, cls, k, w ? &w->err : g->e) < 0)
			return -1;
		grid = psfgrids_colour_get(g, sca, cls, k);
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


void host_init(struct engine *g)
{
	g->host = (struct wfs_host){
		.abi = WFS_ABI_VERSION, .size = sizeof(struct wfs_host), .ctx = g,
		.error = host_error, .log = host_log, .setting = host_setting,
		.epsf = host_epsf, .scratch = host_scratch, .convolve = host_convolve,
		.source_size = sizeof(struct wfs_source), .epsf_colour = host_epsf_colour,
	};
}
