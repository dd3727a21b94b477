/*
 * init_fails.c - a test plugin whose set-up fails the way a real one does
 * when a table it needs is missing: init() records a message with
 * host->error() and returns -1.  wfiscene must print that message and stop
 * with exit 3, leaving no output.
 */
#include "wfiscene/model.h"

static int init(const struct wfs_host *host, void **state)
{
	*state = NULL;
	return host->error(host->ctx, "cannot open its table '%s'",
			   "/nonexistent/init_fails.tab");
}

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
	.name = "init_fails",
	.summary = "test: init() fails",
	.init = init,
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
