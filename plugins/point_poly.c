/*
 * point_poly.c - the polyphase copies of the ePSF arrays a source reads:
 * the host's grid nodes, found by the node's address, and the blends of
 * the four nodes at a cell's centre (psf-blend=cell and core), found by an
 * odd key.  Made in prepare(), on the host's thread, and kept until fini;
 * with each copy its summed-area tables (the box sums of the flux factor)
 * and its enclosed light (psf-box=adaptive).
 *
 * The table is an open-addressed hash of p->nslots slots, never removed
 * from, and read by render() on the workers while prepare() adds to it for
 * the next chunk of rows, on several threads.  A copy is made outside the
 * table by whichever thread first misses it (two may make the same one;
 * one is kept), and then a slot is published as in a single-writer
 * lock-free map: the writers take turns (p->lock), and the one adding looks
 * again under the lock, fills p->slot[i] while it is still unseen, then
 * stores its key into p->keys[i] with release order;
 * every probe loads p->keys[i] with acquire order and reads the slot only
 * after seeing its key there, so it sees the slot whole.  (A probe for a
 * key added in an earlier chunk never passes a slot being filled, as that
 * slot was empty when the key went in; the ordering makes the table safe
 * for any probe, an absent key's included, without relying on that.)
 * One field is written after its slot is published: a class cell's
 * neighbours, nbr[0] and nbr[1] (class_add), each stored from NULL to the
 * neighbour's one published class cell, maybe by several threads at once
 * with the same pointer, with release order, and loaded with acquire
 * order.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

static size_t poly_hash(const struct point *p, uint64_t key)
{
	uint64_t h = key;

	h ^= h >> 17;
	h *= 0x9e3779b97f4a7c15ULL;
	return (size_t)(h >> 20) & (p->nslots - 1);
}

/* The published key of slot i (0: empty). */
static inline uint64_t slot_key(const struct point *p, size_t i)
{
	return atomic_load_explicit(&p->keys[i], memory_order_acquire);
}

/* The slot under key, or where it would go: *empty set to the first empty
 * slot on key's path (p->nslots when the table is full). */
static struct poly *poly_probe(struct point *p, uint64_t key, size_t *empty)
{
	size_t i = poly_hash(p, key);

	for (size_t k = 0; k < p->nslots; k++, i = (i + 1) & (p->nslots - 1)) {
		uint64_t s = slot_key(p, i);

		if (s == key)
			return &p->slot[i];
		if (!s) {
			*empty = i;
			return NULL;
		}
	}
	*empty = p->nslots;
	return NULL;
}

const struct poly *poly_find(const struct point *p, uint64_t key)
{
	size_t empty;

	return poly_probe((struct point *)p, key, &empty);
}

/* Make slot i, filled, visible to every probe. */
static void poly_publish(struct point *p, size_t i)
{
	atomic_store_explicit(&p->keys[i], p->slot[i].key, memory_order_release);
}

/* ee[h]: the fraction of the flux in the (2h - 1)^2 pixels about a source
 * on a pixel centre.  Any box of pixels with |i - x| < h and |j - y| < h
 * covers at least the area [-(h - 1/2), h - 1/2]^2 about the source, which
 * is what these pixels cover, so flux * (ee[nee] - ee[h]) bounds the light
 * a box of half-width h leaves out compared with the full box. */
static void ee_table(struct poly *q, const float *node)
{
	int n = q->n, o = q->over, c = q->centre;

	q->ee[0] = 0;
	for (int h = 1; h <= q->nee; h++) {
		double s = 0;
		int r = h - 1;

		for (int d = -r; d <= r; d++) {
			s += node[(size_t)(c - o * r) * n + c + o * d];
			if (r > 0)
				s += node[(size_t)(c + o * r) * n + c + o * d];
		}
		for (int d = -r + 1; d <= r - 1; d++)
			s += node[(size_t)(c + o * d) * n + c - o * r] +
			     node[(size_t)(c + o * d) * n + c + o * r];
		q->ee[h] = q->ee[h - 1] + s;
	}
}

