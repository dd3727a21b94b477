/*
 * psfgrids.c - the ePSF grids a scene needs, per SCA and brightness class.
 *
 * The built-in grids are built or read from the cache (psfbuild.c) the
 * first time a model asks for one; a --psf FILE serves every SCA, a --psf
 * FILE with %d one file per SCA.  Grids are loaded in prepare() or
 * footprint(), on the main thread or, for a model whose prepare() runs on
 * several (WFS_PARALLEL_PREPARE), on any of those: one at a time under
 * grid_lock, each published whole (a release store that psfgrids_get()'s
 * acquire load pairs with), so a thread that finds a grid sees all of it.
 * Render workers only read grids already loaded.
 *
 * A scene with spectra (spectrum.h) has spectral classes too (psf.h,
 * psfclass.c): their grids are built or loaded the same way, from the
 * class's spectrum, the first time a model asks for one
 * (host->epsf_colour).
 */
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "err.h"
#include "instrument.h"
#include "names.h"
#include "spectrum.h"

/* The size classes a source may have (model.h, enum wfs_psf_class): 0 to
 * SOURCE_CLASSES - 1, the halo's class WFS_PSF_HALO the next; a spectral
 * class has grids of all GRID_CLASSES, its halo included. */
#define SOURCE_CLASSES WFS_PSF_HALO
#define GRID_CLASSES (WFS_PSF_HALO + 1)

const struct psf_grid *psfgrids_get(const struct engine *g, int sca, int cls)
{
	if (g->user_grid && cls < SOURCE_CLASSES)
		return g->user_grid;
	return __atomic_load_n(&g->grid[sca - 1][cls], __ATOMIC_ACQUIRE);
}

/* Make grid (sca, cls) visible to every thread, whole. */
static void publish(struct engine *g, int sca, int cls, struct psf_grid *grid)
{
	__atomic_store_n(&g->grid[sca - 1][cls], grid, __ATOMIC_RELEASE);
}

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
	/* a grid says which pixels it is sampled on (PIXGRID) */
	if (grid->pixgrid != PSF_PIX_UNSAID &&
	    (grid->pixgrid == PSF_PIX_SIAF) != (g->o->geometry == GEOM_SIAF))
		host_log(g, 0, "warning: %s: PSF sampled on %s pixels, the scene's "
			 "geometry is %s", path, grid->pixgrid == PSF_PIX_SIAF ?
			 "the SIAF's" : "square 0.11\"", geom_name(g->o->geometry));
	/* levels 1 and 2 apply IPC to the charge: an ePSF with it, twice;
	 * the scene level has it in the ePSF: one without it, none */
	if (g->o->level && grid->kind == PSF_EPSF)
		host_log(g, 0, "warning: %s: an ePSF with IPC folded in (WFSKIND EPSF); "
			 "--level %d applies IPC again to the charge (give an optical PSF "
			 "or an ePSF without IPC: wfiscene psf --kind psf or epsf-noipc)", path,
			 g->o->level);
	if (!g->o->level && grid->kind == PSF_EPSF_NOIPC)
		host_log(g, 0, "warning: %s: an ePSF without IPC (WFSKIND EPSFNOIPC); the "
			 "scene level draws IPC in the ePSF, so the sources drawn with it have "
			 "none (give an optical PSF or an ePSF: wfiscene psf --kind psf or "
			 "epsf)", path);
}

/* The halo's default radius (psf-halo-radius), pixels */
#define HALO_RADIUS 256

/* The halo's radius, psf-halo-radius, into *rad; errors into e. */
static int halo_radius(struct engine *g, long *rad, struct err *e)
{
	const char *rs = host_setting(g, "psf-halo-radius");
	char *end = NULL;

	*rad = rs ? strtol(rs, &end, 10) : HALO_RADIUS;
	if (rs && (*end || end == rs || *rad < 32 || *rad > PSF_HALO_MAX))
		return err_set(e, EXIT_INPUT, "psf-halo-radius: expected 32 to %d "
			       "pixels, not '%s'", PSF_HALO_MAX, rs);
	return 0;
}

