/*
 * point_epsf.c - a source drawn in its ePSF box (point.c's opening comment
 * has the method): prepare() picks the arrays the source reads, its box
 * and zones, and what its flux factor needs; render() draws a window of
 * the box with the kernels of point_kernels.c.
 */
#include <math.h>
#include <stdlib.h>

#include "point.h"

/* Colour: the source's spectral class (model.h, wfs_source.colour), or -1
 * for the scene's default spectrum (and hosts without classes).  A source
 * with one reads the four nodes of each of its two classes: per source, or
 * (psf-colour-steps > 0) a cell blended from them at its class pair
 * rounded to 1/psf-colour-steps, with psf-blend=core's correction to its
 * own blend in the core (point_poly.c, cell_add). */
static double colour_of(const struct point *p, const struct wfs_source *src)
{
	return point_colour(p, src);
}

/* The host's ePSFs at src: e[0] with weight wc[0], and e[1] with wc[1]
 * for a source between two spectral classes, cls[] their classes (-1:
 * the default spectrum).  Returns how many, or -1. */
static int src_epsf(const struct point *p, const struct wfs_source *src, struct wfs_epsf e[2],
		    double wc[2], int cls[2])
{
	double c = colour_of(p, src), f, w2[2];
	int k, n = 0;

	wc[0] = 1;
	cls[0] = -1;
	if (!(c >= 0))
		return p->host->epsf(p->host->ctx, src->sca, src->x, src->y, src->psf_class,
				     &e[0]) < 0 ? -1 : 1;
	/* the classes of the pair (point_pair) with a weight */
	point_pair(p, c, &k, &f);
	w2[0] = 1 - f;
	w2[1] = f;
	for (int i = 0; i < 2; i++)
		if (w2[i] > 0) {
			if (p->host->epsf_colour(p->host->ctx, src->sca, src->x, src->y,
						 src->psf_class, k + i, &e[n]) < 0)
				return -1;
			cls[n] = k + i;
			wc[n++] = w2[i];
		}
	return n;
}

/* The arrays a source reads and their weights times its flux: the four
 * nodes of its position (blend = BLEND_SOURCE), or its cell's blend.
 * Returns how many, or -1. */
static int source_polys(const struct point *p, const struct wfs_source *src, int blend,
			const struct poly *pl[8], double wn[8])
{
	struct wfs_epsf es[2];
	double wc[2];
	int nn = 0, ne, cls[2];

	if (blend != BLEND_SOURCE) {
		if (!(pl[0] = poly_find(p, cell_key(p, src))))
			return p->host->error(p->host->ctx, "ePSF cell not prepared");
		wn[0] = src->flux;
		return 1;
	}
	if ((ne = src_epsf(p, src, es, wc, cls)) < 0)
		return -1;
	for (int i = 0; i < ne; i++)
		for (int k = 0; k < 4; k++)
			if (es[i].weight[k] != 0) {
				if (!(pl[nn] = poly_find(p, (uint64_t)(uintptr_t)es[i].node[k])))
					return p->host->error(p->host->ctx, "ePSF node not prepared");
				wn[nn++] = wc[i] * es[i].weight[k] * src->flux;
			}
	return nn;
}

/* psf-blend=core: the arrays and weights (times the flux) whose sum is the
 * source's own blend less its cell's, so that cell + this is the blend at
 * the source: the source's nodes with their weights and the cell's with
 * minus theirs, a node in both once (the usual case: the same four).
 * Returns how many (up to 8), or -1. */
static int core_correction(const struct point *p, const struct wfs_source *src,
			   const struct poly *cell, const struct poly *cp[8], double cw[8])
{
	int n = source_polys(p, src, BLEND_SOURCE, cp, cw);

	if (n < 0)
		return -1;
	for (int j = 0; j < 8; j++) {
		uint64_t key = (uint64_t)(uintptr_t)cell->cnode[j];
		int k;

		if (!cell->cnode[j])
			continue;
		for (k = 0; k < n && cp[k]->key != key; k++)
			;
		if (k == n) {
			/* at most 8 (cp's room): prep_colour_fit() blends a
			 * colour source per source where its nodes and its
			 * cell's would be more; a guard, not a path */
			if (n == 8)
				return p->host->error(p->host->ctx, "more than 8 ePSF nodes in a core");
			if (!(cp[n] = poly_find(p, key)))
				return p->host->error(p->host->ctx, "ePSF node not prepared");
			cw[n++] = 0;
		}
		cw[k] -= cell->cweight[j] * src->flux;
	}
	return n;
}

/* The blend a source gets: psf-blend=core draws the 44-pixel class only;
 * the bright classes' boxes (88 and 176 pixels) are blended per source, as
 * their cells would be 4 and 16 times larger (0.6 and 2.3 MB each) for a few
 * sources.  A source in a cell beyond those the table keeps (more than one
 * cell off the detector) is blended per source too. */
static int source_blend(const struct point *p, const struct wfs_source *src)
{
	if (p->blend == BLEND_SOURCE || (colour_of(p, src) >= 0 && !p->colour_cells) ||
	    (p->blend == BLEND_CORE && src->psf_class != WFS_PSF_NORMAL) || !cell_in_range(p, src))
		return BLEND_SOURCE;
	return p->blend;
}

