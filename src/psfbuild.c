/*
 * psfbuild.c - the built-in PSF: grids computed from the Roman optical
 * model (optics.h) at the positions STPSF uses, kept in an on-disk cache;
 * see psf_builtin() in psf.h.
 *
 * Cache files are named after what they hold and a 64-bit key over every
 * input that changes the result (the optics tables' checksums, filter,
 * SCA, size, sampling, wavelengths, pupil sampling, grid, kind, the
 * code: a version and a checksum of its sources, and for a grid on an
 * SCA's own pixels every node's Jacobian), so a stale file is simply
 * never looked up; those grids are named ...-siaf-KEY.fits.  A file
 * is written under a temporary name and renamed, so concurrent runs see
 * either no file or a whole one; two runs that both miss both build and
 * the second rename wins with identical content.  A file that fails its
 * FITS checksum or whose key keyword does not match is rebuilt.  A grid
 * read from the cache has its time stamp renewed; after a grid is
 * stored, the grids used longest ago are removed while the cache's
 * grids take more than WFISCENE_CACHE_MAX mebibytes (psfcache.c).
 */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <fitsio.h>

#include "data.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "optics.h"
#include "psf.h"
#include "psfcache.h"
#include "spectrum.h"

/* The code's part of the key: a version to bump by hand, and a checksum
 * of the sources that compute a grid (optics.c, psf.c, psfbuild.c and
 * their headers), made by the Makefile, so that no edit of them can read
 * a grid the old code cached. */
#include "psf_src.h"
#define PSF_CODE_VERSION "psfbuild-1 " PSF_SRC_SUM

/*
 * Defaults, from the convergence measurements in BENCHMARKS.md ("Built-in
 * PSF", contrib/psf-convergence.py): per filter, the fewest wavelengths for
 * which the optical PSF differs from a 41-wavelength sum by less than
 * 5e-4 of its peak anywhere (the error falls as 1/nwave^2; the 1.07 micron
 * wide F146 needs the most), and a pupil sampling of 256 samples across
 * the 2.416 m mask array at the longest wavelength of the band.
 */
int psf_default_nwave(int filter)
{
	/* F062 F087 F106 F129 F158 F184 F213 F146 */
	static const int nw[WFS_NFILTER] = { 8, 6, 6, 6, 6, 4, 4, 16 };

	return filter >= 0 && filter < WFS_NFILTER ? nw[filter] : 8;
}
#define DEFAULT_PUPIL_N 256

/*
 * The parsed optics tables are constants of the build; they are parsed
 * once per process on first use and only read afterwards.
 */
static pthread_once_t optics_once = PTHREAD_ONCE_INIT;
static struct optics *optics_tables;
static struct err optics_err;

static void optics_load(void)
{
	optics_tables = optics_new(&optics_err);
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
	const unsigned char *c = p;

	for (size_t i = 0; i < n; i++)
		h = (h ^ c[i]) * 0x100000001b3ULL;
	return h;
}

static const char *const table_names[] = {
	"pupil_edge.tsv", "pupil_strut.tsv", "zernike.tsv", "throughput.tsv"
};

/* The tables' checksums, the same for every grid of the run: taken once
 * (a byte at a time over some 10^5 bytes, a millisecond a grid). */
#define NTABLES (sizeof(table_names) / sizeof(*table_names))
static uint64_t table_sums[NTABLES];
static pthread_once_t table_sums_once = PTHREAD_ONCE_INIT;

static void table_sums_load(void)
{
	for (size_t i = 0; i < NTABLES; i++)
		table_sums[i] = data_checksum(table_names[i]);
}

