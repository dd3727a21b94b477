/*
 * tree.c - catalog trees: which files of a directory split by HEALPix
 * pixel a scene needs; see tree.h.
 *
 * A file is opened when its pixel reaches one of the region's discs.  The
 * test is hierarchical on the nested scheme: a pixel whose centre lies
 * farther from the disc's centre than the disc's radius plus the pixel's
 * largest centre-to-corner angle (max_pixrad) cannot reach it; one within
 * the radius minus that angle lies inside; the others are split into their
 * four children, down to pixels a sixteenth of the radius across, which
 * are taken as reaching.  So a file is skipped only when its pixel surely
 * misses every disc, and opened in vain only when it passes within a
 * sixteenth of a disc's radius of it.
 */
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fnmatch.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <chealpix.h>
#include <fitsio.h>

#include "err.h"
#include "options.h"
#include "tree.h"

#define TREE_MAX_DEPTH 8        /* directory levels below the tree */
#define TREE_MAX_ORDER 29       /* NSIDE 2^29, chealpix's limit */
#define DEG (M_PI / 180.0)

struct tfile {
	char *path;
	long long pix;          /* as in the name */
	int order;              /* HATS: its order K; -1: the tree's NSIDE */
	long long size;         /* bytes */
	int read;               /* chosen */
};

struct tree {
	char *dir;
	struct tfile *f;
	size_t n, cap;
	size_t *order;          /* indices of the files to read, in order */
	size_t nread;
	long long nside;        /* of the flat scheme; 0 when unknown */
	int nested;             /* of the flat scheme */
	struct tree_counts counts;
};

int tree_is_dir(const char *path)
{
	struct stat st;

	return path && strcmp(path, "-") != 0 && stat(path, &st) == 0 &&
	       S_ISDIR(st.st_mode);
}

static const char *setting(const struct tree_opts *o, const char *key)
{
	return setting_last(o->settings, key);
}

/* "Npix=N.ext": N; "NAME_N.ext", "NAME-N.ext", "N.ext": N; -2 for such a
 * name whose N has more than 18 digits (no HEALPix pixel is that large);
 * else -1. */
static long long name_pixel(const char *base, int *hats)
{
	const char *dot = strchr(base, '.');
	size_t len = dot ? (size_t)(dot - base) : strlen(base);
	const char *p = base + len;
	long long v = 0;

	*hats = 0;
	if (len > 5 && !strncmp(base, "Npix=", 5)) {
		*hats = 1;
		p = base + 5;
	} else {
		while (p > base && isdigit((unsigned char)p[-1]))
			p--;
		if (p == base + len || (p > base && p[-1] != '_' && p[-1] != '-'))
			return -1;
	}
	for (const char *q = p; q < base + len; q++)
		if (!isdigit((unsigned char)*q))
			return -1;
	if (base + len - p > 18)
		return -2;
	for (; p < base + len; p++)
		v = v * 10 + (*p - '0');
	return v;
}

static int add_file(struct tree *t, const char *path, long long pix, int order,
		    long long size, struct err *e)
{
	if (t->n == t->cap) {
		size_t cap = t->cap ? 2 * t->cap : 64;
		struct tfile *f = realloc(t->f, cap * sizeof(*f));

		if (!f)
			return err_set(e, EXIT_SYSTEM, "out of memory");
		t->f = f;
		t->cap = cap;
	}
	if (!(t->f[t->n].path = strdup(path)))
		return err_set(e, EXIT_SYSTEM, "out of memory");
	t->f[t->n].pix = pix;
	t->f[t->n].order = order;
	t->f[t->n].size = size;
	t->f[t->n].read = 0;
	t->n++;
	return 0;
}

/* Walk dir (depth levels below the tree); order is the HATS order of an
 * enclosing "Norder=K" directory, or -1. */
