/*
 * ephem_sun.c - the Sun's position from the Astronomical Almanac's
 * low-precision formulae and the ecliptic coordinates of sky positions,
 * against independent references:
 *  - the 2025 equinoxes and solstices (times from the US Naval
 *    Observatory's table, to the minute): apparent longitude of date 0,
 *    90, 180, 270 degrees, to 0.01 degree (the Sun moves 0.0007 degree a
 *    minute);
 *  - astropy 5 (get_sun, GCRS, transformed to GeocentricMeanEcliptic with
 *    equinox J2000, and to ICRS) at seven dates 2025-2030: longitude
 *    referred to J2000 within 0.01 degree, RA and Dec within 0.01 degree,
 *    distance within 1e-4 AU;
 *  - astropy's BarycentricMeanEcliptic (J2000) of six ICRS positions
 *    (the equinox, the north ecliptic pole, M31, the Orion nebula, the
 *    Galactic centre, a field near the ecliptic) within 1e-4 degree;
 *  - ephem_separation at 0, 180 and across RA 0/360.
 */
#include <math.h>
#include <stdio.h>

#include "tap.h"
#include "date.h"
#include "ephem.h"

/* Difference of two angles in degrees, in (-180, 180]. */
static double dang(double a, double b)
{
	double d = fmod(a - b, 360.0);

	if (d > 180)
		d -= 360;
	if (d <= -180)
		d += 360;
	return d;
}

int main(void)
{
	static const struct { int y, mo, d, h, mi; double lon; const char *what; } cardinal[] = {
		{ 2025, 3, 20, 9, 1, 0, "March equinox" },
		{ 2025, 6, 21, 2, 42, 90, "June solstice" },
		{ 2025, 9, 22, 18, 19, 180, "September equinox" },
		{ 2025, 12, 21, 15, 3, 270, "December solstice" },
	};
	static const struct { double mjd, lon, ra, dec, dist; } ref[] = {
		{ 60754.37569444445, 359.6472, 359.6765, -0.1408, 0.995889 },
		{ 60847.1125, 89.6435, 89.6114, 23.4355, 1.016204 },
		{ 60940.763194444444, 179.6394, 179.6693, 0.1436, 1.003626 },
		{ 61030.62708333333, 269.6357, 269.6030, -23.4355, 0.983801 },
		{ 61420.0, 294.2105, 296.1079, -21.2684, 0.983619 },
		{ 62714.5, 128.8711, 131.3005, 18.0378, 1.015014 },
		{ 61165.25, 44.3959, 41.9353, 16.1555, 1.008454 },
	};
	static const struct { double ra, dec, lon, lat; } ecl[] = {
		{ 0, 0, 0.00000, -0.00001 },
		{ 270, 66.560708, 298.74656, 89.99999 },
		{ 10.68, 41.27, 27.84610, 33.35137 },
		{ 83.82, -5.39, 82.98306, -28.67887 },
		{ 266.4, -28.94, 266.83523, -5.54026 },
		{ 150, 2.2, 151.30575, -9.41137 },
	};
	struct sun s;

	for (size_t i = 0; i < sizeof(cardinal) / sizeof(cardinal[0]); i++) {
		ephem_sun(date_mjd(cardinal[i].y, cardinal[i].mo, cardinal[i].d, cardinal[i].h,
				   cardinal[i].mi, 0), &s);
		is_near(dang(s.lon_date, cardinal[i].lon), 0, 0.01,
			"%s 2025: apparent longitude of date %.4f", cardinal[i].what, s.lon_date);
	}
	for (size_t i = 0; i < sizeof(ref) / sizeof(ref[0]); i++) {
		ephem_sun(ref[i].mjd, &s);
		is_near(dang(s.lon, ref[i].lon), 0, 0.01, "MJD %.4f: J2000 longitude %.4f "
			"(astropy %.4f)", ref[i].mjd, s.lon, ref[i].lon);
		is_near(dang(s.ra, ref[i].ra), 0, 0.01, "MJD %.4f: RA %.4f", ref[i].mjd, s.ra);
		is_near(s.dec, ref[i].dec, 0.01, "MJD %.4f: Dec %.4f", ref[i].mjd, s.dec);
		is_near(s.dist_au, ref[i].dist, 1e-4, "MJD %.4f: distance %.6f AU", ref[i].mjd,
			s.dist_au);
	}
	for (size_t i = 0; i < sizeof(ecl) / sizeof(ecl[0]); i++) {
		double lon, lat;

		ephem_ecliptic(ecl[i].ra, ecl[i].dec, &lon, &lat);
		is_near(lat, ecl[i].lat, 1e-4, "(%g, %g): ecliptic latitude %.5f", ecl[i].ra,
			ecl[i].dec, lat);
		/* longitude is meaningless at the pole */
		if (fabs(ecl[i].lat) < 89)
			is_near(dang(lon, ecl[i].lon), 0, 1e-4, "(%g, %g): ecliptic longitude %.5f",
				ecl[i].ra, ecl[i].dec, lon);
		ok(lon >= 0 && lon < 360, "longitude in [0, 360): %.5f", lon);
	}
	is_near(ephem_separation(10, 20, 10, 20), 0, 1e-12, "separation of a point from itself");
	is_near(ephem_separation(10, 20, 190, -20), 180, 1e-9, "separation of antipodes");
	is_near(ephem_separation(359.5, 0, 0.5, 0), 1, 1e-9, "separation across RA 0");
	is_near(ephem_separation(0, 89.5, 180, 89.5), 1, 1e-9, "separation across the pole");
	/* The Sun is 90 degrees from both ecliptic poles at every date. */
	for (double m = 60000; m < 64000; m += 97.3) {
		ephem_sun(m, &s);
		if (fabs(ephem_separation(s.ra, s.dec, 270, 66.560708) - 90) > 0.001)
			break;
	}
	ok(fabs(ephem_separation(s.ra, s.dec, 270, 66.560708) - 90) <= 0.001,
	   "the Sun stays on the ecliptic, 90 degrees from its pole");
	return done_testing();
}
