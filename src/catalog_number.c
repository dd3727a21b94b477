/*
 * catalog_number.c - the decimal parser of catalog cells
 * (catalog_parse_double, catalog.h).  Parsing dominates the cost of a
 * faint-star catalog, so it is exact for the common case without strtod;
 * catalog_number.h holds the eight-bytes-at-a-time path of catalog.c's
 * cell loop, which gives the same doubles.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "catalog.h"
#include "catalog_number.h"

/*
 * Parse s (surrounding blanks allowed) as a decimal number.  Returns 0 and
 * *out, 1 when s is not a number, 2 when it is NaN or infinite.
 *
 * Fast path (Clinger 1990): when the significant digits form an integer
 * m < 2^53 and the decimal exponent k has |k| <= 22, m and 10^|k| are both
 * exact doubles, so one IEEE multiplication or division gives the
 * correctly rounded result.  Everything else (more than 15 digits, large
 * exponents, hex, "inf") goes to strtod, which is also correctly rounded.
 */
int catalog_parse_double(const char *s, double *out)
{
	const char *p = s, *start, *d0;
	uint64_t m = 0;
	int k = 0, neg = 0, digits;
	char *end;
	double v;

	while (*p == ' ' || *p == '\t')
		p++;
	start = p;
	if (*p == '-' || *p == '+')
		neg = *p++ == '-';
	d0 = p;
	for (; (unsigned)(*p - '0') < 10; p++)
		m = m * 10 + (uint64_t)(*p - '0');
	digits = (int)(p - d0);
	if (*p == '.') {
		const char *f0 = ++p;

		for (; (unsigned)(*p - '0') < 10; p++)
			m = m * 10 + (uint64_t)(*p - '0');
		k = -(int)(p - f0);
		digits -= k;
	}
	if (!digits)
		goto slow;      /* "inf", "nan", ".", garbage */
	if (*p == 'e' || *p == 'E') {
		int eneg = 0, ex = 0;
		const char *e0;

		p++;
		if (*p == '-' || *p == '+')
			eneg = *p++ == '-';
		e0 = p;
		for (; (unsigned)(*p - '0') < 10; p++)
			if (ex < 100000)
				ex = ex * 10 + (*p - '0');
		if (p == e0)
			return 1;
		k += eneg ? -ex : ex;
	}
	while (*p == ' ' || *p == '\t')
		p++;
	if (*p)
		return 1;
	/* More than 19 digits may have wrapped m: let strtod decide. */
	if (digits <= 19 && m < (1ull << 53) && k >= -22 && k <= 22) {
		v = (double)m;
		v = k < 0 ? v / pow10_exact[-k] : v * pow10_exact[k];
		*out = neg ? -v : v;
		return 0;
	}
slow:
	v = strtod(start, &end);
	if (end == start)
		return 1;
	while (*end == ' ' || *end == '\t')
		end++;
	if (*end)
		return 1;
	/* Overflow gives HUGE_VAL, caught here; underflow to a denormal
	 * or zero is a fine value. */
	if (!isfinite(v))
		return 2;
	*out = v;
	return 0;
}
