/*
 * declines.c - a test plugin that cannot work with this host and says so:
 * its entry returns NULL for every host ABI version, which model.h allows.
 * wfiscene must refuse it cleanly (exit 3).
 */
#include <stddef.h>

#include "wfiscene/model.h"

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return NULL;
}
