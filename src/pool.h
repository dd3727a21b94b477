/*
 * pool.h - a fixed set of worker threads running one parallel loop at a
 * time.  The caller starts a loop of ntasks tasks and may do other work (read
 * the next catalog chunk) before it waits.  Workers claim task indices in
 * increasing order from a shared counter; which worker runs which task varies,
 * so a task must write only memory it owns (a tile).
 */
#ifndef WFS_POOL_H
#define WFS_POOL_H

#include <stddef.h>

struct pool;

/* fn(arg, worker, task): worker is 0..nthreads-1, for per-worker state. */
typedef void (*pool_fn)(void *arg, int worker, size_t task);

struct pool *pool_new(int nthreads);
int pool_threads(const struct pool *p);
void pool_start(struct pool *p, pool_fn fn, void *arg, size_t ntasks);
void pool_wait(struct pool *p);
/* pool_start then pool_wait. */
void pool_run(struct pool *p, pool_fn fn, void *arg, size_t ntasks);
/* The same, each worker that runs tasks of the loop adding its thread CPU
 * seconds in them to cpu[worker] (read before its first task and after its
 * last: a per-task reading is a system call, which cost a 10^7-row sky
 * scene ~1.9 million of them).  cpu has pool_threads(p) entries and stays
 * valid until pool_wait() returns; read it after that. */
void pool_start_timed(struct pool *p, pool_fn fn, void *arg, size_t ntasks, double *cpu);
void pool_run_timed(struct pool *p, pool_fn fn, void *arg, size_t ntasks, double *cpu);
void pool_free(struct pool *p);

/* Zeroed memory for image tiles, from the kernel (mmap), bytes a multiple
 * of the page size.  Where bytes divides 2 MiB (or is a multiple of it) the
 * memory comes from 2 MiB-aligned blocks the kernel is asked to back with
 * huge pages (madvise MADV_HUGEPAGE): a tile's first touch is then one page
 * fault per 2 MiB instead of one per 4 KiB, which was most of the system
 * time of a many-SCA exposure.  WFISCENE_NO_HUGEPAGE=1 asks for plain pages
 * (to measure the difference).  pool_zfree(p, bytes) returns it; NULL if
 * the kernel refused. */
void *pool_zalloc(size_t bytes);
void pool_zfree(void *p, size_t bytes);

/* realloc() for a large array read in scattered order (place.c's
 * placements, which settle_order() and the tiles visit out of order): from
 * 2 MiB on, a new 2 MiB-aligned block the kernel is asked to back with huge
 * pages, the first old bytes copied, so that scattered reads do not each
 * miss the TLB.  free() frees it; NULL (p kept) when out of memory. */
void *pool_realloc_huge(void *p, size_t old, size_t bytes);

/* The number of online processors, at least 1. */
int pool_cpus(void);

#endif
