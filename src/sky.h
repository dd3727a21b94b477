/*
 * sky.h - where each SCA looks: the focal-plane layout for a pointing, and
 * each SCA's geometry (geometry.h).
 *
 * The pointing (ra, dec, pa) is the centre of WFI01 (STIPS's convention) or
 * the WFI boresight.  pa is the position angle of the reference aperture's
 * +y axis (its ideal +y, which is WFI01's detector +y to 0.16 degrees, or
 * the boresight's), degrees east of north, at the reference point.  The
 * focal plane is the reference aperture's ideal frame: the plane tangent to
 * the sky at the reference, +y at pa, +x 90 degrees west of it.  SCA
 * centres sit there at their SIAF offsets (data/sca.tsv), so the whole
 * layout turns with pa (STIPS spins each detector about its own centre
 * instead).
 *
 * --geometry stips: each SCA gets its own TAN projection about its centre,
 * 0.11"/pixel, CRPIX at the geometric centre (2044.5, 2044.5), standard
 * parity (east left when north is up), rotated by the position angle of the
 * focal plane's +y axis measured at its own centre, which differs from pa
 * away from the reference and near the poles.  --geometry siaf: the SIAF's
 * own scales, rotation and distortion per SCA (geometry.h).
 */
#ifndef WFS_SKY_H
#define WFS_SKY_H

#include <stddef.h>

#include "geometry.h"
#include "instrument.h"

struct err;

struct sky_sca {
	int sca;                /* 1..18; 0 when not requested */
	double ra, dec;         /* centre, degrees */
	double pa;              /* position angle of +y at the centre, degrees */
	double fx, fy;          /* centre in the focal-plane frame, arcsec */
	double half;            /* the SCA lies within +-half of (fx, fy) on
	                           both focal-plane axes, arcsec */
	struct geom_sca geo;    /* pixels <-> sky */
};

struct sky {
	double ra0, dec0, pa0;  /* the reference point and position angle */
	int boresight;          /* reference is the boresight, not WFI01 */
	int geometry;           /* GEOM_SIAF or GEOM_STIPS */
	double att[3][3];       /* siaf: V2/V3 unit vector -> sky unit vector */
	double va;              /* velocity aberration's scale factor applied
				 * (1: none, the default) */
	double rot[3][3];       /* sky unit vector -> frame with ref on +x */
	struct sky_sca sca[WFS_NSCA];
};

/* Set up the layout for the SCAs in mask (bit s-1 for SCA s) in geometry
 * GEOM_SIAF or GEOM_STIPS. */
int sky_init(struct sky *sky, double ra, double dec, double pa,
	     int boresight, int geometry, unsigned mask, struct err *e);
void sky_free(struct sky *sky);

/*
 * Velocity aberration (--set velocity-aberration=on): Roman's velocity at
 * mid-exposure mjd from the observer model (motion.h), the scale factor
 * 1 + beta.u of the pointing's reference direction u (beta = v / c), and
 * every SCA's geometry aberrated by it about the reference point
 * (geom_sca_aberrate).  siaf only.  Returns the scale factor.
 */
double sky_va_scale(const struct sky *sky, double mjd);
void sky_aberrate(struct sky *sky, double scale);

/* The setting velocity-aberration (NULL or "off": none; "on": aberrated
 * at the middle of the exposure that starts at mjd, 2027-01-01 for NaN,
 * and lasts exptime s).  0, or -1 for a value not on or off or "on" with
 * the stips geometry. */
int sky_va_setting(struct sky *sky, const char *value, double mjd, double exptime,
		   struct err *e);

/* Focal-plane coordinates (arcsec, ideal frame of the reference: +x along
 * the detectors' +x, +y along +y) of n sky positions.  Rows more than 80
 * degrees from the reference, more than band degrees from it in
 * declination (INFINITY for no limit), or with NaN positions get NaN. */
void sky_to_focal(const struct sky *sky, size_t n, const double *ra,
		  const double *dec, double band, double *fx, double *fy);

/* The focal-plane point (fx, fy) on the sky. */
void sky_from_focal(const struct sky *sky, double fx, double fy, double *ra,
		    double *dec);

/* Exact 0-based pixel coordinates on SCA s of n sky positions through its
 * geometry.  Positions that do not project get NaN.  Returns 0 or -1. */
int sky_to_pixel(struct sky *sky, int s, size_t n, const double *ra,
		 const double *dec, double *x, double *y, struct err *e);

/* The WCS header cards of SCA s (concatenated 80-char cards; free()), for
 * an image whose first row is the SCA's row row0 (0-based; 0 for the whole
 * SCA): CRPIX2 is counted from there. */
int sky_header(struct sky *sky, int s, int row0, char **cards, int *ncards,
	       struct err *e);

/* Half the SCA side in arcsec in the stips geometry (sky_sca.half). */
#define SKY_SCA_HALF (WFS_NPIX * WFS_PIXSCALE / 2.0)

#endif