static uint64_t cache_key(int filter, int sca, int n, int over, int kind, int nwave,
			  int pupil_n, int grid, const double *jac, const struct spectrum *spec)
{
	char buf[512];
	uint64_t h = 0xcbf29ce484222325ULL;

	pthread_once(&table_sums_once, table_sums_load);
	for (size_t i = 0; i < NTABLES; i++)
		h = fnv(h, &table_sums[i], sizeof(table_sums[i]));
	snprintf(buf, sizeof(buf), "%s|f%d|s%d|n%d|o%d|k%d|w%d|p%d|g%d|j%.6f|"
		 "T%.1f|ps%.6f", PSF_CODE_VERSION, filter, sca, n, over,
		 kind, nwave, pupil_n, grid, OPTICS_JITTER, OPTICS_BB_TEMP,
		 WFS_PIXSCALE / over);
	h = fnv(h, buf, strlen(buf));
	/* the SCA's own pixels: the Jacobian of every node (stips' square
	 * grid adds nothing, so its keys are those of before) */
	for (int k = 0; jac && k < 4 * grid * grid; k++) {
		snprintf(buf, sizeof(buf), "|J%.12g", jac[k]);
		h = fnv(h, buf, strlen(buf));
	}
	/* another spectrum than the default (which adds nothing) */
	if (spec) {
		snprintf(buf, sizeof(buf), "|S%d:%.17g", spec->kind, spec->value);
		h = fnv(h, buf, strlen(buf));
	}
	return h;
}

/* The cache directory into buf, or "" when disabled. */
static void cache_dir(const char *opt, char *buf, size_t n)
{
	const char *v;

	if (opt) {
		snprintf(buf, n, "%s", opt);
	} else if ((v = getenv("WFISCENE_CACHE"))) {
		snprintf(buf, n, "%s", v);
	} else if ((v = getenv("XDG_CACHE_HOME")) && *v) {
		snprintf(buf, n, "%s/wfiscene", v);
	} else if ((v = getenv("HOME")) && *v) {
		snprintf(buf, n, "%s/.cache/wfiscene", v);
	} else {
		buf[0] = 0;
	}
}

/* mkdir -p, mode 0777 less the umask as mkdir(1) makes them (a cache
 * shared on a cluster may be group-writable); 0 when the directory exists
 * afterwards. */
static int make_dirs(const char *path)
{
	char tmp[4096];
	size_t len = strlen(path);

	if (len == 0 || len >= sizeof(tmp))
		return -1;
	memcpy(tmp, path, len + 1);
	for (char *p = tmp + 1; *p; p++)
		if (*p == '/') {
			*p = 0;
			if (mkdir(tmp, 0777) && errno != EEXIST)
				return -1;
			*p = '/';
		}
	if (mkdir(tmp, 0777) && errno != EEXIST)
		return -1;
	return 0;
}

/* Load a cache file if it is whole and holds what key names. */
static struct psf_grid *cache_load(const char *path, uint64_t key, int n,
				   int over, int kind, int grid, int siaf)
{
	fitsfile *f = NULL;
	int st = 0, dataok = 0, hduok = 0;
	char want[32], got[FLEN_VALUE];
	struct err e = { 0 };
	struct psf_grid *g;

	if (access(path, R_OK))
		return NULL;
	if (fits_open_diskfile(&f, path, READONLY, &st))
		return NULL;
	snprintf(want, sizeof(want), "%016llx", (unsigned long long)key);
	fits_verify_chksum(f, &dataok, &hduok, &st);
	if (!st)
		fits_read_key(f, TSTRING, "WFSKEY", got, NULL, &st);
	int good = !st && dataok == 1 && hduok == 1 && !strcmp(got, want);
	st = 0;
	fits_close_file(f, &st);
	if (!good)
		return NULL;
	if (!(g = psf_grid_read(path, &e)))
		return NULL;
	if (g->n != n || g->over != over || g->kind != kind || g->nx != grid ||
	    g->ny != grid || (g->pixgrid == PSF_PIX_SIAF) != siaf) {
		psf_grid_free(g);
		return NULL;
	}
	return g;
}

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* STPSF's nodes, round(linspace(0, 4095, grid)) in the 4096 frame, into
 * pos (0-based science pixels). */
static void node_positions(int grid, double *pos)
{
	for (int i = 0; i < grid; i++) {
		double v = grid > 1 ? round(4095.0 * i / (grid - 1)) : 2048;
		pos[i] = v - 4;
	}
}

/* The SIAF's Jacobian d(x_idl, y_idl) / d(x, y), arcsec per pixel, at
 * every node of a grid x grid grid of SCA sca (node k = iy * grid + ix);
 * a new array, or NULL with e set. */
