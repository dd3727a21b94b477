/*
 * unresolved.c - a test plugin that calls a function nothing defines (as
 * one calling a wfiscene-internal function would), only from render().
 * Loaded lazily it would pass every check and die at its first source,
 * mid-run; wfiscene binds a plugin's symbols when loading it and must refuse
 * it there (exit 3, the symbol named, no output).  Built with -Wl,-z,defs
 * it does not link at all.
 */
#include "wfiscene/model.h"

extern int wfs_host_internal_function(double *pix);

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
	return wfs_host_internal_function(win->pix);
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "unresolved",
	.summary = "test: needs a symbol no library defines",
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
