/*
 * ephem.h - where the Sun is, and ecliptic coordinates of the sky.
 *
 * The Sun follows the Astronomical Almanac's low-precision formulae
 * (section C, "Sun, low precision": mean longitude and anomaly linear in
 * time, two terms of the equation of centre), good to 0.01 degree in
 * 1950-2050 and slowly worse outside.  They give the apparent longitude in
 * the ecliptic and equinox of date; wfiscene works in the J2000 (ICRS)
 * frame of catalogs, so the general precession in longitude (50.29"/yr)
 * is taken off to refer it to the J2000 equinox.  The Sun's latitude
 * (< 1.2") is taken as 0.  Roman orbits L2, on the Earth-Sun line, so the
 * Sun's direction seen from it is the geocentric one to within the halo
 * orbit's ~0.3 degree, which is ignored.
 */
#ifndef WFS_EPHEM_H
#define WFS_EPHEM_H

/* Mean obliquity of the ecliptic at J2000 (IAU 2006), degrees. */
#define EPHEM_OBLIQUITY_J2000 23.4392794

struct sun {
	double lon_date;        /* apparent ecliptic longitude, of date, deg */
	double lon;             /* the same referred to the J2000 equinox, deg */
	double ra, dec;         /* J2000 equatorial, degrees */
	double dist_au;         /* Earth-Sun distance, AU */
};

/* The Sun at mjd (UTC; see date.h). */
void ephem_sun(double mjd, struct sun *s);

/* Ecliptic longitude and latitude (J2000 mean ecliptic and equinox,
 * degrees; lon in [0, 360)) of an ICRS position. */
void ephem_ecliptic(double ra, double dec, double *lon, double *lat);

/* Angle (degrees, 0-180) between two positions (ra, dec in degrees). */
double ephem_separation(double ra1, double dec1, double ra2, double dec2);

#endif
