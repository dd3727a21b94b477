/* pool.c - worker threads for parallel loops; see pool.h. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "pool.h"

struct pool {
	int n;
	pthread_t *tid;
	pthread_mutex_t mu;
	pthread_cond_t go, done;
	unsigned long generation;       /* bumped for each loop started */
	int quit;
	pool_fn fn;
	void *arg;
	size_t ntasks;
	atomic_size_t next;             /* next task index to claim */
	int running;                    /* workers still in the current loop */
	double *cpu;                    /* pool_start_timed's, or NULL */
};

/* The calling thread's CPU seconds (a system call, not the vDSO's: read
 * once per worker and loop, not per task). */
static double thread_cpu(void)
{
	struct timespec t;

	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) < 0)
		return 0;
	return t.tv_sec + 1e-9 * t.tv_nsec;
}

struct start {
	struct pool *p;
	int id;
};

static void *worker_main(void *v)
{
	struct start *st = v;
	struct pool *p = st->p;
	int id = st->id;
	unsigned long seen = 0;

	free(st);
	for (;;) {
		double *cpu;
		size_t t;

		pthread_mutex_lock(&p->mu);
		while (!p->quit && p->generation == seen)
			pthread_cond_wait(&p->go, &p->mu);
		if (p->quit) {
			pthread_mutex_unlock(&p->mu);
			return NULL;
		}
		seen = p->generation;
		cpu = p->cpu;
		pthread_mutex_unlock(&p->mu);

		if ((t = atomic_fetch_add(&p->next, 1)) < p->ntasks) {
			double c0 = cpu ? thread_cpu() : 0;

			do
				p->fn(p->arg, id, t);
			while ((t = atomic_fetch_add(&p->next, 1)) < p->ntasks);
			if (cpu)
				cpu[id] += thread_cpu() - c0;
		}

		pthread_mutex_lock(&p->mu);
		if (--p->running == 0)
			pthread_cond_broadcast(&p->done);
		pthread_mutex_unlock(&p->mu);
	}
}

int pool_cpus(void)
{
	long n = sysconf(_SC_NPROCESSORS_ONLN);

	return n > 0 ? (int)n : 1;
}

struct pool *pool_new(int nthreads)
{
	struct pool *p = calloc(1, sizeof(*p));

	if (!p)
		return NULL;
	p->n = nthreads > 0 ? nthreads : 1;
	pthread_mutex_init(&p->mu, NULL);
	pthread_cond_init(&p->go, NULL);
	pthread_cond_init(&p->done, NULL);
	if (!(p->tid = calloc(p->n, sizeof(*p->tid))))
		goto fail;
	for (int i = 0; i < p->n; i++) {
		struct start *st = malloc(sizeof(*st));

		if (!st)
			goto fail;
		st->p = p;
		st->id = i;
		if (pthread_create(&p->tid[i], NULL, worker_main, st)) {
			free(st);
			p->n = i;
			goto fail;
		}
	}
	return p;
fail:
	pool_free(p);
	return NULL;
}

int pool_threads(const struct pool *p)
{
	return p->n;
}

void pool_start(struct pool *p, pool_fn fn, void *arg, size_t ntasks)
{
	pool_start_timed(p, fn, arg, ntasks, NULL);
}

void pool_start_timed(struct pool *p, pool_fn fn, void *arg, size_t ntasks, double *cpu)
{
	pthread_mutex_lock(&p->mu);
	p->cpu = cpu;
	p->fn = fn;
	p->arg = arg;
	p->ntasks = ntasks;
	atomic_store(&p->next, 0);
	p->running = p->n;
	p->generation++;
	pthread_cond_broadcast(&p->go);
	pthread_mutex_unlock(&p->mu);
}

void pool_wait(struct pool *p)
{
	pthread_mutex_lock(&p->mu);
	while (p->running > 0)
		pthread_cond_wait(&p->done, &p->mu);
	pthread_mutex_unlock(&p->mu);
}

