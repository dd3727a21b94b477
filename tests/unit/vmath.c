/*
 * vmath - plugins/vmath.h's exp and log against libm's: within 2 units in
 * the last place over the ranges they promise, their ends and beyond, and
 * the same bytes from the AVX2 loop (as sersic-quick runs them) as from
 * the plain code.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "tap.h"
#include "../../plugins/vmath.h"

/* |a - b| in units in the last place of b */
static double ulps(double a, double b)
{
	int e;

	if (a == b)
		return 0;
	if (!isfinite(a) || !isfinite(b))
		return INFINITY;
	frexp(b, &e);
	return fabs(a - b) / ldexp(1.0, (e < -1021 ? -1021 : e) - 53);
}

/* The worst of |y[i] - ref(x[i])| in ulp over n points, and where. */
static double worst_ulps(int n, const double *x, const double *y, double (*ref)(double),
			 double *at)
{
	double worst = 0;

	for (int i = 0; i < n; i++) {
		double u = ulps(y[i], ref(x[i]));

		if (u > worst) {
			worst = u;
			*at = x[i];
		}
	}
	return worst;
}

/* a reproducible uniform in [0, 1) */
static double uniform(uint64_t *s)
{
	*s = *s * 6364136223846793005ull + 1442695040888963407ull;
	return (double)(*s >> 11) * 0x1p-53;
}

static void exp_plain(int n, const double *x, double *y)
{
	for (int i = 0; i < n; i++)
		y[i] = vm_exp(x[i]);
}

static void log_plain(int n, const double *x, double *y)
{
	for (int i = 0; i < n; i++)
		y[i] = vm_log(x[i]);
}

#if defined(__GNUC__) && defined(__x86_64__)
__attribute__((target("avx2,fma"))) static void exp_avx2(int n, const double *restrict x,
							  double *restrict y)
{
	for (int i = 0; i < n; i++)
		y[i] = vm_exp(x[i]);
}

__attribute__((target("avx2,fma"))) static void log_avx2(int n, const double *restrict x,
							  double *restrict y)
{
	for (int i = 0; i < n; i++)
		y[i] = vm_log(x[i]);
}
#endif

int main(void)
{
	enum { N = 1 << 20 };
	static double x[N], y[N], z[N];
	uint64_t s = 12345;
	double worst = 0, at = 0;

	/* exp: the whole range, and [-1, 1] where the reduction does least */
	for (int i = 0; i < N; i++)
		x[i] = i < N / 4 ? -1 + 2 * uniform(&s) : -708 + 1417 * uniform(&s);
	exp_plain(N, x, y);
	worst = worst_ulps(N, x, y, exp, &at);
	ok(worst <= 2, "exp: worst %.2g ulp (at %.17g) over 2^20 points in [-708, 709]", worst, at);
	ok(vm_exp(0) == 1 && vm_exp(-708) > 0 && ulps(vm_exp(-708), exp(-708)) <= 2 &&
	   ulps(vm_exp(709), exp(709)) <= 2 && vm_exp(-708.5) == 0 && vm_exp(-1e300) == 0 &&
	   vm_exp(710) == vm_exp(709) && vm_exp(1e300) == vm_exp(709),
	   "exp: 1 at 0; the ends of its range; 0 below -708, exp(709) above, finite at +-1e300");

	/* log: every binade of the normal doubles, and [0.5, 2] about 1 */
	for (int i = 0; i < N; i++)
		x[i] = i < N / 4 ? 0.5 + 1.5 * uniform(&s) : exp(-708 + 1417 * uniform(&s));
	log_plain(N, x, y);
	worst = worst_ulps(N, x, y, log, &at);
	ok(worst <= 2, "log: worst %.2g ulp (at %.17g) over 2^20 points in [1e-308, 1e308]", worst, at);
	ok(vm_log(1) == 0 && ulps(vm_log(DBL_MIN), log(DBL_MIN)) <= 2 &&
	   ulps(vm_log(DBL_MAX), log(DBL_MAX)) <= 2 && ulps(vm_log(M_SQRT2), log(M_SQRT2)) <= 2 &&
	   ulps(vm_log(nextafter(M_SQRT2, 0)), log(nextafter(M_SQRT2, 0))) <= 2,
	   "log: 0 at 1; DBL_MIN, DBL_MAX and either side of sqrt(2), where m is halved");

#if defined(__GNUC__) && defined(__x86_64__)
	__builtin_cpu_init();
	if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
		for (int i = 0; i < N; i++)
			x[i] = -708 + 1417 * uniform(&s);
		exp_plain(N, x, y);
		exp_avx2(N, x, z);
		ok(!memcmp(y, z, sizeof(y)), "exp: the AVX2 loop gives the plain code's bytes");
		for (int i = 0; i < N; i++)
			x[i] = exp(-708 + 1417 * uniform(&s));
		log_plain(N, x, y);
		log_avx2(N, x, z);
		ok(!memcmp(y, z, sizeof(y)), "log: the AVX2 loop gives the plain code's bytes");
	} else {
		ok(1, "# SKIP no AVX2 and FMA on this CPU");
		ok(1, "# SKIP no AVX2 and FMA on this CPU");
	}
#endif
	return done_testing();
}