/* Keys' cubic convolution weights for taps -1, 0, 1, 2 at phase t in [0, 1). */
static void keys_weights(double t, double w[4])
{
	double t2 = t * t, t3 = t2 * t;

	w[0] = -0.5 * t3 + t2 - 0.5 * t;
	w[1] = 1.5 * t3 - 2.5 * t2 + 1.0;
	w[2] = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
	w[3] = 0.5 * t3 - 0.5 * t2;
}

/* floor(a / b) for b > 0 and any sign of a */
static long floordiv(long a, long b)
{
	return a >= 0 ? a / b : -((-a + b - 1) / b);
}

static void geom_of(const struct poly *q, double x, double y, struct geom *g)
{
	/* sample index of pixel i: centre + o i + base, plus the phase f */
	int o = q->over;
	double tx = -o * x, ty = -o * y;
	long basex = lfloor(tx), basey = lfloor(ty);
	double fx = tx - basex, fy = ty - basey;
	long sx = q->centre + basex - 1, sy = q->centre + basey - 1;
	/* the built-in grids' sampling is a power of two: a shift floors as
	 * the division does (two divisions were a third of this set-up), a
	 * signed value's shift being arithmetic (checked when built) */
	_Static_assert((-9L >> 2) == -3L, "arithmetic right shift of a signed long");
	int k = (o & (o - 1)) == 0 ? __builtin_ctz((unsigned)o) : -1;
	long mx0 = k >= 0 ? sx >> k : floordiv(sx, o), rx0 = sx - o * mx0;
	long my0 = k >= 0 ? sy >> k : floordiv(sy, o), ry0 = sy - o * my0;
	ptrdiff_t m = q->m, w = m + 1;

	g->o = o;
	g->m = m;
	g->bx[0] = 1 - fx;
	g->bx[1] = fx;
	g->by[0] = 1 - fy;
	g->by[1] = fy;
	keys_weights(fx, g->kx);
	keys_weights(fy, g->ky);
	g->an = fx < 0.5 ? 1 : 2;
	g->bn = fy < 0.5 ? 1 : 2;
	/* tap a is sample sx + a: the next phase, or the next plane column
	 * after the last phase */
	for (int a = 0; a < 4; a++) {
		long rx = rx0 + a, mx = mx0, ry = ry0 + a, my = my0;

		for (; rx >= o; rx -= o)
			mx++;
		for (; ry >= o; ry -= o)
			my++;
		g->rx[a] = rx;
		g->mx[a] = mx;
		g->ry[a] = ry;
		g->my[a] = my;
		/* plane (ry o + rx) of m x m, row my + PAD, column mx + PAD */
		g->tx[a] = rx * m * m + mx + PAD;
		g->ty[a] = (ry * o * m + my + PAD) * m;
		g->sx[a] = rx * w * w + mx + PAD;
		g->sy[a] = (ry * o * w + my + PAD) * w;
	}
}

/* Tap (a, b) of q's pixel (i, j). */
static inline const float *tap_at(const struct poly *q, const struct geom *g, int a, int b,
				  long i, long j)
{
	return q->plane + g->tx[a] + g->ty[b] + j * g->m + i;
}

/* The corners of zone z in a summed-area table (every zone lies in the
 * source's box, and every tap of the box inside its plane). */
struct corners {
	ptrdiff_t c00, c01, c10, c11;
};

static inline struct corners corners_of(const struct geom *g, struct zone z)
{
	ptrdiff_t w = g->m + 1;

	return (struct corners){ z.y0 * w + z.x0, z.y0 * w + z.x1, z.y1 * w + z.x0, z.y1 * w + z.x1 };
}

/* The sum of tap (a, b) of q over the pixels of a zone. */
static inline double tap_sum(const struct poly *q, const struct geom *g, int a, int b,
			     struct corners k)
{
	const float *s = q->sat + g->sx[a] + g->sy[b];

	return ((double)s[k.c11] - s[k.c01]) - ((double)s[k.c10] - s[k.c00]);
}

/* Bilinear interpolation's and Keys' sums of q over the pixels of z. */
static double bil_sum(const struct poly *q, const struct geom *g, struct zone z)
{
	struct corners k = corners_of(g, z);

	if (zone_empty(z))
		return 0;
	return g->by[0] * (g->bx[0] * tap_sum(q, g, 1, 1, k) + g->bx[1] * tap_sum(q, g, 2, 1, k)) +
	       g->by[1] * (g->bx[0] * tap_sum(q, g, 1, 2, k) + g->bx[1] * tap_sum(q, g, 2, 2, k));
}

static double keys_sum(const struct poly *q, const struct geom *g, struct zone z)
{
	struct corners k = corners_of(g, z);
	double s = 0;

	for (int b = 0; b < 4 && !zone_empty(z); b++) {
		double t = 0;

		for (int a = 0; a < 4; a++)
			t += g->kx[a] * tap_sum(q, g, a, b, k);
		s += g->ky[b] * t;
	}
	return s;
}

/* The zones of a draw whose arrays are set: box of half-width half, core,
 * wing square. */
