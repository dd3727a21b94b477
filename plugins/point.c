/*
 * point.c - point sources drawn with the effective PSF (ePSF).
 *
 * The host lends the ePSF near the source: four grid nodes, each an n x n
 * array sampled `over` (4) times per pixel, and their bilinear weights in
 * position.  A sample's value is the fraction of the flux that lands in a
 * detector pixel centred at that offset, so drawing a source is sampling the
 * ePSF at the pixel centres around it (the paper's section 2.2):
 *
 *   pixel(i, j) += flux * ePSF(c + over (i - x), c + over (j - y)).
 *
 * Because over * i is an integer, every pixel of a source sits at the same
 * sub-sample phase: the interpolation weights are computed once per source
 * and each pixel reads a fixed set of taps (the hoisting that makes the hot
 * loop cheap).  The box is the set of pixels within half = centre / over
 * pixels of the source in x and in y (44 x 44 for the 177-sample ePSF),
 * symmetric about the source; the ePSF array covers exactly that range.
 * Three nested squares about the source decide how the ePSF is read there:
 *
 *   core   |i - x|, |j - y| < psf-core (4): Keys' cubic convolution kernel
 *          (a = -1/2, 4 x 4 taps).  It reproduces quadratics, so the sharp
 *          core is not flattened as bilinear interpolation does (the STIPS
 *          paper's Figures 3-4: about 3% error in the core).
 *   wing   within psf-wing (8) pixels: bilinear (2 x 2 taps).  Beyond the
 *          core the ePSF is smooth on the sample scale.
 *   beyond the nearest sample (1 tap).  On the built-in F129 ePSF that is
 *          within 1e-4 of the peak of the bilinear value from 8 pixels out
 *          (5e-4 from 4 pixels), where the light is a few 1e-4 of the peak.
 *
 * Flux.  Bilinear interpolation's weights sum to 1 at every phase and it
 * reads every sample of the box once per tap, so its sum over the box is
 * the ePSF's enclosed fraction; the other kernels' sums differ from it a
 * little (Keys' kernel by about 1e-4 of the flux over a 4-pixel core).  So
 * everything outside the core is scaled by one factor per source, f, that
 * makes the total exactly the bilinear sum over the box (flux_factor).  The
 * box's totals are weighted sums of rectangles of the phase planes, read
 * from their summed-area tables in constant time in prepare(); the core's
 * is the sum of what it draws, and every window draws the whole core into
 * its buffer (only the rows it holds go into the tile), so every window of
 * a source gets the same f.
 *
 * Speed.  A source's pixels read, for each array, the samples at a few x
 * and y phases, every `over` samples apart.  So each array is copied once
 * into a polyphase layout: over x over planes of pixel-spaced samples
 * (plane (q, r) holds samples (over m + q, over l + r)), and a row is a
 * weighted sum of contiguous rows.  The four grid nodes are blended once
 * per 512-pixel cell, at its centre, into one polyphase array (psf-blend=
 * core, the default), which a faint source reads: one stream per pixel
 * beyond the wing square, four within it.  Blending at the cell's centre
 * instead of the source misplaces the PSF's change with position by up to
 * 362 pixels, first order, and that change lives in the core: there the
 * source's own blend is restored, as the bilinear difference (source's
 * blend - cell's) from the nodes added to the cell's Keys value, a small
 * field whose interpolation error is small (for a source with a spectrum
 * its pair's two class cells, blended by its colour, are read on the
 * cell's own Keys taps instead: point_epsf.c, cell_correction_colour).
 * The core is drawn first into a small float buffer, then every row of
 * the window in one call, straight into the tile (sum_rows_avx2).  The
 * copies and blends are made in prepare(), which the host calls in its
 * main thread before render() sees the source, so render() neither
 * allocates nor locks.
 *
 * Approximations, each a setting (wfiscene(1) POINT SOURCES has their
 * measured error and cost):
 *
 *   psf-interp=bilinear|core|bicubic  Keys' cubic nowhere, within psf-core
 *                                     pixels (default 4), or everywhere
 *   psf-wing=W                        bilinear within W pixels (default 8),
 *                                     the nearest sample beyond, for sources
 *                                     drawn from one array of the faint class
 *   psf-box=fixed|adaptive            the box above, or per source the
 *                                     smallest whose left-out light is below
 *                                     psf-box-noise (0.1) of the noise in it;
 *                                     the noise from the scene's background,
 *                                     read noise and exposure time, or
 *                                     psf-box-sigma (counts/s per pixel)
 *   psf-blend=core|source|cell        blend the four nodes once per psf-cell
 *                                     (512) pixel cell, at the source within
 *                                     psf-core (the default; with
 *                                     psf-interp=bicubic the whole box); per
 *                                     source everywhere (16 streams); or per
 *                                     cell everywhere
 *   psf-colour-steps=N                a source with a spectrum (the host's
 *                                     spectral classes, wfs_source.colour):
 *                                     its cell blended from its class pair's
 *                                     eight nodes at the pair's blend rounded
 *                                     to 1/N (default 1), the core corrected
 *                                     to its own exact blend; 0: per source
 *   psf-halo-colour-steps=N           a bright source with a spectrum: the
 *                                     halo of its class pair blended, the
 *                                     blend rounded to 1/N (default 4; 0:
 *                                     the default spectrum's halo)
 *
 * Files: this one holds the settings, init/fini and the callbacks;
 * point_epsf.c a source's ePSF box, point_poly.c the polyphase copies,
 * point_kernels.c the inner loops, point_halo.c psf-extent=noise's halo
 * (the model itself in halo.h, shared with contrib/bench/halo.c),
 * point_near.c its pixels above the level (psf-halo-near), point_far.c
 * the light left out, spread on the diffuse grid, and point.h what they
 * share.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

/* The settings point reads, with their defaults: the one place they are
 * written (init() parses the fallback of an unset key; --report lists the
 * table).  psf-box-sigma's default is derived from the scene. */
