/*
 * psfcache.h - the PSF cache's bound (psfcache.c).
 */
#ifndef WFS_PSFCACHE_H
#define WFS_PSFCACHE_H

/* After a grid was stored as the file `kept` in the cache directory dir:
 * while the cache's grids (files named as psfbuild.c names grids, and
 * removed only when their header holds that name's key) take more than
 * WFISCENE_CACHE_MAX mebibytes (default 4096; 0: no limit), remove the one
 * used longest ago by its time stamp, never `kept`.  verbose > 0 says what
 * was removed; a bad WFISCENE_CACHE_MAX is said unless verbose < 0. */
void psf_cache_trim(const char *dir, const char *kept, int verbose);

/* A grid read from the cache at path: its time stamp renewed, so that the
 * limit removes it last (nothing when the run may not write the file). */
void psf_cache_used(const char *path);

#endif