/* The summed-area tables of q's planes; row is m + 1 doubles of scratch. */
static void sat_table(struct poly *q, double *row)
{
	int m = q->m, w = m + 1;

	for (int k = 0; k < q->over * q->over; k++) {
		const float *pl = q->plane + (size_t)k * m * m;
		float *s = q->sat + (size_t)k * w * w;

		for (int c = 0; c < w; c++)
			row[c] = s[c] = 0;
		for (int r = 0; r < m; r++) {
			double run = 0;

			s[(size_t)(r + 1) * w] = 0;
			for (int c = 0; c < m; c++) {
				run += pl[(size_t)r * m + c];
				row[c + 1] += run;
				s[(size_t)(r + 1) * w + c + 1] = (float)row[c + 1];
			}
		}
	}
}

/* Free what poly_build() allocated (a copy another thread beat into the
 * table, or one that failed). */
static void poly_drop(struct poly *q)
{
	free(q->plane);
	free(q->sat);
	free(q->ee);
	q->plane = q->sat = NULL;
	q->ee = NULL;
}

/* Node array's samples into q's planes (phase r, s: rows and columns
 * PAD .. PAD + its samples - 1), the rest of each plane and the slack
 * after the last set to zero: each float written once (no calloc). */
static void plane_fill(struct poly *q, const float *node)
{
	int n = q->n, over = q->over, m = q->m;

	for (int r = 0; r < over; r++)
		for (int s = 0; s < over; s++) {
			float *pl = q->plane + (size_t)(r * over + s) * m * m;
			int ny = (n - r + over - 1) / over, nx = (n - s + over - 1) / over;

			memset(pl, 0, (size_t)PAD * m * sizeof(float));
			for (int a = 0; a < ny; a++) {
				float *row = pl + (size_t)(PAD + a) * m;
				const float *in = node + (size_t)(r + a * over) * n + s;

				for (int b = 0; b < PAD; b++)
					row[b] = 0;
				for (int b = 0; b < nx; b++)
					row[PAD + b] = in[(size_t)b * over];
				for (int b = PAD + nx; b < m; b++)
					row[b] = 0;
			}
			memset(pl + (size_t)(PAD + ny) * m, 0,
			       (size_t)(m - PAD - ny) * m * sizeof(float));
		}
	memset(q->plane + (size_t)over * over * m * m, 0, VSLACK * sizeof(float));
}

/* The polyphase copy of an n x n ePSF array under key, into *q, outside
 * the table: any thread, no lock.  Returns 0, or -1 with an error recorded
 * (poly_drop() then has nothing to free). */
static int poly_build(struct point *p, uint64_t key, const float *node, int n, int over,
		      struct poly *q)
{
	int m = (n + over - 1) / over + 2 * PAD + 1;
	double *row;

	*q = (struct poly){ .key = key, .n = n, .over = over, .centre = (n - 1) / 2, .m = m };
	q->nee = q->centre / over;
	q->plane = malloc(((size_t)over * over * m * m + VSLACK) * sizeof(float));
	q->sat = malloc((size_t)over * over * (m + 1) * (m + 1) * sizeof(float));
	q->ee = malloc(((size_t)q->nee + 1) * sizeof(double));
	row = malloc((size_t)(m + 1) * sizeof(double));
	if (!q->plane || !q->sat || !q->ee || !row) {
		free(row);
		poly_drop(q);
		return p->host->error(p->host->ctx, "out of memory");
	}
	plane_fill(q, node);
	ee_table(q, node);
	sat_table(q, row);
	free(row);
	return 0;
}

/*
 * Put the copy *q into the table and publish it, unless a copy under its
 * key got there first (then *q is dropped and that one returned): the
 * writers take turns under p->lock, so a slot is filled by one thread while
 * unseen.  NULL with an error recorded when the table is full.
 */
static struct poly *poly_insert(struct point *p, struct poly *q)
{
	struct poly *in;
	size_t i = 0;

