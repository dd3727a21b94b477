/*
 * background_sky.c - the per-SCA background model of background.c from the
 * embedded tables (data/zodi.tsv, data/background.tsv), without ../shared:
 *  - each filter's SCA responses average to 1 and span a few per cent;
 *  - the Project normalisation puts the mean SCA at exactly the Project's
 *    minimum rate where the table has its minimum, and the etc one at the
 *    table times 3.960 m^2 times a 0.11" pixel; the thermal part is the
 *    filter's Project rate (F213 4.38, F062 0.003);
 *  - positions are built from ecliptic coordinates relative to the Sun by
 *    this test's own rotation, so the code's ecliptic conversion and Sun
 *    are checked too: the table is symmetric in latitude and in longitude
 *    from the Sun; at grid nodes the value is the node's; half-way it is
 *    the mean of the neighbours;
 *  - the Sun angle is 90 degrees at the ecliptic pole at any date;
 *  - directions the table marks as too near the Sun are refused with a
 *    message naming the angles;
 *  - 'avg' per SCA keeps STIPS's number as the mean over the SCAs and
 *    stays uniform for F213, whose number is below the thermal rate.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "background.h"
#include "data.h"
#include "ephem.h"
#include "err.h"
#include "instrument.h"

#define D2R (M_PI / 180.0)

/* RA and Dec of ecliptic (J2000) longitude lon and latitude lat. */
static void equatorial(double lon, double lat, double *ra, double *dec)
{
	double e = EPHEM_OBLIQUITY_J2000 * D2R, l = lon * D2R, b = lat * D2R;
	double x = cos(b) * cos(l), y = cos(b) * sin(l), z = sin(b);
	double ye = cos(e) * y - sin(e) * z, ze = sin(e) * y + cos(e) * z;

	*ra = atan2(ye, x) / D2R;
	if (*ra < 0)
		*ra += 360;
	*dec = asin(ze) / D2R;
}

/* The background of SCA sca at latitude lat and longitude dlon from the
 * Sun at mjd. */
static int at(int f, int sca, double lat, double dlon, double mjd, int norm,
	      struct bkg_part *p, struct err *e)
{
	struct sun s;
	double ra, dec;

	ephem_sun(mjd, &s);
	equatorial(s.lon + dlon, lat, &ra, &dec);
	return background_sky(f, sca, ra, dec, mjd, norm, p, e);
}

/* Mean over the 18 SCAs of the zodiacal part. */
static double mean_zodi(int f, double lat, double dlon, double mjd, int norm)
{
	struct bkg_part p;
	struct err e = { 0 };
	double sum = 0;

	for (int s = 1; s <= WFS_NSCA; s++) {
		if (at(f, s, lat, dlon, mjd, norm, &p, &e) < 0)
			return NAN;
		sum += p.zodi;
	}
	return sum / WFS_NSCA;
}

