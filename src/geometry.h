/*
 * geometry.h - where each SCA's pixels look on the sky, for one pointing.
 *
 * Two geometries:
 *
 * siaf (the default): Roman's own.  A science pixel (x, y) goes to the
 *   SCA's ideal frame through the SIAF's degree-5 Sci2Idl polynomials
 *   (data/siaf.tsv, from the WFInn_FULL apertures); the ideal frame is the
 *   plane tangent to the sphere of V2/V3 at the aperture's (V2Ref, V3Ref),
 *   with +y_idl at V3IdlYAngle from +V3 toward +V2 and x_idl of parity
 *   VIdlParity; V2/V3 go to the sky through the attitude, the rotation that
 *   puts the reference aperture's reference point (WFI01_FULL, or WFI_CEN
 *   for the boresight) at (ra, dec) with its +y_idl axis at position angle
 *   pa east of north (pysiaf's PA_APER; romanisim's --roll).  The SIAF's
 *   +V3 axis is then at pa - V3IdlYAngle = pa + 60 degrees.
 *
 * stips: STIPS's idealisation: square 0.11" pixels, every SCA aligned with
 *   the focal plane, one TAN projection per SCA about its centre (sky.h).
 *
 * Pixel coordinates here are 0-based: (0, 0) is the centre of the first
 * pixel, i.e. FITS pixel (1, 1) and SIAF science pixel (1, 1).
 */
#ifndef WFS_GEOMETRY_H
#define WFS_GEOMETRY_H

#include <math.h>
#include <stddef.h>

#include <wcslib/wcs.h>

struct err;

enum wfs_geometry { GEOM_SIAF, GEOM_STIPS };

/* The unit vector of longitude lon, latitude lat (radians): RA/Dec on the
 * sky, V2/V3 in the telescope's frame. */
static inline void geom_unit(double lon, double lat, double u[3])
{
	u[0] = cos(lat) * cos(lon);
	u[1] = cos(lat) * sin(lon);
	u[2] = sin(lat);
}

#define GEOM_DEG 5      /* SIAF polynomial degree */
#define GEOM_NC 21      /* coefficients of a degree-5 polynomial in x, y */
#define GEOM_SIP_INV 6  /* order of the fitted SIP inverse */
#define GEOM_NCI 28     /* coefficients of a degree-6 polynomial */

/* One SIAF aperture, as data/siaf.tsv gives it.  Polynomial coefficients
 * are indexed k = i (i + 1) / 2 + j for the term x^(i-j) y^j (the SIAF's
 * naming: i the degree, j the power of y); the constant k = 0 is zero. */
struct geom_aperture {
	int sca;                        /* 1..18, 0 for WFI_CEN */
	double v2ref, v3ref;            /* arcsec */
	double v3idlyangle, parity;     /* degrees, +1 or -1 */
	double xref, yref;              /* science reference pixel, 1-based */
	double sx[GEOM_NC], sy[GEOM_NC];        /* Sci2Idl, arcsec */
	double ix[GEOM_NC], iy[GEOM_NC];        /* Idl2Sci, pixels */
	double a[GEOM_NC], b[GEOM_NC];          /* SIP forward, pixels */
	double ap[GEOM_NCI], bp[GEOM_NCI];      /* SIP inverse, pixels */
};

/* Load data/siaf.tsv once.  0 or -1 (a broken build). */
int geom_init(struct err *e);

/* The aperture of SCA sca (1..18), or WFI_CEN for sca 0. */
const struct geom_aperture *geom_aperture(int sca);

/* "siaf" or "stips" to the enum; -1 if unknown. */
int geom_parse(const char *name);
const char *geom_name(int kind);

/* An SCA's own mapping that replaces the SIAF chain (--into a Roman file
 * whose gwcs is evaluated): pixel -> sky, and sky -> pixel from the SIAF's
 * answer (x0, y0) as a first guess.  Read-only, any thread. */
struct geom_map {
	const void *ctx;
	void (*to_sky)(const void *ctx, double x, double y, double *ra, double *dec);
	void (*to_pix)(const void *ctx, double ra, double dec, double x0, double y0,
		       double *x, double *y);
};

/*
 * One SCA of one pointing.  The siaf members are read-only after
 * geom_sca_init() (any thread may use them); the stips WCS is used by one
 * thread at a time.
 */
