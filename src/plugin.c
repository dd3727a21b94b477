/* plugin.c - loading model plugins; see plugin.h. */
#include <dlfcn.h>
#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "err.h"
#include "options.h"
#include "plugin.h"

/* Appends dir to a colon-separated path. */
static int path_add(char **path, const char *dir)
{
	size_t old = *path ? strlen(*path) : 0, add = strlen(dir);
	char *p;

	if (!add)
		return 0;
	if (!(p = realloc(*path, old + add + 2)))
		return -1;
	if (old)
		p[old++] = ':';
	memcpy(p + old, dir, add + 1);
	*path = p;
	return 0;
}

/*
 * The path from directory `from` to directory `to`, both absolute, as
 * "../lib/wfiscene" for /usr/local/bin and /usr/local/lib/wfiscene.  -1 when
 * either is not absolute or has a ".." component.
 */
static int relative_dir(const char *from, const char *to, char *out, size_t cap)
{
	const char *a = from, *b = to;
	size_t len = 0;

	if (*from != '/' || *to != '/' || strstr(from, "/..") || strstr(to, "/.."))
		return -1;
	/* Skip the components the two share. */
	for (;;) {
		size_t na, nb;

		while (*a == '/')
			a++;
		while (*b == '/')
			b++;
		na = strcspn(a, "/");
		nb = strcspn(b, "/");
		if (!na || na != nb || memcmp(a, b, na))
			break;
		a += na;
		b += nb;
	}
	out[0] = 0;
	/* One ".." per component of from that is left, then the rest of to. */
	while (*a) {
		size_t na = strcspn(a, "/");

		if (na && !(na == 1 && *a == '.'))
			len += snprintf(out + len, len < cap ? cap - len : 0, "../");
		a += na;
		while (*a == '/')
			a++;
	}
	len += snprintf(out + len, len < cap ? cap - len : 0, "%s", *b ? b : ".");
	return len < cap ? 0 : -1;
}

/* Adds dir to the path if it is a directory other than the plugin
 * directory wfiscene was built for (which comes last anyway). */
static int path_add_own(char **path, const char *dir)
{
	char real[PATH_MAX], installed[PATH_MAX];
	struct stat st;

	if (stat(dir, &st) < 0 || !S_ISDIR(st.st_mode) || !realpath(dir, real))
		return 0;
	if (realpath(WFS_PLUGINDIR, installed) && !strcmp(real, installed))
		return 0;
	return path_add(path, dir);
}

int plugins_init(struct plugins *ps, const char *user_path,
		 const struct wfs_host *host, struct err *e)
{
	char exe[PATH_MAX], dir[PATH_MAX + 16], rel[PATH_MAX], *slash;
	const char *env = getenv("WFISCENE_PLUGIN_PATH");
	ssize_t len;

	memset(ps, 0, sizeof(*ps));
	ps->host = host;
	if (lt_dlinit())
		return err_set(e, EXIT_PLUGIN, "libltdl: %s", lt_dlerror());
	if ((user_path && path_add(&ps->path, user_path) < 0) ||
	    (env && path_add(&ps->path, env) < 0))
		return err_sys(e, "plugin path");
	/*
	 * The plugins that came with this program, before those of the place
	 * it was built for: plugins/ beside it (a build tree), and the plugin
	 * directory where `make install` puts it relative to the program (an
	 * installation under DESTDIR, or moved elsewhere as a whole).
	 */
	len = readlink("/proc/self/exe", exe, sizeof(exe) - 1);
	if (len > 0) {
		exe[len] = 0;
		if ((slash = strrchr(exe, '/'))) {
			*slash = 0;
			snprintf(dir, sizeof(dir), "%s/plugins", exe);
			if (path_add_own(&ps->path, dir) < 0)
				return err_sys(e, "plugin path");
			if (relative_dir(WFS_BINDIR, WFS_PLUGINDIR, rel, sizeof(rel)) == 0 &&
			    (size_t)snprintf(dir, sizeof(dir), "%s/%s", exe, rel) < sizeof(dir) &&
			    path_add_own(&ps->path, dir) < 0)
				return err_sys(e, "plugin path");
		}
	}
	if (path_add(&ps->path, WFS_PLUGINDIR) < 0)
		return err_sys(e, "plugin path");
	return 0;
}

