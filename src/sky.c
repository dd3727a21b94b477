/* sky.c - focal-plane layout and per-SCA WCS; see sky.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "date.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "motion.h"
#include "sky.h"

#define D2R (M_PI / 180.0)
#define AS2R (M_PI / 180.0 / 3600.0)

/*
 * The focal plane is one gnomonic projection about the reference point.  In
 * standard coordinates (xi toward east, eta toward north, radians) a
 * focal-plane offset (x, y) along the detector axes is
 *
 *   xi  = -x cos pa + y sin pa,     eta = x sin pa + y cos pa,
 *
 * the same matrix as each SCA's CD matrix: +y at position angle pa, +x at
 * pa - 90 deg, i.e. standard parity.  The matrix is its own inverse.
 */
static void focal_to_std(double pa, double x, double y, double *xi, double *eta)
{
	double c = cos(pa * D2R), s = sin(pa * D2R);

	*xi = -x * c + y * s;
	*eta = x * s + y * c;
}

/* Rotation taking a sky unit vector into the reference frame: reference
 * along +x, north at the reference along +z, east along +y. */
static void make_rot(struct sky *sky)
{
	double a = sky->ra0 * D2R, d = sky->dec0 * D2R;
	double ca = cos(a), sa = sin(a), cd = cos(d), sd = sin(d);

	sky->rot[0][0] = cd * ca; sky->rot[0][1] = cd * sa; sky->rot[0][2] = sd;
	sky->rot[1][0] = -sa;     sky->rot[1][1] = ca;      sky->rot[1][2] = 0;
	sky->rot[2][0] = -sd * ca; sky->rot[2][1] = -sd * sa; sky->rot[2][2] = cd;
}

void sky_from_focal(const struct sky *sky, double fx, double fy, double *ra,
		    double *dec)
{
	double xi, eta, v[3], w[3];

	focal_to_std(sky->pa0, fx * AS2R, fy * AS2R, &xi, &eta);
	/* The point (1, xi, eta) in the reference frame, rotated back. */
	v[0] = 1; v[1] = xi; v[2] = eta;
	for (int i = 0; i < 3; i++)
		w[i] = sky->rot[0][i] * v[0] + sky->rot[1][i] * v[1] + sky->rot[2][i] * v[2];
	*ra = atan2(w[1], w[0]) / D2R;
	if (*ra < 0)
		*ra += 360;
	*dec = atan2(w[2], hypot(w[0], w[1])) / D2R;
}

void sky_to_focal(const struct sky *sky, size_t n, const double *ra,
		  const double *dec, double band, double *fx, double *fy)
{
	const double (*r)[3] = sky->rot;
	double c = cos(sky->pa0 * D2R), s = sin(sky->pa0 * D2R);
	/* cos 80 deg: farther rows are on no detector, and gnomonic blows up */
	const double dmin = 0.17364817766693;

	for (size_t i = 0; i < n; i++) {
		double a, d, v0, v1, v2, x, y, z, xi, eta;

		/* also true for NaN: x/y rows */
		if (!(fabs(dec[i] - sky->dec0) <= band)) {
			fx[i] = fy[i] = NAN;
			continue;
		}
		a = ra[i] * D2R;
		d = dec[i] * D2R;
		v0 = cos(d) * cos(a);
		v1 = cos(d) * sin(a);
		v2 = sin(d);
		x = r[0][0] * v0 + r[0][1] * v1 + r[0][2] * v2;
		y = r[1][0] * v0 + r[1][1] * v1 + r[1][2] * v2;
		z = r[2][0] * v0 + r[2][1] * v1 + r[2][2] * v2;

		if (!(x > dmin)) {
			fx[i] = fy[i] = NAN;
			continue;
		}
		xi = y / x / AS2R;
		eta = z / x / AS2R;
		fx[i] = -xi * c + eta * s;
		fy[i] = xi * s + eta * c;
	}
}

/* Position angle (east of north, degrees) of the great circle from (a1, d1)
 * toward (a2, d2). */
static double position_angle(double a1, double d1, double a2, double d2)
{
	double da = (a2 - a1) * D2R;

	d1 *= D2R;
	d2 *= D2R;
	return atan2(sin(da) * cos(d2),
		     cos(d1) * sin(d2) - sin(d1) * cos(d2) * cos(da)) / D2R;
}

/* The stips geometry's SCA extent, or the siaf one's from its boundary
 * pixels taken to the focal plane, with half a pixel to spare. */
static double sca_half(const struct sky *sky, struct sky_sca *s)
{
	double half = 0;

	if (sky->geometry == GEOM_STIPS)
		return SKY_SCA_HALF;
	for (int k = 0; k <= 64; k++) {
		double t = -0.5 + k * WFS_NPIX / 64.0;
		double px[4] = { t, t, -0.5, WFS_NPIX - 0.5 };
		double py[4] = { -0.5, WFS_NPIX - 0.5, t, t };

		for (int c = 0; c < 4; c++) {
			double ra, dec, fx, fy;

			geom_pix_to_sky(&s->geo, px[c], py[c], &ra, &dec);
			sky_to_focal(sky, 1, &ra, &dec, INFINITY, &fx, &fy);
			half = fmax(half, fmax(fabs(fx - s->fx), fabs(fy - s->fy)));
		}
	}
	return half + 0.06;
}

