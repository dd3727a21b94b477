/* data.c - the embedded tables of data/; see data.h. */
#include <stdlib.h>
#include <string.h>

#include "data.h"

struct wfs_embedded {
	const char *name;
	const char *text;
	size_t len;
};
extern const struct wfs_embedded wfs_embedded_tables[];

const char *data_table(const char *name, size_t *len)
{
	for (const struct wfs_embedded *t = wfs_embedded_tables; t->name; t++)
		if (!strcmp(t->name, name)) {
			if (len)
				*len = t->len;
			return t->text;
		}
	return NULL;
}

uint64_t data_checksum(const char *name)
{
	size_t len;
	const char *p = data_table(name, &len);
	uint64_t h = 0xcbf29ce484222325ULL;

	for (size_t i = 0; p && i < len; i++)
		h = (h ^ (unsigned char)p[i]) * 0x100000001b3ULL;
	return h;
}

int tsv_parse(struct tsv *t, const char *name)
{
	size_t len;
	const char *src = data_table(name, &len);
	char *p, *line, *save = NULL;
	int cap = 0;

	memset(t, 0, sizeof(*t));
	if (!src || !(t->text = malloc(len + 1)))
		return -1;
	memcpy(t->text, src, len);
	t->text[len] = 0;
	for (line = strtok_r(t->text, "\n", &save); line;
	     line = strtok_r(NULL, "\n", &save)) {
		char **cells;
		int n = 1;

		if (line[0] == '#' || line[0] == 0)
			continue;
		for (p = line; *p; p++)
			n += *p == '\t';
		if (!(cells = malloc(n * sizeof(*cells))))
			goto fail;
		n = 0;
		cells[n++] = line;
		for (p = line; *p; p++)
			if (*p == '\t') {
				*p = 0;
				cells[n++] = p + 1;
			}
		if (t->nrow == 0)
			t->ncol = n;
		if (n < t->ncol) {      /* a short row is a broken build */
			free(cells);
			goto fail;
		}
		if (t->nrow == cap) {
			char ***more;

			cap = cap ? 2 * cap : 64;
			if (!(more = realloc(t->cell, cap * sizeof(*more)))) {
				free(cells);
				goto fail;
			}
			t->cell = more;
		}
		t->cell[t->nrow++] = cells;
	}
	return 0;
fail:
	tsv_free(t);
	return -1;
}

int tsv_col(const struct tsv *t, const char *colname)
{
	for (int c = 0; t->nrow > 0 && c < t->ncol; c++)
		if (!strcmp(t->cell[0][c], colname))
			return c;
	return -1;
}

void tsv_free(struct tsv *t)
{
	for (int r = 0; r < t->nrow; r++)
		free(t->cell[r]);
	free(t->cell);
	free(t->text);
	memset(t, 0, sizeof(*t));
}
