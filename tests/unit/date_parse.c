/*
 * date_parse.c - dates as users type them become the right MJD: ISO 8601
 * forms (date only, minutes, seconds, fractions, 'Z', a space for 'T') and
 * MJDs (plain, 'MJD' prefixed), checked against MJDs astropy's Time gives
 * for the same UTC dates; impossible dates (29 February of a common year,
 * hour 24, second 60), malformed text and years outside 1800-2200 are
 * refused with a message that names the option and quotes the value; the
 * calendar round trip through date_format holds over four centuries.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "tap.h"
#include "date.h"
#include "err.h"

static void good(const char *s, double want)
{
	struct err e = { 0 };
	double m = NAN;
	int r = date_parse(s, "--date", &m, &e);

	ok(r == 0, "'%s' parses%s%s", s, r ? ": " : "", r ? e.msg : "");
	/* 1e-8 day is 1 ms */
	is_near(m, want, 1e-8, "'%s' is MJD %.9f", s, want);
}

static void bad(const char *s, const char *part)
{
	struct err e = { 0 };
	double m = 0;
	int r = date_parse(s, "--date", &m, &e);

	ok(r < 0 && e.code == EXIT_INPUT, "'%s' is refused (exit 1)", s);
	ok(strstr(e.msg, "--date") && strstr(e.msg, s) && strstr(e.msg, part),
	   "its message names the option, the value and says '%s': %s", part, e.msg);
}

int main(void)
{
	char buf[64];
	int fails = 0;

	/* MJDs from astropy.time.Time(d, scale='utc').mjd */
	good("2000-01-01T12:00", 51544.5);
	good("2000-01-01T12:00Z", 51544.5);
	good("2000-01-01 12:00:00", 51544.5);
	good("1858-11-17", 0.0);
	good("2027-02-28T23:59:59.5", 61464.999994212965);
	good("2026-11-25T06:35:03.25Z", 61369.274343171295);
	good("1800-01-01", -21504.0);
	good("2200-12-31T23:59", 124957.99930555555);
	good("2028-02-29", 61830.0);            /* a leap year */
	good("61369.274343171295", 61369.274343171295);
	good("MJD61369.25", 61369.25);
	good("mjd 60000", 60000.0);
	good("MJD=51544.5", 51544.5);
	good(" 51544.5 ", 51544.5);

	bad("2027-02-29", "no such date");
	bad("2025-13-01", "no such date");
	bad("2025-06-31", "no such date");
	bad("2025-06-01T24:00", "no such date");
	bad("2025-06-01T12:00:60", "no such date");
	bad("1799-12-31", "1800-2200");
	bad("2025-6-1xx", "not an ISO 8601 date");
	bad("12:00", "not a date");
	bad("2025-06-01T12", "not an ISO 8601 date");
	bad("2025-06-01T12:00:00.", "not an ISO 8601 date");
	bad("2025-06-01T12:00+02:00", "not an ISO 8601 date");
	bad("tomorrow", "not a date");
	bad("", "not a date");
	bad("MJD", "not a date");
	bad("nan", "not a date");
	bad("1e9", "outside the years");

	/* Every day of four centuries formats back to the date it came from. */
	for (int y = 1800; y < 2200; y++)
		for (int mo = 1; mo <= 12; mo++)
			for (int d = 1; d <= 31; d++) {
				char iso[32];
				struct err e = { 0 };
				double m;

				snprintf(iso, sizeof(iso), "%04d-%02d-%02d", y, mo, d);
				if (date_parse(iso, "x", &m, &e) < 0)
					continue;
				date_format(m + 0.5, buf, sizeof(buf));
				fails += strncmp(buf, iso, 10) || strcmp(buf + 10, "T12:00:00.000");
			}
	ok(fails == 0, "date_format inverts date_parse for every day of 1800-2199 "
	   "(%d mismatches)", fails);
	date_format(61464.999994212965, buf, sizeof(buf));
	ok(!strcmp(buf, "2027-02-28T23:59:59.500"), "date_format keeps milliseconds: %s", buf);
	date_format(61464.9999999999, buf, sizeof(buf));
	ok(!strcmp(buf, "2027-03-01T00:00:00.000"), "the last half millisecond rounds into "
	   "the next day: %s", buf);
	return done_testing();
}
