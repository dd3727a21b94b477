/*
 * tree.h - catalog trees: a directory of catalog files split by HEALPix
 * pixel, of which a scene opens only the files whose pixels reach the sky
 * it simulates (wfiscene-catalog(5), CATALOG TREES).
 *
 * Two naming schemes are recognised, anywhere below the directory:
 *   NAME_PIXEL.EXT      the survey simulations' (and any "_" or "-" before
 *                       the pixel number, e.g. stars-0042.csv.zst); NSIDE
 *                       and ordering from the tree-nside / tree-ordering
 *                       settings, a HEALPIX file (nside=N, ordering=ring
 *                       or nested), a YAML file with "nside:" and
 *                       "ordering:" keys (the survey simulations'
 *                       skyCatalog.yaml), or a full sky of 12 NSIDE^2
 *                       files numbered from 0; ring ordering by default.
 *   Norder=K/.../Npix=N.EXT   HATS / HiPSCat: nested, NSIDE 2^K, each
 *                       file with its own order.
 * Files are read in order of their pixel's position on the sky (nested
 * index at the finest order), ties by path.  Pixel geometry comes from the
 * packaged C HEALPix library (chealpix).
 */
#ifndef WFS_TREE_H
#define WFS_TREE_H

#include <stddef.h>

struct err;

/* A disc on the sky where rows matter, degrees. */
struct tree_disc {
	double ra, dec, radius;
};

struct tree_opts {
	const struct tree_disc *disc;   /* the region: a union of discs */
	int ndisc;                      /* 0: the whole sky */
	const char *const *settings;    /* "key=value", NULL-ended, or NULL:
	                                   tree-nside, tree-ordering, tree-glob */
};

struct tree_counts {
	unsigned long long files;       /* catalog files in the tree */
	unsigned long long skipped;     /* of which not opened */
	unsigned long long bytes_skipped;
	unsigned long long rows_skipped;        /* of the skipped plain FITS
	                                           files, whose headers say */
	unsigned long long rows_uncounted;      /* skipped files whose rows
	                                           are unknown (text, compressed) */
};

struct tree;

/* 1 when path is a directory (a tree), else 0. */
int tree_is_dir(const char *path);

/* List the tree at dir and choose the files that reach o's region.
 * NULL with a message naming the file or the setting at fault. */
struct tree *tree_open(const char *dir, const struct tree_opts *o,
		       struct err *e);

/* The files to read, in order. */
size_t tree_nread(const struct tree *t);
const char *tree_path(const struct tree *t, size_t k);

void tree_get_counts(const struct tree *t, struct tree_counts *out);
void tree_free(struct tree *t);

/* The angle (degrees) within which every point of a HEALPix pixel lies
 * from its centre, at any position, for nside (exposed for tests). */
double tree_max_pixrad(long long nside);

/* 1 when nested pixel pn at nside reaches within radius degrees of the
 * unit vector c (conservatively: also when it comes within a sixteenth of
 * the radius of it), else 0. */
int tree_pixel_reaches(long long nside, long long pn, const double c[3],
		       double radius);

#endif
