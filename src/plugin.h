/*
 * plugin.h - finding and loading source-model plugins with libltdl.
 *
 * A model named NAME lives in NAME.so (or NAME.la) on the search path:
 * --plugin-path, then $WFISCENE_PLUGIN_PATH (colon-separated), then the
 * plugins that came with the running program (plugins/ beside it in a build
 * tree, or the plugin directory of its installation found relative to it),
 * then the plugin directory it was built for.  Loading happens in the main
 * thread, before workers use the model, with every symbol of the plugin
 * bound at once: an unresolved symbol refuses the plugin there.  A model
 * name is a word of [a-z0-9_-], so it can never name a path.
 *
 * The descriptor's appended members (model.h) are read here, once, gated
 * by its size; the rest of the host uses struct plugin's copies and
 * plugin_column() and never looks past a plugin's size.
 */
#ifndef WFS_PLUGIN_H
#define WFS_PLUGIN_H

#include <ltdl.h>

#include "wfiscene/model.h"

struct err;

#define PLUGIN_MAX 64
#define PLUGIN_COLUMNS_MAX WFS_MAX_COLUMNS /* catalog columns one model may read */
#define PLUGIN_ROLES (WFS_ROLE_ANGLE + 1)    /* enum wfs_column_role's values */

struct plugin {
	char name[64];
	char path[1024];
	lt_dlhandle handle;
	const struct wfs_model *m;
	void *dl;               /* the RTLD_NOW handle that bound its symbols */
	void *state;            /* from init() */
	int ready;              /* init() succeeded */
	/* the descriptor's appended members, or what their absence means */
	size_t column_size;     /* stride of m->columns */
	const struct wfs_setting *settings;
	size_t setting_size;    /* stride of settings */
	int nsettings;
	int (*reach)(void *state, const struct wfs_source *src, double *pixels);
	int drawer;             /* index of the drawn_by model, or -1 */
	uint32_t flags;         /* WFS_PARALLEL_PREPARE or 0 */
	int role[PLUGIN_ROLES]; /* the column of each enum wfs_column_role
	                           (role[WFS_ROLE_NONE] unused), or -1 */
	const char *roman_type; /* wfs_model.roman_type, or NULL */
};

/* Column c of pl's model, through the plugin's own stride. */
static inline const struct wfs_column *plugin_column(const struct plugin *pl, int c)
{
	return (const struct wfs_column *)(const void *)
		((const char *)pl->m->columns + (size_t)c * pl->column_size);
}

/* Setting k of pl's model, likewise. */
static inline const struct wfs_setting *plugin_setting(const struct plugin *pl, int k)
{
	return (const struct wfs_setting *)(const void *)
		((const char *)pl->settings + (size_t)k * pl->setting_size);
}

struct plugins {
	char *path;             /* the search path, colon-separated */
	const struct wfs_host *host;
	int n;
	struct plugin p[PLUGIN_MAX];
};

/* Prepare the search path.  host is what models' init() receives. */
int plugins_init(struct plugins *ps, const char *user_path,
		 const struct wfs_host *host, struct err *e);

/* The index of model name, loading and initialising it on first use.
 * Returns the index; or -1: EXIT_INPUT when no plugin of that name exists
 * (an unknown source type), EXIT_PLUGIN when one exists but is refused;
 * or PLUGIN_REFUSED_SETTING, EXIT_INPUT, when the model (or the model that
 * draws it) refused a value the run was given (--set or an option),
 * the message "--set KEY: model 'M' refuses it: ...", about no row. */
#define PLUGIN_REFUSED_SETTING (-2)
int plugins_get(struct plugins *ps, const char *name, struct err *e);

/* Call fini() of every model and unload them. */
void plugins_free(struct plugins *ps);

#endif
