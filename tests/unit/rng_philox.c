/* rng_philox - Philox4x32-10 known answers, uniforms and normal deviates. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "tap.h"
#include "rng.h"

/* Random123's kat_vectors: counter, key, expected output. */
static const uint32_t kat[3][10] = {
	{ 0, 0, 0, 0, 0, 0,
	  0x6627e8d5, 0xe169c58d, 0xbc57ac4c, 0x9b00dbd8 },
	{ 0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff,
	  0x408f276d, 0x41c83b0e, 0xa20bc7c6, 0x6d5451fd },
	{ 0x243f6a88, 0x85a308d3, 0x13198a2e, 0x03707344, 0xa4093822, 0x299f31d0,
	  0xd16cfe09, 0x94fdcceb, 0x5001e420, 0x24126ea1 },
};

static double normal_cdf(double x)
{
	return 0.5 * erfc(-x / sqrt(2));
}

int main(void)
{
	enum { N = 2000000, NB = 40 };
	static double z[N];
	double part[1000];
	uint32_t out[4];
	struct rng g;
	double s1 = 0, s2 = 0, s4 = 0, umin = 1, umax = 0, chi = 0;
	long hist[NB + 2] = { 0 };

	for (int i = 0; i < 3; i++) {
		rng_philox(kat[i], kat[i] + 4, out);
		ok(!memcmp(out, kat[i] + 6, sizeof(out)),
		   "Philox4x32-10 known answer %d: %08x %08x %08x %08x", i,
		   out[0], out[1], out[2], out[3]);
	}

	ok(rng_u01(0, 0) == 0 && rng_u01(0xffffffff, 0xffffffff) < 1,
	   "rng_u01 is in [0, 1)");
	ok(rng_u01_open0(0, 0) > 0 && rng_u01_open0(0xffffffff, 0xffffffff) == 1,
	   "rng_u01_open0 is in (0, 1]");

	/* Two keys that differ in one domain bit give unrelated numbers. */
	{
		struct rng a, b;
		uint32_t oa[4], ob[4];
		int same = 0;

		rng_init(&a, 7, 0x010301);
		rng_init(&b, 7, 0x010302);
		for (uint32_t c = 0; c < 1000; c++) {
			rng_bits(&a, c, 0, oa);
			rng_bits(&b, c, 0, ob);
			same += oa[0] == ob[0];
		}
		ok(same == 0, "different domains share no words (%d)", same);
	}

	rng_init(&g, 12345, 2);
	for (int i = 0; i < 1000; i++) {
		uint32_t w[4];

		rng_bits(&g, (uint32_t)i, 0, w);
		for (int j = 0; j < 4; j += 2) {
			double u = rng_u01(w[j], w[j + 1]);

			umin = u < umin ? u : umin;
			umax = u > umax ? u : umax;
		}
	}
	ok(umin >= 0 && umin < 0.01 && umax < 1 && umax > 0.99, "uniforms span [0, 1)");

	/* A slice of the deviates equals the same slice of the whole, from
	 * odd and even starts: the property tiles rely on. */
	rng_normal_fill(&g, 0, N, z);
	rng_normal_fill(&g, 37, 500, part);
	ok(!memcmp(part, z + 37, 500 * sizeof(double)), "normal slice from an odd start");
	rng_normal_fill(&g, 1000, 999, part);
	ok(!memcmp(part, z + 1000, 999 * sizeof(double)), "normal slice from an even start");
	rng_normal_fill(&g, 3, 1, part);
	ok(part[0] == z[3], "a single deviate");
	{
		struct rng h;

		rng_init(&h, 12345, 3);
		rng_normal_fill(&h, 0, 10, part);
		ok(memcmp(part, z, 10 * sizeof(double)), "another domain gives other numbers");
	}

	/* Bulk Philox equals one call at a time, at any start and length. */
	{
		uint32_t bulk[61][4], one[4];
		int same = 1;

		/* 61: the 32, 16 and 8 calls at a time and the single ones */
		for (int n = 21; n <= 61; n += 40) {
			rng_bits_n(&g, 0xffffffe5u, 9, (size_t)n, bulk);
			for (uint32_t i = 0; i < (uint32_t)n; i++) {
				rng_bits(&g, 0xffffffe5u + i, 9, one);
				same &= !memcmp(one, bulk[i], sizeof(one));
			}
		}
		ok(same, "rng_bits_n = rng_bits, across the 2^32 wrap");
	}

	/* The ziggurat table is the recurrence of rng.c. */
	{
		const double *x = rng_zig_x;
		double r = x[1], fr = exp(-0.5 * r * r);
		double v = r * fr + sqrt(M_PI / 2) * erfc(r / sqrt(2));
		double worst = fabs(x[0] - v / fr) / x[0];

		for (int i = 1; i < 255; i++) {
			double y = exp(-0.5 * x[i] * x[i]) + v / x[i];
			double want = sqrt(-2 * log(y));

			worst = fmax(worst, fabs(x[i + 1] - want) / want);
		}
		ok(worst < 1e-12 && x[256] == 0 &&
		   fabs(exp(-0.5 * x[255] * x[255]) + v / x[255] - 1) < 1e-12,
		   "ziggurat layers have equal areas (worst %.2g)", worst);
	}
	/* f at the edges is exp() of them: within an ulp, the same bits
	 * with the C library the table was made with */
	{
		int same = 0, near = 1;

		for (int i = 0; i < 257; i++) {
			double f = exp(-0.5 * rng_zig_x[i] * rng_zig_x[i]);

			same += rng_zig_f[i] == f;
			near &= fabs(rng_zig_f[i] - f) <= 0x1p-52 * f;
		}
		ok(near, "the ziggurat's f(x_i) is exp(-x_i^2 / 2) (%d of 257 to the bit)", same);
	}

	{
		long tail3 = 0, tail4 = 0;

		for (int i = 0; i < N; i++) {
			tail3 += fabs(z[i]) > 3;
			tail4 += fabs(z[i]) > 4;
		}
		/* P(|z| > 3) = 2.6998e-3, P(|z| > 4) = 6.3342e-5 */
		is_near(tail3, N * 2.6998e-3, 5 * sqrt(N * 2.6998e-3), "tail beyond 3 sigma (%ld)", tail3);
		is_near(tail4, N * 6.3342e-5, 5 * sqrt(N * 6.3342e-5), "tail beyond 4 sigma (%ld)", tail4);
	}

	for (int i = 0; i < N; i++) {
		double x = z[i];
		int b = (int)floor((x + 4) / 8 * NB);

		s1 += x;
		s2 += x * x;
		s4 += x * x * x * x;
		hist[b < 0 ? 0 : b >= NB ? NB + 1 : b + 1]++;
	}
	s1 /= N;
	s2 /= N;
	s4 /= N;
	/* Sampling errors of mean, second and fourth moments of N(0,1):
	 * sqrt(1/N), sqrt(2/N), sqrt(96/N); tolerances are 5 of them. */
	is_near(s1, 0, 5 * sqrt(1.0 / N), "normal mean");
	is_near(s2, 1, 5 * sqrt(2.0 / N), "normal variance");
	is_near(s4, 3, 5 * sqrt(96.0 / N), "normal fourth moment");
	for (int b = 0; b < NB + 2; b++) {
		double lo = b == 0 ? -INFINITY : -4 + 8.0 * (b - 1) / NB;
		double hi = b == NB + 1 ? INFINITY : -4 + 8.0 * b / NB;
		double p = normal_cdf(hi) - normal_cdf(lo), e = N * p;

		chi += (hist[b] - e) * (hist[b] - e) / e;
	}
	/* 41 degrees of freedom: mean 41, sigma 9; 5 sigma is 86. */
	ok(chi < 41 + 5 * sqrt(82.0), "normal chi-square %.1f over 41 dof", chi);
	return done_testing();
}