static const struct wfs_setting point_settings[] = {
	{ "psf-interp", "core", "bilinear|core|bicubic",
	  "Keys' cubic of the ePSF nowhere, within psf-core pixels, or everywhere" },
	{ "psf-core", "4", "number >= 0", "half-width of the Keys' cubic core, pixels" },
	{ "psf-wing", "8", "number >= 0",
	  "half-width of bilinear interpolation beyond the core, pixels" },
	{ "psf-box", "fixed", "fixed|adaptive",
	  "the class's ePSF box, or per source the smallest whose left-out light is small" },
	{ "psf-box-noise", "0.1", "number > 0",
	  "psf-box=adaptive: left-out light as a fraction of the noise in the box" },
	{ "psf-box-sigma", "(the scene's noise)", "number > 0",
	  "psf-box=adaptive: noise per pixel, counts/s" },
	{ "psf-blend", "core", "source|cell|core",
	  "blend the ePSF nodes per source, per cell, or per cell but at the source in the core" },
	{ "psf-cell", "512", "whole number 1 to 4096", "blend cell side, pixels" },
	{ "psf-extent", "noise", "noise|stips",
	  "draw each source out to where it sinks below the noise, or STIPS's boxes" },
	{ "psf-extent-noise", "0.1", "number > 0",
	  "psf-extent=noise: the drawing level as a fraction of the noise per pixel" },
	{ "psf-extent-max", "8192", "number >= 1", "the largest drawing radius, pixels" },
	{ "psf-extent-min", "(the class's box)", "number >= 1",
	  "let a faint source's box shrink toward its drawing radius, down to this" },
	{ "psf-extent-cut", "0.1", "number >= 0",
	  "a faint source's box shrinks to where less than this fraction of the noise per pixel of its light lies beyond, scaled up so its flux is whole (0: the class's box)" },
	{ "psf-colour-steps", "1", "whole number 0 to 64",
	  "sources with a spectrum: their two spectral classes' blend per cell rounded to "
	  "1/N beyond the core, exact in it (0: blended per source everywhere)" },
	{ "psf-halo-colour-steps", "4", "whole number 0 to 64",
	  "sources with a spectrum: the halo of their two spectral classes blended, the "
	  "blend rounded to 1/N (0: the default spectrum's halo)" },
	{ "psf-halo-power", "3", "number >= 2.5", "power-law index of the far tail" },
	{ "psf-halo-taper", "16", "number >= 0",
	  "pixels over which the halo array hands over to the tail" },
	{ "psf-halo-far", "spikes", "spikes|disc",
	  "beyond where the halo away from its spikes sinks below the drawing level, "
	  "draw only the spikes, or the whole disc" },
	{ "psf-halo-near", "1", "number >= 0",
	  "psf-diffuse=grid: within the halo's array draw only the pixels that reach this "
	  "times the drawing level, the rest spread on the diffuse grid (0: the whole disc)" },
	{ "psf-diffuse", "grid", "grid|none",
	  "psf-extent=noise: the light a source's drawing leaves out, spread on a coarse grid "
	  "per SCA so every star keeps the halo's total, or left out" },
	{ "psf-diffuse-cell", "16", "8, 16, 32, 64 or 128",
	  "psf-diffuse=grid: side of a grid cell, pixels" },
	{ "psf-diffuse-floor", "0.001", "number >= 0",
	  "psf-diffuse=grid: a tile no source touched gets the diffuse light where it "
	  "reaches this fraction of the drawing level" },
};
#define NSETTINGS ((int)(sizeof(point_settings) / sizeof(point_settings[0])))

