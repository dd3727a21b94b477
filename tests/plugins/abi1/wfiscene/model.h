/*
 * wfiscene/model.h - the source-model plugin ABI of wfiscene.
 *
 * This header is the whole contract between wfiscene (the host) and a source
 * model (a plugin).  It is the only header a plugin includes, and a plugin
 * calls no symbol of the host: everything it may use arrives through
 * struct wfs_host.  The key words MUST, MUST NOT, SHOULD and MAY are used as
 * in RFC 2119.
 *
 * A plugin is a shared object named after its model (point.so, sersic-quick.so,
 * moffat.so, ...), found on the plugin search path (--plugin-path,
 * $WFISCENE_PLUGIN_PATH, the installed plugin directory).  It MUST export
 * exactly one symbol, wfs_model_entry, and SHOULD hide every other symbol
 * (-fvisibility=hidden).  The host loads a plugin the first time a catalog row
 * names its model, before any worker thread starts.
 *
 * Life of a model in one run:
 *
 *   entry(WFS_ABI_VERSION)  once, returns the static descriptor
 *   init(host, &state)      once, single-threaded: tables, plans, settings
 *   thread_start(state, &t) once per worker thread that renders this model
 *   prepare(state, src)     once per row and SCA it lands on, main thread,
 *                           with x, y, sca, flux and mag set for that SCA:
 *                           validate the row's parameters and precompute
 *                           into src->aux
 *   footprint(state, src)   once per row and SCA, main thread: the pixels the
 *                           source may touch, so the host can bin it by tile
 *   render(state, t, ...)   once per (source, tile) pair, in worker threads
 *   thread_stop(state, t)   per thread started
 *   fini(state)             once
 *
 * Coordinates.  Pixel coordinates are 0-based science-frame pixels of one
 * SCA (4088 x 4088): pixel (i, j) covers [i - 0.5, i + 0.5) x [j - 0.5, j + 0.5)
 * and its centre is at (i, j).  x runs along FITS NAXIS1 (columns), y along
 * NAXIS2 (rows).  FITS and catalog pixel positions are 1-based; the host
 * converts before a plugin sees them.
 *
 * Units.  src->flux is the source's total flux in counts/s (e-/s) after all
 * unit conversions, and a plugin adds counts/s per pixel into the window.
 *
 * New fields are only ever appended to the structs below; the size fields
 * tell each side how much of the other's struct exists.
 */
#ifndef WFISCENE_MODEL_H
#define WFISCENE_MODEL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The ABI major version.  A plugin whose descriptor carries another value is
 * refused.  Bumped only when an existing field changes meaning. */
#define WFS_ABI_VERSION 1

/* Number of per-source scratch values a model may fill in prepare(). */
#define WFS_AUX 8

/* The ePSF size classes: the 44, 88 and 176 pixel boxes of STIPS, chosen by
 * magnitude against the scene's bright and extra-bright limits. */
enum wfs_psf_class { WFS_PSF_NORMAL = 0, WFS_PSF_BRIGHT = 1, WFS_PSF_XBRIGHT = 2 };

/* A rectangle of pixels, [x0, x1) x [y0, y1), 0-based. */
struct wfs_box {
	int x0, y0, x1, y1;
};

/*
 * A window of a tile that render() adds into.  pix points at pixel (x0, y0);
 * pixel (x, y) of the window is pix[(y - y0) * stride + (x - x0)].  The host
 * owns the memory.  A plugin MUST only add to pixels inside the window and
 * MUST NOT read pixels it did not write (they hold other sources' light).
 */
struct wfs_window {
	double *pix;
	ptrdiff_t stride;
	int x0, y0, nx, ny;
};

/*
 * One source placed on one SCA.  The host fills every field but aux; param
 * holds the model's columns (see wfs_column) in the order the model declared
 * them, already parsed as numbers, with the fallback for empty optional cells.
 */
struct wfs_source {
	double x, y;            /* position, 0-based pixels on this SCA */
	double flux;            /* total flux, counts/s; prepare() MAY rewrite */
	double mag;             /* AB magnitude of flux on this SCA */
	const double *param;    /* model columns, ncolumns values */
	int sca;                /* 1..18 */
	int psf_class;          /* enum wfs_psf_class chosen from mag */
	long long id;           /* catalog id, or the row number */
	double aux[WFS_AUX];    /* the model's own per-source values */
};

/*
 * The effective PSF near a position: four grid nodes and their bilinear
 * weights (they sum to 1).  Each node is an n x n array of floats, row-major
 * (row = y), sampled `over` times per detector pixel, with the source centre
 * at sample (centre, centre).  A sample's value is the fraction of the total
 * flux that falls in a detector pixel centred at that offset, IPC included,
 * so samples `over` apart sum to the enclosed flux (about 0.99).  The ePSF at
 * the position is sum_k weight[k] * node[k][...]; a model SHOULD blend only
 * the samples it uses rather than whole arrays.
 */
struct wfs_epsf {
	int n;                  /* samples per side, odd */
	int over;               /* samples per detector pixel */
	int centre;             /* index of the centre sample, (n - 1) / 2 */
	const float *node[4];
	double weight[4];
};

