/*
 * psf.h - PSF grids: a few PSFs of one SCA at known detector positions,
 * interpolated bilinearly in position for any source.
 *
 * A grid is read from an STPSF/WebbPSF gridded PSF file (a cube with
 * DET_YX0..n keywords), or built from the Roman optical model (optics.h)
 * and cached.  Node positions always come from the DET_YX keywords (or the
 * builder), never from index order, and are kept in the 0-based 4088-pixel
 * science frame (STPSF's 4096 frame minus 4).
 */
#ifndef WFS_PSF_H
#define WFS_PSF_H

#include <stddef.h>

struct err;
struct wfs_epsf;

/* PSF_EPSF_NOIPC: the ePSF without the IPC kernel, for the up-the-ramp
 * levels, whose detector applies IPC itself to the collected charge. */
enum psf_kind { PSF_OPTICAL = 0, PSF_EPSF = 1, PSF_EPSF_NOIPC = 2 };

/* Samples per side of each size class (44, 88 and 176 pixel boxes at 4x). */
#define PSF_OVER 4
static const int psf_class_n[3] = { 177, 353, 705 };

struct psf_grid {
	int n;                  /* samples per side, odd */
	int over;               /* samples per detector pixel */
	int nx, ny;             /* nodes along x and y */
	double *xs, *ys;        /* node positions, ascending, 0-based pixels */
	float *data;            /* node (ix, iy) at data + (iy * nx + ix) * n * n,
	                           each n x n row-major (row = y) */
	double pixscale;        /* arcsec per sample */
	int sca;                /* 1..18 */
	int filter;             /* enum wfs_filter, -1 if unknown */
	int kind;               /* enum psf_kind */
	char origin[256];       /* "builtin" or the file it came from */
	/* The pixel grid the samples are on: PSF_PIX_SQUARE, STIPS's square
	 * 0.11" pixels aligned with the optics (jac NULL), or PSF_PIX_SIAF,
	 * the SCA's own pixels: jac[4 k .. 4 k + 3] = d(x_idl, y_idl) /
	 * d(x, y) in arcsec per pixel at node k (k = iy * nx + ix), the SIAF's
	 * local Jacobian (geometry.h); sample (i, j) of node k looks at the
	 * ideal-frame offset jac (i, j) / over arcsec. */
	int pixgrid;
	double *jac;
};

/* PSF_PIX_UNSAID: a file without PIXGRID (STPSF's, STIPS's), taken as
 * square. */
enum psf_pixgrid { PSF_PIX_UNSAID = -1, PSF_PIX_SQUARE = 0, PSF_PIX_SIAF = 1 };

struct psf_grid *psf_grid_new(int n, int over, int nx, int ny);
void psf_grid_free(struct psf_grid *g);

/* Read a gridded PSF file.  Its PSFs are taken to be optical PSFs unless
 * the file says it holds ePSFs (WFSKIND = 'EPSF').  The sampling comes from
 * PIXELSCL (arcsec per sample), else FOV / FOVPIXEL, else OVERSAMP: STPSF's
 * older files say OVERSAMP = 1 of grids sampled 4 times per pixel.  NULL on
 * error. */
struct psf_grid *psf_grid_read(const char *path, struct err *e);

/* Write a grid in the STPSF gridded format: primary HDU cube of nx*ny planes
 * (x-major order as STPSF writes), DET_YX* (4096 frame), NUM_PSFS, FILTER,
 * DETECTOR, OVERSAMP, PIXELSCL, WFSKIND.  Atomic (temp file + rename). */
int psf_grid_write(const char *path, const struct psf_grid *g,
		   const char *const *extra_cards, struct err *e);

/* Turn an optical PSF grid into an ePSF grid in place: convolve with the
 * 4x4-subsample pixel box (the EPSF4 kernel, sum 16) and the IPC kernel at
 * detector-pixel spacing (sum 0.9946), as STIPS does but over the whole array
 * (no unconvolved border).  Only for over == 4. */
int psf_make_epsf(struct psf_grid *g, struct err *e);

/* The same for kind PSF_EPSF or PSF_EPSF_NOIPC (pixel box only). */
int psf_make_epsf_kind(struct psf_grid *g, int kind, struct err *e);

/* The interpolation nodes and weights for position (x, y), clamped to the
 * node range.  Fills out (see wfiscene/model.h). */
void psf_grid_at(const struct psf_grid *g, double x, double y,
		 struct wfs_epsf *out);