/* The value of setting key: the scene's, else the declared default, else
 * NULL (a default in parentheses is derived, not a value). */
static const char *setting_value(const struct wfs_host *host, const char *key)
{
	const char *s = host->setting(host->ctx, key);

	if (s && *s)
		return s;
	for (int k = 0; k < NSETTINGS; k++)
		if (!strcmp(point_settings[k].key, key))
			return point_settings[k].fallback[0] == '(' ? NULL
			       : point_settings[k].fallback;
	return NULL;
}

/* A setting that is one of a list of names: 0 and *out set, or an error
 * naming the key. */
static int setting_choice(const struct wfs_host *host, const char *key,
			  const char *const names[], int nnames, int *out)
{
	const char *s = setting_value(host, key);

	if (!s || !*s)
		return 0;
	for (int i = 0; i < nnames; i++)
		if (!strcmp(s, names[i])) {
			*out = i;
			return 0;
		}
	return host->error(host->ctx, "%s: expected %s%s%s%s%s, not '%s'", key, names[0],
			   nnames > 2 ? ", " : " or ", names[1],
			   nnames > 2 ? " or " : "", nnames > 2 ? names[2] : "", s);
}

/* A numeric setting >= lo (> lo when strict): 0 and *out set, or an error
 * naming the key. */
static int setting_number(const struct wfs_host *host, const char *key, double lo,
			  int strict, double *out)
{
	const char *s = setting_value(host, key);
	char *end;
	double v;

	if (!s || !*s)
		return 0;
	v = strtod(s, &end);
	if (*end || !isfinite(v) || v < lo || (strict && v == lo))
		return host->error(host->ctx, "%s: expected a number %s %g, not '%s'", key,
				   strict ? ">" : ">=", lo, s);
	*out = v;
	return 0;
}

/* The noise of one pixel in counts/s, as the noise stage will draw it:
 * Poisson noise of the background and read noise, over the exposure time.
 * The source's own shot noise is left out (faint stars are what the
 * adaptive box is for, and they are background-limited). */
static double scene_sigma(const struct wfs_host *host)
{
	const char *ps = host->setting(host->ctx, "pixel-sigma");

	if (ps && strtod(ps, NULL) > 0)
		return strtod(ps, NULL);
	const char *t = host->setting(host->ctx, "exptime");
	const char *b = host->setting(host->ctx, "background");
	const char *r = host->setting(host->ctx, "readnoise");
	const char *n = host->setting(host->ctx, "noise");
	double te = t ? strtod(t, NULL) : 0, bk = b ? strtod(b, NULL) : 0;
	double rn = r ? strtod(r, NULL) : 0, var = rn * rn;

	if (n && strstr(n, "poisson") && bk > 0)
		var += bk * te;
	return te > 0 && var > 0 ? sqrt(var) / te : 0;
}

