/*
 * firsttouch.c - how fast this machine hands a new process zeroed memory:
 * the cost of the first write to the accumulation tiles of one SCA (4088^2
 * doubles, 134 MB), which the engine pays in every run.
 *
 *   cc -O2 contrib/bench/firsttouch.c -o firsttouch && firsttouch [MB]
 *
 * Maps MB megabytes (default 134) three times in a row, each 2 MiB-aligned
 * with MADV_HUGEPAGE as the engine's tiles are (pool.c), writes one byte
 * per 4 KiB page, and prints the milliseconds and GB/s of each pass.  The
 * first pass is what a fresh process pays; the later ones reuse pages the
 * process has just freed.  On a virtual machine whose host backs guest
 * memory on demand (and takes freed memory back) the first pass can be
 * many times slower than the others.
 */
#define _DEFAULT_SOURCE
#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <time.h>

#define HUGE_ALIGN ((size_t)2 << 20)

static double now(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return t.tv_sec + 1e-9 * t.tv_nsec;
}

int main(int argc, char **argv)
{
	double mb = argc > 1 ? atof(argv[1]) : 4088.0 * 4088 * 8 / 1e6;
	size_t n = (size_t)(mb * 1e6) / 4096 * 4096;

	if (!(mb > 0) || n == 0) {
		fprintf(stderr, "usage: firsttouch [MB]\n");
		return 2;
	}
	for (int pass = 1; pass <= 3; pass++) {
		char *raw = mmap(NULL, n + HUGE_ALIGN, PROT_READ | PROT_WRITE,
				 MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
		volatile char *p;
		double t;

		if (raw == MAP_FAILED) {
			perror("mmap");
			return 1;
		}
		p = (char *)(((size_t)raw + HUGE_ALIGN - 1) & ~(HUGE_ALIGN - 1));
		madvise((void *)p, n, MADV_HUGEPAGE);
		t = now();
		for (size_t i = 0; i < n; i += 4096)
			p[i] = 1;
		t = now() - t;
		printf("pass %d: %.0f MB in %.1f ms, %.2f GB/s\n", pass, n / 1e6, 1e3 * t,
		       n / t / 1e9);
		munmap(raw, n + HUGE_ALIGN);
	}
	return 0;
}