struct geom_sca {
	int kind;
	int sca;
	const struct geom_aperture *ap;
	/* siaf: the sky unit vector of the reference pixel and those of the
	 * ideal +x and +y axes there (radians of ideal coordinate each) */
	double u[3], ex[3], ey[3];
	double ra, dec;         /* reference pixel (the centre), degrees */
	double pa;              /* position angle of +y there, degrees */
	double va;              /* siaf: sky arcsec per ideal arcsec (1; the
				 * velocity aberration's scale factor) */
	const struct geom_map *map;     /* siaf: NULL, or the mapping in use
					 * (the SIAF's pixels still give the
					 * PSF's sampling and the pixel area) */
	struct wcsprm wcs;      /* stips: the TAN projection */
	int have_wcs;
};

/* The attitude matrix (V2/V3 unit vector -> equatorial unit vector) that
 * puts aperture ref's reference point at (ra, dec) with its +y_idl axis at
 * position angle pa (degrees). */
void geom_attitude(const struct geom_aperture *ref, double ra, double dec,
		   double pa, double m[3][3]);

/* Set up SCA sca: siaf from the attitude m; stips from the centre (ra, dec)
 * and the position angle pa of +y there.  0 or -1. */
int geom_sca_init(struct geom_sca *g, int kind, int sca, const double m[3][3],
		  double ra, double dec, double pa, struct err *e);
void geom_sca_free(struct geom_sca *g);

/* Velocity aberration, to first order in v/c (siaf only): what the
 * detector sees is the sky shrunk by 1 / scale about the unit vector b
 * (the pointing's reference point, which keeps its place), so the
 * reference pixel moves to b + scale (u - b) and an ideal arcsec spans
 * scale arcsec of the sky. */
void geom_sca_aberrate(struct geom_sca *g, double scale, const double b[3]);

/* Exact 0-based pixel coordinates of n sky positions (degrees); positions
 * more than 80 degrees away or that do not project get NaN.  0 or -1. */
int geom_sky_to_pix(struct geom_sca *g, size_t n, const double *ra,
		    const double *dec, double *x, double *y, struct err *e);

/* The sky position (degrees) of 0-based pixel (x, y). */
void geom_pix_to_sky(struct geom_sca *g, double x, double y, double *ra,
		     double *dec);

/* The local Jacobian at 0-based pixel (x, y): d(x_idl, y_idl) / d(x, y) in
 * arcsec per pixel, j = { dxi/dx, dxi/dy, dyi/dx, dyi/dy } (the ideal frame
 * has the sky's scale to 2e-6 over an SCA; stips: 0.11 on the diagonal). */
void geom_jacobian(const struct geom_sca *g, double x, double y, double j[4]);

/* The local Jacobian of pixel -> sky at 0-based pixel (x, y): k = {
 * dE/dx, dE/dy, dN/dx, dN/dy } in arcsec per pixel, E and N the offsets
 * east and north in the plane tangent to the sky there.  Exact for siaf
 * (the SIAF's derivatives carried through the attitude); central
 * differences of one pixel for stips and --into WCSs. */
void geom_sky_jacobian(struct geom_sca *g, double x, double y, double k[4]);

/*
 * An elliptical source given on the sky, major semi-axis a (arcsec), axis
 * ratio q and major axis at position angle pa (degrees east of north), as
 * drawn in the pixels at (x, y): the ellipse mapped through the inverse of
 * geom_sky_jacobian() (an elliptical profile stays one under a linear map,
 * so this is exact to the local linearity of the mapping).  Out: the major
 * semi-axis in pixels, the axis ratio, and phi in the "phi" column's sense
 * (degrees, 0 along +y, increasing toward -x).
 */
void geom_sky_ellipse(struct geom_sca *g, double x, double y, double a, double q,
		      double pa, double *re, double *ratio, double *phi);

/* The solid angle of pixel (x, y) over that of a nominal 0.11" square
 * pixel (1 everywhere for stips). */
double geom_area(const struct geom_sca *g, double x, double y);

/* geom_area() of pixels x0 .. x0 + n - 1 of row y (0-based), by a
 * polynomial per row: a few operations a pixel, for the background. */
void geom_area_row(const struct geom_sca *g, int y, int x0, int n, double *area);

/* The WCS cards (concatenated 80-char cards, free()) of an image whose
 * first row is the SCA's row row0: TAN for stips, TAN-SIP for siaf. */
int geom_header(struct geom_sca *g, int row0, char **cards, int *ncards,
		struct err *e);

/* The SIAF mapping from science pixel offsets (u, v) = (x, y) - ref
 * (pixels) to ideal arcsec, and its derivatives; exposed for tests. */
void geom_sci_to_idl(const struct geom_aperture *ap, double u, double v,
		     double *xi, double *yi, double d[4]);
/* The exact inverse: Idl2Sci, then Newton steps on Sci2Idl. */
void geom_idl_to_sci(const struct geom_aperture *ap, double xi, double yi,
		     double *u, double *v);

#endif
