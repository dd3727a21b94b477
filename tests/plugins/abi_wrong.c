/*
 * abi_wrong.c - a test plugin built for a future ABI: its descriptor says
 * WFS_ABI_VERSION + 1, and wfiscene must refuse it (exit 3) before calling
 * anything in it.  Otherwise a complete, working model.
 */
#include "wfiscene/model.h"

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
	.abi = WFS_ABI_VERSION + 1,
	.size = sizeof(struct wfs_model),
	.name = "abi_wrong",
	.summary = "test: claims the next ABI version",
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