/* The number of the next state made (struct point.serial). */
static atomic_ulong serials;

/* The calling thread's last state and its tally there, so that most calls
 * find their tally without the lock.  The state is known by its address
 * and number: a state freed and another made at the same address differ
 * in number, and the cached tally is never read before both match. */
static _Thread_local struct {
	const struct point *p;
	unsigned long serial;
	struct tally *t;
} mine;

/* The lock of the set-up of obj (a colour halo's place, a slot). */
pthread_mutex_t *set_lock_of(struct point *p, const void *obj)
{
	uintptr_t a = (uintptr_t)obj;

	return &p->set_lock[(a ^ a >> 7 ^ a >> 13) % SET_STRIPES];
}

struct tally *tally_of(struct point *p)
{
	struct tally *t;
	pthread_t self = pthread_self();

	if (mine.p == p && mine.serial == p->serial)
		return mine.t;
	pthread_mutex_lock(&p->lock);
	for (t = p->tallies; t && !pthread_equal(t->thread, self); t = t->next)
		;
	if (!t && (t = calloc(1, sizeof(*t)))) {
		t->thread = self;
		t->next = p->tallies;
		p->tallies = t;
	}
	pthread_mutex_unlock(&p->lock);
	if (t) {
		mine.p = p;
		mine.serial = p->serial;
		mine.t = t;
	}
	return t;
}

