/*
 * silent.c - a test plugin that fails without saying why: one of its
 * callbacks returns -1 but never calls host->error(), against the
 * contract.  Built three times, as silent_prepare, silent_footprint and
 * silent_render (-DSILENT_PREPARE and so on).  wfiscene must stop with
 * exit 3 and a message naming the model and the callback, never carry on
 * as if the source (or its whole chunk of rows) were not there.
 */
#include "wfiscene/model.h"

static int prepare(void *state, struct wfs_source *src)
{
#ifdef SILENT_PREPARE
	return -1;
#else
	return 0;
#endif
}

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	box->x0 = (int)src->x - 2;
	box->y0 = (int)src->y - 2;
	box->x1 = box->x0 + 5;
	box->y1 = box->y0 + 5;
#ifdef SILENT_FOOTPRINT
	return -1;
#else
	return 0;
#endif
}

static int render(void *state, void *tstate, void *thread,
		  const struct wfs_source *src, const struct wfs_window *win)
{
#ifdef SILENT_RENDER
	return -1;
#else
	return 0;
#endif
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = SILENT_NAME,
	.summary = "test: fails without a message",
	.prepare = prepare,
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
