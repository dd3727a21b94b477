/*
 * geometry.c - the SIAF geometry (src/geometry.c) on its own terms:
 *
 * - the exact inverse: Idl2Sci plus Newton on Sci2Idl gives back every
 *   science pixel to 1e-8 px over the SCA and a margin beyond, where the
 *   SIAF's Idl2Sci polynomial alone is off by up to 1e-3 px (printed);
 * - pixel -> sky -> pixel within 1e-6 px and sky -> pixel -> sky within
 *   0.1 mas (the bound; measured far below) on random points of all
 *   18 SCAs, for pointings at both poles, across RA 0/360, both references;
 * - the attitude: the reference aperture's reference point lands on the
 *   pointing and its +y_idl axis at position angle --pa; the SIAF's +V3
 *   axis at pa + 60 degrees;
 * - the Jacobian against finite differences of pixel -> sky, and the pixel
 *   area against the sky's own area of a pixel (spherical excess of its
 *   corners), also by rows (the background's); the stips geometry's area
 *   is exactly 1;
 * - the TAN-SIP header: wcslib (wcspih) reads it and maps every pixel of a
 *   41 x 41 grid plus 2000 random points within 0.005 px of the exact
 *   mapping in both directions, its inverse evaluated from the AP/BP cards
 *   of the header within 0.005 px too; a --rows part's header likewise.
 * - the sky Jacobian against differences of pixel -> sky, and a sky
 *   ellipse mapped into pixels and back;
 * t4102-siaf.sh checks the mapping against an independent Python
 * implementation and astropy's reading of the header.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <wcslib/wcs.h>
#include <wcslib/wcshdr.h>

#include "tap.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "sky.h"

#define D2R (M_PI / 180.0)
#define AS2R (M_PI / 180.0 / 3600.0)

static double urand(double a, double b)
{
	return a + (b - a) * (rand() / (double)RAND_MAX);
}

static void unitv(double ra, double dec, double v[3])
{
	v[0] = cos(dec * D2R) * cos(ra * D2R);
	v[1] = cos(dec * D2R) * sin(ra * D2R);
	v[2] = sin(dec * D2R);
}

/* angle between two sky positions, milliarcseconds (atan2 form: exact at
 * small angles) */
static double sep_mas(double r1, double d1, double r2, double d2)
{
	double a[3], b[3], c[3];

	unitv(r1, d1, a);
	unitv(r2, d2, b);
	c[0] = a[1] * b[2] - a[2] * b[1];
	c[1] = a[2] * b[0] - a[0] * b[2];
	c[2] = a[0] * b[1] - a[1] * b[0];
	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
		     a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / AS2R * 1000;
}

static double pos_angle(double ra1, double dec1, double ra2, double dec2)
{
	double dra = (ra2 - ra1) * D2R;

	return atan2(sin(dra) * cos(dec2 * D2R), cos(dec1 * D2R) * sin(dec2 * D2R) -
		     sin(dec1 * D2R) * cos(dec2 * D2R) * cos(dra)) / D2R;
}

static void inverse(void)
{
	double worst = 0, worst_siaf = 0;

	srand(11);
	for (int s = 1; s <= WFS_NSCA; s++) {
		const struct geom_aperture *ap = geom_aperture(s);

		for (int k = 0; k < 2000; k++) {
			/* the SCA and 300 pixels beyond its edges */
			double u = urand(-2344, 2344), v = urand(-2344, 2344), xi, yi, u2, v2;
			double up[6], vp[6], iu = 0, iv = 0;

			geom_sci_to_idl(ap, u, v, &xi, &yi, NULL);
			geom_idl_to_sci(ap, xi, yi, &u2, &v2);
			worst = fmax(worst, fmax(fabs(u2 - u), fabs(v2 - v)));
			/* the SIAF's own inverse polynomial, for the record */
			up[0] = vp[0] = 1;
			for (int p = 1; p <= 5; p++) {
				up[p] = up[p - 1] * xi;
				vp[p] = vp[p - 1] * yi;
			}
			for (int i = 1; i <= 5; i++)
				for (int j = 0; j <= i; j++) {
					iu += ap->ix[i * (i + 1) / 2 + j] * up[i - j] * vp[j];
					iv += ap->iy[i * (i + 1) / 2 + j] * up[i - j] * vp[j];
				}
			if (fabs(u) < 2044 && fabs(v) < 2044)
				worst_siaf = fmax(worst_siaf, fmax(fabs(iu - u), fabs(iv - v)));
		}
	}
	ok(worst < 1e-8, "Idl2Sci + Newton inverts Sci2Idl to 1e-8 px over the SCAs "
	   "and 300 px beyond (worst %.1e px)", worst);
	diag("the SIAF's Idl2Sci alone: worst %.2e px on the SCAs", worst_siaf);
	ok(worst_siaf > 1e-6 && worst_siaf < 0.01, "and that is why: Idl2Sci alone is "
	   "only approximate (%.1e px)", worst_siaf);
}