static void zones(const struct point *p, const struct wfs_source *src, int blend, double half,
		  struct draw *d)
{
	double r = p->core;

	geom_of(d->pl[0], src->x, src->y, &d->g);
	d->cell = blend != BLEND_SOURCE;
	d->box = square(src->x, src->y, half);
	d->keys = p->interp != INTERP_BILINEAR;
	if (p->interp == INTERP_BILINEAR && blend != BLEND_CORE)
		r = 0;
	/* the cubic's taps must stay inside the array (bicubic everywhere
	 * reads the planes' zero padding at the box's edge instead) */
	if (p->interp == INTERP_BICUBIC)
		d->core = d->box;
	else if (r > 0 && r * d->g.o + 2 < d->pl[0]->centre)
		d->core = meet(square(src->x, src->y, r), d->box);
	else
		d->core = (struct zone){ 0, 0, 0, 0 };
	/* the nearest sample beyond the wing square (which holds the core):
	 * one array of the faint class only; bright sources are bilinear to
	 * the box's edge */
	if (d->cell && src->psf_class == WFS_PSF_NORMAL && p->wing < half && 2 * half <= KV_COLS &&
	    p->interp != INTERP_BICUBIC)
		d->wing = meet(square(src->x, src->y,
				      zone_empty(d->core) || p->wing > r ? p->wing : r), d->box);
	else
		d->wing = d->box;
}

/* render_one() draws it: one blended cell and a core that fits its buffer */
static int one_array(const struct draw *d)
{
	return d->cell && d->core.x1 - d->core.x0 <= KV_COLS && d->core.y1 - d->core.y0 <= KV_ROWS;
}

/* psf-blend=core's correction from the cell's own node copies and the
 * source's node weights w (aux[4..7], in the cell's node order). */
static void cell_correction(const struct poly *cell, double flux, const double w[4],
			    struct draw *d)
{
	d->ncor = 0;
	for (int k = 0; k < 4; k++)
		if (cell->cpoly[k]) {
			d->cp[d->ncor] = cell->cpoly[k];
			d->cw[d->ncor++] = flux * w[k] - flux * cell->cweight[k];
		}
}

/* The same for a colour source in its pair's cell, whose blend at the
 * source is, with A_k and B_k the nodes of classes a and a + 1, w_k the
 * source's position weights (aux[4..7]) and c_k the cell's, f the source's
 * fraction of the way from a to a + 1 and g the cell's (cstep),
 *
 *   sum_k w_k (A_k + f D_k),  D_k = B_k - A_k;
 *
 * with A and B the two classes' cells at the cell's centre (its ends, or a
 * class cell and its neighbour) and E_k the nodes of the class nearer g
 * (e = 0 or 1),
 *
 *   (1 - f) A + f B + sum_k (w_k - c_k) E_k
 *
 * is that blend less (f - e) sum_k (w_k - c_k) D_k: the change of the
 * pair's difference across the grid, times the source's offset from the
 * cell's centre and its colour's from class e (BENCHMARKS.md, "Colour").
 * Six arrays instead of the eight of the exact blend, A and B read with
 * the cell's own taps (render_one): where the core is Keys' cubic, a
 * bilinear B - A missed the curvature of the pair's difference at the
 * peak: up to 1.75e-3 of it for stars half-way between the ePSF's
 * samples (1/8 pixel off a pixel's centre; t2200).  Returns 0, or -1 when
 * a class cell is missing. */
static int cell_correction_colour(const struct point *p, const struct wfs_source *src,
				  const struct poly *cell, const double w[4], struct draw *d)
{
	double f, g, flux = src->flux;
	const struct poly *end[2];
	int a, e;

	point_pair(p, colour_of(p, src), &a, &f);
	if (cell_pair(cell, a, &g, end) < 0)
		return p->host->error(p->host->ctx, "colour cell not prepared");
	e = g >= 0.5;
	d->ncor = 0;
	for (int k = 0; k < 4; k++)
		if (cell->cpoly[k + 4 * e]) {
			d->cp[d->ncor] = cell->cpoly[k + 4 * e];
			d->cw[d->ncor++] = flux * w[k] - flux * (cell->cweight[k] + cell->cweight[k + 4]);
		}
	d->kb = end[e];
	d->kbw = e ? f : 1 - f;
	d->dk = end[!e];
	d->dkw = e ? 1 - f : f;
	return 0;
}

/* T of a colour source in its pair's cell (one_array), from the same six
 * arrays: sum_k w_k E_k + (f - e) (B - A) over the zone z. */
static double colour_total(const struct point *p, const struct wfs_source *src,
			   const struct poly *cell, const struct geom *gm, struct zone z)
{
	double f, g, t = 0;
	const struct poly *end[2];
	int a, e;

	point_pair(p, colour_of(p, src), &a, &f);
	if (cell_pair(cell, a, &g, end) < 0)
		return NAN;
	e = g >= 0.5;
	for (int k = 0; k < 4; k++)
		if (cell->cpoly[k + 4 * e])
			t += src->aux[4 + k] * bil_sum(cell->cpoly[k + 4 * e], gm, z);
	return src->flux * (t + (f - e) * (bil_sum(end[1], gm, z) - bil_sum(end[0], gm, z)));
}

