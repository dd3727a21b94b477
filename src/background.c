/* background.c - zodiacal light, thermal glow and STIPS's numbers per SCA;
 * see background.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "background.h"
#include "data.h"
#include "date.h"
#include "ephem.h"
#include "err.h"
#include "instrument.h"

/* The table's grid: sin(beta) = i / (NLAT - 1), dlon = DLON j degrees. */
#define NLAT 42
#define NLON 46
#define DLON 4.0

/* A nominal 0.11" pixel, arcsec^2. */
#define PIX_AREA (WFS_PIXSCALE * WFS_PIXSCALE)

/* Filled once by background_init() before any thread starts, read-only
 * afterwards: the tables are constants of the build. */
static struct {
	float zodi[NLON][NLAT];         /* table units; < 0 too near the Sun */
	double zodi_min, thermal, etc_min;
	double r[WFS_NSCA];
} tab[WFS_NFILTER];
static int loaded;

static int broken(struct tsv *t, struct err *e, const char *what)
{
	tsv_free(t);
	return err_set(e, EXIT_SYSTEM, "broken build: %s", what);
}

int background_init(struct err *e)
{
	struct tsv t;
	int col[WFS_NFILTER], cr[WFS_NSCA];

	if (loaded)
		return 0;
	if (instrument_init(e) < 0)
		return -1;
	if (tsv_parse(&t, "zodi.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "broken build: no zodi.tsv table");
	if (t.nrow != 1 + NLAT * NLON)
		return broken(&t, e, "zodi.tsv is not a 42 x 46 grid");
	for (int f = 0; f < WFS_NFILTER; f++)
		if ((col[f] = tsv_col(&t, filter_get(f)->name)) < 0)
			return broken(&t, e, "zodi.tsv lacks a filter");
	for (int k = 0; k < NLAT * NLON; k++)
		for (int f = 0; f < WFS_NFILTER; f++)
			tab[f].zodi[k / NLAT][k % NLAT] = (float)atof(t.cell[1 + k][col[f]]);
	tsv_free(&t);

	if (tsv_parse(&t, "background.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "broken build: no background.tsv table");
	{
		int cf = tsv_col(&t, "filter"), cz = tsv_col(&t, "zodi_min");
		int ct = tsv_col(&t, "thermal"), ce = tsv_col(&t, "etc_min"), seen = 0;

		for (int s = 0; s < WFS_NSCA; s++) {
			char name[8];

			snprintf(name, sizeof(name), "r_%02d", s + 1);
			if ((cr[s] = tsv_col(&t, name)) < 0)
				return broken(&t, e, "background.tsv lacks an SCA");
		}
		if (cf < 0 || cz < 0 || ct < 0 || ce < 0)
			return broken(&t, e, "background.tsv lacks a column");
		for (int r = 1; r < t.nrow; r++) {
			int f = filter_lookup(t.cell[r][cf]);

			if (f < 0)
				continue;
			tab[f].zodi_min = atof(t.cell[r][cz]);
			tab[f].thermal = atof(t.cell[r][ct]);
			tab[f].etc_min = atof(t.cell[r][ce]);
			for (int s = 0; s < WFS_NSCA; s++)
				tab[f].r[s] = atof(t.cell[r][cr[s]]);
			seen |= 1 << f;
		}
		if (seen != (1 << WFS_NFILTER) - 1)
			return broken(&t, e, "background.tsv lacks a filter");
	}
	tsv_free(&t);
	loaded = 1;
	return 0;
}

int background_norm_parse(const char *s)
{
	return !strcasecmp(s, "project") ? BKG_NORM_PROJECT :
	       !strcasecmp(s, "etc") ? BKG_NORM_ETC : -1;
}

const char *background_norm_name(int norm)
{
	return norm == BKG_NORM_ETC ? "etc" : "project";
}

double background_thermal(int f)
{
	return tab[f].thermal;
}

double background_r_sca(int f, int sca)
{
	return tab[f].r[sca - 1];
}

double background_sun_angle(double ra, double dec, double mjd)
{
	struct sun s;

	ephem_sun(mjd, &s);
	return ephem_separation(ra, dec, s.ra, s.dec);
}

/*
 * Bilinear interpolation in (41 sin|beta|, |dlon| / 4), the coordinates in
 * which the grid is uniform; the table is symmetric in beta and in dlon.
 * *marked is set when a node with weight in the result is one the table
 * marks as too near the Sun.
 */
static double table_at(int f, double beta, double dlon, int *marked)
{
	double x = (NLAT - 1) * sin(fabs(beta) * M_PI / 180), y = fabs(dlon) / DLON;
	int i = (int)floor(x), j = (int)floor(y);
	double fx, fy, w[4], v[4], sum = 0;

	i = i < 0 ? 0 : i > NLAT - 2 ? NLAT - 2 : i;
	j = j < 0 ? 0 : j > NLON - 2 ? NLON - 2 : j;
	fx = x - i;
	fy = y - j;
	w[0] = (1 - fx) * (1 - fy);
	w[1] = fx * (1 - fy);
	w[2] = (1 - fx) * fy;
	w[3] = fx * fy;
	v[0] = tab[f].zodi[j][i];
	v[1] = tab[f].zodi[j][i + 1];
	v[2] = tab[f].zodi[j + 1][i];
	v[3] = tab[f].zodi[j + 1][i + 1];
	*marked = 0;
	for (int k = 0; k < 4; k++) {
		if (w[k] > 0 && v[k] < 0)
			*marked = 1;
		sum += w[k] * v[k];
	}
	return sum;
}

int background_sky(int f, int sca, double ra, double dec, double mjd, int norm,
		   struct bkg_part *p, struct err *e)
{
	struct sun s;
	int marked;

	ephem_sun(mjd, &s);
	ephem_ecliptic(ra, dec, &p->ecl_lon, &p->ecl_lat);
	p->dlon = fmod(p->ecl_lon - s.lon, 360.0);
	if (p->dlon > 180)
		p->dlon -= 360;
	else if (p->dlon <= -180)
		p->dlon += 360;
	p->sun_angle = ephem_separation(ra, dec, s.ra, s.dec);
	p->table = table_at(f, p->ecl_lat, p->dlon, &marked);
	if (marked)
		return err_set(e, EXIT_INPUT, "WFI%02d (ra %.4f, dec %.4f) is %.1f degrees from "
			       "the Sun (ecliptic latitude %.1f, longitude %.1f from the Sun): "
			       "the zodiacal light table has no value that close to the Sun",
			       sca, ra, dec, p->sun_angle, p->ecl_lat, p->dlon);
	p->scale = norm == BKG_NORM_ETC ? BKG_ETC_AREA * PIX_AREA :
		   tab[f].zodi_min / tab[f].etc_min;
	p->r_sca = tab[f].r[sca - 1];
	p->zodi = p->table * p->scale * p->r_sca;
	p->thermal = tab[f].thermal;
	p->total = p->zodi + p->thermal;
	return 0;
}

void background_avg(int f, int sca, struct bkg_part *p)
{
	double avg = filter_get(f)->bkg_avg, th = tab[f].thermal;

	p->table = p->scale = p->ecl_lon = p->ecl_lat = p->dlon = p->sun_angle = NAN;
	p->r_sca = tab[f].r[sca - 1];
	if (avg >= th) {
		p->thermal = th;
		p->zodi = (avg - th) * p->r_sca;
	} else {
		/* Not separable: Table 1's number as it is. */
		p->thermal = avg;
		p->zodi = 0;
		p->r_sca = 1;
	}
	p->total = p->zodi + p->thermal;
}

int background_exposure(struct bkg_exposure *b, int model, double number, int f,
			double mjd, int norm, int allow_sun, const double *ra,
			const double *dec, double bra, double bdec, struct err *e)
{
	char when[32];

	b->model = model;
	b->norm = norm;
	b->mjd = mjd;
	b->sun_angle = NAN;
	b->least = INFINITY;
	if (!isnan(mjd)) {
		date_format(mjd, when, sizeof(when));
		b->sun_angle = background_sun_angle(bra, bdec, mjd);
		if (!allow_sun && !(b->sun_angle >= BKG_SUN_MIN && b->sun_angle <= BKG_SUN_MAX))
			return err_set(e, EXIT_INPUT, "the boresight (ra %.4f, dec %.4f) is %.1f "
				       "degrees from the Sun on %s: Roman points %g-%g degrees "
				       "from it (--allow-sun-angle simulates it anyway)", bra, bdec,
				       b->sun_angle, when, BKG_SUN_MIN, BKG_SUN_MAX);
	} else if (model == BKG_SKY) {
		return err_set(e, EXIT_INPUT, "--background sky needs a date (--date, or a date "
			       "column in --pointings): the Sun's place sets the zodiacal light");
	}
	for (int s = 0; s < WFS_NSCA; s++) {
		struct bkg_part *p = &b->sca[s];

		switch (model) {
		case BKG_SKY:
			if (background_sky(f, s + 1, ra[s], dec[s], mjd, norm, p, e) < 0)
				return -1;
			break;
		case BKG_AVG:
			background_avg(f, s + 1, p);
			break;
		default:
			*p = (struct bkg_part){ .total = model == BKG_NUMBER ? number : 0,
						.zodi = NAN, .thermal = NAN,
						.r_sca = NAN, .table = NAN, .scale = NAN,
						.ecl_lon = NAN, .ecl_lat = NAN, .dlon = NAN,
						.sun_angle = NAN };
			break;
		}
		b->least = fmin(b->least, p->total);
	}
	return 0;
}