	pthread_mutex_lock(&p->lock);
	if ((in = poly_probe(p, q->key, &i))) {
		poly_drop(q);
	} else if (i == p->nslots) {
		poly_drop(q);
		p->host->error(p->host->ctx, "too many ePSF nodes and cells (%zu): the --psf "
			       "grid has too many nodes", p->nslots);
	} else {
		p->slot[i] = *q;
		poly_publish(p, i);
		in = &p->slot[i];
	}
	pthread_mutex_unlock(&p->lock);
	return in;
}

/* The polyphase copy of an n x n ePSF array under key, made and published
 * the first time (two threads may both make it; one copy is kept).  NULL
 * with an error recorded when it fails. */
struct poly *poly_add(struct point *p, uint64_t key, const float *node, int n, int over)
{
	size_t i;
	struct poly *q = poly_probe(p, key, &i), made;

	if (q)
		return q;
	if (poly_build(p, key, node, n, over, &made) < 0)
		return NULL;
	return poly_insert(p, &made);
}

/* The last cell kept along an axis for psf-cell c: the cells -1 .. this
 * cover the detector and one cell beyond each edge. */
static long cell_last(long c)
{
	return (WFS_SCA_SIDE + c - 1) / c;
}

/* The slots wanted for psf-cell c (twice the cells and nodes kept). */
static size_t slots_wanted(const struct point *p, long c)
{
	size_t side = (size_t)cell_last(c) + 2;
	size_t cells = p->blend == BLEND_SOURCE ? 0 : side * side * WFS_SCA_COUNT *
		       (p->blend == BLEND_CELL ? 3 : 1) * (1 + (size_t)p->colour_cells);

	return 2 * (cells + POLY_NODES);
}

/*
 * The table, sized once for every cell the run can make, so that it never
 * fills in the middle of a run (which row found it full would depend on
 * the order the threads prepare in): the cells of psf-cell pixels over
 * the detector and one cell beyond each edge, on each of the 18 SCAs, for
 * the one class psf-blend=core blends (the faint one) or the three of
 * psf-blend=cell, plus POLY_NODES node copies, at most half full.  A
 * source in a cell beyond that (a faint star placed far off the detector,
 * whose light reaches in) reads its own four nodes (cell_in_range), as
 * decided by its position alone.  Returns 0, or -1 with an error recorded
 * when psf-cell is so small that the table would pass POLY_SLOTS_MAX.
 */
int poly_table_init(struct point *p)
{
	size_t need = slots_wanted(p, p->cell), n = 1024;

	p->cell_hi = cell_last(p->cell);
	if (need > POLY_SLOTS_MAX) {
		long c = p->cell;

		while (c < 4096 && slots_wanted(p, c) > POLY_SLOTS_MAX)
			c++;
		return p->host->error(p->host->ctx, "psf-cell: %d pixels makes more blended "
				      "cells than the point model keeps; use %ld or more", p->cell, c);
	}
	while (n < need)
		n *= 2;
	p->nslots = n;
	p->slot = calloc(n, sizeof(*p->slot));
	p->keys = calloc(n, sizeof(*p->keys));
	if (!p->slot || !p->keys)
		return p->host->error(p->host->ctx, "out of memory for %zu ePSF copies", n);
	return 0;
}

/* Whether src's cell is one the table keeps room for (poly_table_init). */
int cell_in_range(const struct point *p, const struct wfs_source *src)
{
	double cx = floor(src->x / p->cell), cy = floor(src->y / p->cell);

	return cx >= -1 && cx <= p->cell_hi && cy >= -1 && cy <= p->cell_hi;
}

/* The key of the blended cell holding (x, y): odd, so never a node's. */
/* A colour source's cell: its class pair k, k + 1 (point_pair) and the
 * step j of 1/steps (0 .. steps) between them its colour rounds to; the
 * cell's index among the colour cells of its position, or -1 for the
 * default spectrum.  The end steps are one class's blend, which the pairs
 * on either side share: the class cell of class K, index K (steps + 1),
 * for step 0 of pair K and step steps of pair K - 1 (struct poly,
 * cclass). */