/* How src is drawn in render(), its box and what prepare() found in aux:
 * which arrays, and the zones.  Returns 0 or -1. */
static int plan(const struct point *p, const struct wfs_source *src, struct draw *d)
{
	int blend = source_blend(p, src);

	/* a colour source whose cell's nodes are not all its own (prepare) */
	if (colour_of(p, src) >= 0 && src->aux[3] < 0)
		blend = BLEND_SOURCE;
	d->ncor = 0;
	d->kb = d->dk = NULL;
	if (blend != BLEND_SOURCE && !isnan(src->aux[4])) {
		/* the cell found by prepare(), and its nodes are the source's */
		d->nn = 1;
		d->pl[0] = &p->slot[(size_t)src->aux[3]];
		d->wn[0] = src->flux;
		if (blend == BLEND_CORE && colour_of(p, src) >= 0) {
			if (cell_correction_colour(p, src, d->pl[0], src->aux + 4, d) < 0)
				return -1;
		} else if (blend == BLEND_CORE)
			cell_correction(d->pl[0], src->flux, src->aux + 4, d);
	} else {
		if ((d->nn = source_polys(p, src, blend, d->pl, d->wn)) < 0)
			return -1;
		if (blend == BLEND_CORE &&
		    (d->ncor = core_correction(p, src, d->pl[0], d->cp, d->cw)) < 0)
			return -1;
	}
	zones(p, src, blend, src->aux[0], d);
	return 0;
}

/*
 * The factor on everything outside the core.  With T the bilinear sum of
 * the source's blend over the box (its enclosed fraction times the flux),
 * K what the core draws and U what the rest draws before scaling,
 *
 *   f = (T - K) / U
 *
 * makes the total T.  One array (psf-blend=cell or core, render_one): U is
 * the array's bilinear sum over the wing square less the core plus its
 * nearest samples beyond; render_one() sums K from the core it draws.
 * Several arrays: U is their bilinear sum outside the core, and K the
 * core's Keys sum, both from the tables here.  Where less than 1% of the
 * light lies outside the core (an adaptive box barely wider than the core,
 * or the cubic everywhere) f is 1: the kernels' totals then agree to ~1e-4.
 */
static double flux_factor(double t, double k, double u)
{
	return u > 0.01 * fabs(t) && isfinite(t - k) ? (t - k) / u : 1;
}

/* The light of the source (the blend at it, or its cell's) in a box of
 * half-width H but not in that of half-width h (ee_table), absolute. */
static double beyond(const struct wfs_source *src, const struct poly *cell, int blend,
		     const struct poly *const node[8], const double w[8], int nn, int H, int h)
{
	double out = blend == BLEND_CELL ? src->flux * (cell->ee[H] - cell->ee[h]) : 0;

	for (int k = 0; k < nn; k++)
		out += w[k] * src->flux * (node[k]->ee[H] - node[k]->ee[h]);
	return fabs(out);
}

/* What prepare() finds for a source, step by step: its cell (NULL: none),
 * its own nodes' copies with their weights (not times the flux), its
 * blend, whether its cell was blended from exactly its nodes
 * (psf-blend=core's correction from aux[4..7]), and the arrays render()
 * reads with its zones. */
struct prep {
	struct poly *cell;
	const struct poly *node[8];
	double w[8];
	int nn, blend, same;
	struct draw d;
};

/* A colour source in a class cell (psf-blend=core): its arrays as the
 * six of colour_total() and the core's correction, the cell's class's
 * nodes at the source's position weights (to aux[4..7]) and the pair's
 * two class cells times the source's colour less the cell's, f - g on
 * the upper and g - f on the lower, so that the other class's nodes are
 * neither looked up nor read (their enclosed light in box_cut() is the
 * class cells' difference's).  Returns 0, 1 when a node of the source is
 * not the cell's (prep_nodes() then takes the source's own), or -1. */
static int prep_class(struct point *p, struct wfs_source *src, struct prep *r)
{
	const struct poly *cell = r->cell, *end[2];
	struct wfs_epsf e;
	double f, g, w[4] = { 0 };
	int a, nn = 0;

	if (p->host->epsf_colour(p->host->ctx, src->sca, src->x, src->y, src->psf_class,
				 cell->cclass, &e) < 0)
		return -1;
	point_pair(p, colour_of(p, src), &a, &f);
	if (cell_pair(cell, a, &g, end) < 0)
		return 1;
	for (int k = 0; k < 4; k++) {
		int j;

		if (e.weight[k] == 0)
			continue;
		for (j = 0; j < 4 && (cell->cnode[j] != e.node[k] || !cell->cpoly[j]); j++)
			;
		if (j == 4)
			return 1;
		w[j] += e.weight[k];
		r->node[nn] = cell->cpoly[j];
		r->w[nn++] = e.weight[k];
	}
	r->node[nn] = end[1];
	r->w[nn++] = f - g;
	r->node[nn] = end[0];
	r->w[nn++] = g - f;
	r->nn = nn;
	for (int j = 0; j < 4; j++)
		src->aux[4 + j] += w[j];
	return 0;
}