static double *node_jacobians(int sca, int grid, struct err *e)
{
	double *pos = malloc(sizeof(double) * grid), *jac = NULL;
	const struct geom_aperture *ap;

	if (!pos || !(jac = malloc(sizeof(double) * 4 * grid * grid))) {
		free(pos);
		err_set(e, EXIT_SYSTEM, "out of memory");
		return NULL;
	}
	if (geom_init(e) < 0 || !(ap = geom_aperture(sca))) {
		if (!e->code)
			err_set(e, EXIT_INPUT, "no SCA %d", sca);
		free(pos);
		free(jac);
		return NULL;
	}
	node_positions(grid, pos);
	for (int iy = 0; iy < grid; iy++)
		for (int ix = 0; ix < grid; ix++) {
			double xi, yi;
			geom_sci_to_idl(ap, pos[ix] + 1 - ap->xref, pos[iy] + 1 - ap->yref,
					&xi, &yi, jac + 4 * (iy * grid + ix));
		}
	free(pos);
	return jac;
}

/*
 * The rest of build() for a grid at 2 samples per pixel (the halo) whose
 * samples are coarser than lambda / D at the band's shortest wavelength
 * (F062: 0.055" against 0.043"; optics_psf_fits): the optics at 4 samples
 * per pixel over the same field, made into the ePSF there and every other
 * sample kept.  The ePSF's sample is the light of a pixel at that offset
 * whatever the sampling, so this is the 4x ePSF's own value.  Not the 2x
 * optics with the pupil folded into the transform (exact point samples):
 * their sum, which each wavelength is normalised by, then counts aliased
 * light, and the halo came out 4% dim against the 4x ePSF at 5-128 px
 * (F062 SCA 1; BENCHMARKS.md "Halo").  For PSF_OPTICAL the 4x point
 * samples, times 4 so that a sample still stands for the light of its
 * 2x cell.  Four times the 2x optics' work; frees zern, img and rel, and
 * g on failure.
 */
static struct psf_grid *build_fine(struct psf_grid *g, struct optics_psf_req *r, int kind,
				   double *zern, double *img, double *rel, struct err *e)
{
	int n = r->n, nf = 2 * (n - 1) + 1, npos = r->npos;
	struct psf_grid *f = NULL;
	double *fimg = NULL;

	r->n = nf;
	r->scale /= 2;
	if (!(f = psf_grid_new(nf, 4, g->nx, g->ny)) ||
	    !(fimg = malloc(sizeof(double) * npos * nf * nf))) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	if (optics_psf(r, fimg, e))
		goto fail;
	for (size_t i = 0; i < (size_t)npos * nf * nf; i++)
		f->data[i] = (float)fimg[i];
	f->kind = PSF_OPTICAL;
	snprintf(f->origin, sizeof(f->origin), "builtin");
	if (kind != PSF_OPTICAL && psf_make_epsf_kind(f, kind, e))
		goto fail;
	for (int p = 0; p < npos; p++)
		for (int y = 0; y < n; y++)
			for (int x = 0; x < n; x++)
				g->data[((size_t)p * n + y) * n + x] =
					(kind == PSF_OPTICAL ? 4 : 1) *
					f->data[((size_t)p * nf + 2 * y) * nf + 2 * x];
	g->kind = kind;
	g->pixscale = WFS_PIXSCALE / 2;
	snprintf(g->origin, sizeof(g->origin), "builtin");
	psf_grid_free(f);
	free(fimg);
	free(zern);
	free(img);
	free(rel);
	return g;
fail:
	psf_grid_free(f);
	free(fimg);
	psf_grid_free(g);
	free(zern);
	free(img);
	free(rel);
	return NULL;
}

/* Compute a grid: on STIPS's square pixels, or when jac (node_jacobians)
 * is given on the SCA's own. */