static long colour_cell(const struct point *p, const struct wfs_source *src, int *k, int *j)
{
	double c = point_colour(p, src), f;
	int s = p->colour_steps;

	if (!(c >= 0) || !p->colour_cells)
		return -1;
	point_pair(p, c, k, &f);
	/* lround(f s), f s >= 0, without a library call */
	*j = (int)lfloor(f * s + 0.5);
	return (long)(*k + (*j == s)) * (s + 1) + (*j == s ? 0 : *j);
}

/* The key of the cell holding src, whose colour cell is cc (colour_cell). */
static uint64_t key_of(const struct point *p, const struct wfs_source *src, long cc)
{
	uint64_t cx = (uint64_t)(int64_t)floor(src->x / p->cell) & 0xffff;
	uint64_t cy = (uint64_t)(int64_t)floor(src->y / p->cell) & 0xffff;
	uint64_t q = (uint64_t)(cc + 1) & 0x7fff;

	return 1 | (uint64_t)src->sca << 1 | (uint64_t)src->psf_class << 8 | cx << 16 | cy << 32 |
	       q << 48;
}

uint64_t cell_key(const struct point *p, const struct wfs_source *src)
{
	int k, j;

	return key_of(p, src, colour_cell(p, src, &k, &j));
}

/* The blend of the nw arrays node[] with weights w[] (a weight 0 skipped),
 * summed in double in the order given, into a new float array of nn
 * samples; NULL with an error recorded.  Each sample is 0 + the first
 * product + the next ..., as a sum from 0 (-0 becomes +0): in one pass when
 * four weights are not 0 (most cells), else a block of samples at a time
 * on the stack, so that no array of nn doubles is written and read again
 * (a cell of the faint class is 31 000 samples). */
static float *blend_nodes(struct point *p, const float *const node[8], const double w[8],
			  int nw, size_t nn)
{
	float *mix = malloc(nn * sizeof(float));
	const float *nd[8];
	double wk[8], v[256];
	int m = 0;

	if (!mix) {
		p->host->error(p->host->ctx, "out of memory");
		return NULL;
	}
	for (int k = 0; k < nw; k++)
		if (w[k] != 0) {
			nd[m] = node[k];
			wk[m++] = w[k];
		}
	if (m == 4) {           /* one pass */
		for (size_t i = 0; i < nn; i++)
			mix[i] = (float)((((0.0 + wk[0] * nd[0][i]) + wk[1] * nd[1][i]) +
					  wk[2] * nd[2][i]) + wk[3] * nd[3][i]);
		return mix;
	}
	for (size_t i0 = 0; i0 < nn; i0 += 256) {
		size_t nb = nn - i0 < 256 ? nn - i0 : 256;

		for (size_t i = 0; i < nb; i++)
			v[i] = 0.0;
		for (int k = 0; k < m; k++)
			for (size_t i = 0; i < nb; i++)
				v[i] += wk[k] * nd[k][i0 + i];
		for (size_t i = 0; i < nb; i++)
			mix[i0 + i] = (float)v[i];
	}
	return mix;
}

/* The key of class k's cell (colour_cell: index k (steps + 1)) at the
 * position of the cell under key. */
static uint64_t class_key(const struct point *p, uint64_t key, int k)
{
	return (key & ~(0x7fffULL << 48)) | (uint64_t)((long)k * (p->colour_steps + 1) + 1) << 48;
}

/* A cell blended from the nw arrays node[] (n x n, over) with weights w[]
 * into *made, unpublished, with how's colour fields; psf-blend=core: the
 * nodes' own polyphase copies made (and published) first, so that the
 * cell is published whole.  A pair's colour cell keeps both classes'
 * nodes of every position weight (a class's weight may be 0: the core's
 * correction reads them for the sources in the cell).  Returns 0, or -1
 * with an error recorded. */
static int cell_make(struct point *p, uint64_t key, const float *const node[8],
		     const double w[8], int nw, int n, int over, const struct poly *how,
		     struct poly *made)
{
	const float *cnode[8];
	const struct poly *cpoly[8];
	float *mix;
	int rc;

