/*
 * simd.h - the one switch of the vector code, the host's and the built-in
 * plugins'.  Every vector loop gives the same bytes as the plain C beside
 * it, and is chosen twice:
 *
 *   when built: SIMD_X86 is defined where the compiler can build x86
 *     vector loops (GCC or Clang on x86-64: target attributes and
 *     <immintrin.h>, included here); code of such a loop sits under
 *     #ifdef SIMD_X86.  -DWFS_NO_SIMD builds none of them.
 *   when run: simd_flags() says which instructions this process may use;
 *     with WFISCENE_NO_SIMD set to "avx512" none of AVX-512, set to
 *     anything else none at all, so that the tests can compare the vector
 *     loops of each width and the plain loops on a machine that has the
 *     instructions.
 *
 * It is all static inline and needs no symbol of the host, so a built-in
 * plugin includes it by its path ("../src/simd.h") and still links with
 * -z defs: the host and the plugins decide the same way.
 */
#ifndef WFS_SIMD_H
#define WFS_SIMD_H

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#if defined(__GNUC__) && defined(__x86_64__) && !defined(WFS_NO_SIMD)
#define SIMD_X86 1
#include <immintrin.h>
#endif

enum {
	SIMD_AVX2 = 1,		/* AVX2 */
	SIMD_AVX512 = 2,	/* AVX-512 F, DQ and VL */
	SIMD_FMA = 4,		/* FMA3 */
};

/* SIMD_CLONES("avx2,fma", "default") before a function builds it once per
 * target and lets the loader pick one (GCC's target_clones), for a
 * function whose plain C the compiler vectorises well.  Not with clang,
 * and not under the sanitizers: the clones' resolver runs while the object
 * is being relocated, before the instrumentation it calls can be reached
 * (a ThreadSanitizer build jumped to a bad address in dlopen). */
#if defined(SIMD_X86) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__) && \
	!defined(__SANITIZE_THREAD__)
#define SIMD_CLONES(...) __attribute__((target_clones(__VA_ARGS__)))
#else
#define SIMD_CLONES(...)
#endif

/* The SIMD_ bits this process may use, found once per file that asks. */
static inline int simd_flags(void)
{
	static atomic_int cached = -1;
	int f = atomic_load_explicit(&cached, memory_order_relaxed);

	if (f >= 0)
		return f;
	f = 0;
#ifdef SIMD_X86
	const char *no = getenv("WFISCENE_NO_SIMD");

	if (!no || !strcmp(no, "avx512")) {
		__builtin_cpu_init();
		if (__builtin_cpu_supports("avx2"))
			f |= SIMD_AVX2;
		if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
		    __builtin_cpu_supports("avx512vl") && !no)
			f |= SIMD_AVX512;
		if (__builtin_cpu_supports("fma"))
			f |= SIMD_FMA;
	}
#endif
	atomic_store_explicit(&cached, f, memory_order_relaxed);
	return f;
}

#endif
