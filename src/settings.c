/*
 * settings.c - the engine's messages and settings: errors recorded from any
 * thread (a worker's go to its own record, merged by the main thread after
 * the pool waits; the main thread's to the run's), -v logging a line at a
 * time, and the settings by key (the scene's own, fixed for the exposure by
 * settings_init(), then --set).  The engine's files use them, and host.c
 * lends host_error, host_log and host_setting to every model as struct
 * wfs_host's error, log and setting; nothing here calls back into the host
 * or the PSF grids.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "err.h"
#include "options.h"
#include "noise.h"

/* The scene's settings as text, fixed for the exposure: what host_setting()
 * answers (model.h, "Settings"). */
void settings_init(struct engine *g)
{
	const struct scene_opts *o = g->o;

	snprintf(g->filter_name, sizeof(g->filter_name), "%s", filter_get(o->filter)->name);
	snprintf(g->exptime_str, sizeof(g->exptime_str), "%.17g", o->exptime);
	snprintf(g->seed_str, sizeof(g->seed_str), "%llu", (unsigned long long)g->x->seed);
	snprintf(g->mjd_str, sizeof(g->mjd_str), "%.17g", g->x->date);
	/* the least of the 18 SCAs' backgrounds: the same for runs split by SCA */
	snprintf(g->bkg_str, sizeof(g->bkg_str), "%.17g", g->x->bkg.least);
	snprintf(g->readnoise_str, sizeof(g->readnoise_str), "%.17g",
		 o->noise & NOISE_READ ? o->readnoise : 0.0);
	snprintf(g->noise_str, sizeof(g->noise_str), "%s%s%s%s%s",
		 o->noise & NOISE_POISSON ? "poisson," : "", o->noise & NOISE_READ ? "readnoise," : "",
		 o->noise & NOISE_DARK ? "dark," : "", o->noise & NOISE_FLAT ? "flat," : "",
		 o->noise & NOISE_COSMIC ? "cosmic," : "");
	{
		/* The noise of one pixel in counts/s, for models that draw
		 * down to a fraction of it (point's psf-extent): the noise
		 * stages' sky, read noise and dark current over the exposure;
		 * with none of them (or none that adds anything), the nominal
		 * ones (the exposure's or the filter's average sky, the default
		 * read noise), so a noiseless image is the mean of a noisy one. */
		double t = o->exptime, var = 0, bk = g->x->background;
		double sky = bk > 0 ? bk : filter_get(o->filter)->bkg_avg;

		if (o->noise & NOISE_POISSON)
			var += bk * t;
		if (o->noise & NOISE_READ)
			var += o->readnoise * o->readnoise;
		if (o->noise & NOISE_DARK)
			var += o->dark_current * t;
		if (!(var > 0))
			var = sky * t + NOISE_READNOISE * NOISE_READNOISE;
		snprintf(g->sigma_str, sizeof(g->sigma_str), "%.17g", sqrt(var) / t);
	}
}

/*
 * The worker the calling thread draws for.  Thread-local because
 * host->error() has no thread argument (model.h): a model calls it with the
 * host's ctx from render() on any worker.  Set by render_tile() around its
 * work, and by place.c's threads of place_pool around theirs; NULL on the
 * main thread.
 */
static _Thread_local struct worker *current_worker;

void host_worker(struct worker *w)
{
	current_worker = w;
}

struct worker *host_current(const struct engine *g)
{
	return current_worker && current_worker->g == g ? current_worker : NULL;
}

int host_error(void *ctx, const char *fmt, ...)
{
	struct engine *g = ctx;
	struct worker *w = host_current(g);
	char msg[1024];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	err_set(w ? &w->err : g->e, EXIT_PLUGIN, "%s", msg);
	return -1;
}

/* A line at a time, written whole (threads that prepare may log at once). */
void host_log(void *ctx, int level, const char *fmt, ...)
{
	struct engine *g = ctx;
	char line[2048];
	va_list ap;
	int n;

	if (level > g->o->verbose)
		return;
	va_start(ap, fmt);
	n = snprintf(line, sizeof(line), "wfiscene: ");
	vsnprintf(line + n, sizeof(line) - n - 1, fmt, ap);
	va_end(ap);
	strcat(line, "\n");
	fputs(line, stderr);
}

const char *host_setting(void *ctx, const char *key)
{
	struct engine *g = ctx;

	if (!strcmp(key, "filter"))
		return g->filter_name;
	if (!strcmp(key, "exptime"))
		return g->exptime_str;
	if (!strcmp(key, "seed"))
		return g->seed_str;
	if (!strcmp(key, "sersic"))
		return g->o->sersic;
	if (!strcmp(key, "background"))
		return g->bkg_str;
	if (!strcmp(key, "readnoise"))
		return g->readnoise_str;
	if (!strcmp(key, "noise"))
		return g->noise_str;
	if (!strcmp(key, "pixel-sigma"))
		return g->sigma_str;
	if (!strcmp(key, "mjd"))
		return isnan(g->x->date) ? NULL : g->mjd_str;
	if (!strcmp(key, "spectral-classes"))
		return g->classes ? g->classes_str : NULL;
	/* --set key=value: the last one given wins */
	return setting_last(g->o->settings, key);
}
