/*
 * catalog_number.h - the fast reading of a catalog's decimal cells, inline
 * for the cell loop of catalog.c; catalog_number.c has the full parser
 * (catalog_parse_double, declared in catalog.h) that both agree with.
 */
#ifndef WFS_CATALOG_NUMBER_H
#define WFS_CATALOG_NUMBER_H

#include <stdint.h>
#include <string.h>

/* Exact powers of ten: every one up to 1e22 is a double without rounding. */
static const double pow10_exact[23] = {
	1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
	1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

/* Pow10 as integers, for joining blocks of digits. */
static const uint64_t pow10_int[9] = {
	1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000,
};

/* How many of the 8 bytes in x (little-endian: the first byte lowest) are
 * ASCII digits before the first that is not.  A byte below '0' borrows
 * from the bytes above it, and one above 0xb9 carries into them, but only
 * bytes after the first non-digit are disturbed. */
static inline int digit_run(uint64_t x)
{
	uint64_t nd = ((x - 0x3030303030303030ull) | (x + 0x4646464646464646ull)) &
		      0x8080808080808080ull;

	return nd ? __builtin_ctzll(nd) >> 3 : 8;
}

/* The value of the first k (1..8) digits of x (Lemire's SWAR: pairs, then
 * fours, then the eight, each step one multiply). */
static inline uint64_t digit_value(uint64_t x, int k)
{
	x = (x & 0x0f0f0f0f0f0f0f0full) << (8 * (8 - k));
	x = x * 10 + (x >> 8);
	return (((x & 0x000000ff000000ffull) * (100 + (1000000ull << 32))) +
		(((x >> 16) & 0x000000ff000000ffull) * (1 + (10000ull << 32)))) >> 32;
}

/*
 * The common cell of a text catalog, "-123.4567890" (up to 7 integer and
 * 16 fraction digits, 19 in all, no exponent, no blanks), read 8 bytes at
 * a time; p must be followed by 8 readable bytes past its NUL (a padded
 * chunk).  The digits form m < 2^53 and the value is m / 10^f with f <= 16,
 * one correctly rounded division of exact doubles as in
 * catalog_parse_double, so both give the same double.  Returns 0, or -1
 * for anything else (then catalog_parse_double decides).
 */
static inline int parse_plain(const char *p, double *out)
{
	uint64_t x, m;
	int neg = 0, k, f = 0, g;
	double v;

	if (*p == '-')
		neg = 1, p++;
	memcpy(&x, p, 8);
	k = digit_run(x);
	if (k == 8)
		return -1;
	m = k ? digit_value(x, k) : 0;
	p += k;
	if (*p == '.') {
		memcpy(&x, ++p, 8);
		f = digit_run(x);
		if (f) {
			m = m * pow10_int[f] + digit_value(x, f);
			p += f;
		}
		if (f == 8) {
			memcpy(&x, p, 8);
			g = digit_run(x);
			if (g == 8 || k + f + g > 19)
				return -1;
			if (g) {
				m = m * pow10_int[g] + digit_value(x, g);
				p += g;
				f += g;
			}
		}
	}
	if (*p || k + f == 0 || m >= (1ull << 53))
		return -1;
	v = f ? (double)m / pow10_exact[f] : (double)m;
	*out = neg ? -v : v;
	return 0;
}

#endif
