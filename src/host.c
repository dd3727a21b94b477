/*
 * host.c - the plugin host: the services lent to every model through
 * struct wfs_host (include/wfiscene/model.h).
 *
 * host_init() fills the struct: errors, -v logging and settings by key are
 * settings.c's (the engine uses them itself too); here are the rest, ePSF
 * samples (grids loaded by the threads that prepare, see psfgrids.c),
 * per-worker scratch memory and FFT convolution.
 */
#include <pthread.h>
#include <stdlib.h>

#include "engine.h"
#include "err.h"
#include "fftconv.h"

/* What model.h tells plugins of the detector is what the host draws. */
_Static_assert(WFS_SCA_SIDE == WFS_NPIX && WFS_SCA_COUNT == WFS_NSCA,
	       "model.h's SCA constants differ from instrument.h's");

/* Grids are loaded (or built) the first time a model asks for one in
 * prepare() or footprint(), on the main thread or a thread of place_pool:
 * a scene whose models never draw with the ePSF builds none.  Render
 * workers only read grids already loaded. */
static int host_epsf(void *ctx, int sca, double x, double y, int cls,
		     struct wfs_epsf *out)
{
	struct engine *g = ctx;
	/* the calling thread's worker of this engine, NULL on the main thread */
	struct worker *w = host_current(g);
	const struct psf_grid *grid;

	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > WFS_PSF_HALO)
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
 * the default's; the halo (cls 3) too, the class's own (model.h edition
 * 9). */
static int host_epsf_colour(void *ctx, int sca, double x, double y, int cls, int k,
			    struct wfs_epsf *out)
{
	struct engine *g = ctx;
	struct worker *w = host_current(g);
	const struct psf_grid *grid;

	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > WFS_PSF_HALO || !g->classes || k < 0 ||
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

/* The blend of a galaxy's two classes (psfgrids_blend), made in prepare()
 * or footprint() like the classes' grids. */
static int host_epsf_blend(void *ctx, int sca, double x, double y, int cls, double colour,
			   struct wfs_epsf *out)
{
	struct engine *g = ctx;
	struct worker *w = host_current(g);
	int load = w ? w->place : pthread_equal(pthread_self(), g->main_thread);
	const struct psf_grid *grid;

	if (cls == 3 || !(colour >= 0))
		return host_epsf(ctx, sca, x, y, cls, out);
	if (sca < 1 || sca > WFS_NSCA || cls < 0 || cls > 2 || !g->classes ||
	    !(colour <= g->ncgrid - 1))
		return host_error(ctx, "no ePSF for SCA %d class %d spectral class %g", sca, cls,
				  colour);
	grid = psfgrids_blend(g, sca, cls, colour, load, w ? &w->err : g->e);
	if (!grid && !load)
		return host_error(ctx, "ePSF of SCA %d class %d spectral class %g asked for in "
				  "render() but not in prepare() or footprint()", sca, cls, colour);
	if (!grid)
		return -1;
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

static int host_convolve_sum(void *ctx, void *thread, double *const *imgs,
			     const double *const *kernels, int count, int nx, int ny, int kn)
{
	struct engine *g = ctx;
	struct worker *w = thread;

	if (!w->fft && !(w->fft = fftconv_thread_new()))
		return host_error(ctx, "out of memory for FFT buffers");
	if (fftconv_convolve_sum(g->fft, w->fft, imgs, kernels, count, nx, ny, kn) < 0)
		return host_error(ctx, "FFT convolution of %d %d x %d images failed", count, nx, ny);
	return 0;
}

void host_init(struct engine *g)
{
	g->host = (struct wfs_host){
		.abi = WFS_ABI_VERSION, .size = sizeof(struct wfs_host), .ctx = g,
		.error = host_error, .log = host_log, .setting = host_setting,
		.epsf = host_epsf, .scratch = host_scratch, .convolve = host_convolve,
		.source_size = sizeof(struct wfs_source), .epsf_colour = host_epsf_colour,
		.epsf_blend = host_epsf_blend,
		.convolve_sum = host_convolve_sum,
	};
}
