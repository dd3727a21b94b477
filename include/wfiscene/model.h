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
 * exactly one symbol, wfs_model_entry (declared below), and SHOULD hide
 * every other symbol (-fvisibility=hidden).  It MUST NOT need any symbol of
 * the host: link it with -Wl,-z,defs (or your linker's equivalent) so that
 * one cannot creep in.  The host loads a plugin the first time a catalog row
 * names its model, in the main thread, with every symbol bound at once
 * (RTLD_NOW): a plugin with an unresolved symbol is refused then, with the
 * symbol's name and exit status 3, never halfway through a run.
 *
 * Life of a model in one run:
 *
 *   entry(WFS_ABI_VERSION)  once, returns the static descriptor
 *   init(host, &state)      once, single-threaded: tables, plans, settings
 *   reach(state, src)       once per sky row, main thread: how far from its
 *                           position the row may throw light, so the host
 *                           knows which SCAs it may land on
 *   thread_start(state, &t) once per worker thread that renders this model,
 *                           on that thread before its first render() of
 *                           the exposure: 0, or -1 to stop the run
 *   prepare(state, src)     once per row and SCA it lands on, main thread
 *                           (several threads: WFS_PARALLEL_PREPARE), with
 *                           x, y, sca, flux and mag set for that SCA:
 *                           validate the row's parameters and precompute
 *                           into src->aux
 *   footprint(state, src)   once per row and SCA it lands on, right after
 *                           its prepare() on the same thread: the pixels
 *                           the source may touch, so the host can bin it
 *                           by tile
 *   render(state, t, ...)   once per (source, tile) pair, in worker threads
 *   gather(state, t, sca)   once per SCA after the last render(), workers
 *   spread(state, t, ...)   once per tile of an SCA gather() lit, workers
 *   thread_stop(state, t)   per thread started (whose thread_start()
 *                           returned 0), on the main thread once the
 *                           workers are idle
 *   fini(state)             once
 *
 * Coordinates.  Pixel coordinates are 0-based science-frame pixels of one
 * SCA (WFS_SCA_SIDE x WFS_SCA_SIDE, 4088 x 4088; SCAs are numbered 1 to
 * WFS_SCA_COUNT, 18): pixel (i, j) covers [i - 0.5, i + 0.5) x [j - 0.5, j + 0.5)
 * and its centre is at (i, j).  x runs along FITS NAXIS1 (columns), y along
 * NAXIS2 (rows).  FITS and catalog pixel positions are 1-based; the host
 * converts before a plugin sees them.
 *
 * Units.  src->flux is the source's total flux in counts/s (e-/s) after all
 * unit conversions, and a plugin adds counts/s per pixel into the window.
 *
 * How the ABI grows.  WFS_ABI_VERSION changes only when a field changes
 * meaning; otherwise new fields are only ever appended, and each struct that
 * crosses the ABI says how much of it the other side has:
 *
 *   struct wfs_model    the plugin's: its size field.
 *   struct wfs_column   an array in the plugin: wfs_model.column_size is its
 *                       stride (absent or 0: the first edition's 32 bytes on
 *                       LP64), so a grown wfs_column keeps old plugins readable.
 *   struct wfs_setting  an array in the plugin: wfs_model.setting_size.
 *   column_roles        an array of int in the plugin, one per column:
 *                       FROZEN; a later edition adds values, and a host
 *                       ignores a role it does not know.
 *   struct wfs_host     the host's: its size field.
 *   struct wfs_source   the host's, read and partly written by the plugin:
 *                       wfs_host.source_size.  A plugin MUST NOT read an
 *                       appended field the host does not have (WFS_HAS).
 *   struct wfs_epsf     filled by the host in the plugin's memory: FROZEN.
 *                       It never grows; a richer ePSF would come through a
 *                       new service with a struct of its own carrying a size.
 *   struct wfs_box, struct wfs_window
 *                       FROZEN, like wfs_epsf.
 *
 * A member appended to a struct is present when the other side's size
 * covers it: WFS_HAS(size, struct, member).  A plugin built against an
 * older model.h keeps working with a newer host: the host reads only what
 * the plugin's sizes say it has and falls back to the older behaviour for
 * the rest (each appended member says what that is).
 *
 * Settings.  host->setting(key) answers these keys of the scene, as text:
 *
 *   filter       the filter name, e.g. "F158"
 *   exptime      the exposure time in seconds, "%.17g"
 *   seed         the exposure's random seed, an unsigned decimal integer
 *   background   the background in counts/s/pixel, "%.17g" ("0" for none):
 *                the least of the 18 SCAs', so that runs split by SCA see
 *                the same value
 *   readnoise    the read noise in e-, "%.17g"; "0" when --noise leaves it out
 *   noise        the --noise stages drawn, each followed by a comma:
 *                "poisson,readnoise,dark,flat,cosmic," or a subset, "" for none
 *   sersic       the method of the "sersic" family of models (see resolving
 *                types below), "quick" or "precise"
 *   mjd          the exposure's date as an MJD, "%.17g"; NULL when the run
 *                has no date (hosts before edition 3: always NULL)
 *   pixel-sigma  the noise of one pixel in counts/s, "%.17g", always > 0:
 *                the square root of the variance the --noise stages draw
 *                (the sky's Poisson noise, read noise, dark current) over
 *                the exposure time; when they draw none (or none that adds
 *                anything), that of the nominal ones (the exposure's sky, or
 *                the filter's average, and the default read noise), so
 *                that a model which draws down to a fraction of the noise
 *                draws a noiseless image as the mean of a noisy one.  Hosts
 *                before edition 5 MAY answer NULL: work it out from
 *                exptime, background, readnoise and noise then.
 *   spectral-classes  the number of spectral classes of the built-in PSF
 *                (wfs_source.colour, host->epsf_colour: two families of
 *                half of them), "%d"; NULL before the scene's first row
 *                with a spectrum, and without classes (edition 5)
 *
 * and every KEY of --set KEY=VALUE (the value as typed, the last one given
 * winning); NULL for a key that is not set.  A model reads the keys it
 * declares in wfs_model.settings, and SHOULD name them after itself
 * ("psf-core", "sersic-trunc", "moffat-beta").
 *
 * The list above is the whole of the scene's keys.  Hosts of edition 1
 * answered one more, now a field of the source, which a model reads only
 * from a host whose source_size lacks that field:
 *
 *   sersic-flux  what a row's flux column states, "total" or "ie"
 *                (wfs_source.flux_meaning)
 *
 * The host itself reads one --set key for the models: psf-halo-radius (the
 * half-width of the WFS_PSF_HALO array, see host->epsf).  The test
 * tests/t7027-plugin-settings.sh holds the built-in models to this: each
 * key they read is listed here or in their own wfs_model.settings.
 *
 * Time.  An exposure may have a date (wfiscene --date, or a date column of
 * --pointings): src->mjd gives it to a model (edition 3 on, see
 * WFS_ABI_EDITION), and setting "mjd" gives it as text.  A model whose
 * light changes with time (a variable star, a microlensing event) computes
 * its source for that date in prepare(): its flux, or its position.  Such a
 * model usually draws like another one, a point source: it then names that
 * model in wfs_model.drawn_by and does not draw at all (see drawn_by).
 *
 * Another convention.  --set placed=romanisim writes the placed sources
 * as a romanisim catalog would give them (wfiscene-catalog(5)), and a
 * romanisim catalog's galaxy, given on the sky, is reshaped into each
 * SCA's own pixels.  The host does both from what a model declares
 * (edition 6), never from its name or its columns' names: the type its
 * rows take there (wfs_model.roman_type) and which of its columns are
 * the shape of its source (wfs_model.column_roles).
 *
 * Resolving a catalog type.  A row of type T is drawn by the model T, except
 * when the scene has a setting T (an option of that name, or --set T=M):
 * then by the model T-M, a family of methods drawing the same thing.  Today
 * "sersic" (from --sersic, default quick) makes "sersic" rows
 * "sersic-quick" or "sersic-precise"; --set moffat=fast would make "moffat"
 * rows "moffat-fast".
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

/* The edition of this header, raised whenever members are appended (the
 * version above stays): 1 the first; 2 reach(), settings, column_size,
 * setting_size, wfs_host.source_size, wfs_source.flux_meaning; 3 the
 * exposure's time, wfs_source.mjd and wfs_model.drawn_by; 4 wfs_model.flags
 * (WFS_PARALLEL_PREPARE); 5 wfs_source.colour, wfs_host.epsf_colour,
 * wfs_model.gather and spread, the setting spectral-classes, and what the
 * built-in models relied on stated here: WFS_SCA_SIDE, WFS_SCA_COUNT,
 * WFS_MAX_COLUMNS, WFS_PSF_HALO, WFS_PRINTF, the setting pixel-sigma,
 * thread_start()'s return value; 6 wfs_model.column_roles
 * (enum wfs_column_role) and roman_type; 7 wfs_host.convolve_sum; 8
 * wfs_host.epsf_blend; 9 epsf_colour() of the halo (class 3) gives the
 * spectral class's own halo.  A plugin MAY test
 * it at compile time to keep one source for several editions; at run time
 * the sizes decide (WFS_HAS), never the edition. */
#define WFS_ABI_EDITION 9

/* Whether a struct of `size` bytes (the other side's size field) has
 * member m: WFS_HAS(host->source_size, struct wfs_source, flux_meaning). */
#define WFS_HAS(size, type, m) \
	((size_t)(size) >= offsetof(type, m) + sizeof(((type *)0)->m))

/* Number of per-source scratch values a model may fill in prepare(). */
#define WFS_AUX 8

/* The detector.  An SCA has WFS_SCA_SIDE science pixels a side (the
 * reference border is the host's: a model never sees it); the SCAs are
 * numbered 1 to WFS_SCA_COUNT (wfs_source.sca).  A model that keeps
 * something per SCA sizes it with these, never with numbers of its own. */
#define WFS_SCA_SIDE 4088
#define WFS_SCA_COUNT 18

/* The most catalog columns one model may read (wfs_model.ncolumns), and
 * a deciding model and the model that draws its sources together
 * (wfs_model.drawn_by).  The host refuses a model that declares more. */
#define WFS_MAX_COLUMNS 32

/* Compiler attributes, guarded so that the header is plain C11 for any
 * compiler: WFS_EXPORT marks the entry (below), WFS_PRINTF(f, a) says that
 * argument f is a printf format whose arguments start at a, so a model's
 * host->error() and host->log() calls are checked like printf's. */
#if defined(__GNUC__)
#define WFS_EXPORT __attribute__((visibility("default")))
#define WFS_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define WFS_EXPORT
#define WFS_PRINTF(f, a)
#endif

/* The ePSF size classes: the 44, 88 and 176 pixel boxes of STIPS, chosen by
 * magnitude against the scene's bright and extra-bright limits
 * (wfs_source.psf_class is one of the first three).  WFS_PSF_HALO is no
 * source's class but a fourth array host->epsf() gives: the built-in
 * optics' ePSF of the SCA over a larger field, R = psf-halo-radius pixels
 * either side (--set psf-halo-radius, 32 to 1024, default 256) at over = 2
 * samples per pixel (n = 4R + 1), one node at the SCA's centre (its four
 * nodes are the same), for the far wing of bright stars.  It is the
 * built-in optics' whatever --psf says, normalised as the optics give it
 * over its field, the light beyond the field left out (wfiscene(1),
 * "Bright stars: the extent and the halo"). */
enum wfs_psf_class {
	WFS_PSF_NORMAL = 0, WFS_PSF_BRIGHT = 1, WFS_PSF_XBRIGHT = 2,
	WFS_PSF_HALO = 3
};

/* What a row's flux column states, for a model with a half-light radius
 * (wfs_source.flux_meaning).  A catalog fact: STIPS's internal catalogs,
 * and --sersic-flux ie, give the surface brightness at the half-light
 * radius, per square pixel, rather than the total. */
enum wfs_flux_meaning { WFS_FLUX_TOTAL = 0, WFS_FLUX_IE = 1 };

/* A rectangle of pixels, [x0, x1) x [y0, y1), 0-based.  Frozen. */
struct wfs_box {
	int x0, y0, x1, y1;
};

/*
 * A window of a tile that render() adds into.  pix points at pixel (x0, y0);
 * pixel (x, y) of the window is pix[(y - y0) * stride + (x - x0)].  The host
 * owns the memory.  A plugin MUST only add to pixels inside the window and
 * MUST NOT read pixels it did not write (they hold other sources' light).
 * Frozen.
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

	/* Appended; present when WFS_HAS(host->source_size, struct
	 * wfs_source, ...) says so (older hosts: a total flux). */
	int flux_meaning;       /* enum wfs_flux_meaning of the row's flux.
	                           A model with a half-light radius turns
	                           WFS_FLUX_IE into the total in prepare(),
	                           rewriting flux; other models ignore it. */

	/* Edition 3; present when WFS_HAS(host->source_size, struct
	 * wfs_source, mjd) (older hosts: no date, as for NaN). */
	double mjd;             /* the exposure's date, a Modified Julian Date
	                           (UTC, leap seconds ignored) of its start;
	                           NaN when the exposure has none */

	/* Edition 5; present when WFS_HAS(host->source_size, struct
	 * wfs_source, colour) (older hosts: -1). */
	double colour;          /* the source's spectral class, from its
	                           catalog spectrum (wfiscene-catalog(5)
	                           SPECTRA): with i = floor(colour) and
	                           f = colour - i, its ePSF is (1 - f) times
	                           class i's plus f times class i + 1's
	                           (host->epsf_colour(); f is 0 at the end of
	                           a family of classes); negative for the
	                           scene's default spectrum, whose ePSF
	                           host->epsf() gives */
};

/*
 * The effective PSF near a position: four grid nodes and their bilinear
 * weights (they sum to 1).  Each node is an n x n array of floats, row-major
 * (row = y), sampled `over` times per detector pixel, with the source centre
 * at sample (centre, centre).  A sample's value is the fraction of the total
 * flux that falls in a detector pixel centred at that offset, IPC included,
 * so samples `over` apart sum to the enclosed flux (about 0.99).  The ePSF at
 * the position is sum_k weight[k] * node[k][...]; a model SHOULD blend only
 * the samples it uses rather than whole arrays.  The host fills it in the
 * plugin's memory, so it is frozen: it never grows.
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
	 * The host adds the place (file, line, model) in front.  A model
	 * that refuses a setting's value in init() SHOULD begin the message
	 * with its key ("KEY: ..." or "setting KEY: ..."): the host then
	 * reports the user's bad value (exit 1), not a failed model. */
	int (*error)(void *ctx, const char *fmt, ...)
		WFS_PRINTF(2, 3);

	/* A message for people on stderr at verbosity level (0 normal, 1 -v,
	 * 2 -vv).  Not for use in render(). */
	void (*log)(void *ctx, int level, const char *fmt, ...)
		WFS_PRINTF(3, 4);

	/* A setting by its key: the scene's ("filter", "exptime", ...: see
	 * Settings above) or a --set key, or NULL when unset. */
	const char *(*setting)(void *ctx, const char *key);

	/* The ePSF of SCA sca and size class cls (enum wfs_psf_class, the halo
	 * included) at position (x, y).  Returns 0,
	 * or -1 with an error recorded.  The arrays stay valid and unchanged
	 * until fini().  The host loads (or builds) a grid the first time it is
	 * asked for from prepare() or footprint() (on whichever thread the
	 * host runs them: one grid is loaded once, the other threads that
	 * want it waiting); render() may then ask for it from any thread.  A
	 * model that draws with the ePSF MUST therefore ask for its source's
	 * SCA and class in prepare() or footprint() first; a model that never
	 * asks costs no PSF at all. */
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

	/* Appended: sizeof(struct wfs_source) in the host, which tells which
	 * appended fields of a source exist.  Absent in older hosts (check
	 * WFS_HAS(host->size, struct wfs_host, source_size) first). */
	uint32_t source_size;

	/* Edition 5.  The ePSF of spectral class `spectral` (a whole number
	 * from 0, see wfs_source.colour) at (x, y), as epsf() gives the
	 * default spectrum's.  The same rules of loading apply: ask in
	 * prepare() or footprint() first.  The halo (class 3) is the spectral
	 * class's own from edition 9 (hosts of editions 5 to 8 give the
	 * default spectrum's for every class, which a model may use as it
	 * is: no test is needed).  Absent in older hosts (check
	 * WFS_HAS(host->size, struct wfs_host, epsf_colour)): draw with
	 * epsf(). */
	int (*epsf_colour)(void *ctx, int sca, double x, double y, int cls, int spectral,
			   struct wfs_epsf *out);

	/* Edition 7.  convolve() of count images (1 to 8, each nx x ny,
	 * row-major) each with its own odd kn x kn kernel, the results summed
	 * into imgs[0]: imgs[0] <- sum_i imgs[i] * kernels[i]; the others are
	 * left as they were.  Transformed back once, so cheaper than count
	 * calls of convolve().  The result is the same for any thread.
	 * Returns 0 or -1.  Absent in older hosts (check WFS_HAS(host->size,
	 * struct wfs_host, convolve_sum) and that it is not NULL): call
	 * convolve() for each and add. */
	int (*convolve_sum)(void *ctx, void *thread, double *const *imgs,
			    const double *const *kernels, int count, int nx, int ny, int kn);

	/* Edition 8.  The ePSF of a source of spectral class `colour`
	 * (wfs_source.colour, >= 0) at (x, y) as four nodes like epsf()'s:
	 * the blend of its two classes, the blend rounded to steps the host
	 * chooses (wfiscene: 1/psf-colour-galaxy-steps), so that the arrays
	 * are the same for every source of a step (a model may cache what it
	 * derives from a node by its address).  The same rules of loading
	 * apply.  Absent in older hosts (check WFS_HAS(host->size, struct
	 * wfs_host, epsf_blend)): take epsf_colour() of the nearest class. */
	int (*epsf_blend)(void *ctx, int sca, double x, double y, int cls, double colour,
			  struct wfs_epsf *out);
};

/*
 * What a column is to the host beyond the model's own drawing
 * (wfs_model.column_roles, edition 6): the shape of an elliptical source,
 * which the host turns into another convention's and back.  A model gives
 * each role to at most one column (the host refuses a model that gives
 * one twice), and only to a column that means exactly this:
 *
 *   WFS_ROLE_SERSIC_INDEX  the Sérsic index n
 *   WFS_ROLE_HALF_LIGHT    the half-light radius along the major axis, in
 *                          pixels of the nominal 0.11 arcsec
 *   WFS_ROLE_AXIS_RATIO    the axis ratio b/a, in (0, 1]
 *   WFS_ROLE_ANGLE         the major axis's angle on the detector, degrees
 *                          from +y toward -x
 *
 * With the last three a model draws an ellipse the host can reshape: a
 * galaxy of a romanisim catalog (its pa on the sky) lands on the SIAF's
 * pixels, which are neither square nor 0.11 arcsec, so the host maps its
 * ellipse on the sky into each SCA's pixels and hands the model the
 * radius, ratio and angle it has there.  A romanisim catalog's
 * half_light_radius, ba and pa are read as the columns re, ratio and phi
 * (wfiscene-catalog(5)), so a model whose shape columns have those names
 * is given them.  The --placed list in romanisim's convention writes a
 * source's n, half_light_radius, pa and ba from its columns of these
 * roles (-1, 0, 0 and 1 without them).
 */
enum wfs_column_role {
	WFS_ROLE_NONE = 0,
	WFS_ROLE_SERSIC_INDEX = 1,
	WFS_ROLE_HALF_LIGHT = 2,
	WFS_ROLE_AXIS_RATIO = 3,
	WFS_ROLE_ANGLE = 4
};

/*
 * A catalog column a model reads.  The host reads it case-insensitively by
 * name from any catalog format.  A required column missing from a catalog
 * that has a row of this model is an error naming the column, and so is an
 * empty cell of it (file, line, column): the model never sees one; an
 * empty or absent optional cell reads as fallback.  The plugin's array has
 * the stride wfs_model.column_size.
 */
struct wfs_column {
	const char *name;
	double fallback;
	int required;
	const char *doc;        /* one line for --help and the man page */
};

/*
 * A setting a model reads through host->setting(), declared so that the
 * host can say in --report (and a man page can list) which settings a run's
 * models used, with which values.  The plugin's array has the stride
 * wfs_model.setting_size.
 */
struct wfs_setting {
	const char *key;        /* e.g. "psf-core" */
	const char *fallback;   /* the value used when the key is unset, as text
	                           ("4"), or a few words in parentheses when it
	                           is derived ("(the scene's noise)") */
	const char *format;     /* the values allowed: "number >= 0",
	                           "bilinear|core|bicubic", ... */
	const char *doc;        /* one line */
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

	/* Per-thread state for render().  thread_start() is called on a worker
	 * thread before its first render() of this model in the exposure; it
	 * returns 0 with *tstate set (MAY be NULL), which every render() on
	 * that thread then gets, or -1 with an error recorded: the run stops
	 * with exit status 3 and no file, as for render().  thread_stop() is
	 * called for each thread whose thread_start() returned 0, on the
	 * host's main thread once the workers are idle.  Either MAY be NULL
	 * (both NULL: tstate is NULL). */
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

	/* Appended members.  The host reads each only when `size` covers it;
	 * for a shorter descriptor it does what the member's comment says. */

	/* sizeof(struct wfs_column) in the plugin, the stride of columns.
	 * Absent or 0: the first edition's struct. */
	uint32_t column_size;
	/* sizeof(struct wfs_setting) in the plugin, the stride of settings. */
	uint32_t setting_size;
	/* The settings the model reads, nsettings of them; MAY be NULL with
	 * nsettings 0 (and absent: --report lists none for this model). */
	const struct wfs_setting *settings;
	int nsettings;

	/* How far from its position, in pixels, the source of a row may throw
	 * light on any SCA of the scene: the host uses it before any prepare()
	 * to find the SCAs a sky row may land on, so that prepare() and
	 * footprint() run once per row and SCA it lands on.  src is filled as
	 * for prepare() for the scene's first SCA at its centre pixel, but the
	 * position and SCA are only stand-ins: the answer MUST bound the
	 * footprint's extent about (x, y) for any position on any SCA (light
	 * farther out is lost near the SCA's edges).  It MUST NOT change src's
	 * aux or keep state.  Returns 0 with *pixels set, or -1 with an error.
	 * MAY be NULL (and absent): the host then calls prepare() and
	 * footprint() once more per sky row, at (0, 0) of the first SCA, and
	 * takes the footprint's extent plus 2 pixels, as hosts did before
	 * reach() existed. */
	int (*reach)(void *state, const struct wfs_source *src, double *pixels);

	/* Edition 3.  The name of the model that draws this model's sources,
	 * or NULL (and absent): the model draws them itself.  A model that
	 * only decides a source's flux or position, for instance at the
	 * exposure's date, names the model that draws such a source ("point")
	 * and MAY leave footprint() and render() NULL.  The host loads that
	 * model too (it MUST NOT itself name one) and, for each row and SCA:
	 * fills src as for any model, with this model's columns in param;
	 * calls this model's prepare(), which MAY rewrite flux (> 0), x and y
	 * (mag and psf_class are then worked out again from the flux); then
	 * hands src, with param now the drawing model's columns (read from the
	 * catalog after this model's), to the drawing model's prepare(),
	 * footprint() and render(), and reach() where this model's prepare()
	 * ran first on a copy.  The two models' columns together are at most
	 * WFS_MAX_COLUMNS, the most one model may read.  The deciding model's prepare()
	 * runs on the host's main thread, in catalog order, whatever its
	 * flags. */
	const char *drawn_by;

	/* Edition 4.  What the model allows the host, WFS_PARALLEL_PREPARE or
	 * 0; absent: 0. */
	uint32_t flags;

	/* Edition 5.  Light a model gathers while its sources are prepared
	 * and adds once per tile after the last of them is drawn, where a
	 * source's own window would not reach (the point model's far wings
	 * of faint stars: the diffuse light of a crowded field).  Both MAY be
	 * NULL (and absent: nothing is spread).
	 *
	 * gather(state, thread, sca) is called once per SCA of the exposure,
	 * after the last render() of the exposure and before the detector
	 * stage, in a worker thread (thread as for render(); SCAs on several
	 * threads at once).  It returns 1 when the model has light for that
	 * SCA, 0 when it has none, or -1 with an error recorded.  Its result
	 * MUST NOT depend on the order in which the sources were prepared or
	 * on the threads that prepared them (sum in integers, or keep the
	 * sources' order).
	 *
	 * spread(state, thread, sca, win) is then called for every tile of
	 * each SCA whose gather() returned 1, the tile's rows drawn as win,
	 * in worker threads, tiles of one SCA on several threads at once: it
	 * adds the light that falls in win, the same values for any tiling,
	 * and MUST NOT allocate.  Returns 0, or -1 with an error recorded.
	 * For a tile no source touched the host first asks, on its main
	 * thread, with win->pix NULL and thread NULL: 1 when the model would
	 * add light there worth a tile's memory, 0 when not (the tile then
	 * stays unallocated and gets nothing). */
	int (*gather)(void *state, void *thread, int sca);
	int (*spread)(void *state, void *thread, int sca, const struct wfs_window *win);

	/* Edition 6.  The type this model's rows have in romanisim's
	 * catalogs ("PSF" for a point source, "SER" for a Sérsic galaxy), or
	 * NULL (and absent).  The --placed list in romanisim's convention
	 * writes a row under this type when a romanisim catalog's row of
	 * that type is drawn by this very model (wfiscene-catalog(5):
	 * PSF is type point, SER type sersic, resolved as below), so that
	 * the list read back gives the same image; otherwise, and without
	 * it, under the model's own name. */
	const char *roman_type;

	/* Edition 6.  The enum wfs_column_role of each column, ncolumns of
	 * them in the order of columns (WFS_ROLE_NONE for a column that is
	 * only the model's), or NULL: no column has a role.  Absent (a
	 * plugin of an older edition): the host takes the columns named n,
	 * re, ratio and phi as the four roles, as hosts before edition 6
	 * did by name. */
	const int *column_roles;
};

/*
 * flags: prepare() and footprint() are thread-safe.  The host MAY then call
 * them for different sources from several threads at once (never for one
 * source from two threads; footprint() right after prepare() on the same
 * thread), while render() draws an earlier chunk's sources on others.  The
 * model guards whatever its prepare() shares (caches, counters), and its
 * result for a source MUST NOT depend on which thread prepared it or on
 * which other sources were prepared before it, so the image stays the
 * same for any number of threads.  That includes failing: a cache with a
 * limit is sized when the model starts (or the model falls back to what
 * it does without it, decided by the source alone), never full for
 * whichever row comes last.  From such a call the model MAY use
 * host->error() (it records that thread's error: the host reports the
 * first failing row in catalog order, as without the flag), host->log(),
 * host->setting() and host->epsf(); and a row after the first failing one
 * MAY still be prepared, its result dropped.  Without the flag both run on
 * the host's main thread one source at a time.  Either way, within a chunk
 * of rows every deciding model's prepare() (drawn_by) runs before any
 * drawing model's.
 */
#define WFS_PARALLEL_PREPARE 1u

/* The one symbol a plugin exports, defined by the plugin as
 *
 *   WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
 *
 * host_abi is the host's WFS_ABI_VERSION; a plugin MAY return NULL when it
 * cannot work with that host.  The host calls it once, from the main
 * thread, right after loading the plugin. */
WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi);
typedef const struct wfs_model *(*wfs_model_entry_fn)(uint32_t host_abi);
#define WFS_MODEL_ENTRY "wfs_model_entry"

#ifdef __cplusplus
}
#endif

#endif