/* The sky area of pixel (x, y) (0-based) from its corners: the spherical
 * excess of the quadrilateral, in units of a 0.11" square. */
static double sky_area(struct geom_sca *g, double x, double y)
{
	double c[4][3], ra, dec, area = 0;
	const double dx[4] = { -0.5, 0.5, 0.5, -0.5 }, dy[4] = { -0.5, -0.5, 0.5, 0.5 };

	for (int k = 0; k < 4; k++) {
		geom_pix_to_sky(g, x + dx[k], y + dy[k], &ra, &dec);
		unitv(ra, dec, c[k]);
	}
	/* two triangles, each by the Van Oosterom-Strackee formula with the
	 * triple product a.(b x d) taken as a.((b - a) x (d - a)), which is
	 * the same but free of the cancellation of nearly equal vectors */
	for (int t = 0; t < 2; t++) {
		const double *a = c[0], *b = c[1 + t], *d = c[2 + t];
		double p[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
		double q[3] = { d[0] - a[0], d[1] - a[1], d[2] - a[2] };
		double pxq[3] = { p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2],
				  p[0] * q[1] - p[1] * q[0] };
		double num = a[0] * pxq[0] + a[1] * pxq[1] + a[2] * pxq[2];
		double den = 1 + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) +
			     (b[0] * d[0] + b[1] * d[1] + b[2] * d[2]) +
			     (d[0] * a[0] + d[1] * a[1] + d[2] * a[2]);

		area += 2 * atan2(fabs(num), den);
	}
	return area / (0.11 * AS2R) / (0.11 * AS2R);
}

/* The SIP polynomial NAME_p_q of header cards, read once into c[p][q]. */
static void sip_read(const char *cards, int n, const char *name, double c[8][8])
{
	size_t len = strlen(name);

	memset(c, 0, 64 * sizeof(double));
	for (int k = 0; k < n; k++) {
		const char *card = cards + 80 * k;
		int p, q;

		/* NAME_p_q = value, the name matched by hand (no format built
		 * from a string) */
		if (strncmp(card, name, len) || card[len] != '_')
			continue;
		if (sscanf(card + len, "_%d_%d =", &p, &q) == 2 && p >= 0 && q >= 0 &&
		    p < 8 && q < 8)
			c[p][q] = atof(strchr(card, '=') + 1);
	}
}

static double sip_eval(const double c[8][8], double u, double v)
{
	double s = 0, up = 1;

	for (int p = 0; p < 8; p++, up *= u) {
		double vp = 1;

		for (int q = 0; p + q < 8; q++, vp *= v)
			s += c[p][q] * up * vp;
	}
	return s;
}

static double card_value(const char *cards, int n, const char *key)
{
	size_t l = strlen(key);

	for (int k = 0; k < n; k++)
		if (!strncmp(cards + 80 * k, key, l) && cards[80 * k + l] == ' ')
			return atof(strchr(cards + 80 * k, '=') + 1);
	return NAN;
}

