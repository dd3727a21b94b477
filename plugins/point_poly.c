/*
 * point_poly.c - the polyphase copies of the ePSF arrays a source reads:
 * the host's grid nodes, found by the node's address, and the blends of
 * the four nodes at a cell's centre (psf-blend=cell and core), found by an
 * odd key.  Made in prepare(), on the host's thread, and kept until fini;
 * with each copy its summed-area tables (the box sums of the flux factor)
 * and its enclosed light (psf-box=adaptive).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

static size_t poly_hash(uint64_t key)
{
	uint64_t h = key;

	h ^= h >> 17;
	h *= 0x9e3779b97f4a7c15ULL;
	return (size_t)(h >> 20) & (POLY_SLOTS - 1);
}

const struct poly *poly_find(const struct point *p, uint64_t key)
{
	for (size_t i = poly_hash(key), k = 0; k < POLY_SLOTS; k++, i = (i + 1) & (POLY_SLOTS - 1)) {
		if (p->slot[i].key == key)
			return &p->slot[i];
		if (!p->slot[i].key)
			return NULL;
	}
	return NULL;
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

/* The polyphase copy of an n x n ePSF array under key, made the first time.
 * Main thread only (prepare).  NULL with an error recorded when it fails. */
struct poly *poly_add(struct point *p, uint64_t key, const float *node, int n, int over)
{
	int m = (n + over - 1) / over + 2 * PAD + 1;
	size_t i = poly_hash(key), k;
	struct poly q = { .key = key, .n = n, .over = over, .centre = (n - 1) / 2, .m = m };
	double *row;

	for (k = 0; k < POLY_SLOTS && p->slot[i].key; k++) {
		if (p->slot[i].key == key)
			return &p->slot[i];
		i = (i + 1) & (POLY_SLOTS - 1);
	}
	if (k == POLY_SLOTS) {
		p->host->error(p->host->ctx, "too many ePSF nodes and cells (%d)", POLY_SLOTS);
		return NULL;
	}
	q.nee = q.centre / over;
	q.plane = calloc((size_t)over * over * m * m + VSLACK, sizeof(float));
	q.sat = malloc((size_t)over * over * (m + 1) * (m + 1) * sizeof(float));
	q.ee = calloc((size_t)q.nee + 1, sizeof(double));
	row = malloc((size_t)(m + 1) * sizeof(double));
	if (!q.plane || !q.sat || !q.ee || !row) {
		free(q.plane);
		free(q.sat);
		free(q.ee);
		free(row);
		p->host->error(p->host->ctx, "out of memory");
		return NULL;
	}
	for (int r = 0; r < over; r++)
		for (int s = 0; s < over; s++) {
			float *pl = q.plane + (size_t)(r * over + s) * m * m;

			for (int y = r, a = PAD; y < n; y += over, a++)
				for (int x = s, b = PAD; x < n; x += over, b++)
					pl[a * m + b] = node[(size_t)y * n + x];
		}
	ee_table(&q, node);
	sat_table(&q, row);
	free(row);
	p->slot[i] = q;
	return &p->slot[i];
}

/* The key of the blended cell holding (x, y): odd, so never a node's. */
uint64_t cell_key(const struct point *p, const struct wfs_source *src)
{
	uint64_t cx = (uint64_t)(int64_t)floor(src->x / p->cell) & 0xffff;
	uint64_t cy = (uint64_t)(int64_t)floor(src->y / p->cell) & 0xffff;

	return 1 | (uint64_t)src->sca << 1 | (uint64_t)src->psf_class << 8 | cx << 16 | cy << 32;
}

/* psf-blend=cell: the ePSF blended once at the centre of the source's cell
 * (bilinear in position, as the host's weights say), so a source reads one
 * array instead of four.  NULL with an error recorded when it fails. */
struct poly *cell_add(struct point *p, const struct wfs_source *src)
{
	uint64_t key = cell_key(p, src);
	struct wfs_epsf e;
	double cx = (floor(src->x / p->cell) + 0.5) * p->cell - 0.5;
	double cy = (floor(src->y / p->cell) + 0.5) * p->cell - 0.5;
	struct poly *c = (struct poly *)poly_find(p, key);
	float *mix;
	size_t nn;

	if (c)
		return c;
	if (p->host->epsf(p->host->ctx, src->sca, cx, cy, src->psf_class, &e) < 0)
		return NULL;
	nn = (size_t)e.n * e.n;
	if (!(mix = malloc(nn * sizeof(float)))) {
		p->host->error(p->host->ctx, "out of memory");
		return NULL;
	}
	for (size_t i = 0; i < nn; i++) {
		double v = 0;

		for (int k = 0; k < 4; k++)
			if (e.weight[k] != 0)
				v += e.weight[k] * e.node[k][i];
		mix[i] = (float)v;
	}
	c = poly_add(p, key, mix, e.n, e.over);
	free(mix);
	if (!c)
		return NULL;
	/* what the cell was blended from, for the core's correction
	 * (psf-blend=core): the nodes' own polyphase copies too */
	for (int k = 0; k < 4; k++) {
		c->cnode[k] = e.weight[k] != 0 ? e.node[k] : NULL;
		c->cweight[k] = e.weight[k] != 0 ? e.weight[k] : 0;
		c->cpoly[k] = NULL;
		if (p->blend == BLEND_CORE && c->cnode[k] &&
		    !(c->cpoly[k] = poly_add(p, (uint64_t)(uintptr_t)e.node[k], e.node[k], e.n, e.over)))
			return NULL;
	}
	return c;
}

void poly_free_all(struct point *p)
{
	for (int i = 0; i < POLY_SLOTS; i++) {
		free(p->slot[i].plane);
		free(p->slot[i].sat);
		free(p->slot[i].ee);
	}
}
