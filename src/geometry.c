/* geometry.c - the SIAF and STIPS detector geometries; see geometry.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <wcslib/wcshdr.h>

#include "data.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "simd.h"

#define D2R (M_PI / 180.0)
#define AS2R (M_PI / 180.0 / 3600.0)

/* data/siaf.tsv: WFI01..WFI18 at 1..18, WFI_CEN at 0.  Filled once by
 * geom_init() before any thread starts, read-only afterwards. */
static struct geom_aperture aps[WFS_NSCA + 1];
static int loaded;

static int tsv_num(const struct tsv *t, int r, const char *col, double *v)
{
	int c = tsv_col(t, col);

	if (c < 0)
		return -1;
	*v = atof(t->cell[r][c]);
	return 0;
}

/* The coefficients named <p>_<i>_<j> (SIAF naming) into c[]. */
static int read_siaf_poly(const struct tsv *t, int r, const char *p, double *c)
{
	char col[32];
	int bad = 0;

	c[0] = 0;
	for (int i = 1; i <= GEOM_DEG; i++)
		for (int j = 0; j <= i; j++) {
			snprintf(col, sizeof(col), "%s_%d_%d", p, i, j);
			bad |= tsv_num(t, r, col, &c[i * (i + 1) / 2 + j]);
		}
	return bad;
}

/* SIP coefficients <p>_<xpow>_<ypow> of degrees lo..deg into c[] (same
 * indexing: degree i = xpow + ypow, j = ypow). */
static int read_sip(const struct tsv *t, int r, const char *p, int lo, int deg, double *c)
{
	char col[32];
	int bad = 0;

	for (int i = 0; i <= deg; i++)
		for (int j = 0; j <= i; j++) {
			c[i * (i + 1) / 2 + j] = 0;
			if (i < lo)
				continue;
			snprintf(col, sizeof(col), "%s_%d_%d", p, i - j, j);
			bad |= tsv_num(t, r, col, &c[i * (i + 1) / 2 + j]);
		}
	return bad;
}

