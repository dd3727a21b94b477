/*
 * psfcache.c - the PSF cache's bound: the grids used longest ago removed
 * while the cache's grids take more than WFISCENE_CACHE_MAX mebibytes, a
 * grid's use being its time stamp, renewed each time a run reads it.
 * Apart from psfbuild.c, whose sources are part of a grid's key: how
 * the cache is kept does not change what a grid holds.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "psfcache.h"

/*
 * The cache's limit: WFISCENE_CACHE_MAX mebibytes of grids (default
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

static int lowhex(char c)
{
	return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
}

static int digits(const char *p, int n)
{
	for (int i = 0; i < n; i++)
		if (p[i] < '0' || p[i] > '9')
			return 0;
	return 1;
}

/* Whether n is a grid's name as psfbuild.c writes it,
 * psf-FILTER-scaNN-SIZE-KIND[-siaf][-spec]-KEY.fits (FILTER an F and three
 * digits, KIND epsf, epsf-noipc or psf, KEY 16 lowercase hex digits), with
 * its key into key.  A temporary (".psf-...XXXXXX") is none. */
static int grid_name(const char *n, char key[17])
{
	const char *p = n;

	if (strncmp(p, "psf-F", 5) || !digits(p + 5, 3) || strncmp(p + 8, "-sca", 4) ||
	    !digits(p + 12, 2) || p[14] != '-' || !digits(p + 15, 1))
		return 0;
	for (p += 15; *p >= '0' && *p <= '9'; p++)
		;
	if (*p++ != '-')
		return 0;
	if (!strncmp(p, "epsf-noipc", 10))
		p += 10;
	else if (!strncmp(p, "epsf", 4))
		p += 4;
	else if (!strncmp(p, "psf", 3))
		p += 3;
	else
		return 0;
	if (!strncmp(p, "-siaf", 5))
		p += 5;
	if (!strncmp(p, "-spec", 5))
		p += 5;
	if (*p++ != '-')
		return 0;
	for (int i = 0; i < 16; i++)
		if (!lowhex(p[i]))
			return 0;
	memcpy(key, p, 16);
	key[16] = 0;
	return !strcmp(p + 16, ".fits") && strlen(n) < sizeof(((struct cached *)0)->name);
}

/* Whether the regular file name in directory fd begins with the FITS
 * header of a grid this program wrote under key (its WFSKEY card, within
 * the first GRID_HEADER_BLOCKS blocks): 1, 0, or -1 when it is gone.
 * Checked before a file is removed, so that a file of the same name that
 * is no such grid stays. */
#define GRID_HEADER_BLOCKS 16

static int grid_header(int fd, const char *name, const char *key)
{
	char blk[2880];
	struct stat st;
	int f = openat(fd, name, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC), yes = 0;

	if (f < 0)
		return errno == ENOENT ? -1 : 0;
	if (fstat(f, &st) || !S_ISREG(st.st_mode))
		goto out;
	for (int b = 0; b < GRID_HEADER_BLOCKS; b++) {
		if (pread(f, blk, sizeof(blk), (off_t)b * (off_t)sizeof(blk)) != (ssize_t)sizeof(blk) ||
		    (b == 0 && memcmp(blk, "SIMPLE  =", 9)))
			goto out;
		for (int c = 0; c < 36; c++) {
			const char *card = blk + 80 * c;

			if (!memcmp(card, "END     ", 8))
				goto out;
			if (!memcmp(card, "WFSKEY  = '", 11)) {
				yes = !memcmp(card + 11, key, 16) && card[27] == '\'';
				goto out;
			}
		}
	}
out:
	close(f);
	return yes;
}

void psf_cache_used(const char *path)
{
	utimensat(AT_FDCWD, path, NULL, 0);
}

/*
 * After a grid was stored as `kept` in dir: while the cache's grids take
 * more than the limit, remove the one used longest ago (by time stamp:
 * written, or renewed when read), never `kept`.  Only files named as this
 * program names grids are counted, and one is removed only when its header
 * is such a grid's under the key its name holds; a file another run
 * removes first, or one that cannot be removed, is passed over.  Another
 * run that wants a removed grid builds it again, as after `rm -r` of the
 * cache.
 */
void psf_cache_trim(const char *dir, const char *kept, int verbose)
{
	static atomic_flag warned = ATOMIC_FLAG_INIT;  /* said once a run */
	long long limit = cache_limit(), total = 0, freed = 0;
	struct cached *c = NULL;
	size_t n = 0, cap = 0, gone = 0;
	struct dirent *d;
	DIR *dp;
	int fd;

	if (limit < 0) {
		if (verbose >= 0 && !atomic_flag_test_and_set(&warned))
			fprintf(stderr, "wfiscene: WFISCENE_CACHE_MAX=%s: not a whole number "
				"of mebibytes; the PSF cache is not trimmed\n",
				getenv("WFISCENE_CACHE_MAX"));
		return;
	}
	if (!limit || !(dp = opendir(dir)))
		return;
	fd = dirfd(dp);
	while ((d = readdir(dp))) {
		struct stat st;
		char key[17];

		if (!grid_name(d->d_name, key) ||
		    fstatat(fd, d->d_name, &st, AT_SYMLINK_NOFOLLOW) || !S_ISREG(st.st_mode))
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
			char key[17];
			int ours;

			if (!strcmp(c[i].name, kept))
				continue;
			grid_name(c[i].name, key);
			/* gone (another run's trim took it) or not a grid */
			if ((ours = grid_header(fd, c[i].name, key)) <= 0 ||
			    unlinkat(fd, c[i].name, 0)) {
				if (ours < 0 || (ours > 0 && errno == ENOENT))
					total -= c[i].bytes;
				continue;
			}
			total -= c[i].bytes;
			freed += c[i].bytes;
			gone++;
		}
		if (gone && verbose > 0)
			fprintf(stderr, "wfiscene: PSF cache %s: removed %zu grid%s used "
				"longest ago (%.1f MiB), to keep it within %lld MiB\n", dir, gone,
				gone == 1 ? "" : "s", freed / 1048576.0, limit >> 20);
	}
out:
	free(c);
	closedir(dp);
}