/* The source's nodes (not for psf-blend=cell): the cell's copies when the
 * cell was blended from them (their weights go to aux[4..7] in the cell's
 * order), else copies made here.  Returns 0 or -1. */
static int prep_nodes(struct point *p, struct wfs_source *src, struct prep *r)
{
	struct wfs_epsf es[2];
	double wc[2];
	int cls[2], ne;

	if (r->cell && r->cell->cclass >= 0 && r->blend == BLEND_CORE &&
	    colour_of(p, src) >= 0 && (ne = prep_class(p, src, r)) <= 0)
		return ne;
	if ((ne = src_epsf(p, src, es, wc, cls)) < 0)
		return -1;
	for (int i = 0; i < ne; i++)
	for (int k = 0; k < 4; k++) {
		const struct wfs_epsf *e = &es[i];
		const struct poly *q = NULL;
		/* a class cell holds its own class's nodes only: the other
		 * class of the source's pair has its nodes where they are */
		int other = r->cell && r->cell->cclass >= 0 && cls[i] != r->cell->cclass;

		if (e->weight[k] == 0)
			continue;
		/* the position weights (aux[4..7], the cell's node order)
		 * from the source's first class (a pair's colour cell holds
		 * both classes' nodes in one order), or the class cell's */
		for (int j = 0; r->cell && !other && j < 8 && !q; j++)
			if (r->cell->cnode[j] == e->node[k] && r->cell->cpoly[j]) {
				q = r->cell->cpoly[j];
				if (i == 0 || r->cell->cclass >= 0)
					src->aux[4 + (j & 3)] += e->weight[k];
			}
		if (!q) {
			r->same &= other;
			if (!(q = poly_add(p, (uint64_t)(uintptr_t)e->node[k], e->node[k], e->n,
					   e->over)))
				return -1;
		}
		r->node[r->nn] = q;
		/* times 1 for the default spectrum: the same bytes */
		r->w[r->nn++] = wc[i] * e->weight[k];
	}
	return 0;
}

/* A colour source whose cell's nodes are not all its own (a node line
 * between the source and its cell's centre): psf-blend=core's correction
 * would read the source's arrays and the cell's, more than the 8 of
 * draw.cp together, so the cell is left for a blend of the source's own. */
static void prep_colour_fit(const struct point *p, const struct wfs_source *src,
			    struct prep *r)
{
	int extra = 0;

	if (!r->cell || !(colour_of(p, src) >= 0) || r->same)
		return;
	for (int j = 0; r->blend == BLEND_CORE && j < 8; j++) {
		int k;

		for (k = 0; k < r->nn && r->cell->cnode[j] && r->node[k]->key !=
			     (uint64_t)(uintptr_t)r->cell->cnode[j]; k++)
			;
		extra += r->cell->cnode[j] && k == r->nn;
	}
	if (r->nn + extra > 8) {
		r->blend = BLEND_SOURCE;
		r->cell = NULL;
	}
}

/* The arrays render() reads: the cell, or the source's nodes; aux[3] the
 * cell's slot (-1: none).  Returns 0 or -1. */
static int prep_arrays(const struct point *p, struct wfs_source *src, struct prep *r)
{
	struct draw *d = &r->d;

	src->aux[3] = -1;
	d->nn = 0;
	if (r->cell) {
		src->aux[3] = (double)(r->cell - p->slot);
		d->pl[d->nn] = r->cell;
		d->wn[d->nn++] = src->flux;
	} else
		for (int k = 0; k < r->nn && k < 8; k++) {
			d->pl[d->nn] = r->node[k];
			d->wn[d->nn++] = r->w[k] * src->flux;
		}
	if (d->nn == 0)
		return p->host->error(p->host->ctx, "no ePSF node with a weight");
	return 0;
}

/* psf-box=adaptive: the smallest half-width (at most half) whose left-out
 * light is below box_noise times the noise summed over the box, for the
 * blend at the source (at the cell's, psf-blend=cell). */
static double box_adaptive(const struct point *p, const struct wfs_source *src,
			   const struct prep *r, double half)
{
	int h, H = r->d.pl[0]->nee;

	for (h = 1; h < H; h++) {
		double out = 0;

		if (r->blend == BLEND_CELL)
			out = src->flux * (r->cell->ee[H] - r->cell->ee[h]);
		for (int k = 0; k < r->nn; k++)
			out += r->w[k] * src->flux * (r->node[k]->ee[H] - r->node[k]->ee[h]);
		if (fabs(out) <= p->box_noise * p->sigma * 2 * h)
			break;
	}
	return h < half ? h : half;
}

/* psf-extent-cut: the smallest half-width, beyond the core, past which
 * the source's light within the whole box of half-width half (for the
 * blend at the source, or the cell's; ee_table) is at most extent_cut of
 * the noise per pixel (that light is put back by prep_totals), or half. */
