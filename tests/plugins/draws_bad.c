/*
 * draws_bad.c - a test plugin that draws values a float32 image cannot
 * hold: a source of flux 42 puts NaN in its centre pixel, any other adds
 * flux * 1e37 there (1e39 for flux 100).  wfiscene must refuse to write
 * either (exit 3 for NaN, 1 for a value beyond 3.4e38), name the SCA and
 * pixel, and leave no output.
 */
#include <math.h>

#include "wfiscene/model.h"

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	box->x0 = (int)floor(src->x + 0.5) - 1;
	box->y0 = (int)floor(src->y + 0.5) - 1;
	box->x1 = box->x0 + 3;
	box->y1 = box->y0 + 3;
	return 0;
}

static int render(void *state, void *tstate, void *thread,
		  const struct wfs_source *src, const struct wfs_window *win)
{
	int x = (int)floor(src->x + 0.5), y = (int)floor(src->y + 0.5);

	if (x >= win->x0 && x < win->x0 + win->nx && y >= win->y0 && y < win->y0 + win->ny)
		win->pix[(y - win->y0) * win->stride + (x - win->x0)] +=
			src->flux == 42 ? NAN : src->flux * 1e37;
	return 0;
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "draws_bad",
	.summary = "test: draws NaN or values beyond float32",
	.footprint = footprint,
	.render = render,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
