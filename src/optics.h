/*
 * optics.h - the Roman WFI optical model: pupil geometry, field- and
 * wavelength-dependent Zernike aberrations, filter photon weights, and
 * polychromatic optical PSFs computed from them with FFTW.
 *
 * The tables come from data/pupil_edge.tsv, pupil_strut.tsv, zernike.tsv
 * and throughput.tsv (embedded; derived by contrib/tables/derive_optics.py
 * from the public files, see their headers).  The recipe follows STPSF
 * (reference/roman-data.md sections 4 and 5): the pupil mask flipped in y
 * relative to the Zernike plane, circular Noll Zernikes Z4..Z22 over a
 * 1.2 m radius, barycentric interpolation over the five field points and
 * linear interpolation in wavelength, Fraunhofer propagation to a grid of
 * fixed angular sampling, photon-weighted sum over wavelengths, Gaussian
 * jitter.  Positions are 0-based pixels of the 4088 science frame.
 */
#ifndef WFS_OPTICS_H
#define WFS_OPTICS_H

struct err;

#define OPTICS_NANG 720         /* edge radii per turn in pupil_edge.tsv */
#define OPTICS_MAXSTRUT 8
#define OPTICS_NZ 19            /* Z4..Z22 */
#define OPTICS_ZRADIUS 1.2      /* m, STPSF's PUPIL_RADIUS */
#define OPTICS_HALF 1.20810221  /* m, half the 2048 x 1.17979 mm mask array */
#define OPTICS_JITTER 0.012     /* arcsec per axis, STPSF's default */
#define OPTICS_BB_TEMP 5700.0   /* K, the default source (STPSF's default) */


/* A strut blocks the strip smin <= s <= smax, lo_a + lo_b s <= t <=
 * hi_a + hi_b s, with s along the unit axis (c, sn) through (x0, y0) and t
 * across it (the axis turned +90 degrees).  Metres. */
struct optics_strut {
	double x0, y0, c, sn, lo_a, lo_b, hi_a, hi_b, smin, smax;
};

/* A pupil in the frame of the mask files (metres from the array centre, x
 * along NAXIS1, y along NAXIS2): clear where rin(theta) <= r <= rout(theta)
 * (radii at theta_k = -pi + 2 pi k / OPTICS_NANG, linear between), inside
 * the square |x|, |y| <= half, and outside every strut. */
struct optics_pupil {
	double rout[OPTICS_NANG], rin[OPTICS_NANG];
	double rmax;            /* largest rim radius */
	double rout_min, rin_max;       /* smallest rim, largest obscuration radius */
	double half;            /* half-width of the clipping square */
	int nstrut;
	struct optics_strut strut[OPTICS_MAXSTRUT];
};

struct optics;

/* Parse the embedded tables.  NULL on error (a broken build). */
struct optics *optics_new(struct err *e);
void optics_free(struct optics *o);

/* The pupil of SCA sca (1..18), skinny (wide = 0) or wide (F184, F213). */
const struct optics_pupil *optics_pupil(const struct optics *o, int sca,
					int wide);

/* An analytic pupil: a circle of radius r_out with a central circular
 * obscuration of radius r_in (0 for none), no struts, no clipping. */
void optics_pupil_annulus(struct optics_pupil *p, double r_out, double r_in);

/* Fraction of the square cell of side d centred at (x, y) that is clear:
 * exact 0 or 1 well inside or outside, else 8 x 8 sub-samples. */
double optics_pupil_cover(const struct optics_pupil *p, double x, double y,
			  double d);
/* The same by the plain count of every sub-sample against the whole
 * clearance test, without pupil.c's shortcuts: the tests' reference. */
double optics_pupil_cover_plain(const struct optics_pupil *p, double x, double y, double d);

/* The unit-RMS Noll Zernikes Z4..Z22 at (x, y) of the unit disk. */
void optics_zernike_basis(double x, double y, double z[OPTICS_NZ]);

/* Z4..Z22 in nm of wavefront for SCA sca at pixel (x, y) of the 4088 frame
 * and wavelength lam (micron), interpolated as STPSF does. */
void optics_zernike(const struct optics *o, int sca, double x, double y,
		    double lam, double z[OPTICS_NZ]);

/* nwave wavelengths (micron) and photon weights (sum 1) for filter and
 * SCA: the range where the effective area exceeds 10% of its peak, cut in
 * nwave equal bins; each bin weighted by the photons a 5700 K blackbody
 * gives through the effective area, at its photon-weighted mean
 * wavelength.  Returns 0 or -1 (unknown filter or SCA). */
