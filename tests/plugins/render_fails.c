/*
 * render_fails.c - a test plugin that sets up and places its sources but
 * fails while rendering one, from a worker thread, through host->error().
 * wfiscene must stop with exit 3, print the message once, and leave no
 * output, whatever the thread count.
 */
#include <stdlib.h>

#include "wfiscene/model.h"

struct state {
	const struct wfs_host *host;
};

static int init(const struct wfs_host *host, void **state)
{
	struct state *s = malloc(sizeof(*s));

	if (!s)
		return host->error(host->ctx, "out of memory");
	s->host = host;
	*state = s;
	return 0;
}

static void fini(void *state)
{
	free(state);
}

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	box->x0 = (int)src->x - 2;
	box->y0 = (int)src->y - 2;
	box->x1 = box->x0 + 5;
	box->y1 = box->y0 + 5;
	return 0;
}

static int render(void *state, void *tstate, void *thread,
		  const struct wfs_source *src, const struct wfs_window *win)
{
	const struct wfs_host *h = ((struct state *)state)->host;

	return h->error(h->ctx, "deliberate failure while rendering flux %g", src->flux);
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "render_fails",
	.summary = "test: render() fails",
	.init = init,
	.fini = fini,
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