static int point_init(const struct wfs_host *host, void **state)
{
	static const char *const interp[] = { "bilinear", "core", "bicubic" };
	static const char *const box[] = { "fixed", "adaptive" };
	static const char *const blend[] = { "source", "cell", "core" };
	static const char *const extent[] = { "noise", "stips" };
	static const char *const far[] = { "spikes", "disc" };
	static const char *const diffuse[] = { "grid", "none" };
	struct point *p = calloc(1, sizeof(*p));
	double cell = 0, csteps = 0, dcell = 0;

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	pthread_mutex_init(&p->lock, NULL);
	pthread_mutex_init(&p->geom_lock, NULL);
	for (int i = 0; i < SET_STRIPES; i++)
		pthread_mutex_init(&p->set_lock[i], NULL);
	for (int i = 0; i < SCA_SLOTS; i++)
		pthread_mutex_init(&p->hs_lock[i], NULL);
	p->serial = atomic_fetch_add(&serials, 1) + 1;
	kernels_choose(p);
	for (int i = 0; i < SCA_SLOTS; i++)
		p->hs[i].cls = -1;      /* the default spectrum's halos */
	/* the defaults are point_settings' (setting_value); the two derived
	 * from the scene are set here: the noise, and -1 for "the class's box" */
	p->sigma = scene_sigma(host);
	p->extent_min = -1;
	if (setting_choice(host, "psf-interp", interp, 3, &p->interp) < 0 ||
	    setting_number(host, "psf-core", 0, 0, &p->core) < 0 ||
	    setting_number(host, "psf-wing", 0, 0, &p->wing) < 0 ||
	    setting_choice(host, "psf-box", box, 2, &p->adaptive) < 0 ||
	    setting_number(host, "psf-box-noise", 0, 1, &p->box_noise) < 0 ||
	    setting_number(host, "psf-box-sigma", 0, 1, &p->sigma) < 0 ||
	    setting_choice(host, "psf-blend", blend, 3, &p->blend) < 0 ||
	    setting_number(host, "psf-cell", 1, 0, &cell) < 0 ||
	    setting_choice(host, "psf-extent", extent, 2, &p->extent) < 0 ||
	    setting_number(host, "psf-extent-noise", 1e-6, 0, &p->extent_noise) < 0 ||
	    setting_number(host, "psf-extent-max", 1, 0, &p->extent_max) < 0 ||
	    setting_number(host, "psf-extent-min", 1, 0, &p->extent_min) < 0 ||
	    setting_number(host, "psf-extent-cut", 0, 0, &p->extent_cut) < 0 ||
	    setting_number(host, "psf-halo-power", 2.5, 0, &p->halo_power) < 0 ||
	    setting_number(host, "psf-halo-taper", 0, 0, &p->halo_taper) < 0 ||
	    setting_choice(host, "psf-halo-far", far, 2, &p->halo_far) < 0 ||
	    setting_number(host, "psf-halo-near", 0, 0, &p->halo_near) < 0 ||
	    setting_choice(host, "psf-diffuse", diffuse, 2, &p->diffuse) < 0 ||
	    setting_number(host, "psf-diffuse-cell", 8, 0, &dcell) < 0 ||
	    setting_number(host, "psf-diffuse-floor", 0, 0, &p->diffuse_floor) < 0)
		goto fail;
	if (dcell != 8 && dcell != 16 && dcell != 32 && dcell != 64 && dcell != 128) {
		host->error(host->ctx, "psf-diffuse-cell: expected 8, 16, 32, 64 or 128, not '%s'",
			    setting_value(host, "psf-diffuse-cell"));
		goto fail;
	}
	p->far_cell = (int)dcell;
	far_geometry(p);
	if (p->extent == EXTENT_NOISE && p->adaptive) {
		host->error(host->ctx, "psf-box=adaptive goes with psf-extent=stips; "
			    "psf-extent=noise sizes every box itself");
		goto fail;
	}
	if (p->extent == EXTENT_NOISE && !(p->sigma > 0)) {
		host->error(host->ctx, "psf-extent: noise needs the noise per pixel: "
			    "--set psf-box-sigma=S, or psf-extent=stips");
		goto fail;
	}
	if (cell != floor(cell) || cell > 4096) {
		host->error(host->ctx, "psf-cell: expected a whole number of pixels up to 4096, not '%s'",
			    setting_value(host, "psf-cell"));
		goto fail;
	}
	p->cell = (int)cell;
	if (setting_number(host, "psf-colour-steps", 0, 0, &csteps) < 0)
		goto fail;
	if (csteps != floor(csteps) || csteps > 64) {
		host->error(host->ctx, "psf-colour-steps: expected a whole number 0 to 64, not '%s'",
			    setting_value(host, "psf-colour-steps"));
		goto fail;
	}
	p->colour_steps = (int)csteps;
	if (setting_number(host, "psf-halo-colour-steps", 0, 0, &csteps) < 0)
		goto fail;
	if (csteps != floor(csteps) || csteps > 64) {
		host->error(host->ctx, "psf-halo-colour-steps: expected a whole number 0 to 64, "
			    "not '%s'", setting_value(host, "psf-halo-colour-steps"));
		goto fail;
	}
	p->halo_steps = (int)csteps;
	/* the classes the host has (none before the scene's first spectrum):
	 * room for the cells of every step between them */
	if (host->setting(host->ctx, "spectral-classes"))
		p->nclasses = atoi(host->setting(host->ctx, "spectral-classes"));
	if (p->colour_steps > 0 && p->nclasses >= 4)
		p->colour_cells = (p->colour_steps + 1) * p->nclasses;
	if (p->halo_steps > 0 && p->nclasses >= 4 &&
	    !(p->chs = calloc((size_t)SCA_SLOTS * p->nclasses * p->halo_steps, sizeof(*p->chs)))) {
		host->error(host->ctx, "out of memory");
		goto fail;
	}
	if (poly_table_init(p) < 0)
		goto fail;
	if (p->adaptive && !(p->sigma > 0)) {
		host->error(host->ctx, "psf-box: adaptive needs the noise per pixel: --noise "
			    "with --background or read noise, or --set psf-box-sigma=S");
		goto fail;
	}
	*state = p;
	return 0;
fail:
	poly_free_all(p);
	free(p->chs);
	pthread_mutex_destroy(&p->lock);
	pthread_mutex_destroy(&p->geom_lock);
	for (int i = 0; i < SET_STRIPES; i++)
		pthread_mutex_destroy(&p->set_lock[i]);
	for (int i = 0; i < SCA_SLOTS; i++)
		pthread_mutex_destroy(&p->hs_lock[i]);
	free(p);
	return -1;
}