void pool_run(struct pool *p, pool_fn fn, void *arg, size_t ntasks)
{
	pool_start(p, fn, arg, ntasks);
	pool_wait(p);
}

void pool_run_timed(struct pool *p, pool_fn fn, void *arg, size_t ntasks, double *cpu)
{
	pool_start_timed(p, fn, arg, ntasks, cpu);
	pool_wait(p);
}

void pool_free(struct pool *p)
{
	if (!p)
		return;
	pthread_mutex_lock(&p->mu);
	p->quit = 1;
	pthread_cond_broadcast(&p->go);
	pthread_mutex_unlock(&p->mu);
	for (int i = 0; p->tid && i < p->n; i++)
		pthread_join(p->tid[i], NULL);
	free(p->tid);
	pthread_mutex_destroy(&p->mu);
	pthread_cond_destroy(&p->go);
	pthread_cond_destroy(&p->done);
	free(p);
}

/* Tiles: see pool.h.  cur/left: the rest of the current 2 MiB block, which
 * smaller tiles are carved from in turn (each freed alone: munmap of part of
 * a huge page splits it). */
#define HUGE_BYTES ((size_t)2 << 20)

static pthread_mutex_t zmu = PTHREAD_MUTEX_INITIALIZER;
static char *zcur;
static size_t zleft;

static void *map(size_t bytes)
{
	void *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);

	return p == MAP_FAILED ? NULL : p;
}

/* bytes (a multiple of 2 MiB) at a 2 MiB boundary, marked for huge pages */
static void *map_huge(size_t bytes)
{
	char *p = map(bytes + HUGE_BYTES), *a;
	size_t head;

	if (!p)
		return NULL;
	a = (char *)(((uintptr_t)p + HUGE_BYTES - 1) & ~(uintptr_t)(HUGE_BYTES - 1));
	head = (size_t)(a - p);
	if (head)
		munmap(p, head);
	munmap(a + bytes, HUGE_BYTES - head);
#ifdef MADV_HUGEPAGE
	madvise(a, bytes, MADV_HUGEPAGE);      /* advice: refused, plain pages */
#endif
	return a;
}

/* WFISCENE_NO_HUGEPAGE=1: plain pages everywhere */
static int plain_pages(void)
{
	static int plain = -1;

	if (plain < 0) {
		const char *s = getenv("WFISCENE_NO_HUGEPAGE");

		plain = s && *s && *s != '0';
	}
	return plain;
}

void *pool_zalloc(size_t bytes)
{
	void *p;

	if (plain_pages() || !bytes || (bytes % HUGE_BYTES && HUGE_BYTES % bytes) ||
	    bytes % (size_t)sysconf(_SC_PAGESIZE))
		return map(bytes);
	if (bytes >= HUGE_BYTES)
		return map_huge(bytes);
	pthread_mutex_lock(&zmu);
	if (zleft < bytes) {
		zcur = map_huge(HUGE_BYTES);
		zleft = zcur ? HUGE_BYTES : 0;
	}
	p = zcur;
	if (p) {
		zcur += bytes;
		zleft -= bytes;
	}
	pthread_mutex_unlock(&zmu);
	return p;
}

void pool_zfree(void *p, size_t bytes)
{
	if (p)
		munmap(p, bytes);
}

void *pool_realloc_huge(void *p, size_t old, size_t bytes)
{
	size_t whole = (bytes + HUGE_BYTES - 1) & ~(HUGE_BYTES - 1);
	void *q;

	if (bytes < HUGE_BYTES || plain_pages() || !(q = aligned_alloc(HUGE_BYTES, whole)))
		return realloc(p, bytes);
#ifdef MADV_HUGEPAGE
	madvise(q, whole, MADV_HUGEPAGE);      /* before the first touch */
#endif
	if (p)
		memcpy(q, p, old < bytes ? old : bytes);
	free(p);
	return q;
}
