/*
 * counts.c - a test model that is neither a point source nor a Sérsic
 * galaxy: a uniform square of `side` pixels (column, default 5), its flux
 * scaled by the setting counts-gain (default 1).  It counts its prepare()
 * and footprint() calls and says how many at fini(), so a test can hold the
 * host to model.h's promise: one of each per row and SCA the row lands on.
 *
 * Built twice by t7025: against today's model.h, with reach() and its
 * settings declared, and against the first edition of the header
 * (tests/plugins/abi1/), which has neither; the #ifdef is what an author
 * keeping one source for both would write.  COUNTS_NAME names the model.
 *
 * With COUNTS_SHAPE (edition 6 on) it also reads four columns it does not
 * draw with, index, hl, q and angle, and declares them the shape of its
 * source (column_roles) and its rows romanisim's SER (roman_type), so that
 * a test can see the host write them in romanisim's convention by what
 * the model declares, whatever the columns' names.
 *
 * With COUNTS_UNREAD it also declares a setting it never reads,
 * counts-unread, for the warning about --set keys that nothing reads.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"

#ifndef COUNTS_NAME
#define COUNTS_NAME "counts"
#endif

struct counts {
	const struct wfs_host *host;
	double gain;
	long prepared, footprints, reached;
};

static const struct wfs_column columns[] = {
	{ "side", 5.0, 0, "side of the square, pixels (odd, 1 to 99)" },
#ifdef COUNTS_SHAPE
	{ "index", 1.0, 0, "the Sérsic index it would have" },
	{ "hl", 1.0, 0, "half-light radius along the major axis, pixels" },
	{ "q", 1.0, 0, "axis ratio b/a" },
	{ "angle", 0.0, 0, "major axis, degrees from +y toward -x" },
#endif
};

#ifdef COUNTS_SHAPE
static const int roles[] = {
	WFS_ROLE_NONE, WFS_ROLE_SERSIC_INDEX, WFS_ROLE_HALF_LIGHT, WFS_ROLE_AXIS_RATIO,
	WFS_ROLE_ANGLE
};
#endif

static int init(const struct wfs_host *host, void **state)
{
	struct counts *c = calloc(1, sizeof(*c));
	const char *g = host->setting(host->ctx, "counts-gain");

	if (!c)
		return host->error(host->ctx, "out of memory");
	c->host = host;
	c->gain = g ? strtod(g, NULL) : 1.0;
	*state = c;
	return 0;
}

static void fini(void *state)
{
	struct counts *c = state;

	c->host->log(c->host->ctx, 0, "%s: prepare %ld footprint %ld reach %ld", COUNTS_NAME,
		     c->prepared, c->footprints, c->reached);
	free(c);
}

static int prepare(void *state, struct wfs_source *src)
{
	struct counts *c = state;
	double side = src->param[0];

	c->prepared++;
	if (!(side >= 1 && side <= 99) || fmod(side, 2) != 1)
		return c->host->error(c->host->ctx, "column 'side': want an odd number "
				      "from 1 to 99, not %g", side);
	src->aux[0] = (side - 1) / 2;
	return 0;
}

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	struct counts *c = state;
	int h = (int)src->aux[0], x = (int)floor(src->x + 0.5), y = (int)floor(src->y + 0.5);

	c->footprints++;
	box->x0 = x - h;
	box->y0 = y - h;
	box->x1 = x + h + 1;
	box->y1 = y + h + 1;
	return 0;
}

static int render(void *state, void *tstate, void *thread,
		  const struct wfs_source *src, const struct wfs_window *win)
{
	struct counts *c = state;
	double side = 2 * src->aux[0] + 1, v = c->gain * src->flux / (side * side);

	for (int j = 0; j < win->ny; j++)
		for (int i = 0; i < win->nx; i++)
			win->pix[j * win->stride + i] += v;
	return 0;
}

#ifdef WFS_HAS
/* The square's half-diagonal is the farthest its light goes; half the side
 * along the axes would do too, but the host asks for any direction. */
static int reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct counts *c = state;

	c->reached++;
	*pixels = src->param[0] / 2 * sqrt(2) + 1;
	return 0;
}

static const struct wfs_setting settings[] = {
	{ "counts-gain", "1", "number", "factor on every source's flux" },
#ifdef COUNTS_UNREAD
	{ "counts-unread", "0", "number", "declared, never read" },
#endif
};
#endif

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = COUNTS_NAME,
	.summary = "test: a uniform square that counts the host's calls",
	.columns = columns,
	.ncolumns = sizeof(columns) / sizeof(columns[0]),
	.init = init,
	.fini = fini,
	.prepare = prepare,
	.footprint = footprint,
	.render = render,
#ifdef WFS_HAS
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = settings,
	.nsettings = sizeof(settings) / sizeof(settings[0]),
	.reach = reach,
#endif
#ifdef COUNTS_SHAPE
	.roman_type = "SER",
	.column_roles = roles,
#endif
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &model : NULL;
}