int main(void)
{
	struct err e = { 0 };
	struct bkg_part p, q;
	struct tsv t;
	double mjd = 61234.5;   /* 2026-08-20 */
	int F129 = filter_lookup("F129"), F213 = filter_lookup("F213");
	int F062 = filter_lookup("F062");

	if (background_init(&e) < 0) {
		printf("Bail out! %s\n", e.msg);
		return 1;
	}
	for (int f = 0; f < WFS_NFILTER; f++) {
		double sum = 0, lo = 9, hi = 0;

		for (int s = 1; s <= WFS_NSCA; s++) {
			double r = background_r_sca(f, s);

			sum += r;
			lo = fmin(lo, r);
			hi = fmax(hi, r);
		}
		is_near(sum / WFS_NSCA, 1, 1e-4, "%s: SCA responses average to 1",
			filter_get(f)->name);
		ok(lo > 0.85 && hi < 1.15 && hi - lo > 0.03, "%s: they span %.3f-%.3f",
		   filter_get(f)->name, lo, hi);
	}
	is_near(background_thermal(F213), 4.38, 1e-12, "F213 thermal 4.38 e-/s/pixel");
	is_near(background_thermal(F062), 0.003, 1e-12, "F062 thermal 0.003 e-/s/pixel");

	/* The table's F129 minimum is at the node lat 77.3196, dlon 152. */
	is_near(mean_zodi(F129, 77.3196, 152, mjd, BKG_NORM_PROJECT), 0.267, 1e-5,
		"F129 project: the mean SCA at the table's minimum is the Project's 0.267");
	is_near(mean_zodi(F129, 77.3196, -152, mjd + 182.6, BKG_NORM_ETC),
		27.1613 * 3.960 * 0.0121, 1e-4,
		"F129 etc: the same node, six months later, is 27.1613 x 3.960 x 0.0121");

	/* Symmetries, and the nodes of the embedded table. */
	if (tsv_parse(&t, "zodi.tsv") < 0) {
		printf("Bail out! no zodi.tsv\n");
		return 1;
	}
	{
		int c = tsv_col(&t, "F129"), worst = 0;
		double maxerr = 0;

		for (int r = 1; r < t.nrow; r += 37) {
			double lat = atof(t.cell[r][0]), dlon = atof(t.cell[r][1]);
			double v = atof(t.cell[r][c]);

			if (v < 0 || fabs(lat) > 89.9)
				continue;
			if (at(F129, 7, lat, dlon, mjd, BKG_NORM_ETC, &p, &e) < 0) {
				worst = r;
				break;
			}
			maxerr = fmax(maxerr, fabs(p.table / v - 1));
		}
		ok(!worst && maxerr < 1e-4, "at table nodes the value is the node's (worst %.2g)%s%s",
		   maxerr, worst ? ": " : "", worst ? e.msg : "");
		err_clear(&e);
	}
	tsv_free(&t);
	at(F129, 3, 30, 70, mjd, BKG_NORM_PROJECT, &p, &e);
	at(F129, 3, -30, -70, mjd, BKG_NORM_PROJECT, &q, &e);
	is_near(q.total, p.total, 1e-6 * p.total, "symmetric in latitude and longitude from the Sun");
	is_near(p.ecl_lat, 30, 1e-6, "ecliptic latitude 30 recovered");
	is_near(p.dlon, 70, 0.001, "longitude from the Sun 70 recovered");
	is_near(p.total, p.zodi + p.thermal, 1e-12, "total is zodi + thermal");
	is_near(p.zodi, p.table * p.scale * p.r_sca, 1e-12, "zodi is table x scale x r_sca");
	/* Half-way between the latitude nodes 19.9661 and 21.4601 (sin 14/41,
	 * 15/41) and the longitude nodes 88 and 92: the mean of the four. */
	{
		double b = asin(14.5 / 41) / D2R, v[4];

		at(F129, 1, b, 90, mjd, BKG_NORM_ETC, &p, &e);
		at(F129, 1, asin(14.0 / 41) / D2R, 88, mjd, BKG_NORM_ETC, &q, &e); v[0] = q.table;
		at(F129, 1, asin(15.0 / 41) / D2R, 88, mjd, BKG_NORM_ETC, &q, &e); v[1] = q.table;
		at(F129, 1, asin(14.0 / 41) / D2R, 92, mjd, BKG_NORM_ETC, &q, &e); v[2] = q.table;
		at(F129, 1, asin(15.0 / 41) / D2R, 92, mjd, BKG_NORM_ETC, &q, &e); v[3] = q.table;
		is_near(p.table, (v[0] + v[1] + v[2] + v[3]) / 4, 1e-4 * p.table,
			"half-way between nodes: the mean of the four (%.4f)", p.table);
	}
	/* The ecliptic pole is 90 degrees from the Sun at every date. */
	for (double m = 60500; m < 62000; m += 123.4)
		is_near(background_sun_angle(270, 66.560708, m), 90, 0.01,
			"MJD %.1f: the north ecliptic pole is 90 degrees from the Sun", m);
	/* Too close to the Sun for the table. */
	err_clear(&e);
	ok(at(F129, 5, 2, 6, mjd, BKG_NORM_PROJECT, &p, &e) < 0 && e.code == EXIT_INPUT,
	   "latitude 2, 6 degrees from the Sun is refused");
	ok(strstr(e.msg, "WFI05") && strstr(e.msg, "degrees from the Sun") &&
	   strstr(e.msg, "no value"), "its message names the SCA and the angle: %s", e.msg);
	err_clear(&e);
	ok(at(F129, 5, 20, 0, mjd, BKG_NORM_PROJECT, &p, &e) == 0,
	   "latitude 20 straight above the Sun has a value (%.1f)", p.table);

	/* avg */
	for (int f = 0; f < WFS_NFILTER; f++) {
		double sum = 0, lo = 1e9, hi = 0;

		for (int s = 1; s <= WFS_NSCA; s++) {
			background_avg(f, s, &p);
			sum += p.total;
			lo = fmin(lo, p.total);
			hi = fmax(hi, p.total);
		}
		is_near(sum / WFS_NSCA, filter_get(f)->bkg_avg, 1e-4,
			"%s avg: the mean over the SCAs is STIPS's %.2f", filter_get(f)->name,
			filter_get(f)->bkg_avg);
		if (f == F213)
			ok(lo == hi, "F213 avg is one number on every SCA");
		else
			ok(hi > lo * 1.02, "%s avg differs between SCAs (%.3f-%.3f)",
			   filter_get(f)->name, lo, hi);
	}
	return done_testing();
}
