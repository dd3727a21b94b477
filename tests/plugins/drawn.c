/*
 * drawn.c - a test model drawn by another (model.h, drawn_by): it doubles
 * a source's flux and moves it DX pixels along x, and names DRAWN_BY
 * ("point" unless built otherwise) to draw it.  DRAWN_NAME names the model.
 * t7026 builds it drawn by point, by itself and by microlens (which is
 * drawn by point: a chain the host refuses).
 */
#include <stddef.h>

#include "wfiscene/model.h"

#ifndef DRAWN_NAME
#define DRAWN_NAME "drawn"
#endif
#ifndef DRAWN_BY
#define DRAWN_BY "point"
#endif

static const struct wfs_column columns[] = {
	{ "dx", 0.0, 0, "pixels to move the source along x" },
};

static int prepare(void *state, struct wfs_source *src)
{
	src->flux *= 2;
	src->x += src->param[0];
	return 0;
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = DRAWN_NAME,
	.summary = "test: twice the flux, moved, drawn by another model",
	.columns = columns,
	.ncolumns = 1,
	.prepare = prepare,
	.column_size = sizeof(struct wfs_column),
	.drawn_by = DRAWN_BY,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &model : NULL;
}