static double box_cut(const struct point *p, const struct wfs_source *src,
		      const struct prep *r, double half)
{
	const struct poly *const *node = r->node;
	int rc = (int)ceil(p->core), h = rc + 1, H = (int)half, nn = r->nn;
	double all = beyond(src, r->cell, r->blend, node, r->w, nn, H, 0);

	/* most sources that need the whole box are seen at its edge */
	if (h < H && !(beyond(src, r->cell, r->blend, node, r->w, nn, H, H - 1) <=
		       p->extent_cut * p->sigma))
		h = H;
	/* the light put back goes outside the core (flux_factor), so the box
	 * keeps at least 2% of the light there; bicubic (the core is the
	 * box) is never cut */
	for (; h < H; h++)
		if (beyond(src, r->cell, r->blend, node, r->w, nn, H, h) <=
		    p->extent_cut * p->sigma &&
		    beyond(src, r->cell, r->blend, node, r->w, nn, h, rc) >= 0.02 * all)
			break;
	return h < H ? h : half;
}

/* The flux factor's terms (aux[1..2]) for the box of half-width half, cut
 * from whole; returns the light the box places. */
static double prep_totals(const struct point *p, struct wfs_source *src, const struct prep *r,
			  double half, double whole)
{
	const struct draw *d = &r->d;
	const struct poly *cell = r->cell;
	double t = 0, t_all;

	/* T: the bilinear sum over the box of the blend at the source (of
	 * the cell's, psf-blend=cell); one array with a cut box draws the
	 * whole box's light below instead, and needs no T */
	if (!(half < whole && one_array(d)) && r->same && colour_of(p, src) >= 0 && one_array(d))
		t = colour_total(p, src, cell, &d->g, d->box);
	else if (!(half < whole && one_array(d))) {
		if (r->blend == BLEND_CELL)
			t = src->flux * bil_sum(cell, &d->g, d->box);
		for (int k = 0; k < r->nn; k++)
			t += r->w[k] * src->flux * bil_sum(r->node[k], &d->g, d->box);
	}
	/* A box the cut shrank draws the light of the whole one at the
	 * source's phase: its factor below carries the light beyond it (below
	 * the cut), outside the core.  That light is taken from the cell's
	 * blend where there is one (one table instead of four; the blends'
	 * light in the whole box differs by some 1e-4 of it). */
	t_all = t;
	if (half < whole) {
		struct zone all = square(src->x, src->y, whole);

		if (cell)
			t_all = src->flux * bil_sum(cell, &d->g, all);
		else
			for (int k = t_all = 0; k < r->nn; k++)
				t_all += r->w[k] * src->flux * bil_sum(r->node[k], &d->g, all);
	}
	if (one_array(d)) {
		const struct geom *g = &d->g;

		src->aux[1] = t_all;
		src->aux[2] = src->flux * (tap_sum(cell, g, g->an, g->bn, corners_of(g, d->box)) -
					   (zone_empty(d->wing) ? 0 :
					    tap_sum(cell, g, g->an, g->bn, corners_of(g, d->wing))) +
					   bil_sum(cell, g, d->wing) - bil_sum(cell, g, d->core));
	} else {
		double k = 0, u = t;

		for (int i = 0; i < d->nn; i++) {
			double b = bil_sum(d->pl[i], &d->g, d->core);

			u -= d->wn[i] * b;
			k += d->wn[i] * (d->keys ? keys_sum(d->pl[i], &d->g, d->core) : b);
		}
		src->aux[1] = flux_factor(t_all, k, u);
		src->aux[2] = 0;
	}
	return t_all;
}

/*
 * prepare(): the arrays the source reads (polyphase copies of its grid
 * nodes and of its cell's blend, made once and kept), its box and what its
 * flux factor needs, in aux:
 *
 *   aux[0]     the box's half-width, pixels
 *   aux[1..2]  T and U (render_one), or f and 0 (several arrays)
 *   aux[3]     the slot of the source's cell
 *   aux[4..7]  the source's weights of its cell's nodes (psf-blend=core),
 *              or NaN when render() must look the arrays up itself
 *
 * and *drawn (when not NULL) the light the box places, counts/s.
 */
int epsf_prepare(struct point *p, struct wfs_source *src, double cap, int cut, double *drawn)
{
	struct prep r;          /* not zeroed: a source's prepare is hot */
	const struct poly *q0;
	double half, whole, t_all;

	r.cell = NULL;
	r.nn = 0;
	r.d.pl[0] = NULL;
	r.blend = source_blend(p, src);
	r.same = r.blend == BLEND_CORE;
	if (r.blend != BLEND_SOURCE && !(r.cell = cell_add(p, src)))
		return -1;
	src->aux[4] = src->aux[5] = src->aux[6] = src->aux[7] = 0;
	if (r.blend != BLEND_CELL && prep_nodes(p, src, &r) < 0)
		return -1;
	prep_colour_fit(p, src, &r);
	if (!r.same)
		src->aux[4] = NAN;
	if (prep_arrays(p, src, &r) < 0)
		return -1;
	q0 = r.d.pl[0];
	half = (double)q0->centre / q0->over;
	if (p->adaptive)
		half = box_adaptive(p, src, &r, half);
	if (cap > 0 && cap < half)
		half = cap;
	whole = half;
	if (cut && p->extent_cut > 0 && p->sigma > 0 && half == floor(half) && half <= q0->nee &&
	    p->interp != INTERP_BICUBIC)
		half = box_cut(p, src, &r, half);
	src->aux[0] = half;
	zones(p, src, r.blend, half, &r.d);
	t_all = prep_totals(p, src, &r, half, whole);
	if (drawn)
		*drawn = t_all;         /* the light the box places */
	return 0;
}

