/*
 * date.h - dates of exposures: parsed from what a user types, kept as a
 * Modified Julian Date (days since 1858-11-17T00:00).
 *
 * wfiscene treats every date as UTC and ignores leap seconds and the
 * UTC-TT difference (69 s in 2025): the sky background, the first user,
 * changes by far less in a minute, and a time-domain model that needs
 * better than a minute should say so in its own column.
 */
#ifndef WFS_DATE_H
#define WFS_DATE_H

#include <stddef.h>

struct err;

/* MJD of J2000.0 (2000-01-01T12:00 TT, taken as UTC). */
#define DATE_MJD_J2000 51544.5

/*
 * Parse a date into an MJD:
 *   ISO 8601   2027-03-20, 2027-03-20T14:05, 2027-03-20T14:05:30,
 *              2027-03-20T14:05:30.25 (any number of decimals), a
 *              trailing 'Z' allowed; a space may stand for the 'T';
 *   MJD        a plain number (61484.5), or one prefixed 'MJD' or
 *              'MJD ' or 'MJD=' (MJD61484.5), any case.
 * Years 1800-2200; fields are range-checked (2027-02-29 is refused).
 * what names the value in messages ("--date", "pointings.txt:3: date").
 * Returns 0, or -1 with a message (EXIT_INPUT) quoting the value.
 */
int date_parse(const char *s, const char *what, double *mjd, struct err *e);

/* MJD of the calendar date and time (proleptic Gregorian, UTC). */
double date_mjd(int year, int month, int day, int hour, int minute, double second);

/* The calendar date of an MJD, "YYYY-MM-DDThh:mm:ss.sss" (UTC), into
 * buf of n bytes (24 suffice). */
void date_format(double mjd, char *buf, size_t n);

#endif