static int valid_name(const char *name)
{
	if (!*name || strlen(name) >= 64)
		return 0;
	for (const char *p = name; *p; p++)
		if (!((*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') ||
		      *p == '-' || *p == '_'))
			return 0;
	return 1;
}

/* The first NAME.so or NAME.la on the search path, into out. */
static int find_file(const char *path, const char *name, char *out, size_t cap)
{
	const char *p = path;

	while (p && *p) {
		const char *colon = strchr(p, ':');
		size_t n = colon ? (size_t)(colon - p) : strlen(p);
		static const char *const ext[] = { ".so", ".la" };

		for (int i = 0; i < 2 && n; i++) {
			snprintf(out, cap, "%.*s/%s%s", (int)n, p, name, ext[i]);
			if (access(out, R_OK) == 0)
				return 0;
		}
		p = colon ? colon + 1 : NULL;
	}
	return -1;
}

/* Unload a plugin that cannot be used and record why (a printf format and
 * its arguments, checked by the compiler like any other). */
static int refuse(struct plugin *pl, struct err *e, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static int refuse(struct plugin *pl, struct err *e, const char *fmt, ...)
{
	char why[512];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(why, sizeof(why), fmt, ap);
	va_end(ap);
	if (pl->handle)
		lt_dlclose(pl->handle);
	if (pl->dl)
		dlclose(pl->dl);
	pl->handle = NULL;
	pl->dl = NULL;
	return err_set(e, EXIT_PLUGIN, "model '%s' (%s): %s", pl->name, pl->path, why);
}

/*
 * Open pl->path with every symbol bound now.  libltdl's dlopen loader always
 * asks for RTLD_LAZY (lt_dladvise offers global, local, resident, ext and
 * preload, not immediate binding), and a lazily bound plugin with a symbol
 * nothing defines would load fine and die at its first call, mid-render.
 * So the shared object is first opened with dlopen(RTLD_NOW | RTLD_LOCAL),
 * which binds every symbol or fails naming the missing one; libltdl then
 * finds it loaded and bound.  (Reopening an object already loaded lazily
 * with RTLD_NOW binds nothing more, so a .la, which names its object, is
 * opened through libltdl once to learn the object's file, closed, and
 * opened again in that order.)
 */
static int open_bound(struct plugin *pl, struct err *e)
{
	char object[1024];
	size_t n = strlen(pl->path);
	const char *why;

	snprintf(object, sizeof(object), "%s", pl->path);
	if (n > 3 && !strcmp(pl->path + n - 3, ".la")) {
		lt_dlhandle h;
		const lt_dlinfo *info;

		lt_dlerror();
		if (!(h = lt_dlopen(pl->path)))
			return refuse(pl, e, "cannot load: %s (ldd(1) shows missing libraries)",
				      lt_dlerror());
		info = lt_dlgetinfo(h);
		snprintf(object, sizeof(object), "%s", info && info->filename ?
			 info->filename : pl->path);
		lt_dlclose(h);
	}
	dlerror();
	if (!(pl->dl = dlopen(object, RTLD_NOW | RTLD_LOCAL))) {
		why = dlerror();
		if (why && strstr(why, "undefined symbol"))
			return refuse(pl, e, "cannot load: %s: a plugin may use only the C "
				      "library, libm and what struct wfs_host lends (link it "
				      "with -Wl,-z,defs to find this when building it)", why);
		return refuse(pl, e, "cannot load: %s (ldd(1) shows missing libraries)",
			      why ? why : "unknown error");
	}
	lt_dlerror();
	if (!(pl->handle = lt_dlopen(pl->path)))
		return refuse(pl, e, "cannot load: %s (ldd(1) shows missing libraries)",
			      lt_dlerror());
	return 0;
}

/* The column of each role (model.h, wfs_model.column_roles): as the model
 * declares them, or, for a plugin of an edition before roles, by the names
 * hosts before edition 6 went by. */
static int read_roles(struct plugin *pl, struct err *e)
{
	static const char *const legacy[PLUGIN_ROLES] = { NULL, "n", "re", "ratio", "phi" };
	const struct wfs_model *m = pl->m;
	int declared = WFS_HAS(m->size, struct wfs_model, column_roles);

	for (int k = 0; k < PLUGIN_ROLES; k++)
		pl->role[k] = -1;
	for (int c = 0; c < m->ncolumns; c++) {
		const char *name = plugin_column(pl, c)->name;
		int k = WFS_ROLE_NONE;

		if (declared)
			k = m->column_roles ? m->column_roles[c] : WFS_ROLE_NONE;
		else
			for (int j = 1; j < PLUGIN_ROLES; j++)
				if (name && !strcasecmp(name, legacy[j]))
					k = j;
		/* a role of a later edition is one this host does not use */
		if (k <= WFS_ROLE_NONE || k >= PLUGIN_ROLES)
			continue;
		if (pl->role[k] >= 0)
			return refuse(pl, e, "columns %d and %d of the descriptor have "
				      "one role, %d", pl->role[k] + 1, c + 1, k);
		pl->role[k] = c;
	}
	return 0;
}

/* Read the descriptor's appended members (model.h), each only when the
 * descriptor's size covers it, and check them. */
static int read_appended(struct plugin *pl, struct err *e)
{
	const struct wfs_model *m = pl->m;
	/* Neither struct has grown since its first edition: the host's are the
	 * smallest a plugin may have. */
	const size_t column1 = sizeof(struct wfs_column), setting1 = sizeof(struct wfs_setting);

	pl->column_size = column1;
	if (WFS_HAS(m->size, struct wfs_model, column_size) && m->column_size) {
		if (m->column_size < column1)
			return refuse(pl, e, "descriptor's column_size %ld is below the %ld "
				      "bytes of struct wfs_column", (long)m->column_size,
				      (long)column1);
		pl->column_size = m->column_size;
	}
	if (WFS_HAS(m->size, struct wfs_model, nsettings) && m->nsettings) {
		pl->setting_size = m->setting_size ? m->setting_size : setting1;
		if (m->nsettings < 0 || !m->settings || pl->setting_size < setting1)
			return refuse(pl, e, "descriptor's settings are inconsistent "
				      "(%ld of %ld bytes)", (long)m->nsettings,
				      (long)pl->setting_size);
		pl->settings = m->settings;
		pl->nsettings = m->nsettings;
		for (int k = 0; k < pl->nsettings; k++)
			if (!plugin_setting(pl, k)->key || !*plugin_setting(pl, k)->key)
				return refuse(pl, e, "setting %d of the descriptor has no key",
					      k + 1);
	}
	if (WFS_HAS(m->size, struct wfs_model, reach))
		pl->reach = m->reach;
	if (WFS_HAS(m->size, struct wfs_model, flags))
		pl->flags = m->flags & WFS_PARALLEL_PREPARE;
	if (WFS_HAS(m->size, struct wfs_model, roman_type))
		pl->roman_type = m->roman_type;
	return read_roles(pl, e);
}

/* The model that draws pl's sources (model.h, drawn_by): loaded, not
 * itself drawn by another, and the two models' columns within the limit. */
static int load_drawer(struct plugins *ps, struct plugin *pl, const char *name,
		       struct err *e)
{
	int d;

	if (!strcmp(name, pl->name))
		return refuse(pl, e, "drawn_by names the model itself");
	if ((d = plugins_get(ps, name, e)) == PLUGIN_REFUSED_SETTING)
		return d;       /* the user's value, as it is */
	if (d < 0) {
		err_prefix(e, "model '%s' is drawn by '%s'", pl->name, name);
		e->code = EXIT_PLUGIN;
		return -1;
	}
	if (ps->p[d].drawer >= 0)
		return refuse(pl, e, "drawn_by names '%s', which is drawn by another model", name);
	if (pl->m->ncolumns + ps->p[d].m->ncolumns > PLUGIN_COLUMNS_MAX)
		return refuse(pl, e, "its columns and those of '%s' are more than %d", name,
			      PLUGIN_COLUMNS_MAX);
	pl->drawer = d;
	return 0;
}

/*
 * Whether a model's refusal at set-up, msg, is of a value the run was
 * given: its first word (after "setting ", as the Sérsic models write it;
 * the point model writes the key alone, a curve file's refusal the key
 * and the file) up to a blank or colon is a key the host answers, an
 * option or --set.  Such a value is the user's bad input (exit 1), not the
 * plugin's failure; the key in key.
 */
static int given_setting(const struct plugins *ps, const char *msg, char *key, size_t size)
{
	size_t n;

	if (!strncmp(msg, "setting ", 8))
		msg += 8;
	n = strcspn(msg, " \t:");
	if (!n || n >= size || (msg[n] != ':' && msg[n] != ' ') || !ps->host->setting)
		return 0;
	memcpy(key, msg, n);
	key[n] = 0;
	return ps->host->setting(ps->host->ctx, key) != NULL;
}

int plugins_get(struct plugins *ps, const char *name, struct err *e)
{
	struct plugin *pl;
	wfs_model_entry_fn entry;
	const struct wfs_model *m;
	const char *drawn_by;
	int idx, r;
	size_t need = offsetof(struct wfs_model, render) + sizeof(m->render);

	for (int i = 0; i < ps->n; i++)
		if (!strcmp(ps->p[i].name, name))
			return ps->p[i].ready ? i : err_set(e, EXIT_PLUGIN, "model '%s' was "
							    "refused earlier in the run", name);
	if (!valid_name(name))
		return err_set(e, EXIT_INPUT, "unknown source type '%s'", name);
	if (ps->n == PLUGIN_MAX)
		return err_set(e, EXIT_PLUGIN, "too many source models (at most %d)",
			       PLUGIN_MAX);
	pl = &ps->p[ps->n];
	memset(pl, 0, sizeof(*pl));
	pl->drawer = -1;
	snprintf(pl->name, sizeof(pl->name), "%s", name);
	if (find_file(ps->path, name, pl->path, sizeof(pl->path)) < 0)
		return err_set(e, EXIT_INPUT,
			       "unknown source type '%s': no model plugin '%s.so' on the "
			       "plugin path %s", name, name, ps->path);
	idx = ps->n++;  /* remembered, so a refused model is refused once */
	if (open_bound(pl, e) < 0)
		return -1;
	entry = (wfs_model_entry_fn)(uintptr_t)lt_dlsym(pl->handle, WFS_MODEL_ENTRY);
	if (!entry)
		return refuse(pl, e, "no symbol '%s': not a wfiscene model plugin",
			      WFS_MODEL_ENTRY);
	if (!(m = entry(WFS_ABI_VERSION)))
		return refuse(pl, e, "the plugin declined this host's ABI version %d",
			      WFS_ABI_VERSION);
	if (m->abi != WFS_ABI_VERSION)
		return refuse(pl, e, "plugin ABI version %ld, this wfiscene speaks "
			      "version %d: rebuild the plugin", (long)m->abi,
			      WFS_ABI_VERSION);
	if (m->size < need)
		return refuse(pl, e, "descriptor of %ld bytes is too small (at least "
			      "%zu): built against another model.h?", (long)m->size, need);
	if (!m->name || strcmp(m->name, name))
		return refuse(pl, e, "descriptor names the model '%s', not the file's name",
			      m->name ? m->name : "(null)");
	drawn_by = WFS_HAS(m->size, struct wfs_model, drawn_by) ? m->drawn_by : NULL;
	if ((!drawn_by && (!m->footprint || !m->render)) ||
	    (m->ncolumns > 0 && !m->columns) || m->ncolumns < 0)
		return refuse(pl, e, "descriptor lacks footprint(), render() or its columns");
	if (m->ncolumns > PLUGIN_COLUMNS_MAX)
		return refuse(pl, e, "descriptor lists %d columns; a model reads at most %d",
			      m->ncolumns, PLUGIN_COLUMNS_MAX);
	pl->m = m;
	if (read_appended(pl, e) < 0)
		return -1;
	/* for the warning that names a misspelt --set key */
	for (int k = 0; k < pl->nsettings; k++)
		setting_declare(plugin_setting(pl, k)->key);
	if (drawn_by && (r = load_drawer(ps, pl, drawn_by, e)) < 0)
		return r;
	for (int c = 0; c < m->ncolumns; c++)
		if (!plugin_column(pl, c)->name || !*plugin_column(pl, c)->name)
			return refuse(pl, e, "column %d of the descriptor has no name", c + 1);
	if (m->init && m->init(ps->host, &pl->state) < 0) {
		char key[64];

		if (e->code != EXIT_OK && given_setting(ps, e->msg, key, sizeof(key))) {
			err_prefix(e, "--set %s: model '%s' refuses it", key, name);
			e->code = EXIT_INPUT;
			return PLUGIN_REFUSED_SETTING;
		}
		err_prefix(e, "model '%s' (%s): set-up failed", name, pl->path);
		if (e->code == EXIT_OK)
			err_set(e, EXIT_PLUGIN, "model '%s' (%s): set-up failed", name, pl->path);
		e->code = EXIT_PLUGIN;
		return -1;
	}
	pl->ready = 1;
	return idx;
}

void plugins_free(struct plugins *ps)
{
	for (int i = 0; i < ps->n; i++) {
		struct plugin *pl = &ps->p[i];

		if (pl->ready && pl->m->fini)
			pl->m->fini(pl->state);
		if (pl->handle)
			lt_dlclose(pl->handle);
		if (pl->dl)
			dlclose(pl->dl);
	}
	if (ps->path)
		lt_dlexit();
	free(ps->path);
	memset(ps, 0, sizeof(*ps));
}