/* The ePSF sample sum over pixel-spaced samples for phase (px, py) in
 * samples [0, over), i.e. the enclosed flux fraction, of node k. */
double psf_enclosed(const struct psf_grid *g, int k, int px, int py);

/*
 * The built-in PSF from the Roman optical model, with the on-disk cache.
 * kind is PSF_EPSF (what the point plugin uses) or PSF_OPTICAL.  cls is the
 * size class (0, 1, 2 for 177, 353, 705 samples).
 */
struct psf_build_opts {
	const char *cache_dir;  /* NULL: $WFISCENE_CACHE, $XDG_CACHE_HOME/wfiscene,
	                           ~/.cache/wfiscene; "" disables the cache */
	int nwave;              /* wavelengths; 0 for the measured default */
	int pupil_n;            /* pupil samples across; 0 for the default */
	int grid;               /* nodes per axis; 0 for 3 */
	int threads;            /* for building; 0 for all cores */
	int pixgrid;            /* enum psf_pixgrid; 0 (square) by default */
	int verbose;
	int built, loaded;      /* out: grids built and loaded from the cache */
	/* The source's spectrum for the wavelength weights (spectrum.h):
	 * SPEC_DEFAULT (0), the 5700 K blackbody, or a blackbody of
	 * spec_value K or a power law of slope spec_value.  A grid of
	 * another spectrum than the default is cached under a key of its
	 * own, and its file named ...-spec-KEY.fits. */
	int spec_kind;
	double spec_value;
};
struct psf_grid *psf_builtin(int filter, int sca, int cls, int kind,
			     struct psf_build_opts *o, struct err *e);

/*
 * The halo: the built-in ePSF of a point source far from its core, for the
 * wings of bright stars.  Computed from the same optical model as the
 * grids above (same wavelengths, pupil sampling, jitter) but PSF_HALO_OVER
 * samples per pixel over +-radius pixels, with grid x grid nodes (0: one,
 * at the SCA's centre), cached like them.  Each wavelength's optical PSF is
 * normalised to 1 over the halo's larger box.
 */
#define PSF_HALO_OVER 2
#define PSF_HALO_MAX 1024
struct psf_grid *psf_builtin_halo(int filter, int sca, int radius, int grid, int kind,
				  struct psf_build_opts *o, struct err *e);

/*
 * Spectral classes (psfclass.c).  A filter has two families of n classes,
 * one ePSF grid each: power laws (f_nu ~ nu^beta[k], for the beta and
 * colour columns) and blackbodies (teff[k], for teff), whose effective
 * wavelengths on SCA 1 are evenly spaced over the family's span: beta 3
 * to -3, 50000 to 2500 K (the span of both for power laws, so a colour
 * between the two is covered too).  lam[sca - 1][fam][k] is each class's
 * effective wavelength on each SCA (spectrum.h).  Class k of family fam
 * is spectral class fam n + k; a source of effective wavelength l on an
 * SCA is class fam n + u, u the fraction of the way from class floor(u)
 * to the next by effective wavelength, its ePSF the blend of the two
 * (model.h wfs_source.colour).  Beyond its family's span a source takes
 * the end class.
 */
#define PSF_COLOUR_MAX 16
struct colour;
struct spectrum;
struct psf_grid;
struct psf_classes {
	int filter, n;
	double beta[PSF_COLOUR_MAX], teff[PSF_COLOUR_MAX];
	double lam[18][2][PSF_COLOUR_MAX];
	/* galaxies' blends (psfgrids.c, host->epsf_blend): steps between two
	 * classes (0: the nearest class), and the blended grids, NULL until
	 * made */
	int gsteps;
	struct psf_grid **blend;
};
int psf_default_classes(int filter);
int psf_classes_make(struct psf_classes *pc, struct colour *c, int filter, int n,
		     struct err *e);
/* The spectral class (fam n + u) of spectrum s on SCA sca. */
double psf_classes_of(const struct psf_classes *pc, struct colour *c, int sca,
		      const struct spectrum *s);
/* The same from the spectrum's effective wavelength lam on SCA sca and its
 * family fam (1: a blackbody, 0: a power law). */
double psf_classes_at(const struct psf_classes *pc, int sca, int fam, double lam);
/* The spectrum of spectral class k (0 .. 2 n - 1) into kind and value. */
void psf_classes_spectrum(const struct psf_classes *pc, int k, int *kind, double *value);

#endif
