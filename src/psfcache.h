/*
 * psfcache.h - the PSF cache's bound (psfcache.c).
 */
#ifndef WFS_PSFCACHE_H
#define WFS_PSFCACHE_H

/* After a grid was stored as the file `kept` in the cache directory dir:
 * while the cache's grids (files psf-*.fits) take more than
 * WFISCENE_CACHE_MAX mebibytes (default 4096; 0: no limit), remove the one
 * used longest ago by its time stamp, never `kept`.  verbose > 0 says what
 * was removed; a bad WFISCENE_CACHE_MAX is said unless verbose < 0. */
void psf_cache_trim(const char *dir, const char *kept, int verbose);

#endif