/* One array (psf-blend=cell or core) whose core fits the kv buffer: the
 * core's pixels first (Keys' cubic of the array, or bilinear, plus
 * psf-blend=core's correction), in float, 8 columns at a time over the
 * core's columns, and all its rows, inside the window or not, so that their
 * sum K, and with prepare()'s T and U the flux factor, is the same in every
 * window of the source; then the whole window in one call. */
static inline __attribute__((always_inline)) int render_one(const struct point *p,
							    const struct draw *d, double t,
							    double u, const struct wfs_window *win)
{
	const struct poly *q = d->pl[0];
	const struct geom *g = &d->g;
	long X = win->x0, Y = win->y0;
	ptrdiff_t m = q->m;
	double fl = d->wn[0];
	int empty = zone_empty(d->core);
	int ka = empty ? 0 : (int)(d->core.x0 - X), kb = empty ? 0 : (int)(d->core.x1 - X);
	int jc = empty ? 0 : (int)(d->core.y0 - Y), nc = empty ? 0 : (int)(d->core.y1 - d->core.y0);
	float kvb[KV_ROWS * KV_PITCH + 8];
	double k = 0, f;
	struct rows_args ra = {
		{ tap_at(q, g, 1, 1, X, Y), tap_at(q, g, 2, 1, X, Y),
		  tap_at(q, g, 1, 2, X, Y), tap_at(q, g, 2, 2, X, Y) },
		tap_at(q, g, g->an, g->bn, X, Y), m, { 0 }, 0,
		(int)(d->wing.y0 - Y), (int)(d->wing.y1 - d->wing.y0),
		(int)(d->wing.x0 - X), (int)(d->wing.x1 - X),
		jc, nc, ka, kb, kvb
	};

	if (nc > 0) {
		/* set field by field: a zeroing initialiser cleared its 350
		 * bytes a star, of which a faint star's core uses a third */
		struct core_args ca;
		ptrdiff_t at = (ptrdiff_t)d->core.y0 * m + d->core.x0;
		/* a colour source's nearer class cell, or the cell */
		double kw = d->dk ? fl * d->kbw : fl;

		ca.ncor = d->ncor;
		ca.keys = d->keys;
		ca.nc = nc;
		ca.nk = kb - ka;
		ca.m = m;
		ca.dbase = NULL;
		ca.ds = 0;
		ca.base = (d->dk ? d->kb : q)->plane + at;
		for (int a = 0; a < 4; a++) {
			ca.tx[a] = g->tx[a];
			ca.ty[a] = g->ty[a];
			ca.kx[a] = (float)g->kx[a];
			ca.ky[a] = (float)(g->ky[a] * kw);
			ca.bw[a] = (float)(kw * g->by[a >> 1] * g->bx[a & 1]);
		}
		for (int c = 0; c < d->ncor; c++) {
			ca.cbase[c] = d->cp[c]->plane + at;
			for (int t = 0; t < 4; t++)
				ca.cw[4 * c + t] = (float)(d->cw[c] * g->by[t >> 1] * g->bx[t & 1]);
		}
		if (d->dk && d->keys) {
			ca.dbase = d->dk->plane + at;
			ca.ds = (float)(d->dkw / d->kbw);
		} else if (d->dk) {     /* bilinear core: one more correction */
			ca.cbase[ca.ncor] = d->dk->plane + at;
			for (int t = 0; t < 4; t++)
				ca.cw[4 * ca.ncor + t] = (float)(fl * d->dkw * g->by[t >> 1] *
								 g->bx[t & 1]);
			ca.ncor++;
		}
		k = p->core_rows(&ca, kvb);
	}
	f = flux_factor(t, k, u);
	for (int a = 0; a < 4; a++)
		ra.w[a] = (float)(f * fl * g->by[a >> 1] * g->bx[a & 1]);
	ra.wn = (float)(f * fl);
	p->sum_rows(win->pix, win->stride, win->nx, win->ny, &ra);
	return 0;
}

/* Several arrays (psf-blend=source, and the bright classes under the
 * default), or a cell's blend with a core too wide for render_one (the
 * cubic everywhere in a bright box under psf-blend=cell): row by row, the
 * bilinear sum of every array's 4 streams times f into a float row, then
 * Keys' cubic over the core's columns, in double, from the same samples.
 * No psf-blend=core correction comes here (a faint box's core always fits
 * render_one), and a core here is always cubic (a bilinear one is only
 * psf-blend=core's). */
