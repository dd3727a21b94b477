/*
 * background.h - the sky and instrument background of an exposure, per SCA:
 * zodiacal light from where the SCA looks and when, the telescope's own
 * thermal glow, and STIPS's fixed per-filter numbers.
 *
 * The model (wfiscene(1), BACKGROUND):
 *
 *   B_sca = Z(beta, dlon) r_sca + T
 *
 * Z is the zodiacal light at the SCA centre's ecliptic latitude beta and
 * ecliptic longitude from the Sun dlon, interpolated bilinearly in the
 * exposure time calculator's table (data/zodi.tsv, in 41 sin|beta| and
 * |dlon| / 4, as the table is laid out) and normalised one of two ways:
 *
 *   project (default): Z = zodi_min * table / table_min, the Roman
 *     Project's count rate at minimum zodiacal light (2024) carried over the
 *     sky by the table's shape;
 *   etc: Z = table * 3.960 m^2 * 0.0121 arcsec^2, the table's own scale
 *     (GalSim's collecting area, pi/4 2.37^2 (1 - 0.32^2), and a 0.11"
 *     pixel), about 4.9 times the Project's.
 *
 * r_sca is the SCA's response to zodiacal light relative to the mean of the
 * 18 (data/background.tsv: 0.93-1.11) and T the Project's internal thermal
 * rate of the filter.  Rates are e-/s per nominal 0.11" pixel; a geometry
 * whose pixels are smaller scales the zodiacal part by the pixel's area.
 *
 * The zodiacal light changes by at most 1.1 % across an SCA (0.2 % median)
 * and 4.8 % across the field (1.3 % median) over the sky Roman can see
 * (contrib/tables/derive_sky.py), so one value per SCA centre is kept.
 */
#ifndef WFS_BACKGROUND_H
#define WFS_BACKGROUND_H

struct err;

#include "instrument.h"

/* What --background asked for. */
enum bkg_model {
	BKG_NONE,               /* no background */
	BKG_NUMBER,             /* one number for every SCA */
	BKG_AVG,                /* STIPS paper Table 1, per SCA (background_avg) */
	BKG_SKY,                /* zodiacal light by position and date + thermal */
};

enum bkg_norm { BKG_NORM_PROJECT, BKG_NORM_ETC };

/* Roman may point only this far from the Sun (degrees): the solar panels'
 * limit, 36 degrees either side of perpendicular. */
#define BKG_SUN_MIN 54.0
#define BKG_SUN_MAX 126.0

/* GalSim's Roman collecting area for the ETC table, m^2. */
#define BKG_ETC_AREA 3.960

/* One SCA's background and its parts. */
struct bkg_part {
	double total;           /* e-/s/pixel: zodi + thermal */
	/* BKG_AVG and BKG_SKY (NaN for a number or none): */
	double zodi;            /* zodiacal light through this SCA's response */
	double thermal;         /* internal thermal */
	double r_sca;           /* the SCA's response relative to the mean */
	/* BKG_SKY only (NaN otherwise): */
	double table;           /* the table at the position, e-/s/m^2/arcsec^2 */
	double scale;           /* e-/s/pixel per table unit (the normalisation) */
	double ecl_lon, ecl_lat;/* J2000 ecliptic coordinates of the centre, deg */
	double dlon;            /* ecliptic longitude from the Sun, (-180, 180] */
	double sun_angle;       /* degrees from the Sun */
};

/* Load the tables once.  0 or -1 (a broken build). */
int background_init(struct err *e);

/* "project" or "etc" to enum bkg_norm; -1 if neither. */
int background_norm_parse(const char *s);
const char *background_norm_name(int norm);

/* The angle (degrees) between (ra, dec) and the Sun at mjd. */
double background_sun_angle(double ra, double dec, double mjd);

/*
 * The sky background of SCA sca (1..18) in filter f for an SCA centred at
 * (ra, dec) at mjd, normalised by norm.  Positions the table marks as too
 * close to the Sun (only reachable with the Sun-angle check overridden)
 * are refused: -1 with a message naming the angles.  Returns 0 or -1.
 */
int background_sky(int f, int sca, double ra, double dec, double mjd, int norm,
		   struct bkg_part *p, struct err *e);

/*
 * STIPS's 'avg' (the STIPS paper's Table 1, one number per filter for a
 * benchmark pointing) made per SCA where it can be: the part of it above
 * the Project's thermal rate is taken as zodiacal light and scaled by r_sca;
 * the thermal part is kept.  Where the Table 1 number is below the thermal
 * rate (F213: 3.88 against 4.38), the number cannot be split and is kept,
 * the same on every SCA.  The mean over the 18 SCAs is Table 1's number.
 */
void background_avg(int f, int sca, struct bkg_part *p);

/*
 * The background of one exposure on all 18 SCAs (whatever SCAs a run
 * draws, so that runs split by SCA agree on everything derived from it).
 */
struct bkg_exposure {
	int model;              /* enum bkg_model */
	int norm;               /* enum bkg_norm (BKG_SKY) */
	double mjd;             /* the date, NaN when none was given */
	double sun_angle;       /* of the boresight, degrees; NaN without a date */
	struct bkg_part sca[WFS_NSCA];  /* per SCA (index sca - 1) */
	double least;           /* the smallest total over the 18 SCAs */
};

/*
 * Work out an exposure's background: model (enum bkg_model) with number
 * for BKG_NUMBER, in filter f, at mjd (NaN for none), the 18 SCA centres
 * ra[s], dec[s] (degrees, index sca - 1) and the boresight (bra, bdec).
 * With a date, a boresight outside BKG_SUN_MIN-BKG_SUN_MAX from the Sun is
 * refused unless allow_sun.  BKG_SKY needs a date.  Returns 0 or -1 with
 * a message (EXIT_INPUT) naming the angle and the date.
 */
int background_exposure(struct bkg_exposure *b, int model, double number, int f,
			double mjd, int norm, int allow_sun, const double *ra,
			const double *dec, double bra, double bdec, struct err *e);

/* The internal thermal rate and the zodiacal response of an SCA (for
 * tests and reports). */
double background_thermal(int f);
double background_r_sca(int f, int sca);

#endif
