/*
 * rngfloor - the random-number floor of the noise stages: Philox calls per
 * second as the ramp and the noise stages take them (rng_bits_n, 256 cells
 * a call, the AVX-512 or AVX2 path simd.h picks), thread CPU, best of 3;
 * and what that makes the floor of one SCA: level 1 or 2 takes two calls
 * per light pixel and resultant (the arrivals' Poisson count and the read
 * noise with the split), the scene's --noise all four per pixel (Poisson,
 * read, flat, dark residual).
 *
 *   make all && cc -O2 -Isrc contrib/bench/rngfloor.c build/libwfs.a -lm -lpthread -o rngfloor && ./rngfloor
 */
#include <stdint.h>
#include <stdio.h>
#include <time.h>

#include "rng.h"

static double cpu(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(void)
{
	enum { N = 256, ROWS = 4096 * 16 };
	static uint32_t w[N][4];
	struct rng g;
	double best = 1e30, npix = 4088.0 * 4088.0;
	volatile uint32_t sink = 0;

	rng_init(&g, 1, 0x44);
	for (int rep = 0; rep < 3; rep++) {
		double t0 = cpu(), t;

		for (uint32_t c = 0; c < (uint32_t)ROWS * N; c += N) {
			rng_bits_n(&g, c, 0, N, w);
			sink += w[N - 1][3];
		}
		t = (cpu() - t0) / ((double)ROWS * N);
		if (t < best)
			best = t;
	}
	printf("philox: %.2f ns per call (%.0f Mcalls/s)\n", 1e9 * best, 1e-6 / best);
	printf("level 1/2, MA table 4 (9 resultants): %.2f CPU s per SCA\n", best * 2 * 9 * npix);
	printf("--noise all: %.3f CPU s per SCA\n", best * 4 * npix);
	return (int)(sink & 0);
}
