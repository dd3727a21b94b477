/*
 * clock.c - the run's clock and its progress line; see clock.h.
 */
#include <stdio.h>
#include <time.h>

#include "clock.h"
#include "engine.h"

double engine_clock(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* A progress line on a terminal, at most a few times a second. */
void engine_progress(struct engine *g, const char *stage, int force)
{
	double t = engine_clock(), since = t - (g->t_progress.tv_sec + 1e-9 * g->t_progress.tv_nsec);
	double el = t - (g->t_start.tv_sec + 1e-9 * g->t_start.tv_nsec);

	if (!g->progress || (!force && since < 0.25))
		return;
	clock_gettime(CLOCK_MONOTONIC, &g->t_progress);
	fprintf(stderr, "\rwfiscene: %llu rows, %.0f rows/s, %.1f s, %-10s", g->rows_read,
		el > 0 ? g->rows_read / el : 0.0, el, stage);
	fflush(stderr);
}

