/*
 * rowpool.h - a per-row step over rows 0 .. n-1 on a pool's threads, with
 * the error of one thread going through the rows in order.
 */
#ifndef WFS_ROWPOOL_H
#define WFS_ROWPOOL_H

#include <stddef.h>

#include "err.h"
#include "pool.h"

/* One row's step: 0, or -1 with the error in e.  It writes only row i's
 * own results, so rows may run on any thread in any order. */
typedef int (*rowpool_fn)(void *arg, size_t i, struct err *e);

/*
 * fn for rows 0 .. n-1, part rows a task on pool p (here, in order, when p
 * is NULL or there is a single part).  Returns 0, or -1 with the error of
 * the first failing row in order in e: a later row may have run too, its
 * result to be dropped with the rest.
 */
int rowpool_run(struct pool *p, size_t n, size_t part, rowpool_fn fn, void *arg,
		struct err *e);

#endif