	for (int k = 0; k < 8; k++) {
		cnode[k] = k < nw && (w[k] != 0 || (nw == 8 && w[k ^ 4] != 0)) ? node[k] : NULL;
		cpoly[k] = NULL;
		if (p->blend == BLEND_CORE && cnode[k] &&
		    !(cpoly[k] = poly_add(p, (uint64_t)(uintptr_t)node[k], node[k], n, over)))
			return -1;
	}
	if (!(mix = blend_nodes(p, node, w, nw, (size_t)n * n)))
		return -1;
	rc = poly_build(p, key, mix, n, over, made);
	free(mix);
	if (rc < 0)
		return -1;
	for (int k = 0; k < 8; k++) {
		made->cnode[k] = cnode[k];
		made->cweight[k] = cnode[k] ? w[k] : 0;
		/* a class cell's nodes are those of either step (cpoly[k +
		 * 4 e], point_epsf.c) */
		made->cpoly[k] = how->cclass >= 0 && k >= 4 ? cpoly[k - 4] : cpoly[k];
	}
	made->cstep = how->cstep;
	made->ends[0] = how->ends[0];
	made->ends[1] = how->ends[1];
	made->cclass = how->cclass;
	made->nbr[0] = made->nbr[1] = NULL;
	return 0;
}

/* Class k's cell at the position of the cell under key (centre cx, cy)
 * of the source's SCA and size class: the published one, else made (its
 * nodes kept, psf-blend=core's copies made) and published with no
 * neighbours yet.  NULL with an error recorded. */
static struct poly *class_cell(struct point *p, const struct wfs_source *src, uint64_t key,
			       double cx, double cy, int k)
{
	struct poly made, how = { .cclass = k };
	struct poly *c = (struct poly *)poly_find(p, class_key(p, key, k));
	struct wfs_epsf e;
	const float *node[8] = { NULL };
	double w[8] = { 0 };

	if (c)
		return c;
	if (p->host->epsf_colour(p->host->ctx, src->sca, cx, cy, src->psf_class, k, &e) < 0)
		return NULL;
	for (int i = 0; i < 4; i++) {
		node[i] = e.node[i];
		w[i] = e.weight[i];
	}
	if (cell_make(p, class_key(p, key, k), node, w, 4, e.n, e.over, &how, &made) < 0)
		return NULL;
	return poly_insert(p, &made);
}

/*
 * psf-blend=core: class K's cell at the position of the cell under key
 * (centre cx, cy), with its neighbours' cells there (the classes K - 1
 * and K + 1 of its family, where they are) made or found, published and
 * set in it: a colour source of either pair about K reads both classes'
 * cells in its core (cell_correction_colour).  A neighbour is set once,
 * from NULL to its one published cell (poly_insert() keeps the first of
 * two threads'), so threads that set it at once store the same pointer.
 * Before, the neighbours were set before the cell was published.  (The
 * pairs' differences were kept as arrays of their own before: in a scene
 * of many colours, three more arrays per position in F146.)  Returns the
 * cell; NULL with an error recorded.
 */
static struct poly *class_add(struct point *p, const struct wfs_source *src, uint64_t key,
			      double cx, double cy, int K)
{
	int n = p->nclasses / 2, lo = K % n > 0, hi = K % n < n - 1;
	struct poly *c, *nc;

	if (!(c = class_cell(p, src, key, cx, cy, K)))
		return NULL;
	for (int s = 0; s < 2; s++) {
		if (!(s ? hi : lo) || __atomic_load_n(&c->nbr[s], __ATOMIC_ACQUIRE))
			continue;
		if (!(nc = class_cell(p, src, key, cx, cy, s ? K + 1 : K - 1)))
			return NULL;
		__atomic_store_n(&c->nbr[s], nc, __ATOMIC_RELEASE);
	}
	return c;
}

