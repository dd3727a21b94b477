/*
 * vmath.h - exp and log over arrays, for a plugin's inner loops.
 *
 * libm's exp and log are one call per value, with branches for every
 * special case; a galaxy's wing needs several of each per pixel.  These
 * are the textbook reductions written without branches, so that a loop
 * over an array of them becomes vector code (the compiler's, in a caller's
 * function built for AVX2 and FMA, given -fno-trapping-math so that the
 * selects between doubles become blends: the Makefile's FP_FLAGS) and runs
 * four values per instruction:
 *
 *   exp(x) = 2^k exp(r),  k = round(x / ln 2),  r = x - k ln 2 (ln 2 in two
 *            parts, so r is exact), |r| <= ln2 / 2, exp(r) by its Taylor
 *            series to r^13 (the remainder is below 2e-16 of it);
 *   log(x) = e ln 2 + log(m),  x = m 2^e with m in [sqrt(1/2), sqrt(2)),
 *            log(m) = 2 atanh(s) = 2 (s + s^3/3 + ...), s = (m - 1)/(m + 1),
 *            |s| <= 0.172, to s^23.
 *
 * Both agree with libm to a few units in the last place over the range a
 * caller may pass (tests/unit/vmath.c measures it): exp for x in
 * [-708, 709] (below -708 it returns 0, above 709 the value at 709), log
 * for normal positive x (the caller keeps 0, negatives, infinities and
 * NaN away).  Every operation is the same in the vector and the plain
 * code, fma included, so a machine without AVX2 gets the same bytes, as
 * long as the compiler fuses no a * b + c of its own (-ffp-contract=off,
 * FP_FLAGS: clang would fuse one in vm_log's AVX2 copy otherwise).
 */
#ifndef WFS_VMATH_H
#define WFS_VMATH_H

#include <math.h>
#include <stdint.h>
#include <string.h>

static inline uint64_t vm_bits(double x)
{
	uint64_t u;

	memcpy(&u, &x, sizeof(u));
	return u;
}

static inline double vm_double(uint64_t u)
{
	double x;

	memcpy(&x, &u, sizeof(x));
	return x;
}

/* exp(x) for x in [-708, 709]; 0 below, exp(709) above. */
static inline double vm_exp(double x)
{
	const double shift = 0x1.8p52;                  /* rounds to a whole number */
	const double ln2hi = 0x1.62e42fefa3800p-1, ln2lo = 0x1.ef35793c76730p-45;
	double xc = x < -708.0 ? -708.0 : x > 709.0 ? 709.0 : x;
	double kd = fma(xc, 0x1.71547652b82fep0, shift);
	uint64_t ki = vm_bits(kd);
	double k = kd - shift;
	double r = fma(-k, ln2lo, fma(-k, ln2hi, xc));
	double p = 1.0 / 6227020800.0;                  /* 1/13! */

	p = fma(p, r, 1.0 / 479001600.0);
	p = fma(p, r, 1.0 / 39916800.0);
	p = fma(p, r, 1.0 / 3628800.0);
	p = fma(p, r, 1.0 / 362880.0);
	p = fma(p, r, 1.0 / 40320.0);
	p = fma(p, r, 1.0 / 5040.0);
	p = fma(p, r, 1.0 / 720.0);
	p = fma(p, r, 1.0 / 120.0);
	p = fma(p, r, 1.0 / 24.0);
	p = fma(p, r, 1.0 / 6.0);
	p = fma(p, r, 0.5);
	p = fma(p, r * r, r);                           /* exp(r) - 1 */
	/* 2^k from k's low bits (ki holds shift + k): k + 1023 into the
	 * exponent field, the rest shifted out */
	double s = vm_double((ki + 1023) << 52);
	double y = fma(s, p, s);

	return x < -708.0 ? 0.0 : y;
}

/* log(x) for normal x > 0. */
static inline double vm_log(double x)
{
	const double ln2hi = 0x1.62e42fefa3800p-1, ln2lo = 0x1.ef35793c76730p-45;
	uint64_t u = vm_bits(x);
	/* the exponent as a double without an integer conversion: its 11
	 * bits under 2^52's, less 2^52 and the bias */
	double e = vm_double(0x4330000000000000ull | (u >> 52)) - (0x1p52 + 1023.0);
	double m = vm_double((u & 0x000fffffffffffffull) | 0x3ff0000000000000ull);
	int big = m > 0x1.6a09e667f3bcdp0;              /* sqrt(2) */

	m = big ? 0.5 * m : m;
	e = big ? e + 1.0 : e;
	double f = m - 1.0, s = f / (2.0 + f), z = s * s;
	double q = 2.0 / 23;

	q = fma(q, z, 2.0 / 21);
	q = fma(q, z, 2.0 / 19);
	q = fma(q, z, 2.0 / 17);
	q = fma(q, z, 2.0 / 15);
	q = fma(q, z, 2.0 / 13);
	q = fma(q, z, 2.0 / 11);
	q = fma(q, z, 2.0 / 9);
	q = fma(q, z, 2.0 / 7);
	q = fma(q, z, 2.0 / 5);
	q = fma(q, z, 2.0 / 3);
	/* log m = 2s + s z q = f - (f - 2s) + s z q; f - 2s = s f exactly
	 * enough: 2s = f - s f */
	double lm = fma(s * z, q, f - s * f);

	return fma(e, ln2hi, fma(e, ln2lo, lm));
}

#endif