static int walk(struct tree *t, const char *dir, int depth, int order,
		const char *glob, struct err *e)
{
	DIR *d = opendir(dir);
	struct dirent *de;
	int rc = 0;

	if (!d)
		return err_set(e, EXIT_SYSTEM, "%s: %s", dir, strerror(errno));
	while (rc == 0 && (errno = 0, de = readdir(d))) {
		char *path;
		struct stat st;
		size_t n;

		if (de->d_name[0] == '.')
			continue;
		n = strlen(dir) + strlen(de->d_name) + 2;
		if (!(path = malloc(n))) {
			rc = err_set(e, EXIT_SYSTEM, "out of memory");
			break;
		}
		snprintf(path, n, "%s/%s", dir, de->d_name);
		if (stat(path, &st) < 0) {
			rc = err_set(e, EXIT_SYSTEM, "%s: %s", path, strerror(errno));
		} else if (S_ISDIR(st.st_mode)) {
			int k = order;

			if (!strncmp(de->d_name, "Norder=", 7)) {
				char *end;
				long v = strtol(de->d_name + 7, &end, 10);

				if (*end || end == de->d_name + 7 || v < 0 || v > TREE_MAX_ORDER)
					rc = err_set(e, EXIT_INPUT, "%s: not a HEALPix order (0 to %d)",
						     path, TREE_MAX_ORDER);
				k = (int)v;
			}
			if (rc == 0 && depth >= TREE_MAX_DEPTH)
				rc = err_set(e, EXIT_INPUT, "%s: more than %d levels of directories",
					     path, TREE_MAX_DEPTH);
			if (rc == 0)
				rc = walk(t, path, depth + 1, k, glob, e);
		} else if (S_ISREG(st.st_mode)) {
			int hats;
			long long pix = name_pixel(de->d_name, &hats);

			if (pix != -1 && (!glob || fnmatch(glob, de->d_name, 0) == 0)) {
				if (pix == -2)
					rc = err_set(e, EXIT_INPUT, "%s: a pixel number of more "
						     "than 18 digits: no HEALPix pixel is that large",
						     path);
				else if (hats && order < 0)
					rc = err_set(e, EXIT_INPUT,
						     "%s: a HATS file 'Npix=N' outside a 'Norder=K' directory",
						     path);
				else
					rc = add_file(t, path, pix, hats ? order : -1,
						      (long long)st.st_size, e);
			}
		}
		free(path);
	}
	if (rc == 0 && errno)
		rc = err_set(e, EXIT_SYSTEM, "%s: %s", dir, strerror(errno));
	closedir(d);
	return rc;
}

static int parse_ordering(const char *v, const char *where, int *nested,
			  struct err *e)
{
	if (!strcasecmp(v, "ring"))
		*nested = 0;
	else if (!strcasecmp(v, "nested") || !strcasecmp(v, "nest"))
		*nested = 1;
	else
		return err_set(e, EXIT_INPUT, "%s: ordering '%s': want ring or nested", where, v);
	return 0;
}

static int parse_nside(const char *v, const char *where, long long *nside,
		       struct err *e)
{
	char *end;
	long long n = strtoll(v, &end, 10);

	while (*end == ' ' || *end == '\t')
		end++;
	if (end == v || *end || n < 1 || n > (1ll << TREE_MAX_ORDER))
		return err_set(e, EXIT_INPUT, "%s: NSIDE '%s': want an integer from 1 to 2^%d",
			       where, v, TREE_MAX_ORDER);
	*nside = n;
	return 0;
}

/* A HEALPIX file (key=value lines) or a YAML file (key: value lines): its
 * nside and ordering keys, at any indentation.  Returns 0 or -1. */
