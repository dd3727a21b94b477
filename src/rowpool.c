/*
 * rowpool.c - a per-row step on a pool's threads, failing as one thread
 * would (rowpool.h).
 */
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>

#include "rowpool.h"

struct rowpool_job {
	rowpool_fn fn;
	void *arg;
	size_t n, part;
	atomic_size_t first;    /* the lowest failing row so far, or SIZE_MAX */
	size_t *failed;         /* per task: its failing row, or SIZE_MAX */
	struct err *err;        /* per task */
};

static void rowpool_task(void *arg, int worker, size_t task)
{
	struct rowpool_job *j = arg;
	size_t end = (task + 1) * j->part < j->n ? (task + 1) * j->part : j->n;

	(void)worker;
	j->failed[task] = SIZE_MAX;
	for (size_t i = task * j->part; i < end; i++) {
		size_t f = atomic_load_explicit(&j->first, memory_order_relaxed);

		if (i > f)
			return;         /* an earlier row failed: this one is moot */
		if (j->fn(j->arg, i, &j->err[task]) < 0) {
			j->failed[task] = i;
			while (i < f && !atomic_compare_exchange_weak(&j->first, &f, i))
				;
			return;
		}
	}
}

int rowpool_run(struct pool *p, size_t n, size_t part, rowpool_fn fn, void *arg,
		struct err *e)
{
	size_t parts = part ? (n + part - 1) / part : 0;
	struct rowpool_job j = { .fn = fn, .arg = arg, .n = n, .part = part };

	if (!p || parts < 2) {
		for (size_t i = 0; i < n; i++)
			if (fn(arg, i, e) < 0)
				return -1;
		return 0;
	}
	atomic_init(&j.first, SIZE_MAX);
	j.failed = malloc(parts * sizeof(*j.failed));
	j.err = calloc(parts, sizeof(*j.err));
	if (!j.failed || !j.err) {
		free(j.failed);
		free(j.err);
		return err_sys(e, "row tasks");
	}
	pool_run(p, rowpool_task, &j, parts);
	for (size_t t = 0; t < parts; t++)
		if (j.failed[t] != SIZE_MAX) {
			err_set(e, j.err[t].code, "%s", j.err[t].msg);
			break;
		}
	free(j.failed);
	free(j.err);
	return e->code != EXIT_OK ? -1 : 0;
}
