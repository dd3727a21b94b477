/*
 * psfcache.c - the PSF cache's bound: the grids used longest ago removed
 * while the cache's grids take more than WFISCENE_CACHE_MAX megabytes.
 * Apart from psfbuild.c, whose sources are part of a grid's key: how
 * the cache is kept does not change what a grid holds.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "psfcache.h"

/*
 * The cache's limit: WFISCENE_CACHE_MAX megabytes of grids (default
 * CACHE_MAX_MB; 0: none).  The box and halo grids of every filter and
 * SCA, with and without IPC, take some 1.5 GB (more with spectral
 * classes), and every change to the code that computes a grid makes new
 * keys, so without a limit the old files would stay for good.  -1 when
 * the variable is not a number.
 */
#define CACHE_MAX_MB 4096

static long long cache_limit(void)
{
	const char *v = getenv("WFISCENE_CACHE_MAX");
	char *end;
	long long mb;

	if (!v || !*v)
		return (long long)CACHE_MAX_MB << 20;
	errno = 0;
	mb = strtoll(v, &end, 10);
	if (errno || *end || mb < 0 || mb > (1LL << 40))
		return -1;
	return mb << 20;
}

struct cached {
	time_t mtime;
	long mnsec;
	long long bytes;
	char name[256];
};

static int cached_cmp(const void *a, const void *b)
{
	const struct cached *u = a, *v = b;

	if (u->mtime != v->mtime)
		return (u->mtime > v->mtime) - (u->mtime < v->mtime);
	if (u->mnsec != v->mnsec)
		return (u->mnsec > v->mnsec) - (u->mnsec < v->mnsec);
	return strcmp(u->name, v->name);
}

/* A cached grid's name: psf-*.fits, not a temporary (".name.XXXXXX"). */
static int cached_name(const char *n)
{
	size_t len = strlen(n);

	return len > 9 && len < sizeof(((struct cached *)0)->name) && !strncmp(n, "psf-", 4) &&
	       !strcmp(n + len - 5, ".fits");
}

/*
 * After a grid was stored as `kept` in dir: while the cache's grids take
 * more than the limit, remove the one used longest ago (by time stamp:
 * written, or renewed when read), never `kept`.  Only files named as this
 * program names grids are counted or removed; a file another run removes
 * first, or one that cannot be removed, is passed over.  Another run that
 * wants a removed grid builds it again, as after `rm -r` of the cache.
 */
void psf_cache_trim(const char *dir, const char *kept, int verbose)
{
	long long limit = cache_limit(), total = 0, freed = 0;
	struct cached *c = NULL;
	size_t n = 0, cap = 0, gone = 0;
	struct dirent *d;
	DIR *dp;
	int fd;

	if (limit < 0) {
		if (verbose >= 0)
			fprintf(stderr, "wfiscene: WFISCENE_CACHE_MAX=%s: not a number of "
				"megabytes; the PSF cache is not trimmed\n",
				getenv("WFISCENE_CACHE_MAX"));
		return;
	}
	if (!limit || !(dp = opendir(dir)))
		return;
	fd = dirfd(dp);
	while ((d = readdir(dp))) {
		struct stat st;

		if (!cached_name(d->d_name) || fstatat(fd, d->d_name, &st, AT_SYMLINK_NOFOLLOW) ||
		    !S_ISREG(st.st_mode))
			continue;
		if (n == cap) {
			struct cached *m = realloc(c, (cap = cap ? 2 * cap : 256) * sizeof(*c));

			if (!m)
				goto out;
			c = m;
		}
		c[n].mtime = st.st_mtim.tv_sec;
		c[n].mnsec = st.st_mtim.tv_nsec;
		c[n].bytes = (long long)st.st_size;
		snprintf(c[n].name, sizeof(c[n].name), "%s", d->d_name);
		total += c[n++].bytes;
	}
	if (total > limit && n) {
		qsort(c, n, sizeof(*c), cached_cmp);
		for (size_t i = 0; i < n && total > limit; i++) {
			if (!strcmp(c[i].name, kept))
				continue;
			if (unlinkat(fd, c[i].name, 0) && errno != ENOENT)
				continue;
			total -= c[i].bytes;
			freed += c[i].bytes;
			gone++;
		}
		if (gone && verbose > 0)
			fprintf(stderr, "wfiscene: PSF cache %s: removed %zu grid%s used "
				"longest ago (%.1f MB), to keep it within %lld MB\n", dir, gone,
				gone == 1 ? "" : "s", freed / 1048576.0, limit >> 20);
	}
out:
	free(c);
	closedir(dp);
}