static int read_config(struct tree *t, const char *path, char sep, struct err *e)
{
	FILE *f = fopen(path, "r");
	char line[512];
	long ln = 0;
	int rc = 0;

	if (!f)
		return err_set(e, EXIT_SYSTEM, "%s: %s", path, strerror(errno));
	while (rc == 0 && fgets(line, sizeof(line), f)) {
		char *k = line, *v, *q, where[4200];

		ln++;
		while (*k == ' ' || *k == '\t' || *k == '-')
			k++;
		if (!(v = strchr(k, sep)))
			continue;
		*v++ = 0;
		for (q = v + strlen(v); q > v && isspace((unsigned char)q[-1]); )
			*--q = 0;
		while (*v == ' ' || *v == '\t')
			v++;
		if ((q = strchr(v, '#')))
			*q = 0;
		for (q = v + strlen(v); q > v && isspace((unsigned char)q[-1]); )
			*--q = 0;
		for (q = k + strlen(k); q > k && isspace((unsigned char)q[-1]); )
			*--q = 0;
		if (*v == '\'' || *v == '"') {
			v++;
			if (*v && (v[strlen(v) - 1] == '\'' || v[strlen(v) - 1] == '"'))
				v[strlen(v) - 1] = 0;
		}
		snprintf(where, sizeof(where), "%s:%ld", path, ln);
		if (!strcasecmp(k, "nside"))
			rc = parse_nside(v, where, &t->nside, e);
		else if (!strcasecmp(k, "ordering"))
			rc = parse_ordering(v, where, &t->nested, e);
	}
	fclose(f);
	return rc;
}

/* NSIDE and ordering of the flat scheme: settings, then a HEALPIX file,
 * then a YAML file, in the tree's top directory. */
