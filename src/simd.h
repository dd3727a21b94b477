/*
 * simd.h - which vector loops the host's own code may take.  Every vector
 * loop in src/ gives the same bytes as the plain C beside it; with
 * WFISCENE_NO_SIMD set (to anything) the host keeps to the plain loops,
 * so that the tests can compare the two on a machine that has the
 * instructions (as point.so does with the same variable).
 */
#ifndef WFS_SIMD_H
#define WFS_SIMD_H

#include <stdatomic.h>
#include <stdlib.h>

enum {
	SIMD_AVX2 = 1,		/* AVX2 */
	SIMD_AVX512 = 2,	/* AVX-512 F and DQ */
};

/* The SIMD_ bits this process may use, found once per file that asks. */
static inline int simd_flags(void)
{
	static atomic_int cached = -1;
	int f = atomic_load_explicit(&cached, memory_order_relaxed);

	if (f >= 0)
		return f;
	f = 0;
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
	if (!getenv("WFISCENE_NO_SIMD")) {
		__builtin_cpu_init();
		if (__builtin_cpu_supports("avx2"))
			f |= SIMD_AVX2;
		if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq"))
			f |= SIMD_AVX512;
	}
#endif
	atomic_store_explicit(&cached, f, memory_order_relaxed);
	return f;
}

#endif
