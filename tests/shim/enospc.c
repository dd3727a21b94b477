/*
 * enospc.c - an LD_PRELOAD shim that makes a disk look full.
 *
 *   cc -shared -fPIC -o enospc.so tests/shim/enospc.c -ldl
 *   WFS_ENOSPC_MATCH=/full/ WFS_ENOSPC_AFTER=5000 LD_PRELOAD=./enospc.so cmd
 *
 * write(2) and fwrite(3) to any file whose path contains WFS_ENOSPC_MATCH
 * succeed for the first WFS_ENOSPC_AFTER bytes in all (default 0), the
 * write that crosses the limit is cut short, and every later one fails with
 * ENOSPC, as on a file system that just filled up.  Both calls are wrapped
 * because cfitsio writes through stdio, whose own flushes bypass write(2)'s
 * public symbol inside glibc.  Test code: the byte count is a process-wide
 * static, which is what a full disk is.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static long long used;

static int matches(int fd)
{
	const char *want = getenv("WFS_ENOSPC_MATCH");
	char link[64], path[4096];
	ssize_t n;

	if (!want || !*want || fd < 0)
		return 0;
	snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
	n = readlink(link, path, sizeof(path) - 1);
	if (n < 0)
		return 0;
	path[n] = 0;
	return strstr(path, want) != NULL;
}

/* How many of n bytes may still be written; 0 means the disk is full. */
static size_t allowance(size_t n)
{
	const char *s = getenv("WFS_ENOSPC_AFTER");
	long long limit = s ? atoll(s) : 0, left = limit - used;

	if (left <= 0)
		return 0;
	return (long long)n < left ? n : (size_t)left;
}

ssize_t write(int fd, const void *buf, size_t n)
{
	static ssize_t (*real)(int, const void *, size_t);
	int full = n > 0 && matches(fd);
	size_t k = full ? allowance(n) : n;
	ssize_t r;

	if (!real)
		real = (ssize_t (*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
	if (full && k == 0) {
		errno = ENOSPC;
		return -1;
	}
	r = real(fd, buf, k);
	if (full && r > 0)
		used += r;
	return r;
}

size_t fwrite(const void *ptr, size_t size, size_t nmemb, FILE *fp)
{
	static size_t (*real)(const void *, size_t, size_t, FILE *);
	size_t bytes = size * nmemb, k, r;

	if (!real)
		real = (size_t (*)(const void *, size_t, size_t, FILE *))
			dlsym(RTLD_NEXT, "fwrite");
	if (bytes == 0 || !matches(fileno(fp)))
		return real(ptr, size, nmemb, fp);
	k = allowance(bytes) / size;
	r = k ? real(ptr, size, k, fp) : 0;
	used += (long long)(r * size);
	if (r < nmemb)
		errno = ENOSPC;
	return r;
}
