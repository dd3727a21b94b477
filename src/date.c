/* date.c - ISO 8601 and MJD dates; see date.h. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "date.h"
#include "err.h"

#define MJD_UNIX_EPOCH 40587.0  /* 1970-01-01 */

/*
 * Days from 1970-01-01 to a proleptic Gregorian date.  The year is counted
 * from March, so that the leap day is the last day of a year; the 400-year
 * cycle (146097 days) then has the same shape from every era's start, and
 * the day of a shifted year follows from the month by the 30.6-day rule
 * (153 days per 5 months, March to July and August to December).
 */
static long days_from_civil(long y, int m, int d)
{
	long era, yoe, doy, doe;

	y -= m <= 2;
	era = (y >= 0 ? y : y - 399) / 400;
	yoe = y - era * 400;
	doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
	doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
	return era * 146097 + doe - 719468;
}

/* The inverse of days_from_civil. */
static void civil_from_days(long z, long *y, int *m, int *d)
{
	long era, doe, yoe, doy, mp;

	z += 719468;
	era = (z >= 0 ? z : z - 146096) / 146097;
	doe = z - era * 146097;
	yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
	doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
	mp = (5 * doy + 2) / 153;
	*d = (int)(doy - (153 * mp + 2) / 5 + 1);
	*m = (int)(mp < 10 ? mp + 3 : mp - 9);
	*y = yoe + era * 400 + (*m <= 2);
}

static int days_in_month(long y, int m)
{
	static const int n[12] = { 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31 };
	int leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;

	return m == 2 && leap ? 29 : n[m - 1];
}

double date_mjd(int year, int month, int day, int hour, int minute, double second)
{
	return MJD_UNIX_EPOCH + (double)days_from_civil(year, month, day) +
	       (hour * 3600.0 + minute * 60.0 + second) / 86400.0;
}

void date_format(double mjd, char *buf, size_t n)
{
	double day = floor(mjd), ms;
	long y, ims;
	int m, d;

	/* Milliseconds of the day, rounded; a day's last half millisecond
	 * rounds into the next day. */
	ms = round((mjd - day) * 86400e3);
	if (ms >= 86400e3) {
		ms -= 86400e3;
		day += 1;
	}
	civil_from_days((long)(day - MJD_UNIX_EPOCH), &y, &m, &d);
	ims = (long)ms;
	snprintf(buf, n, "%04ld-%02d-%02dT%02ld:%02ld:%02ld.%03ld", y, m, d, ims / 3600000,
		 ims / 60000 % 60, ims / 1000 % 60, ims % 1000);
}

/* Exactly ndig digits at *p, as a number; advances *p.  -1 if not. */
static int digits(const char **p, int ndig)
{
	int v = 0;

	for (int i = 0; i < ndig; i++) {
		if (!isdigit((unsigned char)(*p)[i]))
			return -1;
		v = v * 10 + ((*p)[i] - '0');
	}
	*p += ndig;
	return v;
}

static int parse_iso(const char *s, double *mjd)
{
	const char *p = s;
	int y, mo, d, h = 0, mi = 0;
	double sec = 0;

	if ((y = digits(&p, 4)) < 0 || *p++ != '-' || (mo = digits(&p, 2)) < 0 ||
	    *p++ != '-' || (d = digits(&p, 2)) < 0)
		return -1;
	if (*p == 'T' || *p == 't' || *p == ' ') {
		p++;
		if ((h = digits(&p, 2)) < 0 || *p++ != ':' || (mi = digits(&p, 2)) < 0)
			return -1;
		if (*p == ':') {
			int si;

			p++;
			if ((si = digits(&p, 2)) < 0)
				return -1;
			sec = si;
			if (*p == '.') {
				double scale = 0.1;

				if (!isdigit((unsigned char)p[1]))
					return -1;
				for (p++; isdigit((unsigned char)*p); p++, scale /= 10)
					sec += (*p - '0') * scale;
			}
		}
	}
	if (*p == 'Z' || *p == 'z')
		p++;
	if (*p)
		return -1;
	/* 60 seconds: no leap seconds (see date.h) */
	if (y < 1800 || y > 2200 || mo < 1 || mo > 12 || d < 1 || d > days_in_month(y, mo) ||
	    h > 23 || mi > 59 || sec >= 60)
		return -2;
	*mjd = date_mjd(y, mo, d, h, mi, sec);
	return 0;
}

int date_parse(const char *s, const char *what, double *mjd, struct err *e)
{
	const char *p = s;
	char *end;
	double v;
	int r;

	while (isspace((unsigned char)*p))
		p++;
	if (!strncasecmp(p, "mjd", 3)) {
		p += 3;
		if (*p == '=' || *p == ' ' || *p == ':')
			p++;
	} else if (strlen(p) >= 10 && p[4] == '-') {
		if ((r = parse_iso(p, mjd)) == 0)
			return 0;
		if (r == -2)
			return err_set(e, EXIT_INPUT, "%s: no such date, or outside the years "
				       "1800-2200: '%s'", what, s);
		return err_set(e, EXIT_INPUT, "%s: not an ISO 8601 date: '%s' (expected "
			       "YYYY-MM-DD, YYYY-MM-DDThh:mm[:ss[.fff]][Z], or an MJD)", what, s);
	}
	errno = 0;
	v = strtod(p, &end);
	while (end != p && isspace((unsigned char)*end))
		end++;
	if (end == p || *end || errno || !isfinite(v))
		return err_set(e, EXIT_INPUT, "%s: not a date: '%s' (expected YYYY-MM-DD, "
			       "YYYY-MM-DDThh:mm[:ss[.fff]][Z], an MJD such as 61484.5, or "
			       "MJD61484.5)", what, s);
	/* The years 1800-2200, as for ISO dates. */
	if (v < date_mjd(1800, 1, 1, 0, 0, 0) || v >= date_mjd(2201, 1, 1, 0, 0, 0))
		return err_set(e, EXIT_INPUT, "%s: MJD %g is outside the years 1800-2200: '%s'",
			       what, v, s);
	*mjd = v;
	return 0;
}
