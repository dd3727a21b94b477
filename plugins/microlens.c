/*
 * microlens.c - the "microlens" model: a star magnified by a point lens
 * (point-source point-lens, PSPL), drawn as a point source (drawn_by
 * "point") with its flux at the exposure's date.
 *
 * The lens passes at impact parameter u0 (in Einstein radii) at MJD t0,
 * crossing an Einstein radius in te days: u(t) = sqrt(u0^2 + ((t - t0)/te)^2)
 * and the source is magnified by A(u) = (u^2 + 2) / (u sqrt(u^2 + 4))
 * (Paczynski 1986).  The catalog's flux is the baseline, the source's and
 * the unmagnified blend's together; the source holds a fraction fs of it,
 * so the star's flux is baseline (fs A(u) + 1 - fs).  Without a date the
 * star has its baseline flux.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>

#include "wfiscene/model.h"

enum { C_T0, C_TE, C_U0, C_FS, NCOL };

static const struct wfs_column columns[NCOL] = {
	{ "t0", 0, 1, "MJD of the closest approach" },
	{ "te", 0, 1, "Einstein radius crossing time, days (> 0)" },
	{ "u0", 0, 1, "impact parameter, Einstein radii (not 0)" },
	{ "fs", 1, 0, "the source's fraction of the baseline flux, 0 to 1 (default 1)" },
};

struct microlens {
	const struct wfs_host *host;
	double mjd;
};

static int microlens_init(const struct wfs_host *host, void **state)
{
	struct microlens *m = calloc(1, sizeof(*m));
	const char *mjd = host->setting(host->ctx, "mjd");

	if (!m)
		return host->error(host->ctx, "out of memory");
	m->host = host;
	m->mjd = mjd ? strtod(mjd, NULL) : NAN;
	*state = m;
	return 0;
}

static void microlens_fini(void *state)
{
	free(state);
}

/* A(u) = (u^2 + 2) / (u sqrt(u^2 + 4)), as written, for u whose square is
 * a finite double (u below 1.3e154); microlens_prepare() handles the
 * rest.  For u below 1.5e-154 u^2 underflows to 0 or a subnormal, and the
 * formula is 2 / (2u) = 1/u, which is A to the last bit (the next term is
 * 3u/8); it overflows to infinity for u below 1 / DBL_MAX (5.6e-309). */
static double magnification(double u)
{
	return (u * u + 2) / (u * sqrt(u * u + 4));
}

static int microlens_prepare(void *state, struct wfs_source *src)
{
	struct microlens *m = state;
	const struct wfs_host *h = m->host;
	double mjd = m->mjd;
	const double *p = src->param;
	double u0 = fabs(p[C_U0]), te = p[C_TE], fs = p[C_FS], tau, u, a, f;

	if (!(te > 0 && te <= 1e6))
		return h->error(h->ctx, "column 'te': want days from 0 to 1e6, not %g", te);
	if (!(u0 > 0 && u0 <= 1e6))
		return h->error(h->ctx, "column 'u0': want a size from 0 to 1e6 (PSPL's "
				"magnification is infinite at 0), not %g", p[C_U0]);
	if (!(fs >= 0 && fs <= 1))
		return h->error(h->ctx, "column 'fs': want 0 to 1, not %g", fs);
	if (WFS_HAS(h->size, struct wfs_host, source_size) &&
	    WFS_HAS(h->source_size, struct wfs_source, mjd))
		mjd = src->mjd;
	/* Without a date, or without light from the source (fs = 0), the
	 * star has its baseline flux exactly, however large A is. */
	if (isnan(mjd) || fs == 0)
		return 0;
	/* hypot() keeps u finite while tau^2 overflows; tau itself, or
	 * mjd - t0, is infinite when t0 is far from the date or te tiny.
	 * Then, and wherever u^2 overflows (u above 1.3e154), A = 1 + 2/u^4
	 * - ... is 1 to the last bit, and the star has its baseline flux.
	 * (t0 is finite, so u is never NaN: the catalog has no NaN.) */
	tau = (mjd - p[C_T0]) / te;
	u = hypot(u0, tau);
	if (isinf(u * u))
		return 0;
	a = magnification(u);
	if (isinf(a))
		/* u below 1 / DBL_MAX, where A = 1/u (see magnification()):
		 * the magnified flux baseline fs / u may still be a double
		 * for a faint enough star. */
		f = src->flux * fs / u + src->flux * (1 - fs);
	else
		f = src->flux * (fs * a + 1 - fs);
	/* A star past DBL_MAX counts/s is past the 1e32 the host allows one
	 * source: give it the largest double, so that the host refuses it
	 * with that limit rather than as "not a finite number". */
	src->flux = isinf(f) ? DBL_MAX : f;
	return 0;
}

static const struct wfs_model microlens_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "microlens",
	.summary = "star magnified by a point lens (PSPL), drawn as a point source",
	.columns = columns,
	.ncolumns = NCOL,
	.init = microlens_init,
	.fini = microlens_fini,
	.prepare = microlens_prepare,
	.column_size = sizeof(struct wfs_column),
	.drawn_by = "point",
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &microlens_model : NULL;
}