static int find_scheme(struct tree *t, const struct tree_opts *o, struct err *e)
{
	const char *v;
	DIR *d;
	struct dirent *de;
	int rc = 0;
	long long nside_set = 0;
	int nested_set = -1;

	if ((v = setting(o, "tree-nside")) && parse_nside(v, "--set tree-nside", &nside_set, e) < 0)
		return -1;
	if ((v = setting(o, "tree-ordering")) &&
	    parse_ordering(v, "--set tree-ordering", &nested_set, e) < 0)
		return -1;
	if (!(d = opendir(t->dir)))
		return err_set(e, EXIT_SYSTEM, "%s: %s", t->dir, strerror(errno));
	while (rc == 0 && (de = readdir(d))) {
		size_t n = strlen(de->d_name);
		char sep = 0, path[4096];

		if (!strcmp(de->d_name, "HEALPIX"))
			sep = '=';
		else if ((n > 5 && !strcmp(de->d_name + n - 5, ".yaml")) ||
			 (n > 4 && !strcmp(de->d_name + n - 4, ".yml")))
			sep = ':';
		if (!sep || de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s", t->dir, de->d_name);
		rc = read_config(t, path, sep, e);
	}
	closedir(d);
	if (rc < 0)
		return -1;
	if (nside_set)
		t->nside = nside_set;
	if (nested_set >= 0)
		t->nested = nested_set;
	return 0;
}

double tree_max_pixrad(long long nside)
{
	/* The largest centre-to-corner angle of any pixel: between the
	 * corner at z = 2/3, phi = pi/(4 nside) and the centre at
	 * z = 1 - (1 - 1/nside)^2 / 3, phi = 0 (Gorski et al. 2005; the
	 * HEALPix library's max_pixrad). */
	double t1 = 1.0 - 1.0 / (double)nside, za = 2.0 / 3.0, zb;
	double pa = M_PI / (4.0 * (double)nside), sa, sb, a[3], b[3], c[3];

	t1 *= t1;
	zb = 1.0 - t1 / 3.0;
	sa = sqrt((1 - za) * (1 + za));
	sb = sqrt((1 - zb) * (1 + zb));
	a[0] = sa * cos(pa), a[1] = sa * sin(pa), a[2] = za;
	b[0] = sb, b[1] = 0, b[2] = zb;
	c[0] = a[1] * b[2] - a[2] * b[1];
	c[1] = a[2] * b[0] - a[0] * b[2];
	c[2] = a[0] * b[1] - a[1] * b[0];
	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
		     a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / DEG;
}

static double angle_deg(const double a[3], const double b[3])
{
	double c[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
			a[0] * b[1] - a[1] * b[0] };

	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
		     a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / DEG;
}

int tree_pixel_reaches(long long nside, long long pn, const double c[3],
		       double radius)
{
	double v[3], th, rp;

	pix2vec_nest64(nside, pn, v);
	th = angle_deg(v, c);
	/* 1% on the bound: pixel edges are not all great circles */
	rp = tree_max_pixrad(nside) * 1.01 + 1e-9;
	if (th > radius + rp)
		return 0;
	if (th + rp <= radius || rp < radius / 16 || nside >= (1ll << TREE_MAX_ORDER))
		return 1;
	for (int k = 0; k < 4; k++)
		if (tree_pixel_reaches(2 * nside, 4 * pn + k, c, radius))
			return 1;
	return 0;
}

/* Rows of a plain FITS file, from its table headers; -1 when unknown. */
static long long fits_rows(const char *path)
{
	FILE *f = fopen(path, "rb");
	char magic[9];
	fitsfile *ff;
	int status = 0, hdutype;
	long long rows = 0;

	if (!f)
		return -1;
	if (fread(magic, 1, 9, f) != 9 || memcmp(magic, "SIMPLE  =", 9) != 0) {
		fclose(f);
		return -1;
	}
	fclose(f);
	if (fits_open_diskfile(&ff, path, READONLY, &status))
		return -1;
	while (!fits_movrel_hdu(ff, 1, &hdutype, &status)) {
		LONGLONG n = 0;

		if (hdutype == BINARY_TBL || hdutype == ASCII_TBL) {
			fits_get_num_rowsll(ff, &n, &status);
			rows += n;
		}
	}
	if (status == END_OF_FILE)
		status = 0;
	fits_close_file(ff, &status);
	return status ? -1 : rows;
}

/* A file to read and where it sorts. */
struct sortable {
	long long key;
	const char *path;
	size_t index;
};

/* Sky position along the nested curve at order 29 (HATS files, and flat
 * nested ones), or the pixel number (flat ring files); ties by path. */
static long long sort_key(const struct tree *t, const struct tfile *f)
{
	int k = f->order;

	if (k < 0) {
		if (!t->nested)
			return f->pix;
		for (k = 0; (1ll << k) < t->nside; k++)
			;
	}
	return f->pix << (2 * (TREE_MAX_ORDER - k));
}

static int cmp_files(const void *pa, const void *pb)
{
	const struct sortable *a = pa, *b = pb;

	if (a->key != b->key)
		return a->key < b->key ? -1 : 1;
	return strcmp(a->path, b->path);
}

/* Which files of t to read: those whose pixels reach a disc of o (all of
 * them without discs); the others counted as skipped, with their bytes and
 * (from a FITS header) rows. */
static int mark_reads(struct tree *t, const struct tree_opts *o, struct err *e)
{
	double (*cv)[3] = NULL;

	if (o->ndisc && !(cv = malloc((size_t)o->ndisc * sizeof(*cv))))
		return err_set(e, EXIT_SYSTEM, "out of memory");
	for (int d = 0; d < o->ndisc; d++) {
		double th = (90.0 - o->disc[d].dec) * DEG, ph = o->disc[d].ra * DEG;

		cv[d][0] = sin(th) * cos(ph);
		cv[d][1] = sin(th) * sin(ph);
		cv[d][2] = cos(th);
	}
	t->counts.files = t->n;
	for (size_t i = 0; i < t->n; i++) {
		struct tfile *f = &t->f[i];
		long long ns = f->order < 0 ? t->nside : 1ll << f->order, pn = f->pix;

		if (f->order < 0 && !t->nested) {
			int64_t q;

			ring2nest64(ns, f->pix, &q);
			pn = q;
		}
		f->read = !o->ndisc;
		for (int d = 0; d < o->ndisc && !f->read; d++)
			f->read = tree_pixel_reaches(ns, pn, cv[d], o->disc[d].radius);
		if (!f->read) {
			long long rows = fits_rows(f->path);

			t->counts.skipped++;
			t->counts.bytes_skipped += (unsigned long long)f->size;
			if (rows >= 0)
				t->counts.rows_skipped += (unsigned long long)rows;
			else
				t->counts.rows_uncounted++;
		}
	}
	free(cv);
	return 0;
}

struct tree *tree_open(const char *dir, const struct tree_opts *o,
		       struct err *e)
{
	struct tree *t = calloc(1, sizeof(*t));
	int flat = 0, hats = 0;

	if (!t || !(t->dir = strdup(dir))) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	if (find_scheme(t, o, e) < 0 || walk(t, dir, 0, -1, setting(o, "tree-glob"), e) < 0)
		goto fail;
	if (!t->n) {
		err_set(e, EXIT_INPUT, "%s: a directory (a catalog tree) without catalog files: "
			"none is named NAME_PIXEL.EXT or Norder=K/.../Npix=N.EXT%s", dir,
			setting(o, "tree-glob") ? " and matches tree-glob" : "");
		goto fail;
	}
	for (size_t i = 0; i < t->n; i++) {
		flat += t->f[i].order < 0;
		hats += t->f[i].order >= 0;
	}
	if (flat && !t->nside) {
		/* A full sky, numbered from 0, tells its NSIDE. */
		long long max = -1, nside = 1;

		for (size_t i = 0; i < t->n; i++)
			if (t->f[i].order < 0 && t->f[i].pix > max)
				max = t->f[i].pix;
		while (12 * nside * nside < max + 1)
			nside *= 2;
		if (12 * nside * nside == max + 1 && (size_t)(max + 1) == (size_t)flat)
			t->nside = nside;
		else if (12 * nside * nside == max + 1 && (size_t)flat > (size_t)(max + 1))
			t->nside = nside;       /* several files a pixel */
		else {
			err_set(e, EXIT_INPUT,
				"%s: HEALPix NSIDE unknown: give --set tree-nside=N, or a HEALPIX "
				"file with nside=N in the directory", dir);
			goto fail;
		}
	}
	if (flat && t->nested && (t->nside & (t->nside - 1))) {
		err_set(e, EXIT_INPUT, "%s: nested ordering needs NSIDE a power of 2, not %lld",
			dir, t->nside);
		goto fail;
	}
	for (size_t i = 0; i < t->n; i++) {
		struct tfile *f = &t->f[i];
		long long ns = f->order < 0 ? t->nside : 1ll << f->order;

		if (f->pix >= 12 * ns * ns) {
			err_set(e, EXIT_INPUT, "%s: pixel %lld does not exist at NSIDE %lld",
				f->path, f->pix, ns);
			goto fail;
		}
	}

	if (mark_reads(t, o, e) < 0)
		goto fail;
	if (!(t->order = malloc((t->n + 1) * sizeof(size_t)))) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	{
		struct sortable *so = malloc((t->n + 1) * sizeof(*so));

		if (!so) {
			err_set(e, EXIT_SYSTEM, "out of memory");
			goto fail;
		}
		for (size_t i = 0; i < t->n; i++)
			if (t->f[i].read) {
				so[t->nread].key = sort_key(t, &t->f[i]);
				so[t->nread].path = t->f[i].path;
				so[t->nread++].index = i;
			}
		qsort(so, t->nread, sizeof(*so), cmp_files);
		for (size_t k = 0; k < t->nread; k++)
			t->order[k] = so[k].index;
		free(so);
	}
	return t;
fail:
	tree_free(t);
	return NULL;
}

size_t tree_nread(const struct tree *t)
{
	return t->nread;
}

const char *tree_path(const struct tree *t, size_t k)
{
	return k < t->nread ? t->f[t->order[k]].path : NULL;
}

void tree_get_counts(const struct tree *t, struct tree_counts *out)
{
	*out = t->counts;
}

void tree_free(struct tree *t)
{
	if (!t)
		return;
	for (size_t i = 0; i < t->n; i++)
		free(t->f[i].path);
	free(t->f);
	free(t->order);
	free(t->dir);
	free(t);
}