int sky_init(struct sky *sky, double ra, double dec, double pa, int boresight,
	     int geometry, unsigned mask, struct err *e)
{
	memset(sky, 0, sizeof(*sky));
	if (!isfinite(ra) || !isfinite(dec) || dec < -90 || dec > 90)
		return err_set(e, EXIT_INPUT, "bad pointing: ra %g, dec %g", ra, dec);
	if (!isfinite(pa))
		return err_set(e, EXIT_INPUT, "bad position angle %g", pa);
	if (geom_init(e) < 0)
		return -1;
	sky->ra0 = fmod(fmod(ra, 360) + 360, 360);
	sky->dec0 = dec;
	sky->pa0 = fmod(fmod(pa, 360) + 360, 360);
	sky->boresight = boresight;
	sky->geometry = geometry;
	sky->va = 1;
	make_rot(sky);
	geom_attitude(geom_aperture(boresight ? 0 : 1), sky->ra0, sky->dec0, sky->pa0, sky->att);
	for (int i = 0; i < WFS_NSCA; i++) {
		const struct sca_info *si = sca_get(i + 1);
		struct sky_sca *s = &sky->sca[i];
		double ra2, dec2;

		if (!(mask & (1u << i)))
			continue;
		s->sca = i + 1;
		s->fx = boresight ? si->x_bore : si->x_idl;
		s->fy = boresight ? si->y_bore : si->y_idl;
		sky_from_focal(sky, s->fx, s->fy, &s->ra, &s->dec);
		/* +y at the SCA centre: toward a point a little further along +y.
		 * 1" keeps the finite difference exact to ~1e-9 deg. */
		sky_from_focal(sky, s->fx, s->fy + 1.0, &ra2, &dec2);
		s->pa = position_angle(s->ra, s->dec, ra2, dec2);
		if (geom_sca_init(&s->geo, geometry, i + 1, (const double (*)[3])sky->att,
				  s->ra, s->dec, s->pa, e) < 0)
			return -1;
		/* siaf: the SCA's own reference pixel and +y */
		s->ra = s->geo.ra;
		s->dec = s->geo.dec;
		s->pa = s->geo.pa;
		s->half = sca_half(sky, s);
	}
	return 0;
}

/* The pointing's reference direction, a unit vector. */
static void ref_unit(const struct sky *sky, double b[3])
{
	double a = sky->ra0 * M_PI / 180, d = sky->dec0 * M_PI / 180;

	b[0] = cos(d) * cos(a);
	b[1] = cos(d) * sin(a);
	b[2] = sin(d);
}

double sky_va_scale(const struct sky *sky, double mjd)
{
	/* km/s per AU/s and the speed of light */
	const double au_km = 149597870.7, c_kms = 299792.458;
	double p[3], q[3], b[3], ub = 0;

	/* the velocity by a central difference of an hour either side, as
	 * the ASDF writer's meta.ephemeris */
	motion_observer(mjd - 1.0 / 24, p);
	motion_observer(mjd + 1.0 / 24, q);
	ref_unit(sky, b);
	for (int k = 0; k < 3; k++)
		ub += b[k] * (q[k] - p[k]) * au_km / 7200.0 / c_kms;
	return 1 + ub;
}

void sky_aberrate(struct sky *sky, double scale)
{
	double b[3];

	ref_unit(sky, b);
	sky->va = scale;
	for (int i = 0; i < WFS_NSCA; i++) {
		struct sky_sca *s = &sky->sca[i];

		if (!s->sca)
			continue;
		geom_sca_aberrate(&s->geo, scale, b);
		s->ra = s->geo.ra;
		s->dec = s->geo.dec;
		s->pa = s->geo.pa;
		/* the SCA moves by (scale - 1) of its distance from the
		 * reference, and grows by scale */
		s->half += fabs(scale - 1) * (hypot(s->fx, s->fy) + s->half) + 0.01;
	}
}

int sky_va_setting(struct sky *sky, const char *value, double mjd, double exptime,
		   struct err *e)
{
	if (!value || !strcmp(value, "off"))
		return 0;
	if (strcmp(value, "on"))
		return err_set(e, EXIT_INPUT, "--set velocity-aberration=%s: expected on or off",
			       value);
	if (sky->geometry != GEOM_SIAF)
		return err_set(e, EXIT_INPUT, "--set velocity-aberration=on goes with the SIAF "
			       "geometry (--geometry stips draws the sky unaberrated)");
	if (isnan(mjd))
		mjd = date_mjd(2027, 1, 1, 0, 0, 0);
	sky_aberrate(sky, sky_va_scale(sky, mjd + exptime / 2 / 86400));
	return 0;
}

void sky_free(struct sky *sky)
{
	for (int i = 0; i < WFS_NSCA; i++)
		if (sky->sca[i].sca)
			geom_sca_free(&sky->sca[i].geo);
}

int sky_to_pixel(struct sky *sky, int s, size_t n, const double *ra,
		 const double *dec, double *x, double *y, struct err *e)
{
	return geom_sky_to_pix(&sky->sca[s - 1].geo, n, ra, dec, x, y, e);
}

int sky_header(struct sky *sky, int s, int row0, char **cards, int *ncards,
	       struct err *e)
{
	return geom_header(&sky->sca[s - 1].geo, row0, cards, ncards, e);
}