int optics_weights(const struct optics *o, int filter, int sca, int nwave,
		   double *lam, double *w, struct err *e);

/* The same for the photons of spectrum spec (spectrum.h) instead of the
 * 5700 K blackbody; spec NULL is optics_weights(). */
struct spectrum;
int optics_weights_spec(const struct optics *o, int filter, int sca, int nwave,
			const struct spectrum *spec, double *lam, double *w, struct err *e);

/* The largest wavelength optics_weights can return for a filter, micron. */
double optics_lam_max(const struct optics *o, int filter);

/*
 * Polychromatic optical PSFs at npos field positions on one pupil.  For
 * each position p, out + p n n receives an n x n image (row = y, n odd,
 * the optical axis at sample ((n-1)/2, (n-1)/2)), `scale` arcsec per
 * sample, summing to 1: sum_k wt[k] PSF(lam[k]), each PSF(lam) normalised
 * to 1 in the box (STPSF's normalize='last'), then convolved with a
 * Gaussian of sigma `jitter` arcsec per axis and normalised again.
 * zern[(p * nwave + k) * OPTICS_NZ + j] is Z(4+j) in nm for position p and
 * wavelength k (NULL for none).
 *
 * The pupil is sampled so that a padded FFT of size nfft lands exactly on
 * the output sampling (dx = lam / (nfft scale)): nfft is the smallest
 * FFTW-friendly size with at least pupil_n samples across the 2 half
 * wide array at the longest wavelength and at least 2 n samples of field.
 * Only the pupil rows and the output columns are transformed.
 *
 * With a Jacobian A per position the same transform samples the PSF on the
 * skewed grid: the field at sky offset scale A u is the transform at u of
 * the pupil seen at B s, B = A^-T (r . A u = (A^T r) . u), so each
 * position rasterises its own pupil at B s and the jitter becomes the
 * Gaussian of covariance sigma^2 A^-1 A^-T in samples.  Exact, at the cost
 * of rasterising the pupil and its Zernikes per position.
 */
struct optics_psf_req {
	const struct optics_pupil *pupil;
	int flip_y;             /* mask seen at (x, -y) in the Zernike frame */
	int n;
	double scale;           /* arcsec per sample */
	int pupil_n;            /* 0: 256 */
	int nwave;
	const double *lam, *wt;
	int npos;
	const double *zern;
	double jitter;          /* arcsec, 0 for none */
	int threads;            /* 0: all cores */
	/* NULL: the samples are a square grid of `scale` on the sky, aligned
	 * with the optical model's axes (STIPS's 0.11" pixels).  Else, for
	 * each position p, jac[4 p .. 4 p + 3] = { a11, a12, a21, a22 }: one
	 * sample step along x is the sky offset scale (a11, a21), one along y
	 * scale (a12, a22) (the detector's local Jacobian over its nominal
	 * pixel scale; optics_psf then samples |det A| I(scale A (i, j)),
	 * the PSF seen through that pixel grid). */
	const double *jac;
	/* for tests: every cell of the pupil by the plain count
	 * (optics_pupil_cover_plain), with no coarse map; the same numbers */
	int plain_cover;
};
int optics_psf(const struct optics_psf_req *r, double *out, struct err *e);

/* Whether optics_psf() can compute r: 1 when the pupil's raster at the
 * shortest wavelength fits the transform, i.e. r->scale is finer than
 * about lambda_min / (stretch D) (0.043" for F062's shortest wavelength
 * bin, about 0.5 micron: not the halo's 0.055" samples); 0 when not; -1 with e set on a bad
 * request. */
int optics_psf_fits(const struct optics_psf_req *r, struct err *e);

/* The measured default number of wavelengths for a filter (psfbuild.c). */
int psf_default_nwave(int filter);

/* For `wfiscene psf --jitter` (psfbuild.c): a built-in grid with another
 * jitter, computed without the cache.  NULL on error. */
struct psf_build_opts;
struct psf_grid *psf_build_uncached(int filter, int sca, int cls, int kind,
				    const struct psf_build_opts *o,
				    double jitter, struct err *e);

/* For the measurements of the halo (contrib/bench/halo.c): one grid of n
 * samples at `over` (2 or 4) per pixel, o->grid nodes per axis (0: one, at
 * the centre), computed without the cache.  NULL on error. */
struct psf_grid *psf_build_one(int filter, int sca, int n, int over, int kind,
			       const struct psf_build_opts *o, struct err *e);

#endif