static inline __attribute__((always_inline)) int render_many(const struct draw *d, double f,
		       const struct wfs_window *win)
{
	const struct geom *g = &d->g;
	int nn = d->nn;
	long X = win->x0, Y = win->y0;
	float wt[32];
	const float *tap0[128]; /* [array][y tap][x tap] at the window's first pixel */
	float acc[MAX_ROW + 8];
	double dv[MAX_ROW + 4], tv[MAX_ROW + 4];
	int core = !zone_empty(d->core);
	ptrdiff_t m = d->pl[0]->m;

	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 2; b++)
			for (int a = 0; a < 2; a++)
				wt[(k * 2 + b) * 2 + a] = (float)(f * d->wn[k] * g->by[b] * g->bx[a]);
	for (int k = 0; k < nn; k++)
		for (int b = 0; b < 4; b++)
			for (int a = 0; a < 4; a++)
				tap0[(k * 4 + b) * 4 + a] = tap_at(d->pl[k], g, a, b, X, Y);
	for (int j = 0; j < win->ny; j++) {
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		ptrdiff_t step = (ptrdiff_t)j * m;
		long jj = Y + j;
		/* the core's columns on this row, [ca, cb) of the window */
		long ca = 0, cb = 0;

		if (core && jj >= d->core.y0 && jj < d->core.y1) {
			ca = d->core.x0 - X < 0 ? 0 : d->core.x0 - X;
			cb = d->core.x1 - X > win->nx ? win->nx : d->core.x1 - X;
		}
		for (int i0 = 0; i0 < win->nx; i0 += MAX_ROW) {
			int len = win->nx - i0 < MAX_ROW ? win->nx - i0 : MAX_ROW;
			long ia = ca - i0, ib = cb - i0;

			if (ia < 0)
				ia = 0;
			if (ib > len)
				ib = len;
			for (int k = 0; k < nn; k++) {
				const float *const *t = tap0 + 16 * k;
				const float *s0 = t[5] + step + i0, *s1 = t[6] + step + i0;
				const float *s2 = t[9] + step + i0, *s3 = t[10] + step + i0;
				v8f w0 = SPLAT(wt[4 * k]), w1 = SPLAT(wt[4 * k + 1]);
				v8f w2 = SPLAT(wt[4 * k + 2]), w3 = SPLAT(wt[4 * k + 3]);

				for (int i = 0; i < len; i += 8) {
					v8f v = { 0 };

					if (k > 0)
						v = *(const v8f *)(acc + i);
					v += w0 * *(const v8f *)(s0 + i);
					v += w1 * *(const v8f *)(s1 + i);
					v += w2 * *(const v8f *)(s2 + i);
					v += w3 * *(const v8f *)(s3 + i);
					*(v8f *)(acc + i) = v;
				}
			}
			/* the core: Keys' cubic from the same samples, 4 pixels
			 * at a time, past the run's end into the planes' slack;
			 * only the run is kept */
			if (ia < ib) {
				int cn = (int)(ib - ia);

				for (int i = 0; i < cn; i += 4)
					*(v4d *)(dv + i) = (v4d){ 0 };
				for (int k = 0; k < nn; k++) {
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(tv + i) = (v4d){ 0 };
					for (int b = 0; b < 4; b++) {
						const float *const *t = tap0 + (k * 4 + b) * 4;
						const float *t0 = t[0] + step + i0 + ia, *t1 = t[1] + step + i0 + ia;
						const float *t2 = t[2] + step + i0 + ia, *t3 = t[3] + step + i0 + ia;
						v4d c0 = SPLAT4(g->kx[0]), c1 = SPLAT4(g->kx[1]);
						v4d c2 = SPLAT4(g->kx[2]), c3 = SPLAT4(g->kx[3]);
						v4d cb4 = SPLAT4(g->ky[b]);

						for (int i = 0; i < cn; i += 4)
							*(v4d *)(tv + i) += cb4 * (c0 * TO_V4D(t0 + i) + c1 * TO_V4D(t1 + i) +
										   c2 * TO_V4D(t2 + i) + c3 * TO_V4D(t3 + i));
					}
					for (int i = 0; i < cn; i += 4)
						*(v4d *)(dv + i) += SPLAT4(d->wn[k]) * *(v4d *)(tv + i);
				}
				for (int i = 0; i < cn; i++)
					acc[ia + i] = (float)dv[i];
			}
			for (int i = 0; i < len; i++)
				row[i0 + i] += acc[i];
		}
	}
	return 0;
}

/* Built twice, for AVX2 and for any x86-64, and chosen at load time: the
 * core's sums run 8 floats wide where the processor allows. */
/* Not under the sanitizers: the clones' resolver runs while the plugin is
 * being relocated, before the instrumentation it calls can be reached (a
 * ThreadSanitizer build jumped to a bad address in dlopen). */
SIMD_CLONES("avx2,fma", "default")
int epsf_render(struct point *p, const struct wfs_source *src, const struct wfs_window *win)
{
	struct draw d;
	const struct geom *g = &d.g;
	int m;

	if (plan(p, src, &d) < 0)
		return -1;
	m = d.pl[0]->m;
	if (win->x0 + g->mx[0] + PAD < 0 || win->x0 + win->nx + g->mx[3] + PAD > m ||
	    win->y0 + g->my[0] + PAD < 0 || win->y0 + win->ny + g->my[3] + PAD > m)
		return p->host->error(p->host->ctx, "window outside the source's box");
	if (one_array(&d))
		return render_one(p, &d, src->aux[1], src->aux[2], win);
	if (d.ncor || d.dk || (!zone_empty(d.core) && !d.keys))
		return p->host->error(p->host->ctx, "no drawing for this blend and core");
	return render_many(&d, src->aux[1], win);
}
