/* ephem.c - the Sun's position and ecliptic coordinates; see ephem.h. */
#include <math.h>

#include "date.h"
#include "ephem.h"

#define D2R (M_PI / 180.0)

/* Reduce an angle to [0, 360). */
static double wrap360(double a)
{
	a = fmod(a, 360.0);
	return a < 0 ? a + 360.0 : a;
}

void ephem_sun(double mjd, struct sun *s)
{
	/* Days from J2000.0. */
	double n = mjd - DATE_MJD_J2000;
	/* Mean longitude (aberration included) and mean anomaly, degrees. */
	double L = wrap360(280.460 + 0.9856474 * n);
	double g = wrap360(357.528 + 0.9856003 * n) * D2R;
	double lam = L + 1.915 * sin(g) + 0.020 * sin(2 * g);
	/* General precession in longitude, 5029.0966"/century. */
	double prec = 5029.0966 / 3600.0 * (n / 36525.0);
	double eps = EPHEM_OBLIQUITY_J2000 * D2R, l;

	s->lon_date = wrap360(lam);
	s->lon = wrap360(lam - prec);
	s->dist_au = 1.00014 - 0.01671 * cos(g) - 0.00014 * cos(2 * g);
	/* On the J2000 ecliptic (latitude 0) to J2000 equatorial. */
	l = s->lon * D2R;
	s->ra = wrap360(atan2(cos(eps) * sin(l), cos(l)) / D2R);
	s->dec = asin(sin(eps) * sin(l)) / D2R;
}

void ephem_ecliptic(double ra, double dec, double *lon, double *lat)
{
	double a = ra * D2R, d = dec * D2R, eps = EPHEM_OBLIQUITY_J2000 * D2R;
	double x = cos(d) * cos(a), y = cos(d) * sin(a), z = sin(d);
	/* Rotate about x (the equinox) by the obliquity. */
	double ye = cos(eps) * y + sin(eps) * z, ze = -sin(eps) * y + cos(eps) * z;

	*lon = wrap360(atan2(ye, x) / D2R);
	*lat = atan2(ze, hypot(x, ye)) / D2R;
}

double ephem_separation(double ra1, double dec1, double ra2, double dec2)
{
	/* atan2 of the cross and dot products of the unit vectors: accurate
	 * at every angle, where acos of the dot product is not near 0 and 180. */
	double a1 = ra1 * D2R, d1 = dec1 * D2R, a2 = ra2 * D2R, d2 = dec2 * D2R;
	double v1[3] = { cos(d1) * cos(a1), cos(d1) * sin(a1), sin(d1) };
	double v2[3] = { cos(d2) * cos(a2), cos(d2) * sin(a2), sin(d2) };
	double c[3] = { v1[1] * v2[2] - v1[2] * v2[1], v1[2] * v2[0] - v1[0] * v2[2],
			v1[0] * v2[1] - v1[1] * v2[0] };
	double dot = v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2];

	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), dot) / D2R;
}
