/*
 * tempfile.c - the temporary file beside an output; see tempfile.h.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "tempfile.h"

int tempfile_beside(const char *path, char *tmp, size_t cap, struct err *e)
{
	static const char alnum[] =
		"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
	const char *slash = strrchr(path, '/');
	const char *base = slash ? slash + 1 : path;
	struct timespec ts;
	uint64_t x;

	tmp[0] = 0;
	if (!*base)
		return err_set(e, EXIT_INPUT, "%s: not a file name", path);
	if (cap < TEMPFILE_SIZE(path)) {
		errno = ENAMETOOLONG;
		return err_sys(e, "%s", path);
	}
	/* names nobody else is likely to be trying: splitmix64 steps from
	 * the clock, the process and the caller's buffer */
	clock_gettime(CLOCK_REALTIME, &ts);
	x = (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30) ^
	    ((uint64_t)getpid() << 16) ^ (uint64_t)(uintptr_t)tmp;
	for (int attempt = 0; attempt < 100; attempt++) {
		uint64_t z = (x += 0x9E3779B97F4A7C15u);
		char suffix[7];
		int fd;

		z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
		z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
		z ^= z >> 31;
		for (int i = 0; i < 6; i++, z /= 62)
			suffix[i] = alnum[z % 62];
		suffix[6] = 0;
		snprintf(tmp, cap, "%.*s.%s.%s", (int)(base - path), path, base, suffix);
		fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
		if (fd >= 0)
			return fd;
		if (errno != EEXIST)
			break;
	}
	err_sys(e, "%s: cannot create temporary file '%s'", path, tmp);
	tmp[0] = 0;
	return -1;
}

int tempfile_open_output(const char *path, char *tmp, size_t cap, struct err *e)
{
	struct stat st;
	int fd;

	tmp[0] = 0;
	if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
		if (S_ISDIR(st.st_mode))
			return err_set(e, EXIT_INPUT, "%s: is a directory", path);
		if ((fd = open(path, O_WRONLY | O_CLOEXEC | O_NOCTTY)) < 0)
			return err_sys(e, "%s", path);
		return fd;
	}
	return tempfile_beside(path, tmp, cap, e);
}