static struct psf_grid *build(const struct optics *o, int filter, int sca,
			      int n, int over, int kind, int nwave, int pupil_n, int grid,
			      double jit, int threads, const double *jac,
			      const struct spectrum *spec, struct err *e)
{
	const struct filter_info *fi = filter_get(filter);
	double lam[64], wt[64];
	double *zern = NULL, *img = NULL, *rel = NULL;
	struct psf_grid *g = NULL;
	int npos = grid * grid;

	if (nwave > 64)
		nwave = 64;
	if (optics_weights_spec(o, filter, sca, nwave, spec, lam, wt, e))
		return NULL;
	if (!(g = psf_grid_new(n, over, grid, grid)) ||
	    !(zern = malloc(sizeof(double) * npos * nwave * OPTICS_NZ)) ||
	    !(img = malloc(sizeof(double) * npos * n * n))) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	node_positions(grid, g->xs);
	memcpy(g->ys, g->xs, sizeof(double) * grid);
	if (jac) {
		/* the grid keeps the Jacobians; the optics take them over the
		 * nominal scale of a sample */
		if (!(g->jac = malloc(sizeof(double) * 4 * npos)) ||
		    !(rel = malloc(sizeof(double) * 4 * npos))) {
			err_set(e, EXIT_SYSTEM, "out of memory");
			goto fail;
		}
		memcpy(g->jac, jac, sizeof(double) * 4 * npos);
		for (int i = 0; i < 4 * npos; i++)
			rel[i] = jac[i] / WFS_PIXSCALE;
		g->pixgrid = PSF_PIX_SIAF;
	}
	for (int iy = 0; iy < grid; iy++)
		for (int ix = 0; ix < grid; ix++) {
			int p = iy * grid + ix;
			for (int k = 0; k < nwave; k++)
				optics_zernike(o, sca, g->xs[ix], g->ys[iy], lam[k],
					       zern + ((size_t)p * nwave + k) *
					       OPTICS_NZ);
		}
	struct optics_psf_req r = {
		.pupil = optics_pupil(o, sca, fi && fi->wide_pupil),
		.flip_y = 1,
		.n = n,
		.scale = WFS_PIXSCALE / over,
		.pupil_n = pupil_n,
		.nwave = nwave,
		.lam = lam,
		.wt = wt,
		.npos = npos,
		.zern = zern,
		.jitter = jit,
		.threads = threads,
		.jac = rel,
	};
	if (!r.pupil) {
		err_set(e, EXIT_INPUT, "no SCA %d", sca);
		goto fail;
	}
	g->sca = sca;
	g->filter = filter;
	int fits = optics_psf_fits(&r, e);
	if (fits < 0)
		goto fail;
	if (!fits && over == 2)
		return build_fine(g, &r, kind, zern, img, rel, e);
	if (optics_psf(&r, img, e))
		goto fail;
	for (size_t i = 0; i < (size_t)npos * n * n; i++)
		g->data[i] = (float)img[i];
	g->sca = sca;
	g->filter = filter;
	g->kind = PSF_OPTICAL;
	g->pixscale = WFS_PIXSCALE / over;
	snprintf(g->origin, sizeof(g->origin), "builtin");
	if (kind != PSF_OPTICAL && psf_make_epsf_kind(g, kind, e))
		goto fail;
	free(zern);
	free(img);
	free(rel);
	return g;
fail:
	psf_grid_free(g);
	free(zern);
	free(img);
	free(rel);
	return NULL;
}

/* The spectrum o asks for, in *sp, or NULL for the default. */
static const struct spectrum *spec_of(const struct psf_build_opts *o, struct spectrum *sp)
{
	if (!o || o->spec_kind == SPEC_DEFAULT)
		return NULL;
	sp->kind = o->spec_kind;
	sp->value = o->spec_value;
	return sp;
}

/* A grid of n samples per side at `over` per pixel, from the cache or
 * built and kept; what psf_builtin() and psf_builtin_halo() share. */
static struct psf_grid *builtin(int filter, int sca, int n, int over, int kind,
				int grid, struct psf_build_opts *o, struct err *e);

struct psf_grid *psf_builtin(int filter, int sca, int cls, int kind,
			     struct psf_build_opts *o, struct err *e)
{
	if (cls < 0 || cls > 2)
		return err_set(e, EXIT_INPUT, "no PSF size class %d", cls), NULL;
	return builtin(filter, sca, psf_class_n[cls], PSF_OVER, kind,
		       o && o->grid > 0 ? o->grid : 3, o, e);
}

