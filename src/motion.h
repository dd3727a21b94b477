/*
 * motion.h - where a star is at an exposure's date: proper motion from the
 * catalog's epoch and parallax as seen from Roman.
 *
 * The model.  A row at (ra, dec) at Julian epoch T0 with proper motion
 * (pmra, which includes cos(dec), and pmdec, mas/yr) and parallax plx (mas)
 * is seen at the date t in the direction of
 *
 *     p = u + (t - T0) (pmra e_ra + pmdec e_dec) - plx b
 *
 * normalised, where u is the unit vector of (ra, dec), e_ra and e_dec the
 * unit vectors east and north there, angles in radians and b the observer's
 * position in AU.  The first two terms are the star's straight-line motion
 * through space at zero radial velocity, which is what Gaia's catalogue
 * propagation does without a radial velocity; the last is the parallax.
 * The light-travel time over the years (a few ms/yr changes) and perspective
 * acceleration (radial velocity unknown) are left out.
 *
 * The observer, Roman, is taken on the line from the Sun through the Earth,
 * MOTION_L2_AU beyond the Earth (Sun-Earth L2), with the Sun from ephem.c;
 * positions are heliocentric where Gaia's parallaxes are barycentric.  What
 * that costs: the Sun's offset from the barycentre (up to 0.01 AU), Roman's
 * halo orbit about L2 (up to about 0.005 AU) and the Sun's ephemeris
 * (0.01 deg, 2e-4 AU) add up to less than 0.016 AU of observer position,
 * so less than 0.016 plx: 0.16 mas (0.0015 pixel) for a star at 100 pc.
 */
#ifndef WFS_MOTION_H
#define WFS_MOTION_H

#include <stddef.h>

/* Roman's distance beyond the Earth on the Sun-Earth line, AU (1.5e6 km). */
#define MOTION_L2_AU 0.01

/* Gaia DR3's reference epoch, the default --epoch. */
#define MOTION_EPOCH_DEFAULT 2016.0

/* Limits of the catalog columns: the fastest known star moves 10.4"/yr
 * and the nearest has a parallax of 768 mas. */
#define MOTION_PM_MAX 1e5       /* mas/yr */
#define MOTION_PLX_MAX 1e4      /* mas */
#define MOTION_EPOCH_MIN 1000.0
#define MOTION_EPOCH_MAX 3000.0

/* The Julian year (J2000.0 = 2000.0) of an MJD. */
double motion_jyear(double mjd);

/* Roman's position at mjd: heliocentric, ICRS axes, AU. */
void motion_observer(double mjd, double b[3]);

/*
 * Rows ra[i], dec[i] (degrees) moved to the date mjd seen from b
 * (motion_observer), into ra_out, dec_out (which may be the inputs).  pmra,
 * pmdec, plx, epoch as above; any of pmra, pmdec, plx may be NULL (zero).
 * Rows whose ra is NaN (pixel rows) stay NaN.
 */
void motion_apply(double mjd, const double b[3], size_t n, const double *ra,
		  const double *dec, const double *pmra, const double *pmdec,
		  const double *plx, const double *epoch, double *ra_out, double *dec_out);

#endif
