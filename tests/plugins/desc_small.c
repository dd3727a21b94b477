/*
 * desc_small.c - a test plugin whose descriptor is smaller than the host
 * needs: it says it ends before render(), as one built against an older,
 * shorter model.h would.  wfiscene must not read past `size` and must
 * refuse it (exit 3).
 */
#include <stddef.h>

#include "wfiscene/model.h"

static int footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	box->x0 = (int)src->x;
	box->y0 = (int)src->y;
	box->x1 = box->x0 + 1;
	box->y1 = box->y0 + 1;
	return 0;
}

static const struct wfs_model model = {
	.abi = WFS_ABI_VERSION,
	.size = offsetof(struct wfs_model, render),
	.name = "desc_small",
	.summary = "test: descriptor ends before render()",
	.footprint = footprint,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return &model;
}
