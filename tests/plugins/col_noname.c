/*
 * col_noname.c - a test plugin whose descriptor lists a catalog column
 * with no name (a NULL where the name belongs).  wfiscene must refuse it
 * when it loads it (exit 3), not look the column up.
 */
#include <stddef.h>

#include "wfiscene/model.h"

static const struct wfs_column columns[] = {
	{ "size", 1, 0, "a column with a name" },
	{ NULL, 0, 1, "a column without one" },
};

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	box->x0 = (int)src->x;
	box->y0 = (int)src->y;
	box->x1 = box->x0 + 1;
	box->y1 = box->y0 + 1;
	return 0;
}

static int render(void *state, void *tstate, void *thread,
		  const struct wfs_source *src, const struct wfs_window *win)
{
	return 0;
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "col_noname",
	.summary = "test: a column without a name",
	.columns = columns,
	.ncolumns = 2,
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