/* The halo (class WFS_PSF_HALO): always the built-in optics' (a --psf file's core is
 * scaled to join it by the point model). */
static int need_halo(struct engine *g, int sca, struct err *e)
{
	long rad;
	struct psf_grid *grid;

	if (halo_radius(g, &rad, e) < 0)
		return -1;
	if (strcmp(g->o->psf, "builtin"))
		host_log(g, 1, "%s: the far wing beyond its box is the built-in optics' "
			 "(%s SCA %d), scaled to join", g->o->psf, g->filter_name, sca);
	host_log(g, 1, "PSF halo for %s SCA %d, +-%ld pixels: building or loading",
		 g->filter_name, sca, rad);
	if (!(grid = psf_builtin_halo(g->o->filter, sca, (int)rad, 1,
				      g->o->level ? PSF_EPSF_NOIPC : PSF_EPSF, &g->pbo, e)))
		return -1;
	publish(g, sca, WFS_PSF_HALO, grid);
	return 0;
}

/* Load the grid of (sca, cls), with grid_lock held; errors into e. */
static int load(struct engine *g, int sca, int cls, struct err *e)
{
	const struct scene_opts *o = g->o;
	struct psf_grid *grid;

	if (psfgrids_get(g, sca, cls))
		return 0;       /* another thread loaded it first */
	if (cls == WFS_PSF_HALO)
		return need_halo(g, sca, e);
	if (strcmp(o->psf, "builtin")) {
		/* A user file: per SCA when the name holds %d, and then its one
		 * size serves every brightness class. */
		char path[PATH_MAX];

		if (g->grid[sca - 1][0]) {
			publish(g, sca, cls, g->grid[sca - 1][0]);
			return 0;
		}
		if (name_expand(path, sizeof(path), "--psf", o->psf, sca, NULL, e) < 0 ||
		    !(grid = psf_grid_read(path, e)))
			return -1;
		psf_file_warn(g, grid, path, sca);
		if (grid->kind == PSF_OPTICAL &&
		    psf_make_epsf_kind(grid, o->level ? PSF_EPSF_NOIPC : PSF_EPSF, e) < 0) {
			psf_grid_free(grid);
			return -1;
		}
		publish(g, sca, 0, grid);
		publish(g, sca, cls, grid);
		return 0;
	}
	host_log(g, 1, "ePSF grid for %s SCA %d, %d samples: building or loading",
		 g->filter_name, sca, psf_class_n[cls]);
	/* levels 1 and 2 apply IPC to the charge themselves (levels.c) */
	if (!(grid = psf_builtin(o->filter, sca, cls, o->level ? PSF_EPSF_NOIPC : PSF_EPSF,
				 &g->pbo, e)))
		return -1;
	publish(g, sca, cls, grid);
	return 0;
}

/* Make sure the ePSF grid of (sca, cls) is loaded, from any thread that
 * runs prepare() or footprint(); errors into e. */
int psfgrids_need(struct engine *g, int sca, int cls, struct err *e)
{
	int rc;

	if (psfgrids_get(g, sca, cls))
		return 0;
	pthread_mutex_lock(&g->grid_lock);
	rc = load(g, sca, cls, e);
	pthread_mutex_unlock(&g->grid_lock);
	return rc;
}


/* A whole number setting from lo to hi, or fallback when unset. */
static int int_setting(struct engine *g, const char *key, int lo, int hi, int fallback,
		       int *out)
{
	const char *v = host_setting(g, key);
	char *end;
	long n;

	*out = fallback;
	if (!v)
		return 0;
	n = strtol(v, &end, 10);
	if (*end || end == v || n < lo || n > hi)
		return err_set(g->e, EXIT_INPUT, "%s: expected a whole number %d to %d, not '%s'",
			       key, lo, hi, v);
	*out = (int)n;
	return 0;
}

