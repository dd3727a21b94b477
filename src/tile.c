/*
 * tile.c - the memory of the image's tiles (struct slot, engine.h): place.c
 * allocates a tile when the first placement touches it (place_tiles),
 * render.c draws into it, write.c allocates the tiles of a strip that the
 * detector stage fills though no source touched them, and write.c and
 * run.c free them.  Tiles come from the pool's allocator of zeroed,
 * huge-page memory (pool.h); why not calloc() is said at tile_alloc().
 */
#include <stddef.h>

#include "engine.h"
#include "pool.h"

/*
 * A zeroed tile.  Tiles are mapped from the kernel directly: its pages come
 * zeroed and are only touched by the worker that first draws on them,
 * whereas calloc() would zero them with memset in the main thread once
 * glibc's mmap threshold has risen above a tile's size (it does after the
 * first large free).  18 SCAs of 512-pixel tiles are 2.4 GB of doubles.
 */
double *tile_alloc(int T)
{
	return pool_zalloc((size_t)T * T * sizeof(double));     /* huge pages: pool.h */
}

void tile_free(double *p, int T)
{
	pool_zfree(p, (size_t)T * T * sizeof(double));
}
