/*
 * sky_wcs.c - the WCS header that each image HDU carries (the cards of
 * sky_header(), copied verbatim into the output by image_cards()) read
 * back with wcslib's own header parser, wcspih(), must be the mapping that
 * placed the sources: for every SCA of several pointings (position angles,
 * the boresight reference, near both poles, across RA 0/360), pixels taken
 * to the sky through the parsed header come back through sky_to_pixel() to
 * within 1e-6 pixel; the pixel scales are 0.11" (stips) or the SIAF's
 * linear terms (siaf), the parity standard (east to the left of north,
 * less the SIAF's skew of the pixel axes), and +y points at the position angle the header's
 * PA_APER records.  The header of a --rows part (CRPIX2 counted from its
 * first row) maps its pixel (x, y - row0) as the SCA's (x, y).
 * Both geometries.  t4101-wcs.sh does the same through astropy.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <wcslib/wcs.h>
#include <wcslib/wcshdr.h>

#include "tap.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "sky.h"

#define D2R (M_PI / 180.0)

/* Angular separation (degrees) and position angle east of north (degrees)
 * of (ra2, dec2) seen from (ra1, dec1). */
static double separation(double ra1, double dec1, double ra2, double dec2)
{
	double a = sin((dec2 - dec1) * D2R / 2), b = sin((ra2 - ra1) * D2R / 2);
	double h = a * a + cos(dec1 * D2R) * cos(dec2 * D2R) * b * b;

	return 2 * asin(sqrt(h)) / D2R;
}

static double pos_angle(double ra1, double dec1, double ra2, double dec2)
{
	double dra = (ra2 - ra1) * D2R;
	double y = sin(dra) * cos(dec2 * D2R);
	double x = cos(dec1 * D2R) * sin(dec2 * D2R) -
		   sin(dec1 * D2R) * cos(dec2 * D2R) * cos(dra);

	return atan2(y, x) / D2R;
}

/* The position angle at (r0, d0) of the direction toward (r1, d1), the
 * point one step forward, averaged with that toward (r2, d2), one step back,
 * turned by 180 degrees. */
static double mean_bearing(double r0, double d0, double r1, double d1, double r2,
			   double d2)
{
	double a = pos_angle(r0, d0, r1, d1), b = pos_angle(r0, d0, r2, d2) + 180;

	return a + remainder(b - a, 360) / 2;
}

/* pixel (1-based, FITS) to sky through a parsed header */
static int p2s(struct wcsprm *w, double x, double y, double *ra, double *dec)
{
	double pix[2] = { x, y }, img[2], phi, theta, world[2];
	int stat;

	if (wcsp2s(w, 1, 2, pix, img, &phi, &theta, world, &stat))
		return -1;
	*ra = world[0];
	*dec = world[1];
	return 0;
}

