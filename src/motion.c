/* motion.c - proper motion and parallax at an exposure's date; see motion.h. */
#include <math.h>

#include "date.h"
#include "ephem.h"
#include "motion.h"

#define D2R (M_PI / 180.0)
#define MAS2RAD (M_PI / (180.0 * 3600.0 * 1000.0))

double motion_jyear(double mjd)
{
	return 2000.0 + (mjd - DATE_MJD_J2000) / 365.25;
}

void motion_observer(double mjd, double b[3])
{
	struct sun s;
	double r;

	ephem_sun(mjd, &s);
	/* The Sun's geocentric direction; the Earth is at minus it from the
	 * Sun, and L2 MOTION_L2_AU farther on the same line. */
	r = -(s.dist_au + MOTION_L2_AU);
	b[0] = r * cos(s.dec * D2R) * cos(s.ra * D2R);
	b[1] = r * cos(s.dec * D2R) * sin(s.ra * D2R);
	b[2] = r * sin(s.dec * D2R);
}

void motion_apply(double mjd, const double b[3], size_t n, const double *ra,
		  const double *dec, const double *pmra, const double *pmdec,
		  const double *plx, const double *epoch, double *ra_out, double *dec_out)
{
	double year = motion_jyear(mjd);

	for (size_t i = 0; i < n; i++) {
		double a = ra[i] * D2R, d = dec[i] * D2R;
		double ca = cos(a), sa = sin(a), cd = cos(d), sd = sin(d);
		double dt = year - epoch[i];
		double mua = (pmra ? pmra[i] : 0) * MAS2RAD * dt;
		double mud = (pmdec ? pmdec[i] : 0) * MAS2RAD * dt;
		double w = (plx ? plx[i] : 0) * MAS2RAD;
		double p[3];

		if (isnan(ra[i])) {
			ra_out[i] = dec_out[i] = NAN;
			continue;
		}
		/* u + mua e_ra + mud e_dec - w b, with
		 * e_ra = (-sin a, cos a, 0), e_dec = (-sin d cos a, -sin d sin a, cos d) */
		p[0] = cd * ca - mua * sa - mud * sd * ca - w * b[0];
		p[1] = cd * sa + mua * ca - mud * sd * sa - w * b[1];
		p[2] = sd + mud * cd - w * b[2];
		a = atan2(p[1], p[0]) / D2R;
		if (a < 0)
			a += 360.0;
		ra_out[i] = a;
		dec_out[i] = atan2(p[2], hypot(p[0], p[1])) / D2R;
	}
}