struct psf_grid *psf_builtin_halo(int filter, int sca, int radius, int grid, int kind,
				  struct psf_build_opts *o, struct err *e)
{
	if (radius < 8 || radius > PSF_HALO_MAX)
		return err_set(e, EXIT_INPUT, "halo radius %d: expected 8 to %d pixels",
			       radius, PSF_HALO_MAX), NULL;
	return builtin(filter, sca, 2 * PSF_HALO_OVER * radius + 1, PSF_HALO_OVER,
		       kind, grid > 0 ? grid : 1, o, e);
}

static struct psf_grid *builtin(int filter, int sca, int n, int over, int kind,
				int grid, struct psf_build_opts *o, struct err *e)
{
	struct psf_build_opts none = { 0 };
	char dir[4096], path[4400];
	struct psf_grid *g;

	if (!o)
		o = &none;
	if (filter < 0 || filter >= WFS_NFILTER)
		return err_set(e, EXIT_INPUT, "unknown filter %d", filter), NULL;
	if (sca < 1 || sca > WFS_NSCA)
		return err_set(e, EXIT_INPUT, "no SCA %d", sca), NULL;
	if (instrument_init(e))
		return NULL;
	int nwave = o->nwave > 0 ? o->nwave : psf_default_nwave(filter);
	int pupil_n = o->pupil_n > 0 ? o->pupil_n : DEFAULT_PUPIL_N;
	double *jac = NULL;

	if (o->pixgrid == PSF_PIX_SIAF && !(jac = node_jacobians(sca, grid, e)))
		return NULL;
	struct spectrum sp;
	const struct spectrum *spec = spec_of(o, &sp);
	uint64_t key = cache_key(filter, sca, n, over, kind, nwave, pupil_n, grid, jac, spec);
	const char *fname = filter_get(filter)->name;

	cache_dir(o->cache_dir, dir, sizeof(dir));
	if (dir[0]) {
		/* the SIAF's grids under a name of their own beside stips' */
		snprintf(path, sizeof(path), "%s/psf-%s-sca%02d-%d-%s%s%s-%016llx.fits",
			 dir, fname, sca, n, kind == PSF_EPSF ? "epsf" :
			 kind == PSF_EPSF_NOIPC ? "epsf-noipc" : "psf",
			 jac ? "-siaf" : "", spec ? "-spec" : "", (unsigned long long)key);
		double t0 = now();
		if ((g = cache_load(path, key, n, over, kind, grid, jac != NULL))) {
			free(jac);
			o->loaded++;
			psf_cache_used(path);
			snprintf(g->origin, sizeof(g->origin), "builtin");
			if (o->verbose > 0)
				fprintf(stderr, "wfiscene: PSF %s SCA%02d %d: "
					"cache %s (%.1f ms)\n", fname, sca, n,
					path, 1e3 * (now() - t0));
			return g;
		}
	}
	/* the optical model's tables, read only to build (a grid from the
	 * cache needs none of them) */
	pthread_once(&optics_once, optics_load);
	if (!optics_tables) {
		free(jac);
		err_set(e, optics_err.code, "%s", optics_err.msg);
		return NULL;
	}
	double t0 = now();
	g = build(optics_tables, filter, sca, n, over, kind, nwave, pupil_n,
		  grid, OPTICS_JITTER, o->threads, jac, spec, e);
	free(jac);
	if (!g) {
		err_prefix(e, "PSF %s SCA%02d", fname, sca);
		return NULL;
	}
	o->built++;
	if (o->verbose > 0)
		fprintf(stderr, "wfiscene: PSF %s SCA%02d %d: built with %d "
			"wavelengths in %.2f s\n", fname, sca, n, nwave, now() - t0);
	if (dir[0]) {
		char cards[6][81];
		const char *list[7];
		struct err we = { 0 };

		snprintf(cards[0], 81, "WFSKEY  = '%016llx' / cache key of the "
			 "inputs", (unsigned long long)key);
		snprintf(cards[1], 81, "NWAVES  = %d / Number of wavelengths used "
			 "in calculation", nwave);
		snprintf(cards[2], 81, "PUPILN  = %d / Pupil samples across 2.416 "
			 "m at the longest wavelength", pupil_n);
		snprintf(cards[3], 81, "JITRSIGM= %g / Gaussian sigma for jitter, "
			 "per axis [arcsec]", OPTICS_JITTER);
		if (!spec || spec->kind == SPEC_BLACKBODY)
			snprintf(cards[4], 81, "SRCTEMP = %.10g / [K] Blackbody source for "
				 "the wavelength weights", spec ? spec->value : OPTICS_BB_TEMP);
		else
			snprintf(cards[4], 81, "SRCBETA = %.10g / Source f_nu ~ nu^beta for "
				 "the wavelength weights", spec->value);
		snprintf(cards[5], 81, "PSFCODE = '%s' / wfiscene PSF code "
			 "version", PSF_CODE_VERSION);
		for (int i = 0; i < 6; i++)
			list[i] = cards[i];
		list[6] = NULL;
		if (make_dirs(dir) || psf_grid_write(path, g, list, &we)) {
			/* a cache that cannot be written costs time, not
			 * correctness */
			if (o->verbose >= 0)
				fprintf(stderr, "wfiscene: PSF cache %s: %s (the grid "
					"is used but not kept)\n",
					dir, we.code ? we.msg : strerror(errno));
		} else {
			psf_cache_trim(dir, strrchr(path, '/') + 1, o->verbose);
		}
	}
	return g;
}