int psfgrids_colour_init(struct engine *g)
{
	int n;

	if (g->classes || strcmp(g->o->psf, "builtin"))
		return 0;
	if (int_setting(g, "psf-colour-classes", 2, PSF_COLOUR_MAX,
			psf_default_classes(g->o->filter), &n) < 0)
		return -1;
	if (!(g->classes = malloc(sizeof(*g->classes))))
		return err_set(g->e, EXIT_SYSTEM, "out of memory");
	if (psf_classes_make(g->classes, g->colour, g->o->filter, n, g->e) < 0)
		return -1;
	if (int_setting(g, "psf-colour-galaxy-steps", 0, 64, 32, &g->classes->gsteps) < 0)
		return -1;
	g->ncgrid = 2 * n;
	snprintf(g->classes_str, sizeof(g->classes_str), "%d", 2 * n);
	if (!(g->cgrid = calloc((size_t)WFS_NSCA * GRID_CLASSES * g->ncgrid, sizeof(*g->cgrid))))
		return err_set(g->e, EXIT_SYSTEM, "out of memory");
	for (int k = 0; k < 2 * n; k++) {
		int kind;
		double v;

		psf_classes_spectrum(g->classes, k, &kind, &v);
		host_log(g, 1, "PSF spectral class %d of %s: %s %.6g, effective wavelength "
			 "%.4f micron on SCA 1", k, g->filter_name, kind == SPEC_POWER ? "beta" :
			 "teff", v, g->classes->lam[0][k >= n][k % n]);
	}
	return 0;
}

static struct psf_grid **cslot(const struct engine *g, int sca, int cls, int k)
{
	return &g->cgrid[((size_t)(sca - 1) * GRID_CLASSES + cls) * g->ncgrid + k];
}

const struct psf_grid *psfgrids_colour_get(const struct engine *g, int sca, int cls, int k)
{
	return __atomic_load_n(cslot(g, sca, cls, k), __ATOMIC_ACQUIRE);
}

/* Load spectral class k's grid of (sca, cls), grid_lock held: built or
 * read from the cache like the default's, the halo (cls WFS_PSF_HALO)
 * too. */
static int cload(struct engine *g, int sca, int cls, int k, struct err *e)
{
	struct psf_build_opts bo = g->pbo;
	struct psf_grid *grid;
	int kind = g->o->level ? PSF_EPSF_NOIPC : PSF_EPSF;
	long rad = 0;

	if (psfgrids_colour_get(g, sca, cls, k))
		return 0;
	if (cls == WFS_PSF_HALO && halo_radius(g, &rad, e) < 0)
		return -1;
	bo.built = bo.loaded = 0;
	psf_classes_spectrum(g->classes, k, &bo.spec_kind, &bo.spec_value);
	if (cls == WFS_PSF_HALO)
		host_log(g, 1, "PSF halo for %s SCA %d, +-%ld pixels, spectral class %d (%s "
			 "%.6g): building or loading", g->filter_name, sca, rad, k,
			 bo.spec_kind == SPEC_POWER ? "beta" : "teff", bo.spec_value);
	else
		host_log(g, 1, "ePSF grid for %s SCA %d, %d samples, spectral class %d (%s %.6g): "
			 "building or loading", g->filter_name, sca, psf_class_n[cls], k,
			 bo.spec_kind == SPEC_POWER ? "beta" : "teff", bo.spec_value);
	grid = cls == WFS_PSF_HALO ? psf_builtin_halo(g->o->filter, sca, (int)rad, 1, kind, &bo, e) :
				     psf_builtin(g->o->filter, sca, cls, kind, &bo, e);
	if (!grid)
		return -1;
	g->pbo.built += bo.built;
	g->pbo.loaded += bo.loaded;
	__atomic_store_n(cslot(g, sca, cls, k), grid, __ATOMIC_RELEASE);
	return 0;
}