static void pointing(double ra, double dec, double pa, int boresight,
		     int geometry, unsigned seed)
{
	const char *gn = geom_name(geometry);
	struct err e = { 0 };
	struct sky sky;
	double worst = 0, worst_scale = 0, worst_pa = 0, worst_part = 0;
	int parity_ok = 1, parsed_ok = 1;

	if (!ok(sky_init(&sky, ra, dec, pa, boresight, geometry, (1u << WFS_NSCA) - 1,
			 &e) == 0, "sky_init %g %g %g: %s", ra, dec, pa, e.msg))
		return;
	srand(seed);
	for (int s = 1; s <= WFS_NSCA; s++) {
		char *cards = NULL, *pcards = NULL;
		int ncards = 0, nrej = 0, nwcs = 0, npcards = 0, pnrej = 0, pnwcs = 0;
		/* the header of a --rows part starting at 0-based row row0 */
		int row0 = 500 + 37 * s;
		struct wcsprm *w = NULL, *pw = NULL;

		if (sky_header(&sky, s, 0, &cards, &ncards, &e) < 0 ||
		    wcspih(cards, ncards, WCSHDR_all, 0, &nrej, &nwcs, &w) ||
		    nrej != 0 || nwcs != 1 || wcsset(w) ||
		    sky_header(&sky, s, row0, &pcards, &npcards, &e) < 0 ||
		    wcspih(pcards, npcards, WCSHDR_all, 0, &pnrej, &pnwcs, &pw) ||
		    pnrej != 0 || pnwcs != 1 || wcsset(pw)) {
			parsed_ok = 0;
			diag("SCA %d: header not parsed (%d rejected, %d WCS)", s,
			     nrej, nwcs);
			free(cards);
			free(pcards);
			if (w)
				wcsvfree(&nwcs, &w);
			if (pw)
				wcsvfree(&pnwcs, &pw);
			continue;
		}
		free(cards);
		free(pcards);
		/* pixels over the detector and a little beyond its edges */
		for (int k = 0; k < 60; k++) {
			double x = -50 + 4188.0 * rand() / RAND_MAX;
			double y = -50 + 4188.0 * rand() / RAND_MAX;
			double r, d, px, py;

			if (p2s(w, x + 1, y + 1, &r, &d) ||
			    sky_to_pixel(&sky, s, 1, &r, &d, &px, &py, &e) < 0) {
				worst = INFINITY;
				continue;
			}
			worst = fmax(worst, fmax(fabs(px - x), fabs(py - y)));
			/* the part's pixel (x, y - row0) is the SCA's (x, y) */
			if (p2s(pw, x + 1, y + 1 - row0, &r, &d) ||
			    sky_to_pixel(&sky, s, 1, &r, &d, &px, &py, &e) < 0) {
				worst_part = INFINITY;
				continue;
			}
			worst_part = fmax(worst_part, fmax(fabs(px - x), fabs(py - y)));
		}
		/* scale, parity and orientation at the centre: 0.11" square
		 * pixels for stips; the SIAF's linear terms for siaf, whose
		 * axes are a fraction of a degree from square */
		const struct geom_aperture *ap = geom_aperture(s);
		double sxs = geometry == GEOM_STIPS ? 0.11 : hypot(ap->sx[1], ap->sy[1]);
		double sys = geometry == GEOM_STIPS ? 0.11 : hypot(ap->sx[2], ap->sy[2]);
		double skew = geometry == GEOM_STIPS ? 0 :
			(atan2(ap->sx[2], ap->sy[2]) + atan2(ap->sy[1], ap->sx[1])) / D2R;
		double r0 = 0, d0 = 0, rx = 0, dx = 0, ry = 0, dy = 0;
		/* centred differences: the SIAF's quadratic terms cancel in the
		 * scale and in the mean of the bearings from the centre toward
		 * +1 and (turned by 180 degrees) toward -1 pixel */
		p2s(w, 2044.5, 2044.5, &r0, &d0);
		p2s(w, 2045.5, 2044.5, &rx, &dx);
		p2s(w, 2043.5, 2044.5, &ry, &dy);
		worst_scale = fmax(worst_scale,
				   fabs(separation(ry, dy, rx, dx) * 3600 / 2 / sxs - 1));
		double pax = mean_bearing(r0, d0, rx, dx, ry, dy);
		p2s(w, 2044.5, 2045.5, &rx, &dx);
		p2s(w, 2044.5, 2043.5, &ry, &dy);
		worst_scale = fmax(worst_scale,
				   fabs(separation(ry, dy, rx, dx) * 3600 / 2 / sys - 1));
		double pay = mean_bearing(r0, d0, rx, dx, ry, dy);
		/* standard parity: +x is 90 degrees clockwise of +y on the sky
		 * (north up, east left: +y north, +x west), less the skew */
		double turn = remainder(pax - pay, 360);
		if (fabs(turn + 90 - skew) > 1e-4) {
			parity_ok = 0;
			diag("SCA %d: +x is %.6f deg from +y (skew %.6f)", s, turn, skew);
		}
		worst_pa = fmax(worst_pa, fabs(remainder(pay - sky.sca[s - 1].pa, 360)));
		wcsvfree(&nwcs, &w);
		wcsvfree(&pnwcs, &pw);
	}
	ok(parsed_ok, "%s %g %g PA %g%s: wcspih reads every SCA's header", gn, ra, dec, pa,
	   boresight ? " boresight" : "");
	ok(worst < 1e-6, "%s %g %g PA %g: header pixel -> sky -> placement within "
	   "1e-6 px (worst %.2e)", gn, ra, dec, pa, worst);
	ok(worst_part < 1e-6, "%s %g %g PA %g: a --rows part's header, from its first "
	   "row, within 1e-6 px (worst %.2e)", gn, ra, dec, pa, worst_part);
	ok(worst_scale < 1e-7, "%s %g %g PA %g: the pixel scales at the centre "
	   "(worst relative error %.1e)", gn, ra, dec, pa, worst_scale);
	ok(parity_ok, "%s %g %g PA %g: standard parity, +x 90 deg clockwise of +y",
	   gn, ra, dec, pa);
	ok(worst_pa < 1e-6, "%s %g %g PA %g: +y at the SCA's recorded position "
	   "angle (worst %.1e deg)", gn, ra, dec, pa, worst_pa);
	sky_free(&sky);
}

int main(void)
{
	struct err e = { 0 };

	if (instrument_init(&e) < 0)
		return printf("# %s\n", e.msg), 1;
	for (int g = GEOM_SIAF; g <= GEOM_STIPS; g++) {
		pointing(10, 20, 0, 0, g, 1);
		pointing(10, 20, 90, 0, g, 2);
		pointing(200, -35, 217, 1, g, 3);
		pointing(45, 89.9, 30, 0, g, 4);
		pointing(300, -89.95, 300, 0, g, 5);
		pointing(0.05, 0, 10, 0, g, 6);
	}
	return done_testing();
}