/*
 * Services the host lends a plugin.  ctx is the host's; pass it back as the
 * first argument.  thread is the host's per-worker handle passed to render().
 */
struct wfs_host {
	uint32_t abi;           /* WFS_ABI_VERSION of the host */
	uint32_t size;          /* sizeof(struct wfs_host) in the host */
	void *ctx;

	/* Record an error message (printf format, no trailing newline) and
	 * return -1, so a callback can `return host->error(host->ctx, ...)`.
	 * The host adds the place (file, line, model) in front. */
	int (*error)(void *ctx, const char *fmt, ...)
		__attribute__((format(printf, 2, 3)));

	/* A message for people on stderr at verbosity level (0 normal, 1 -v,
	 * 2 -vv).  Not for use in render(). */
	void (*log)(void *ctx, int level, const char *fmt, ...)
		__attribute__((format(printf, 3, 4)));

	/* A scene setting by its long option name without dashes ("filter",
	 * "exptime", "sersic-flux", ...), or NULL when unset. */
	const char *(*setting)(void *ctx, const char *key);

	/* The ePSF of SCA sca and size class cls at position (x, y).  Returns 0,
	 * or -1 with an error recorded.  The arrays stay valid and unchanged
	 * until fini().  The host loads (or builds) a grid the first time it is
	 * asked for from prepare() or footprint(), which run in the main
	 * thread; render() may then ask for it from any thread.  A model that
	 * draws with the ePSF MUST therefore ask for its source's SCA and class
	 * in prepare() or footprint() first; a model that never asks costs no
	 * PSF at all. */
	int (*epsf)(void *ctx, int sca, double x, double y, int cls,
		    struct wfs_epsf *out);

	/* Per-thread scratch memory of at least `bytes` bytes, aligned for
	 * doubles and SIMD, reused between calls: each call MAY return the
	 * memory of the previous one (its contents are then undefined), so ask
	 * once for everything one render() needs.  NULL when out of memory. */
	void *(*scratch)(void *thread, size_t bytes);

	/* Convolve an nx x ny image (row-major, in place) with an odd kn x kn
	 * kernel whose centre is at (kn - 1) / 2, treating everything outside the
	 * image as zero, through FFTW with plans the host makes once per size and
	 * reuses.  The result is the same for any thread.  Returns 0 or -1. */
	int (*convolve)(void *ctx, void *thread, double *img, int nx, int ny,
			const double *kernel, int kn);
};

/*
 * A catalog column a model reads.  The host reads it case-insensitively by
 * name from any catalog format.  A required column missing from a catalog
 * that has a row of this model is an error naming the column, and so is an
 * empty cell of it (file, line, column): the model never sees one; an
 * empty or absent optional cell reads as fallback.
 */
struct wfs_column {
	const char *name;
	double fallback;
	int required;
	const char *doc;        /* one line for --help and the man page */
};

/*
 * The descriptor a plugin's entry returns.  All strings and arrays are static
 * and stay valid while the plugin is loaded.
 */
struct wfs_model {
	uint32_t abi;           /* MUST be WFS_ABI_VERSION */
	uint32_t size;          /* MUST be sizeof(struct wfs_model) */
	const char *name;       /* the `type` value the model draws, e.g. "point" */
	const char *summary;    /* one line */
	const struct wfs_column *columns;
	int ncolumns;

	/* Set up for one scene.  Returns 0 and sets *state (MAY be NULL), or
	 * -1 with an error recorded. */
	int (*init)(const struct wfs_host *host, void **state);
	/* Release what init made.  MAY be NULL. */
	void (*fini)(void *state);

	/* Per-thread state for render(), or NULL.  MAY be NULL. */
	int (*thread_start)(void *state, void **tstate);
	void (*thread_stop)(void *state, void *tstate);

	/* Check one row and precompute what render needs into src->aux.
	 * Returns 0, or -1 with an error saying which parameter is wrong and
	 * why (the host names the file and line).  MAY be NULL. */
	int (*prepare)(void *state, struct wfs_source *src);

	/* The pixels the source may touch on its SCA (before clipping to the
	 * detector; the host clips).  Returns 0, or -1 with an error. */
	int (*footprint)(void *state, const struct wfs_source *src,
			 struct wfs_box *box);

	/* Add the source into the part of it that falls in win.  Called for
	 * every tile the footprint touches, possibly from several threads at
	 * once for different tiles, so it MUST be thread-safe and MUST give the
	 * same pixel values whichever tiles the source is split across.  It
	 * MUST NOT allocate memory: use host->scratch.  Returns 0, or -1 with an
	 * error recorded, which stops the run. */
	int (*render)(void *state, void *tstate, void *thread,
		      const struct wfs_source *src, const struct wfs_window *win);
};

/* The one symbol a plugin exports.  host_abi is the host's WFS_ABI_VERSION;
 * a plugin MAY return NULL when it cannot work with that host. */
typedef const struct wfs_model *(*wfs_model_entry_fn)(uint32_t host_abi);
#define WFS_MODEL_ENTRY "wfs_model_entry"

#if defined(__GNUC__)
#define WFS_EXPORT __attribute__((visibility("default")))
#else
#define WFS_EXPORT
#endif

#ifdef __cplusplus
}
#endif

#endif