int psfgrids_colour_need(struct engine *g, int sca, int cls, int k, struct err *e)
{
	int rc;

	if (psfgrids_colour_get(g, sca, cls, k))
		return 0;
	pthread_mutex_lock(&g->grid_lock);
	rc = cload(g, sca, cls, k, e);
	pthread_mutex_unlock(&g->grid_lock);
	return rc;
}

/*
 * Galaxies (host->epsf_blend): the blend of a galaxy's two classes a, a +
 * 1 (as point.so pairs them: the last class of a family is step 1 of the
 * pair before it), rounded to 1/gsteps, one grid per SCA, size class,
 * pair and step, made under grid_lock the first time a prepare() asks
 * and kept, so that the sersic models see the same nodes for a step (and
 * cache what they derive from them).  The end steps are the classes'
 * own grids; gsteps 0 takes the nearest class.
 */
static struct psf_grid *blend_make(const struct psf_grid *a, const struct psf_grid *b,
				   double f)
{
	struct psf_grid *m = psf_grid_new(a->n, a->over, a->nx, a->ny);
	size_t nd = (size_t)a->nx * a->ny * a->n * a->n, nj = 4 * (size_t)a->nx * a->ny;

	if (!m)
		return NULL;
	memcpy(m->xs, a->xs, a->nx * sizeof(*a->xs));
	memcpy(m->ys, a->ys, a->ny * sizeof(*a->ys));
	if (a->jac && !(m->jac = malloc(nj * sizeof(*a->jac)))) {
		psf_grid_free(m);
		return NULL;
	}
	if (a->jac)
		memcpy(m->jac, a->jac, nj * sizeof(*a->jac));
	m->pixscale = a->pixscale;
	m->sca = a->sca;
	m->filter = a->filter;
	m->kind = a->kind;
	m->pixgrid = a->pixgrid;
	snprintf(m->origin, sizeof(m->origin), "%s", a->origin);
	for (size_t i = 0; i < nd; i++)
		m->data[i] = (float)((1 - f) * a->data[i] + f * b->data[i]);
	return m;
}

/* Class k's grid of (sca, cls), loaded when load is set. */
static const struct psf_grid *class_grid(struct engine *g, int sca, int cls, int k, int load,
					 struct err *e)
{
	const struct psf_grid *grid = psfgrids_colour_get(g, sca, cls, k);

	if (grid || !load || psfgrids_colour_need(g, sca, cls, k, e) < 0)
		return grid;
	return psfgrids_colour_get(g, sca, cls, k);
}

const struct psf_grid *psfgrids_blend(struct engine *g, int sca, int cls, double colour,
				      int load, struct err *e)
{
	struct psf_classes *pc = g->classes;
	int n = pc->n, N = pc->gsteps, a = (int)colour, j;
	double f = colour - a;
	struct psf_grid **slot, *m;
	const struct psf_grid *ga, *gb;

	if (N == 0)
		return class_grid(g, sca, cls, (int)floor(colour + 0.5), load, e);
	if (a % n == n - 1) {
		a--;
		f += 1;
	}
	j = (int)lround(f * N);
	if (j == 0 || j == N)
		return class_grid(g, sca, cls, a + (j == N), load, e);
	if (!pc->blend && load) {
		pthread_mutex_lock(&g->grid_lock);
		if (!pc->blend)
			__atomic_store_n(&pc->blend, calloc((size_t)WFS_NSCA * SOURCE_CLASSES *
							    g->ncgrid * (N + 1), sizeof(*pc->blend)),
					 __ATOMIC_RELEASE);
		pthread_mutex_unlock(&g->grid_lock);
		if (!pc->blend)
			return err_set(e, EXIT_SYSTEM, "out of memory"), NULL;
	}
	if (!__atomic_load_n(&pc->blend, __ATOMIC_ACQUIRE))
		return NULL;
	slot = &pc->blend[(((size_t)(sca - 1) * SOURCE_CLASSES + cls) * g->ncgrid + a) * (N + 1) + j];
	if ((m = __atomic_load_n(slot, __ATOMIC_ACQUIRE)) || !load)
		return m;
	if (!(ga = class_grid(g, sca, cls, a, 1, e)) || !(gb = class_grid(g, sca, cls, a + 1, 1, e)))
		return NULL;
	pthread_mutex_lock(&g->grid_lock);
	if (!(m = __atomic_load_n(slot, __ATOMIC_ACQUIRE))) {
		m = blend_make(ga, gb, (double)j / N);
		__atomic_store_n(slot, m, __ATOMIC_RELEASE);
	}
	pthread_mutex_unlock(&g->grid_lock);
	if (!m)
		err_set(e, EXIT_SYSTEM, "out of memory");
	return m;
}

