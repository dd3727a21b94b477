/* sky.c - focal-plane layout and per-SCA WCS; see sky.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <wcslib/wcshdr.h>
#include <wcslib/wcsfix.h>

#include "err.h"
#include "instrument.h"
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

static int setup_wcs(struct sky_sca *s, struct err *e)
{
	struct wcsprm *w = &s->wcs;
	double c = cos(s->pa * D2R), sn = sin(s->pa * D2R);
	int status;

	w->flag = -1;
	if ((status = wcsini(1, 2, w)))
		return err_set(e, EXIT_SYSTEM, "wcslib: %s", wcs_errmsg[status]);
	strcpy(w->ctype[0], "RA---TAN");
	strcpy(w->ctype[1], "DEC--TAN");
	strcpy(w->cunit[0], "deg");
	strcpy(w->cunit[1], "deg");
	strcpy(w->radesys, "ICRS");
	w->crval[0] = s->ra;
	w->crval[1] = s->dec;
	/* FITS pixel (1, 1) is the centre of the first pixel, so the centre of
	 * a 4088-pixel axis is at 2044.5 (STIPS uses 2044, half a pixel off). */
	w->crpix[0] = w->crpix[1] = (WFS_NPIX + 1) / 2.0;
	w->cdelt[0] = -WFS_PIXSCALE / 3600.0;
	w->cdelt[1] = WFS_PIXSCALE / 3600.0;
	w->pc[0] = c;
	w->pc[1] = -sn;
	w->pc[2] = sn;
	w->pc[3] = c;
	w->lonpole = 180;
	if ((status = wcsset(w)))
		return err_set(e, EXIT_SYSTEM, "wcslib: %s", wcs_errmsg[status]);
	return 0;
}

int sky_init(struct sky *sky, double ra, double dec, double pa, int boresight,
	     unsigned mask, struct err *e)
{
	memset(sky, 0, sizeof(*sky));
	if (!isfinite(ra) || !isfinite(dec) || dec < -90 || dec > 90)
		return err_set(e, EXIT_INPUT, "bad pointing: ra %g, dec %g", ra, dec);
	if (!isfinite(pa))
		return err_set(e, EXIT_INPUT, "bad position angle %g", pa);
	sky->ra0 = fmod(fmod(ra, 360) + 360, 360);
	sky->dec0 = dec;
	sky->pa0 = fmod(fmod(pa, 360) + 360, 360);
	sky->boresight = boresight;
	make_rot(sky);
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
		if (setup_wcs(s, e) < 0)
			return -1;
	}
	return 0;
}

void sky_free(struct sky *sky)
{
	for (int i = 0; i < WFS_NSCA; i++)
		if (sky->sca[i].sca)
			wcsfree(&sky->sca[i].wcs);
}

int sky_to_pixel(struct sky *sky, int s, size_t n, const double *ra,
		 const double *dec, double *x, double *y, struct err *e)
{
	struct wcsprm *w = &sky->sca[s - 1].wcs;
	enum { BLOCK = 512 };
	double world[BLOCK][2], img[BLOCK][2], pix[BLOCK][2], phi[BLOCK], theta[BLOCK];
	int stat[BLOCK];

	for (size_t i0 = 0; i0 < n; i0 += BLOCK) {
		int m = n - i0 < BLOCK ? (int)(n - i0) : BLOCK, status;

		for (int k = 0; k < m; k++) {
			world[k][0] = ra[i0 + k];
			world[k][1] = dec[i0 + k];
		}
		status = wcss2p(w, m, 2, world[0], phi, theta, img[0], pix[0], stat);
		if (status && status != WCSERR_BAD_WORLD)
			return err_set(e, EXIT_SYSTEM, "wcslib: %s", wcs_errmsg[status]);
		for (int k = 0; k < m; k++) {
			x[i0 + k] = stat[k] ? NAN : pix[k][0] - 1.0;
			y[i0 + k] = stat[k] ? NAN : pix[k][1] - 1.0;
		}
	}
	return 0;
}

int sky_header(struct sky *sky, int s, int row0, char **cards, int *ncards,
	       struct err *e)
{
	struct wcsprm part = { .flag = -1 };
	int status;

	if (!row0) {
		status = wcshdo(WCSHDO_P17, &sky->sca[s - 1].wcs, ncards, cards);
	} else {
		/* A copy whose reference pixel is counted from the part's
		 * first row; the SCA's own WCS stays as it is. */
		if (!(status = wcssub(1, &sky->sca[s - 1].wcs, NULL, NULL, &part))) {
			part.crpix[1] -= row0;
			part.flag = 0;
			status = wcshdo(WCSHDO_P17, &part, ncards, cards);
		}
		wcsfree(&part);
	}
	if (status)
		return err_set(e, EXIT_SYSTEM, "wcslib: %s", wcs_errmsg[status]);
	return 0;
}