static void point_fini(void *state)
{
	struct point *p = state;
	struct tally all = { 0 };

	if (!p)
		return;
	poly_free_all(p);
	for (struct tally *t = p->tallies, *next; t; t = next) {
		next = t->next;
		all.requested += t->requested;
		all.left += t->left;
		all.nhalo += t->nhalo;
		all.npoint += t->npoint;
		all.spread += t->spread;
		for (int s = 0; s < SCA_SLOTS; s++)
			free(t->cnt[s]);
		free(t->dep);
		free(t);
	}
	if (p->extent == EXTENT_NOISE && all.requested > 0)
		p->host->log(p->host->ctx, 1, "point: %.6g of %.6g counts/s (%.3g%%) beyond "
			     "the drawn radii, %.6g of it spread on the diffuse grid; %lld of "
			     "%lld sources with a halo", all.left, all.requested,
			     100 * all.left / all.requested, all.spread, all.nhalo, all.npoint);
	far_free(p);
	hslot_free_all(p);
	pthread_mutex_destroy(&p->lock);
	pthread_mutex_destroy(&p->geom_lock);
	for (int i = 0; i < SET_STRIPES; i++)
		pthread_mutex_destroy(&p->set_lock[i]);
	for (int i = 0; i < SCA_SLOTS; i++)
		pthread_mutex_destroy(&p->hs_lock[i]);
	free(p);
}

static int point_footprint(void *state, const struct wfs_source *src,
			   struct wfs_box *box)
{
	/* pixels i with x - half < i < x + half, or within the halo's radius */
	double half = box_half_of(src), r = halo_radius_of(src);
	struct zone z = square(src->x, src->y, r + 1 > half ? r + 1 : half);

	box->x0 = (int)z.x0;
	box->x1 = (int)z.x1;
	box->y0 = (int)z.y0;
	box->y1 = (int)z.y1;
	return 0;
}

/* psf-extent=noise reads its sources' halo radius and box from aux[0] (see
 * point_halo.c), psf-extent=stips draws the ePSF box alone. */
static int point_prepare(void *state, struct wfs_source *src)
{
	struct point *p = state;

	return p->extent == EXTENT_STIPS ? epsf_prepare(p, src, 0, 0, NULL) : noise_prepare(p, src);
}

static int point_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct point *p = state;

	return p->extent == EXTENT_STIPS ? epsf_render(p, src, win) : noise_render(p, src, win);
}

/*
 * How far a source's light can reach, for the host's culling: the
 * extra-bright class's half-width (STIPS's 176-pixel box), or with
 * psf-extent=noise the radius where the source's halo sinks below the
 * drawing level, when that is farther.  Called on the host's thread, as
 * prepare() is, so the halo may be set up here.
 */
static int point_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct point *p = state;

	*pixels = XBRIGHT_HALF;
	if (p->extent == EXTENT_STIPS || !(src->flux > 0))
		return 0;
	return noise_reach(p, src, pixels);
}

static const struct wfs_model point_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "point",
	.summary = "point source drawn with the Roman effective PSF",
	.columns = NULL,
	.ncolumns = 0,
	.init = point_init,
	.fini = point_fini,
	.prepare = point_prepare,
	.footprint = point_footprint,
	.render = point_render,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = point_settings,
	.nsettings = NSETTINGS,
	.reach = point_reach,
	.flags = WFS_PARALLEL_PREPARE,
	.gather = far_gather,
	.spread = far_spread,
	.roman_type = "PSF",
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &point_model : NULL;
}
