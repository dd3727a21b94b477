/*
 * no_entry.c - a shared object that is not a wfiscene model: it exports a
 * function, but not wfs_model_entry (a typo'd name, as happens).  wfiscene
 * must say so and stop with exit 3.
 */
#include "wfiscene/model.h"

WFS_EXPORT int wfs_model_entri(void)
{
	return 42;
}