static void pointing(double ra, double dec, double pa, int boresight, unsigned seed)
{
	struct err e = { 0 };
	struct sky sky;
	double w_pix = 0, w_mas = 0, w_jac = 0, w_area = 0, w_fwd = 0, w_inv = 0;
	double w_ap = 0, w_part = 0, amin = INFINITY, amax = 0, w_row = 0;
	int parsed = 1;

	if (!ok(sky_init(&sky, ra, dec, pa, boresight, GEOM_SIAF, (1u << WFS_NSCA) - 1,
			 &e) == 0, "sky_init: %s", e.msg))
		return;
	srand(seed);
	/* the attitude: the reference on the pointing, its +y_idl at pa,
	 * the +V3 axis at pa + 60 */
	{
		double m[3][3], v[3], w[3], r0 = 0, d0 = 0, r1 = 0, d1 = 0;
		const struct geom_aperture *ref = geom_aperture(boresight ? 0 : 1);
		double a = ref->v2ref * AS2R, d = ref->v3ref * AS2R, h = 1 * AS2R;

		memcpy(m, sky.att, sizeof(m));
		/* V2/V3 of the reference point, then 1" along +V3 */
		for (int k = 0; k < 2; k++) {
			v[0] = cos(d + k * h) * cos(a);
			v[1] = cos(d + k * h) * sin(a);
			v[2] = sin(d + k * h);
			for (int i = 0; i < 3; i++)
				w[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
			*(k ? &r1 : &r0) = atan2(w[1], w[0]) / D2R;
			*(k ? &d1 : &d0) = atan2(w[2], hypot(w[0], w[1])) / D2R;
		}
		ok(sep_mas(r0, d0, ra, dec) < 1e-4, "%g %g PA %g%s: the reference point is "
		   "on the pointing", ra, dec, pa, boresight ? " boresight" : "");
		is_near(remainder(pos_angle(r0, d0, r1, d1) - (pa + 60), 360), 0, 1e-6,
			"%g %g PA %g: +V3 at position angle pa + 60", ra, dec, pa);
		if (!boresight) {
			/* WFI01's +y_idl: its science +y less the Sci2Idl rotation */
			const struct geom_aperture *ap = geom_aperture(1);
			double rot = atan2(ap->sx[2], ap->sy[2]) / D2R;

			/* +x_idl is west of +y_idl: turning from +y_idl
			 * toward +x_idl lowers the position angle */
			is_near(remainder(sky.sca[0].pa + rot - pa, 360), 0, 1e-6,
				"%g %g PA %g: WFI01's +y_idl at position angle pa "
				"(its pixel +y %.4f deg off)", ra, dec, pa, rot);
			ok(sep_mas(sky.sca[0].ra, sky.sca[0].dec, ra, dec) < 1e-4,
			   "%g %g PA %g: WFI01's centre pixel on the pointing", ra, dec, pa);
		}
	}
	for (int s = 1; s <= WFS_NSCA; s++) {
		struct geom_sca *g = &sky.sca[s - 1].geo;
		char *cards = NULL, *pcards = NULL;
		int ncards = 0, nrej = 0, nwcs = 0, npc = 0, pnrej = 0, pnwcs = 0, row0 = 300 + s;
		struct wcsprm *w = NULL, *pw = NULL;
		double crpix1, crpix2, cd[4], det, cdi[4], apc[8][8], bpc[8][8];

		for (int k = 0; k < 300; k++) {
			double x = urand(-0.5, 4087.5), y = urand(-0.5, 4087.5);
			double r, d, px, py, r2, d2, j[4], h = 0.5;

			geom_pix_to_sky(g, x, y, &r, &d);
			geom_sky_to_pix(g, 1, &r, &d, &px, &py, &e);
			w_pix = fmax(w_pix, fmax(fabs(px - x), fabs(py - y)));
			geom_pix_to_sky(g, px, py, &r2, &d2);
			w_mas = fmax(w_mas, sep_mas(r, d, r2, d2));
			/* the Jacobian: ideal arcsec per pixel; the ideal frame
			 * is the tangent plane, so the sky's separations agree
			 * to (225")^2 ~ 1e-6 */
			geom_jacobian(g, x, y, j);
			for (int ax = 0; ax < 2; ax++) {
				double ra1, de1, ra2, de2, len;

				geom_pix_to_sky(g, x + (ax ? 0 : h), y + (ax ? h : 0), &ra1, &de1);
				geom_pix_to_sky(g, x - (ax ? 0 : h), y - (ax ? h : 0), &ra2, &de2);
				len = sep_mas(ra1, de1, ra2, de2) / 1000 / (2 * h);
				w_jac = fmax(w_jac, fabs(len / hypot(j[ax], j[2 + ax]) - 1));
			}
			if (k < 40) {
				double a = geom_area(g, x, y), row[3];
				int ix = (int)floor(x + 0.5), iy = (int)floor(y + 0.5);

				/* the per-row polynomial is the same area */
				geom_area_row(g, iy, ix - 1, 3, row);
				for (int q = 0; q < 3; q++)
					w_row = fmax(w_row, fabs(row[q] / geom_area(g, ix - 1 + q, iy) - 1));

				w_area = fmax(w_area, fabs(a / sky_area(g, x, y) - 1));
				amin = fmin(amin, a);
				amax = fmax(amax, a);
			}
		}
		if (geom_header(g, 0, &cards, &ncards, &e) < 0 ||
		    wcspih(cards, ncards, WCSHDR_all, 0, &nrej, &nwcs, &w) || nrej || nwcs != 1 ||
		    wcsset(w) || geom_header(g, row0, &pcards, &npc, &e) < 0 ||
		    wcspih(pcards, npc, WCSHDR_all, 0, &pnrej, &pnwcs, &pw) || pnrej ||
		    pnwcs != 1 || wcsset(pw)) {
			parsed = 0;
			diag("SCA %d: header not read: %s", s, e.msg);
			free(cards);
			free(pcards);
			continue;
		}
		sip_read(cards, ncards, "AP", apc);
		sip_read(cards, ncards, "BP", bpc);
		crpix1 = card_value(cards, ncards, "CRPIX1");
		crpix2 = card_value(cards, ncards, "CRPIX2");
		cd[0] = card_value(cards, ncards, "CD1_1");
		cd[1] = card_value(cards, ncards, "CD1_2");
		cd[2] = card_value(cards, ncards, "CD2_1");
		cd[3] = card_value(cards, ncards, "CD2_2");
		det = cd[0] * cd[3] - cd[1] * cd[2];
		cdi[0] = cd[3] / det;
		cdi[1] = -cd[1] / det;
		cdi[2] = -cd[2] / det;
		cdi[3] = cd[0] / det;
		for (int k = 0; k < 41 * 41 + 2000; k++) {
			double x = k < 41 * 41 ? -0.5 + 4088.0 * (k % 41) / 40 : urand(-0.5, 4087.5);
			double y = k < 41 * 41 ? -0.5 + 4088.0 * (k / 41) / 40 : urand(-0.5, 4087.5);
			double pix[2] = { x + 1, y + 1 }, img[2], phi, theta, world[2], r, d;
			double px, py, sc = 0.1033e3;   /* mas per pixel, the smallest scale */
			int st;

			geom_pix_to_sky(g, x, y, &r, &d);
			/* forward: the header's sky of the pixel */
			if (wcsp2s(w, 1, 2, pix, img, &phi, &theta, world, &st)) {
				w_fwd = INFINITY;
				continue;
			}
			w_fwd = fmax(w_fwd, sep_mas(world[0], world[1], r, d) / sc);
			/* inverse: wcslib's (it iterates on A/B) */
			world[0] = r;
			world[1] = d;
			if (wcss2p(w, 1, 2, world, &phi, &theta, img, pix, &st)) {
				w_inv = INFINITY;
				continue;
			}
			w_inv = fmax(w_inv, fmax(fabs(pix[0] - 1 - x), fabs(pix[1] - 1 - y)));
			/* the header's AP/BP: the intermediate pixel from wcslib's
			 * TAN step (img, degrees) through CD^-1, then the cards */
			{
				double U = cdi[0] * img[0] + cdi[1] * img[1];
				double V = cdi[2] * img[0] + cdi[3] * img[1];

				px = crpix1 + U + sip_eval(apc, U, V) - 1;
				py = crpix2 + V + sip_eval(bpc, U, V) - 1;
				w_ap = fmax(w_ap, fmax(fabs(px - x), fabs(py - y)));
			}
			/* the part's header maps (x, y - row0) like the SCA's (x, y) */
			if (k % 50 == 0) {
				pix[0] = x + 1;
				pix[1] = y + 1 - row0;
				if (wcsp2s(pw, 1, 2, pix, img, &phi, &theta, world, &st))
					w_part = INFINITY;
				else
					w_part = fmax(w_part, sep_mas(world[0], world[1], r, d) / sc);
			}
		}
		wcsvfree(&nwcs, &w);
		wcsvfree(&pnwcs, &pw);
		free(cards);
		free(pcards);
	}
	ok(w_pix < 1e-6, "%g %g PA %g: pixel -> sky -> pixel within 1e-6 px on all SCAs "
	   "(worst %.1e)", ra, dec, pa, w_pix);
	ok(w_mas < 0.1, "%g %g PA %g: sky -> pixel -> sky within 0.1 mas (worst %.1e mas)",
	   ra, dec, pa, w_mas);
	ok(w_jac < 1e-5, "%g %g PA %g: the Jacobian's scales match finite differences "
	   "on the sky (worst relative %.1e)", ra, dec, pa, w_jac);
	ok(w_area < 1e-5, "%g %g PA %g: pixel area matches the sky's (worst relative "
	   "%.1e; range %.4f-%.4f of 0.11\" squared)", ra, dec, pa, w_area, amin, amax);
	ok(w_row < 1e-12, "%g %g PA %g: geom_area_row is geom_area (worst relative %.1e)",
	   ra, dec, pa, w_row);
	ok(parsed, "%g %g PA %g: wcslib reads every SCA's TAN-SIP header", ra, dec, pa);
	ok(w_fwd < 0.005, "%g %g PA %g: SIP forward within 0.005 px (worst %.1e px)",
	   ra, dec, pa, w_fwd);
	ok(w_inv < 0.005, "%g %g PA %g: wcslib's inverse within 0.005 px (worst %.1e px)",
	   ra, dec, pa, w_inv);
	ok(w_ap < 0.005, "%g %g PA %g: the AP/BP inverse within 0.005 px (worst %.1e px)",
	   ra, dec, pa, w_ap);
	ok(w_part < 0.005, "%g %g PA %g: a --rows part's header within 0.005 px "
	   "(worst %.1e px)", ra, dec, pa, w_part);
	sky_free(&sky);
}

static void stips_area(void)
{
	struct err e = { 0 };
	struct sky sky;
	double j[4];

	if (!ok(sky_init(&sky, 10, 20, 30, 0, GEOM_STIPS, 1u << 4, &e) == 0, "stips: %s",
		e.msg))
		return;
	geom_jacobian(&sky.sca[4].geo, 100, 3000, j);
	ok(geom_area(&sky.sca[4].geo, 100, 3000) == 1.0 && j[0] == 0.11 && j[3] == 0.11 &&
	   j[1] == 0 && j[2] == 0, "stips: 0.11\" square pixels, relative area exactly 1");
	ok(sky.sca[4].half == SKY_SCA_HALF, "stips: the culling extent is the old constant");
	sky_free(&sky);
}

/* The sky Jacobian (geom_sky_jacobian) against central differences of
 * pixel -> sky on the tangent plane, and geom_sky_ellipse: the pixel
 * ellipse it returns, mapped back to the sky through that Jacobian, is the
 * sky ellipse (a, q, pa); in stips' square pixels re = a / 0.11" and
 * q stays; and its cost. */
static void sky_shapes(int kind)
{
	struct err e = { 0 };
	struct sky sky;
	double worst_j = 0, worst_a = 0, worst_q = 0, worst_pa = 0;
	const char *name = kind == GEOM_SIAF ? "siaf" : "stips";

	if (!ok(sky_init(&sky, 150, -60, 70, 0, kind, (1u << WFS_NSCA) - 1, &e) == 0,
		"%s: sky_init: %s", name, e.msg))
		return;
	srand(7);
	for (int n = 0; n < 400; n++) {
		struct geom_sca *g = &sky.sca[n % WFS_NSCA].geo;
		double x = urand(0, 4087), y = urand(0, 4087), k[4], f[4], ra, dec;
		double a = urand(0.05, 5), q = urand(0.05, 1), pa = urand(-180, 360);
		double re, ratio, phi;

		geom_sky_jacobian(g, x, y, k);
		geom_pix_to_sky(g, x, y, &ra, &dec);
		/* central differences of 0.5 px in the gnomonic plane at (ra, dec) */
		double c[3], e_[3] = { -sin(ra * D2R), cos(ra * D2R), 0 };
		double n_[3] = { -sin(dec * D2R) * cos(ra * D2R), -sin(dec * D2R) * sin(ra * D2R),
				 cos(dec * D2R) };
		unitv(ra, dec, c);
		for (int t = 0; t < 2; t++) {
			double p[2][2], v[3];
			for (int sg = 0; sg < 2; sg++) {
				double r2, d2, h = sg ? -0.5 : 0.5;
				geom_pix_to_sky(g, x + (t ? 0 : h), y + (t ? h : 0), &r2, &d2);
				unitv(r2, d2, v);
				double w = v[0] * c[0] + v[1] * c[1] + v[2] * c[2];
				p[sg][0] = (v[0] * e_[0] + v[1] * e_[1] + v[2] * e_[2]) / w / AS2R;
				p[sg][1] = (v[0] * n_[0] + v[1] * n_[1] + v[2] * n_[2]) / w / AS2R;
			}
			f[t] = p[0][0] - p[1][0];
			f[2 + t] = p[0][1] - p[1][1];
		}
		for (int i = 0; i < 4; i++)
			worst_j = fmax(worst_j, fabs(k[i] - f[i]) / 0.11);
		geom_sky_ellipse(g, x, y, a, q, pa, &re, &ratio, &phi);
		/* the major axis in pixels, (-sin phi, cos phi) re, back on the sky */
		double px = -sin(phi * D2R) * re, py = cos(phi * D2R) * re;
		double E = k[0] * px + k[1] * py, N = k[2] * px + k[3] * py;
		double qx = -cos(phi * D2R) * re * ratio, qy = -sin(phi * D2R) * re * ratio;
		double E2 = k[0] * qx + k[1] * qy, N2 = k[2] * qx + k[3] * qy;
		/* the sky ellipse's shape matrix from the two conjugate
		 * semi-diameters, compared with a^2 v v' + b^2 w w' */
		double s11 = E * E + E2 * E2, s12 = E * N + E2 * N2, s22 = N * N + N2 * N2;
		double vE = sin(pa * D2R), vN = cos(pa * D2R), b = q * a;
		double t11 = a * a * vE * vE + b * b * vN * vN, t12 = (a * a - b * b) * vE * vN;
		double t22 = a * a * vN * vN + b * b * vE * vE;
		worst_a = fmax(worst_a, fmax(fabs(s11 - t11), fmax(fabs(s12 - t12),
					     fabs(s22 - t22))) / (a * a));
		if (kind == GEOM_STIPS) {
			worst_q = fmax(worst_q, fabs(ratio - q));
			worst_pa = fmax(worst_pa, fabs(re * 0.11 - a) / a);
		}
	}
	diag("%s: sky Jacobian %.1e of 0.11\" from differences; ellipse back on the sky "
	     "%.1e of a^2", name, worst_j, worst_a);
	ok(worst_j < 1e-7, "%s: the sky Jacobian is the derivative of pixel -> sky", name);
	ok(worst_a < 1e-9, "%s: the pixel ellipse is the sky ellipse through it", name);
	if (kind == GEOM_STIPS)
		/* the TAN projection about the SCA's centre scales by up to
		 * 1 / cos^2 of the 0.06 deg to its corner, 1e-6 */
		ok(worst_q < 1e-5 && worst_pa < 1e-5, "stips: square 0.11\" pixels keep q "
		   "(%.1e) and re = a / 0.11 (%.1e) to the projection's 1e-6", worst_q,
		   worst_pa);
	if (kind == GEOM_SIAF) {
		struct timespec t0, t1;
		double re, ratio, phi, sum = 0;
		clock_gettime(CLOCK_MONOTONIC, &t0);
		for (int n = 0; n < 100000; n++) {
			geom_sky_ellipse(&sky.sca[n % WFS_NSCA].geo, n % 4088, (n * 7) % 4088,
					 1, 0.5, n % 360, &re, &ratio, &phi);
			sum += re;
		}
		clock_gettime(CLOCK_MONOTONIC, &t1);
		diag("geom_sky_ellipse: %.0f ns a call (%g)", ((t1.tv_sec - t0.tv_sec) * 1e9 +
		     (t1.tv_nsec - t0.tv_nsec)) / 1e5, sum > 0 ? 1.0 : 0.0);
	}
	sky_free(&sky);
}

int main(void)
{
	struct err e = { 0 };

	if (instrument_init(&e) < 0 || geom_init(&e) < 0)
		return printf("# %s\n", e.msg), 1;
	ok(geom_parse("SIAF") == GEOM_SIAF && geom_parse("stips") == GEOM_STIPS &&
	   geom_parse("tan") < 0, "geometry names");
	inverse();
	pointing(10, 20, 0, 0, 1);
	pointing(200, -35, 217, 1, 2);
	pointing(45, 89.9, 30, 0, 3);
	pointing(300, -89.95, 300, 1, 4);
	pointing(0.05, 0, 10, 0, 5);
	stips_area();
	sky_shapes(GEOM_SIAF);
	sky_shapes(GEOM_STIPS);
	return done_testing();
}