/* The nodes a cell is blended from at its centre (cx, cy), into node[]
 * and w[] (returns how many, or -1), and its colour fields into *how: the
 * default spectrum's four, a class cell's four of its class (cclass;
 * psf-blend=core's come from class_add), or a pair cell's eight at step
 * f, with psf-blend=core the two classes' cells (ends). */
static int cell_nodes(struct point *p, const struct wfs_source *src, uint64_t key, double cx,
		      double cy, struct poly *how, const float *node[8], double w[8],
		      struct wfs_epsf *e)
{
	struct wfs_epsf ep[2];
	const struct poly *c;
	int ck, cj, nw = 0;

	how->cclass = -1;
	how->cstep = 0;
	how->ends[0] = how->ends[1] = how->nbr[0] = how->nbr[1] = NULL;
	if (colour_cell(p, src, &ck, &cj) < 0) {
		if (p->host->epsf(p->host->ctx, src->sca, cx, cy, src->psf_class, e) < 0)
			return -1;
		for (int k = 0; k < 4; k++) {
			node[nw] = e->node[k];
			w[nw++] = e->weight[k];
		}
		return nw;
	}
	if (cj == 0 || cj == p->colour_steps) {
		how->cclass = ck + (cj != 0);
		if (p->host->epsf_colour(p->host->ctx, src->sca, cx, cy, src->psf_class,
					 how->cclass, e) < 0)
			return -1;
		for (int k = 0; k < 4; k++) {
			node[nw] = e->node[k];
			w[nw++] = e->weight[k];
		}
		return nw;
	}
	/* a pair cell: the pair's nodes, its blend rounded to cj / steps */
	how->cstep = (double)cj / p->colour_steps;
	for (int i = 0; i < 2; i++) {
		if (p->host->epsf_colour(p->host->ctx, src->sca, cx, cy, src->psf_class, ck + i,
					 &ep[i]) < 0)
			return -1;
		*e = ep[i];
		for (int k = 0; k < 4; k++) {
			node[nw] = e->node[k];
			w[nw++] = (i ? how->cstep : 1 - how->cstep) * e->weight[k];
		}
	}
	if (p->blend == BLEND_CORE) {
		if (!(c = class_add(p, src, key, cx, cy, ck)))
			return -1;
		/* set (class_add), maybe stored again by another thread */
		how->ends[0] = c;
		how->ends[1] = __atomic_load_n(&c->nbr[1], __ATOMIC_ACQUIRE);
	}
	return nw;
}

/* psf-blend=cell: the ePSF blended once at the centre of the source's cell
 * (bilinear in position, as the host's weights say), so a source reads one
 * array instead of four.  Made outside the lock, like poly_add().  NULL
 * with an error recorded when it fails. */
struct poly *cell_add(struct point *p, const struct wfs_source *src)
{
	int nw, ck, cj;
	long cc = colour_cell(p, src, &ck, &cj);
	uint64_t key = key_of(p, src, cc);
	struct wfs_epsf e;
	double cx = (floor(src->x / p->cell) + 0.5) * p->cell - 0.5;
	double cy = (floor(src->y / p->cell) + 0.5) * p->cell - 0.5;
	struct poly *c, made, how;
	const float *node[8];
	double w[8];

	/* a class cell: found there, its pairs checked (class_add) */
	if (p->blend == BLEND_CORE && cc >= 0 && (cj == 0 || cj == p->colour_steps))
		return class_add(p, src, key, cx, cy, ck + (cj != 0));
	if ((c = (struct poly *)poly_find(p, key)))
		return c;
	if ((nw = cell_nodes(p, src, key, cx, cy, &how, node, w, &e)) < 0 ||
	    cell_make(p, key, node, w, nw, e.n, e.over, &how, &made) < 0)
		return NULL;
	return poly_insert(p, &made);
}

void poly_free_all(struct point *p)
{
	for (size_t i = 0; p->slot && i < p->nslots; i++) {
		free(p->slot[i].plane);
		free(p->slot[i].sat);
		free(p->slot[i].ee);
	}
	free(p->slot);
	free((void *)p->keys);
	p->slot = NULL;
	p->keys = NULL;
}
