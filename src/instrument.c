/* instrument.c - filters, zeropoints and SCA layout from data/; see instrument.h. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "data.h"
#include "err.h"
#include "instrument.h"

static const char *const filter_names[WFS_NFILTER] = {
	"F062", "F087", "F106", "F129", "F158", "F184", "F213", "F146"
};

/* Filled once by instrument_init() before any thread starts, read-only
 * afterwards: the tables are constants of the build. */
static struct filter_info filters[WFS_NFILTER];
static struct sca_info scas[WFS_NSCA];
static double stips_zp[WFS_NFILTER];
static double photplam[WFS_NFILTER];
static int loaded;

int instrument_init(struct err *e)
{
	struct tsv t;
	int c[8];

	if (loaded)
		return 0;
	if (tsv_parse(&t, "filters.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "broken build: no filters.tsv table");
	c[0] = tsv_col(&t, "filter");
	c[1] = tsv_col(&t, "lam_min");
	c[2] = tsv_col(&t, "lam_max");
	c[3] = tsv_col(&t, "photplam");
	c[4] = tsv_col(&t, "bkg_avg");
	c[5] = tsv_col(&t, "wide");
	c[6] = tsv_col(&t, "stips_zp");
	c[7] = tsv_col(&t, "zp_01");
	for (int i = 0; i < 8; i++)
		if (c[i] < 0) {
			tsv_free(&t);
			return err_set(e, EXIT_SYSTEM, "broken build: filters.tsv lacks a column");
		}
	for (int r = 1; r < t.nrow; r++) {
		int f = filter_lookup(t.cell[r][c[0]]);
		struct filter_info *fi;

		if (f < 0)
			continue;
		fi = &filters[f];
		fi->name = filter_names[f];
		fi->lam_min = atof(t.cell[r][c[1]]);
		fi->lam_max = atof(t.cell[r][c[2]]);
		fi->pivot = photplam[f] = atof(t.cell[r][c[3]]);
		fi->bkg_avg = atof(t.cell[r][c[4]]);
		fi->wide_pupil = atoi(t.cell[r][c[5]]);
		stips_zp[f] = atof(t.cell[r][c[6]]);
		for (int s = 0; s < WFS_NSCA; s++)
			fi->zp_ab[s] = atof(t.cell[r][c[7] + s]);
	}
	tsv_free(&t);

	if (tsv_parse(&t, "sca.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "broken build: no sca.tsv table");
	c[0] = tsv_col(&t, "sca");
	c[1] = tsv_col(&t, "x_wfi01");
	c[2] = tsv_col(&t, "y_wfi01");
	c[3] = tsv_col(&t, "x_bore");
	c[4] = tsv_col(&t, "y_bore");
	for (int r = 1; r < t.nrow; r++) {
		int s = atoi(t.cell[r][c[0]]);

		if (s < 1 || s > WFS_NSCA)
			continue;
		scas[s - 1].sca = s;
		scas[s - 1].x_idl = atof(t.cell[r][c[1]]);
		scas[s - 1].y_idl = atof(t.cell[r][c[2]]);
		scas[s - 1].x_bore = atof(t.cell[r][c[3]]);
		scas[s - 1].y_bore = atof(t.cell[r][c[4]]);
	}
	tsv_free(&t);
	for (int f = 0; f < WFS_NFILTER; f++)
		if (!filters[f].name)
			return err_set(e, EXIT_SYSTEM, "broken build: filter %s missing",
				       filter_names[f]);
	for (int s = 0; s < WFS_NSCA; s++)
		if (!scas[s].sca)
			return err_set(e, EXIT_SYSTEM, "broken build: SCA %d missing", s + 1);
	loaded = 1;
	return 0;
}

int filter_lookup(const char *name)
{
	for (int f = 0; f < WFS_NFILTER; f++)
		if (!strcasecmp(name, filter_names[f]))
			return f;
	return -1;
}

const struct filter_info *filter_get(int filter)
{
	return filter >= 0 && filter < WFS_NFILTER ? &filters[filter] : NULL;
}

const struct sca_info *sca_get(int sca)
{
	return sca >= 1 && sca <= WFS_NSCA ? &scas[sca - 1] : NULL;
}

double filter_stips_zp(int filter)
{
	return stips_zp[filter];
}

double filter_zeropoint(int filter, int sca, int stips)
{
	return stips ? stips_zp[filter] : filters[filter].zp_ab[sca - 1];
}

/* One SCA number: "5", "05", "WFI05", "SCA5" (any case). */
static int parse_one_sca(const char *s, const char *end)
{
	char buf[16];
	size_t n = end - s;
	char *p;
	long v;

	if (n == 0 || n >= sizeof(buf))
		return -1;
	memcpy(buf, s, n);
	buf[n] = 0;
	p = buf;
	if (!strncasecmp(p, "wfi", 3) || !strncasecmp(p, "sca", 3))
		p += 3;
	if (!isdigit((unsigned char)*p))
		return -1;
	v = strtol(p, &p, 10);
	if (*p || v < 1 || v > WFS_NSCA)
		return -1;
	return (int)v;
}

int sca_parse_list(const char *s, unsigned *mask, struct err *e)
{
	const char *p = s;

	*mask = 0;
	while (*p) {
		const char *comma = strchr(p, ','), *end = comma ? comma : p + strlen(p);
		const char *dash = memchr(p, '-', end - p);
		int a, b;

		if (dash) {
			a = parse_one_sca(p, dash);
			b = parse_one_sca(dash + 1, end);
		} else {
			a = b = parse_one_sca(p, end);
		}
		if (a < 0 || b < 0 || a > b)
			return err_set(e, EXIT_INPUT,
				       "--sca: bad SCA list '%s': expected numbers 1-18 "
				       "such as '1', '1-18', '2,5,9' or 'WFI05'", s);
		for (int i = a; i <= b; i++)
			*mask |= 1u << (i - 1);
		if (!comma)
			break;
		p = comma + 1;
		if (!*p)
			return err_set(e, EXIT_INPUT, "--sca: bad SCA list '%s'", s);
	}
	if (!*mask)
		return err_set(e, EXIT_INPUT, "--sca: empty SCA list");
	return 0;
}

/*
 * Counts/s per unit of flux.  AB magnitudes are handled by the caller
 * (10^(-0.4 (m - zp))); here the linear units of STIPS's mixed catalogs:
 *   Jy:  1 count/s is PHOTFNU = 10^(0.4 (8.9 - zp)) Jy, so counts = 1/PHOTFNU
 *   'p': photons/s/cm^2/Hz: 1e23 h / (PHOTFNU AREA)            (STIPS 'p')
 *   'e': erg/s/cm^2/Hz:     1e23 / (PHOTFNU AREA nu), nu = c / PHOTPLAM
 */
double unit_to_counts(int filter, int sca, int unit)
{
	double zp = filters[filter].zp_ab[sca - 1];
	double photfnu = pow(10.0, 0.4 * (8.9 - zp));
	const double h = 6.6260755e-27, c_um = 2.99792458e14;

	switch (unit) {
	case 'j':
		return 1.0 / photfnu;
	case 'p':
		return 1e23 * h / (photfnu * WFS_AREA_CM2);
	case 'e':
		return 1e23 / (photfnu * WFS_AREA_CM2 * (c_um / photplam[filter]));
	default:
		return 1.0;
	}
}