/* --psf FILE without %d: one grid read up front for every SCA. */
int psfgrids_open_user(struct engine *g)
{
	const struct scene_opts *o = g->o;

	if (o->psf && strcmp(o->psf, "builtin") && !(name_fields(o->psf) & NAME_SCA)) {
		char path[PATH_MAX];

		if (name_expand(path, sizeof(path), "--psf", o->psf, 0, NULL, g->e) < 0 ||
		    !(g->user_grid = psf_grid_read(path, g->e)))
			return -1;
		psf_file_warn(g, g->user_grid, path, 0);
		if (g->user_grid->kind == PSF_OPTICAL &&
		    psf_make_epsf_kind(g->user_grid, o->level ? PSF_EPSF_NOIPC : PSF_EPSF,
				       g->e) < 0)
			return -1;
	}
	return 0;
}

void psfgrids_drop(struct engine *g, int sca)
{
	struct psf_grid **gr = g->grid[sca - 1];

	for (int c = WFS_PSF_HALO; c >= 0; c--) {
		if (gr[c] && (c == 0 || gr[c] != gr[0]))
			psf_grid_free(gr[c]);
		gr[c] = NULL;
	}
	for (int c = 0; g->cgrid && c < GRID_CLASSES; c++)
		for (int k = 0; k < g->ncgrid; k++) {
			struct psf_grid **cg = &g->cgrid[((size_t)(sca - 1) * GRID_CLASSES + c) *
							 g->ncgrid + k];

			psf_grid_free(*cg);
			*cg = NULL;
		}
	/* the galaxies' blends: kept, an SCA group's would stay to the run's
	 * end (some 100 MB an SCA in F146) */
	if (g->classes && g->classes->blend) {
		size_t per = (size_t)SOURCE_CLASSES * g->ncgrid * (g->classes->gsteps + 1);
		struct psf_grid **b = g->classes->blend + (size_t)(sca - 1) * per;

		for (size_t i = 0; i < per; i++) {
			psf_grid_free(b[i]);
			b[i] = NULL;
		}
	}
}

void psfgrids_free(struct engine *g)
{
	for (int s = 0; s < WFS_NSCA; s++)
		for (int c = 0; c <= WFS_PSF_HALO; c++)
			if (g->grid[s][c] && (c == 0 || g->grid[s][c] != g->grid[s][0]))
				psf_grid_free(g->grid[s][c]);
	psf_grid_free(g->user_grid);
	for (size_t i = 0; g->cgrid && i < (size_t)WFS_NSCA * GRID_CLASSES * g->ncgrid; i++)
		psf_grid_free(g->cgrid[i]);
	free(g->cgrid);
	for (size_t i = 0; g->classes && g->classes->blend &&
	     i < (size_t)WFS_NSCA * SOURCE_CLASSES * g->ncgrid * (g->classes->gsteps + 1); i++)
		psf_grid_free(g->classes->blend[i]);
	free(g->classes ? g->classes->blend : NULL);
	free(g->classes);
	colour_free(g->colour);
}