int geom_init(struct err *e)
{
	struct tsv t;
	int bad = 0, seen = 0;

	if (loaded)
		return 0;
	if (tsv_parse(&t, "siaf.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "broken build: no siaf.tsv table");
	for (int r = 1; r < t.nrow; r++) {
		double s;
		struct geom_aperture *a;

		if (tsv_num(&t, r, "sca", &s) < 0 || s < 0 || s > WFS_NSCA) {
			bad = 1;
			break;
		}
		a = &aps[(int)s];
		a->sca = (int)s;
		bad |= tsv_num(&t, r, "v2ref", &a->v2ref);
		bad |= tsv_num(&t, r, "v3ref", &a->v3ref);
		bad |= tsv_num(&t, r, "v3idlyangle", &a->v3idlyangle);
		bad |= tsv_num(&t, r, "vidlparity", &a->parity);
		seen |= 1 << a->sca;
		if (!a->sca)
			continue;
		bad |= tsv_num(&t, r, "xsciref", &a->xref);
		bad |= tsv_num(&t, r, "ysciref", &a->yref);
		bad |= read_siaf_poly(&t, r, "sx", a->sx);
		bad |= read_siaf_poly(&t, r, "sy", a->sy);
		bad |= read_siaf_poly(&t, r, "ix", a->ix);
		bad |= read_siaf_poly(&t, r, "iy", a->iy);
		bad |= read_sip(&t, r, "a", 2, GEOM_DEG, a->a);
		bad |= read_sip(&t, r, "b", 2, GEOM_DEG, a->b);
		bad |= read_sip(&t, r, "ap", 1, GEOM_SIP_INV, a->ap);
		bad |= read_sip(&t, r, "bp", 1, GEOM_SIP_INV, a->bp);
	}
	tsv_free(&t);
	if (bad || seen != (1 << (WFS_NSCA + 1)) - 1)
		return err_set(e, EXIT_SYSTEM, "broken build: siaf.tsv lacks a column or an SCA");
	loaded = 1;
	return 0;
}

const struct geom_aperture *geom_aperture(int sca)
{
	return sca >= 0 && sca <= WFS_NSCA ? &aps[sca] : NULL;
}

int geom_parse(const char *name)
{
	if (!strcasecmp(name, "siaf"))
		return GEOM_SIAF;
	if (!strcasecmp(name, "stips"))
		return GEOM_STIPS;
	return -1;
}

const char *geom_name(int kind)
{
	return kind == GEOM_STIPS ? "stips" : "siaf";
}

/* ---- the SIAF polynomials ---- */

/* A degree-5 polynomial (SIAF indexing) and its two partial derivatives. */
static void poly5(const double *c, const double *up, const double *vp, double *f,
		  double *fu, double *fv)
{
	double s = 0, su = 0, sv = 0;

	for (int i = 1; i <= GEOM_DEG; i++) {
		const double *ci = c + i * (i + 1) / 2;

		for (int j = 0; j <= i; j++) {
			int p = i - j;

			s += ci[j] * up[p] * vp[j];
			if (p)
				su += ci[j] * p * up[p - 1] * vp[j];
			if (j)
				sv += ci[j] * j * up[p] * vp[j - 1];
		}
	}
	*f = s;
	*fu = su;
	*fv = sv;
}

static double poly5_value(const double *c, const double *up, const double *vp)
{
	double s = 0;

	for (int i = 1; i <= GEOM_DEG; i++) {
		const double *ci = c + i * (i + 1) / 2;

		for (int j = 0; j <= i; j++)
			s += ci[j] * up[i - j] * vp[j];
	}
	return s;
}

static void powers(double u, double *up, int n)
{
	up[0] = 1;
	for (int k = 1; k <= n; k++)
		up[k] = up[k - 1] * u;
}

void geom_sci_to_idl(const struct geom_aperture *ap, double u, double v,
		     double *xi, double *yi, double d[4])
{
	double up[GEOM_DEG + 1], vp[GEOM_DEG + 1];

	powers(u, up, GEOM_DEG);
	powers(v, vp, GEOM_DEG);
	if (d) {
		poly5(ap->sx, up, vp, xi, &d[0], &d[1]);
		poly5(ap->sy, up, vp, yi, &d[2], &d[3]);
	} else {
		*xi = poly5_value(ap->sx, up, vp);
		*yi = poly5_value(ap->sy, up, vp);
	}
}

void geom_idl_to_sci(const struct geom_aperture *ap, double xi, double yi,
		     double *u, double *v)
{
	double up[GEOM_DEG + 1], vp[GEOM_DEG + 1], x, y, d[4];

	/* The SIAF's inverse polynomial is good to 3.5e-3 pixel on the SCA;
	 * Newton steps on Sci2Idl make it the exact inverse.  The error after
	 * a step is of the order of the step squared times the relative
	 * curvature (< 1e-5 per pixel), so a step under 0.01 pixel leaves
	 * < 1e-9 and ends the loop: on the SCA one step is enough, only far
	 * outside it does a second one run. */
	powers(xi, up, GEOM_DEG);
	powers(yi, vp, GEOM_DEG);
	x = poly5_value(ap->ix, up, vp);
	y = poly5_value(ap->iy, up, vp);
	for (int it = 0; it < 4; it++) {
		double fx, fy, det, dx, dy;

		geom_sci_to_idl(ap, x, y, &fx, &fy, d);
		fx -= xi;
		fy -= yi;
		det = d[0] * d[3] - d[1] * d[2];
		dx = (d[3] * fx - d[1] * fy) / det;
		dy = (d[0] * fy - d[2] * fx) / det;
		x -= dx;
		y -= dy;
		if (!(fabs(dx) + fabs(dy) > 1e-2))
			break;
	}
	*u = x;
	*v = y;
}

/* ---- the attitude ---- */

/* The aperture's reference point and ideal +x, +y axes as V2/V3 unit
 * vectors: +y_idl at V3IdlYAngle from the local +V3 toward +V2, x_idl of
 * parity VIdlParity (the SIAF's planar rule applied in the tangent plane). */
static void aperture_frame(const struct geom_aperture *ap, double ut[3], double xt[3],
			   double yt[3])
{
	double a = ap->v2ref * AS2R, d = ap->v3ref * AS2R, th = ap->v3idlyangle * D2R;
	double e2[3] = { -sin(a), cos(a), 0 };                          /* +V2 */
	double e3[3] = { -sin(d) * cos(a), -sin(d) * sin(a), cos(d) };  /* +V3 */

	geom_unit(a, d, ut);
	for (int k = 0; k < 3; k++) {
		xt[k] = ap->parity * (cos(th) * e2[k] - sin(th) * e3[k]);
		yt[k] = sin(th) * e2[k] + cos(th) * e3[k];
	}
}

/* East and north unit vectors at (ra, dec) (radians). */
static void sky_frame(double a, double d, double s[3], double east[3], double north[3])
{
	geom_unit(a, d, s);
	east[0] = -sin(a);
	east[1] = cos(a);
	east[2] = 0;
	north[0] = -sin(d) * cos(a);
	north[1] = -sin(d) * sin(a);
	north[2] = cos(d);
}

void geom_attitude(const struct geom_aperture *ref, double ra, double dec,
		   double pa, double m[3][3])
{
	double ut[3], xt[3], yt[3], s[3], e[3], n[3], xs[3], ys[3];
	double c = cos(pa * D2R), sn = sin(pa * D2R);

	aperture_frame(ref, ut, xt, yt);
	sky_frame(ra * D2R, dec * D2R, s, e, n);
	/* +y_idl at position angle pa; +x_idl 90 degrees from it on the side
	 * the parity says (west of +y for parity -1, the sky's own parity). */
	for (int k = 0; k < 3; k++) {
		ys[k] = c * n[k] + sn * e[k];
		xs[k] = ref->parity * (c * e[k] - sn * n[k]);
	}
	/* m = s ut^T + xs xt^T + ys yt^T: both triads share their handedness,
	 * so m is a rotation. */
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			m[i][j] = s[i] * ut[j] + xs[i] * xt[j] + ys[i] * yt[j];
}

static void mat_vec(const double m[3][3], const double v[3], double w[3])
{
	for (int i = 0; i < 3; i++)
		w[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
}

static double dot(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void vec_to_radec(const double s[3], double *ra, double *dec)
{
	*ra = atan2(s[1], s[0]) / D2R;
	if (*ra < 0)
		*ra += 360;
	/* -1e-15 + 360 rounds to 360 */
	if (*ra >= 360)
		*ra -= 360;
	*dec = atan2(s[2], hypot(s[0], s[1])) / D2R;
}

/* ---- the STIPS geometry: one TAN per SCA (the WCS sky.c had) ---- */

static int stips_wcs(struct geom_sca *g, struct err *e)
{
	struct wcsprm *w = &g->wcs;
	double c = cos(g->pa * D2R), sn = sin(g->pa * D2R);
	int status;

	w->flag = -1;
	if ((status = wcsini(1, 2, w)))
		return err_set(e, EXIT_SYSTEM, "wcslib: %s", wcs_errmsg[status]);
	g->have_wcs = 1;
	strcpy(w->ctype[0], "RA---TAN");
	strcpy(w->ctype[1], "DEC--TAN");
	strcpy(w->cunit[0], "deg");
	strcpy(w->cunit[1], "deg");
	strcpy(w->radesys, "ICRS");
	w->crval[0] = g->ra;
	w->crval[1] = g->dec;
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

/* ---- one SCA ---- */

int geom_sca_init(struct geom_sca *g, int kind, int sca, const double m[3][3],
		  double ra, double dec, double pa, struct err *e)
{
	double ut[3], xt[3], yt[3], s[3], east[3], north[3], dir[3];

	memset(g, 0, sizeof(*g));
	g->kind = kind;
	g->sca = sca;
	g->ap = geom_aperture(sca);
	if (kind == GEOM_STIPS) {
		g->ra = ra;
		g->dec = dec;
		g->pa = pa;
		return stips_wcs(g, e);
	}
	aperture_frame(g->ap, ut, xt, yt);
	mat_vec(m, ut, g->u);
	mat_vec(m, xt, g->ex);
	mat_vec(m, yt, g->ey);
	g->va = 1;
	vec_to_radec(g->u, &g->ra, &g->dec);
	/* +y of the science frame at the reference pixel: d(ideal)/dy */
	for (int k = 0; k < 3; k++)
		dir[k] = g->ap->sx[2] * g->ex[k] + g->ap->sy[2] * g->ey[k];
	sky_frame(g->ra * D2R, g->dec * D2R, s, east, north);
	g->pa = atan2(dot(dir, east), dot(dir, north)) / D2R;
	return 0;
}

void geom_sca_aberrate(struct geom_sca *g, double scale, const double b[3])
{
	double s[3], east[3], north[3], dir[3], len, pe, pn;

	if (g->kind != GEOM_SIAF)
		return;
	for (int k = 0; k < 3; k++)
		g->u[k] = b[k] + scale * (g->u[k] - b[k]);
	len = sqrt(dot(g->u, g->u));
	for (int k = 0; k < 3; k++)
		g->u[k] /= len;
	/* the ideal axes back in the plane tangent at the new u (they turn
	 * by its move, ~1e-6 rad) */
	pe = dot(g->ex, g->u);
	pn = dot(g->ey, g->u);
	for (int k = 0; k < 3; k++) {
		g->ex[k] -= pe * g->u[k];
		g->ey[k] -= pn * g->u[k];
	}
	len = sqrt(dot(g->ex, g->ex));
	pe = sqrt(dot(g->ey, g->ey));
	for (int k = 0; k < 3; k++) {
		g->ex[k] /= len;
		g->ey[k] /= pe;
	}
	g->va = scale;
	vec_to_radec(g->u, &g->ra, &g->dec);
	for (int k = 0; k < 3; k++)
		dir[k] = g->ap->sx[2] * g->ex[k] + g->ap->sy[2] * g->ey[k];
	sky_frame(g->ra * D2R, g->dec * D2R, s, east, north);
	g->pa = atan2(dot(dir, east), dot(dir, north)) / D2R;
}

void geom_sca_free(struct geom_sca *g)
{
	if (g->have_wcs)
		wcsfree(&g->wcs);
	g->have_wcs = 0;
}

static int stips_sky_to_pix(struct geom_sca *g, size_t n, const double *ra,
			    const double *dec, double *x, double *y, struct err *e)
{
	struct wcsprm *w = &g->wcs;
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

int geom_sky_to_pix(struct geom_sca *g, size_t n, const double *ra,
		    const double *dec, double *x, double *y, struct err *e)
{
	const struct geom_aperture *ap = g->ap;
	/* cos 80 degrees: farther rows are on no detector */
	const double wmin = 0.17364817766693;

	if (g->kind == GEOM_STIPS)
		return stips_sky_to_pix(g, n, ra, dec, x, y, e);
	for (size_t i = 0; i < n; i++) {
		double a = ra[i] * D2R, d = dec[i] * D2R, cd = cos(d), s[3], w, u, v;

		s[0] = cd * cos(a);
		s[1] = cd * sin(a);
		s[2] = sin(d);
		w = dot(s, g->u);
		/* also false for NaN */
		if (!(w > wmin)) {
			x[i] = y[i] = NAN;
			continue;
		}
		w *= g->va;
		geom_idl_to_sci(ap, dot(s, g->ex) / w / AS2R, dot(s, g->ey) / w / AS2R, &u, &v);
		x[i] = isfinite(u) && isfinite(v) ? ap->xref - 1 + u : NAN;
		y[i] = isfinite(u) && isfinite(v) ? ap->yref - 1 + v : NAN;
		/* (ra, dec may be x, y: sky_to_pixel works in place) */
		if (g->map && isfinite(x[i]))
			g->map->to_pix(g->map->ctx, a / D2R, d / D2R, x[i], y[i], &x[i], &y[i]);
	}
	return 0;
}

void geom_pix_to_sky(struct geom_sca *g, double x, double y, double *ra,
		     double *dec)
{
	double xi, yi, s[3];

	if (g->kind == GEOM_STIPS) {
		double pix[2] = { x + 1, y + 1 }, img[2], phi, theta, world[2];
		int stat;

		if (wcsp2s(&g->wcs, 1, 2, pix, img, &phi, &theta, world, &stat)) {
			*ra = *dec = NAN;
			return;
		}
		*ra = world[0];
		*dec = world[1];
		return;
	}
	if (g->map) {
		g->map->to_sky(g->map->ctx, x, y, ra, dec);
		return;
	}
	geom_sci_to_idl(g->ap, x + 1 - g->ap->xref, y + 1 - g->ap->yref, &xi, &yi, NULL);
	xi *= g->va;
	yi *= g->va;
	for (int k = 0; k < 3; k++)
		s[k] = g->u[k] + xi * AS2R * g->ex[k] + yi * AS2R * g->ey[k];
	vec_to_radec(s, ra, dec);
}

void geom_jacobian(const struct geom_sca *g, double x, double y, double j[4])
{
	double xi, yi;

	if (g->kind == GEOM_STIPS) {
		j[0] = j[3] = WFS_PIXSCALE;
		j[1] = j[2] = 0;
		return;
	}
	geom_sci_to_idl(g->ap, x + 1 - g->ap->xref, y + 1 - g->ap->yref, &xi, &yi, j);
}

void geom_sky_jacobian(struct geom_sca *g, double x, double y, double k[4])
{
	double ra, dec;

	geom_pix_to_sky(g, x, y, &ra, &dec);
	double ca = cos(ra * D2R), sa = sin(ra * D2R), cd = cos(dec * D2R), sd = sin(dec * D2R);
	double east[3] = { -sa, ca, 0 }, north[3] = { -sd * ca, -sd * sa, cd };

	if (g->kind == GEOM_STIPS || g->map) {
		/* the gnomonic offsets of the four neighbours about (ra, dec) */
		double h[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } }, t[4][2];
		for (int n = 0; n < 4; n++) {
			double r2, d2, v[3];
			geom_pix_to_sky(g, x + h[n][0], y + h[n][1], &r2, &d2);
			geom_unit(r2 * D2R, d2 * D2R, v);
			double w = v[0] * cd * ca + v[1] * cd * sa + v[2] * sd;
			t[n][0] = dot(v, east) / w / AS2R;
			t[n][1] = dot(v, north) / w / AS2R;
		}
		k[0] = (t[0][0] - t[1][0]) / 2;
		k[1] = (t[2][0] - t[3][0]) / 2;
		k[2] = (t[0][1] - t[1][1]) / 2;
		k[3] = (t[2][1] - t[3][1]) / 2;
		return;
	}
	/* s = u + xi ex + yi ey (radians), the sky direction s / |s|: its
	 * derivative along a tangent unit vector t is t . ds / |s| */
	double xi, yi, j[4], s[3];

	geom_sci_to_idl(g->ap, x + 1 - g->ap->xref, y + 1 - g->ap->yref, &xi, &yi, j);
	for (int c = 0; c < 4; c++)
		j[c] *= g->va;
	xi *= g->va;
	yi *= g->va;
	for (int c = 0; c < 3; c++)
		s[c] = g->u[c] + xi * AS2R * g->ex[c] + yi * AS2R * g->ey[c];
	double len = sqrt(dot(s, s));
	for (int c = 0; c < 2; c++) {
		double ds[3];
		for (int q = 0; q < 3; q++)
			ds[q] = j[c] * g->ex[q] + j[2 + c] * g->ey[q];  /* arcsec */
		k[c] = dot(ds, east) / len;
		k[2 + c] = dot(ds, north) / len;
	}
}

void geom_sky_ellipse(struct geom_sca *g, double x, double y, double a, double q,
		      double pa, double *re, double *ratio, double *phi)
{
	double k[4], vE = sin(pa * D2R), vN = cos(pa * D2R), b = q * a;

	geom_sky_jacobian(g, x, y, k);
	/* the sky's shape matrix a^2 v v' + b^2 w w' (w = v turned 90 deg) */
	double s11 = a * a * vE * vE + b * b * vN * vN;
	double s12 = (a * a - b * b) * vE * vN;
	double s22 = a * a * vN * vN + b * b * vE * vE;
	/* in pixels: K^-1 S K^-T */
	double det = k[0] * k[3] - k[1] * k[2];
	double i11 = k[3] / det, i12 = -k[1] / det, i21 = -k[2] / det, i22 = k[0] / det;
	double t11 = i11 * s11 + i12 * s12, t12 = i11 * s12 + i12 * s22;
	double t21 = i21 * s11 + i22 * s12, t22 = i21 * s12 + i22 * s22;
	double p11 = t11 * i11 + t12 * i12, p12 = t11 * i21 + t12 * i22;
	double p22 = t21 * i21 + t22 * i22;
	/* its eigenvalues (semi-axes squared) and the major axis' direction */
	double m = 0.5 * (p11 + p22), dd = hypot(0.5 * (p11 - p22), p12);
	double l1 = m + dd, l2 = fmax(m - dd, 0);
	double th = 0.5 * atan2(2 * p12, p11 - p22);   /* from +x toward +y */

	*re = sqrt(l1);
	*ratio = l1 > 0 ? sqrt(l2 / l1) : 1;
	*phi = th / D2R - 90;
}

double geom_area(const struct geom_sca *g, double x, double y)
{
	double j[4];

	if (g->kind == GEOM_STIPS)
		return 1.0;
	geom_jacobian(g, x, y, j);
	return fabs(j[0] * j[3] - j[1] * j[2]) / (WFS_PIXSCALE * WFS_PIXSCALE);
}

/* The Jacobian's entries along row v as polynomials in u (degree <= 4):
 * d[0] dxi/du, d[1] dxi/dv, d[2] dyi/du, d[3] dyi/dv, coefficient of u^p
 * in d[k][p]. */
static void row_jacobian(const struct geom_aperture *ap, double v, double d[4][GEOM_DEG])
{
	double vp[GEOM_DEG + 1];

	powers(v, vp, GEOM_DEG);
	memset(d, 0, 4 * GEOM_DEG * sizeof(double));
	for (int i = 1; i <= GEOM_DEG; i++)
		for (int j = 0; j <= i; j++) {
			int k = i * (i + 1) / 2 + j, p = i - j;

			if (p) {
				d[0][p - 1] += p * ap->sx[k] * vp[j];
				d[2][p - 1] += p * ap->sy[k] * vp[j];
			}
			if (j) {
				d[1][p] += j * ap->sx[k] * vp[j - 1];
				d[3][p] += j * ap->sy[k] * vp[j - 1];
			}
		}
}

#ifdef SIMD_X86
/* The Horner loop of geom_area_row() for eight pixels at a time: the same
 * operations in the same order on each, so the same areas.  Returns the
 * pixels done. */
__attribute__((target("avx512f,avx512dq"))) static int
area_avx512(const double *c, double u0, double nominal, int n, double *area)
{
	const __m512i step = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
	const __m512d sgn = _mm512_set1_pd(-0.0);
	int i = 0;

	for (; i + 8 <= n; i += 8) {
		__m512d u = _mm512_add_pd(_mm512_set1_pd(u0), _mm512_cvtepi64_pd(
						  _mm512_add_epi64(_mm512_set1_epi64(i), step)));
		__m512d s = _mm512_set1_pd(c[2 * GEOM_DEG - 2]);

		for (int k = 2 * GEOM_DEG - 3; k >= 0; k--)
			s = _mm512_add_pd(_mm512_mul_pd(s, u), _mm512_set1_pd(c[k]));
		_mm512_storeu_pd(area + i, _mm512_div_pd(_mm512_andnot_pd(sgn, s),
							 _mm512_set1_pd(nominal)));
	}
	return i;
}
#endif

void geom_area_row(const struct geom_sca *g, int y, int x0, int n, double *area)
{
	const struct geom_aperture *ap = g->ap;
	double d[4][GEOM_DEG], c[2 * GEOM_DEG - 1] = { 0 }, u0, nominal;
	int i0 = 0;

	if (g->kind == GEOM_STIPS) {
		for (int i = 0; i < n; i++)
			area[i] = 1.0;
		return;
	}
	/* det J along the row, a polynomial of degree 8 in u, then Horner */
	row_jacobian(ap, y + 1 - ap->yref, d);
	for (int p = 0; p < GEOM_DEG; p++)
		for (int q = 0; q < GEOM_DEG; q++)
			c[p + q] += d[0][p] * d[3][q] - d[1][p] * d[2][q];
	nominal = WFS_PIXSCALE * WFS_PIXSCALE;
	u0 = x0 + 1 - ap->xref;
#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX512)
		i0 = area_avx512(c, u0, nominal, n, area);
#endif
	for (int i = i0; i < n; i++) {
		double u = u0 + i, s = c[2 * GEOM_DEG - 2];

		for (int k = 2 * GEOM_DEG - 3; k >= 0; k--)
			s = s * u + c[k];
		area[i] = fabs(s) / nominal;
	}
}

/* ---- headers ---- */

static int add(char **cards, int *n, int *cap, const char *card)
{
	if (*n == *cap) {
		int c = *cap ? 2 * *cap : 128;
		char *p = realloc(*cards, (size_t)c * 80);

		if (!p)
			return -1;
		*cards = p;
		*cap = c;
	}
	memcpy(*cards + (size_t)80 * (*n)++, card, 80);
	return 0;
}

/* One card: a string value, a real (17 significant digits, as wcslib's
 * WCSHDO_P17) or an integer. */
static void card(char *c, const char *key, const char *sval, double dval, int ival,
		 const char *comment)
{
	char v[48], buf[96];

	if (sval)
		snprintf(v, sizeof(v), "'%-8s'", sval);
	else if (ival >= 0)
		snprintf(v, sizeof(v), "%d", ival);
	else
		snprintf(v, sizeof(v), "%.17G", dval);
	if (!sval && ival < 0 && !strpbrk(v, ".E"))
		strcat(v, ".0");
	snprintf(buf, sizeof(buf), "%-8.8s= %20s / %s", key, v, comment ? comment : "");
	memset(c, ' ', 80);
	memcpy(c, buf, strlen(buf) < 80 ? strlen(buf) : 80);
}

static int sip_cards(char **cards, int *n, int *cap, const char *name, int lo,
		     int deg, const double *c)
{
	char key[16], k[81], com[32];
	int bad = 0;

	snprintf(key, sizeof(key), "%s_ORDER", name);
	card(k, key, NULL, 0, deg, "SIP polynomial order");
	bad |= add(cards, n, cap, k);
	for (int i = lo; i <= deg; i++)
		for (int j = 0; j <= i; j++) {
			snprintf(key, sizeof(key), "%s_%d_%d", name, i - j, j);
			snprintf(com, sizeof(com), "SIP coefficient");
			card(k, key, NULL, c[i * (i + 1) / 2 + j], -1, com);
			bad |= add(cards, n, cap, k);
		}
	return bad;
}

int geom_header(struct geom_sca *g, int row0, char **cards, int *ncards,
		struct err *e)
{
	const struct geom_aperture *ap = g->ap;
	double s[3], east[3], north[3], r[4], cd[4];
	char k[81];
	int cap = 0, bad = 0, status;

	*cards = NULL;
	*ncards = 0;
	if (g->kind == GEOM_STIPS) {
		struct wcsprm part = { .flag = -1 };

		if (!row0) {
			status = wcshdo(WCSHDO_P17, &g->wcs, ncards, cards);
		} else {
			/* A copy whose reference pixel is counted from the part's
			 * first row; the SCA's own WCS stays as it is. */
			if (!(status = wcssub(1, &g->wcs, NULL, NULL, &part))) {
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
	/* TAN about the reference pixel, whose tangent plane is the SCA's
	 * ideal frame turned by r (ideal axes -> east, north); CD = r L. */
	sky_frame(g->ra * D2R, g->dec * D2R, s, east, north);
	r[0] = g->va * dot(g->ex, east);
	r[1] = g->va * dot(g->ey, east);
	r[2] = g->va * dot(g->ex, north);
	r[3] = g->va * dot(g->ey, north);
	cd[0] = (r[0] * ap->sx[1] + r[1] * ap->sy[1]) / 3600;
	cd[1] = (r[0] * ap->sx[2] + r[1] * ap->sy[2]) / 3600;
	cd[2] = (r[2] * ap->sx[1] + r[3] * ap->sy[1]) / 3600;
	cd[3] = (r[2] * ap->sx[2] + r[3] * ap->sy[2]) / 3600;
#define C(key, sv, dv, iv, com) (card(k, key, sv, dv, iv, com), bad |= add(cards, ncards, &cap, k))
	C("CTYPE1", "RA---TAN-SIP", 0, 0, "TAN with SIP distortion (Roman SIAF)");
	C("CTYPE2", "DEC--TAN-SIP", 0, 0, "TAN with SIP distortion (Roman SIAF)");
	C("CUNIT1", "deg", 0, 0, NULL);
	C("CUNIT2", "deg", 0, 0, NULL);
	C("CRPIX1", NULL, ap->xref, -1, "SIAF XSciRef");
	C("CRPIX2", NULL, ap->yref - row0, -1, row0 ? "SIAF YSciRef, from this part's row 1"
	  : "SIAF YSciRef");
	C("CRVAL1", NULL, g->ra, -1, "reference pixel RA (deg)");
	C("CRVAL2", NULL, g->dec, -1, "reference pixel Dec (deg)");
	C("CD1_1", NULL, cd[0], -1, NULL);
	C("CD1_2", NULL, cd[1], -1, NULL);
	C("CD2_1", NULL, cd[2], -1, NULL);
	C("CD2_2", NULL, cd[3], -1, NULL);
	C("LONPOLE", NULL, 180, -1, NULL);
	C("RADESYS", "ICRS", 0, 0, NULL);
#undef C
	bad |= sip_cards(cards, ncards, &cap, "A", 2, GEOM_DEG, ap->a);
	bad |= sip_cards(cards, ncards, &cap, "B", 2, GEOM_DEG, ap->b);
	bad |= sip_cards(cards, ncards, &cap, "AP", 1, GEOM_SIP_INV, ap->ap);
	bad |= sip_cards(cards, ncards, &cap, "BP", 1, GEOM_SIP_INV, ap->bp);
	if (bad) {
		free(*cards);
		*cards = NULL;
		return err_set(e, EXIT_SYSTEM, "out of memory: WCS header");
	}
	return 0;
}