struct psf_grid *psf_build_uncached(int filter, int sca, int cls, int kind,
				    const struct psf_build_opts *o,
				    double jitter, struct err *e)
{
	struct spectrum sp;

	if (filter < 0 || filter >= WFS_NFILTER || sca < 1 || sca > WFS_NSCA ||
	    cls < 0 || cls > 2) {
		err_set(e, EXIT_INPUT, "no such PSF: filter %d SCA %d class %d",
			filter, sca, cls);
		return NULL;
	}
	if (instrument_init(e))
		return NULL;
	pthread_once(&optics_once, optics_load);
	if (!optics_tables) {
		err_set(e, optics_err.code, "%s", optics_err.msg);
		return NULL;
	}
	int grid = o->grid > 0 ? o->grid : 3;
	double *jac = NULL;
	if (o->pixgrid == PSF_PIX_SIAF && !(jac = node_jacobians(sca, grid, e)))
		return NULL;
	struct psf_grid *g = build(optics_tables, filter, sca, psf_class_n[cls], PSF_OVER,
				   kind, o->nwave > 0 ? o->nwave : psf_default_nwave(filter),
				   o->pupil_n > 0 ? o->pupil_n : DEFAULT_PUPIL_N,
				   grid, jitter, o->threads, jac, spec_of(o, &sp), e);
	free(jac);
	return g;
}

struct psf_grid *psf_build_one(int filter, int sca, int n, int over, int kind,
			       const struct psf_build_opts *o, struct err *e)
{
	struct spectrum sp;

	if (filter < 0 || filter >= WFS_NFILTER || sca < 1 || sca > WFS_NSCA ||
	    n < 3 || n % 2 == 0 || (over != 2 && over != 4)) {
		err_set(e, EXIT_INPUT, "no such PSF: filter %d SCA %d, %d samples at %d per pixel",
			filter, sca, n, over);
		return NULL;
	}
	if (instrument_init(e))
		return NULL;
	pthread_once(&optics_once, optics_load);
	if (!optics_tables) {
		err_set(e, optics_err.code, "%s", optics_err.msg);
		return NULL;
	}
	int grid = o->grid > 0 ? o->grid : 1;
	double *jac = NULL;
	if (o->pixgrid == PSF_PIX_SIAF && !(jac = node_jacobians(sca, grid, e)))
		return NULL;
	struct psf_grid *g = build(optics_tables, filter, sca, n, over, kind,
				   o->nwave > 0 ? o->nwave : psf_default_nwave(filter),
				   o->pupil_n > 0 ? o->pupil_n : DEFAULT_PUPIL_N,
				   grid, OPTICS_JITTER, o->threads, jac, spec_of(o, &sp), e);
	free(jac);
	return g;
}
