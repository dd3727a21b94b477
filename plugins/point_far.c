/*
 * point_far.c - psf-diffuse=grid: the light a source's drawing leaves out
 * (a faint star's wings beyond its box, a bright one's beyond its radius),
 * gathered on a coarse grid per SCA and spread once per tile, so that every
 * star places the same fraction of its PSF's light (the halo model's
 * total, halo.h) and a crowded field's diffuse light lands where it falls.
 *
 * Gathering.  prepare() adds the light left out of a source, L, to the
 * four cells of side s (psf-diffuse-cell) nearest it, with bilinear
 * ("cloud in cell") weights, into its thread's own grid.  The grids hold
 * integers, so that their sum does not depend on the order the sources
 * were prepared in nor on the threads: a deposit v is split into a whole
 * number of FAR_TOP counts/s, one of FAR_HI and a remainder in units of
 * FAR_LO, summed in three 64-bit counters (exact; no carry is needed since
 * each counter only grows by its own part).
 *
 * The wing's shape.  K(p, q), the share of unit light that a source at
 * the centre of a cell sends into the cell (p, q) away: the halo model
 * (halo.h) summed over the cell's pixels outside the faint class's box,
 * over the model's light outside the box: the default spectrum's halo for
 * faint sources, and for a bright one the halo it is drawn with (a
 * source with a spectrum: its spectrum's, point_halo.c), each halo's
 * kernels built when the SCA is gathered.  Cells that meet the box, or lie
 * within FAR_EXACT cells, are summed pixel by pixel; nearer than 512 pixels
 * every other pixel, nearer than 1024 on 2 x 2 points, beyond at one
 * (the wing is smooth there on the scale of a cell, its spikes a few
 * pixels wide apart: see cell_sum).
 *
 * Spreading.  gather() convolves each SCA's grid with K once (the host's
 * FFT): the light in each cell.  spread() adds to each pixel the bilinear
 * interpolation of that light per pixel between the cells' centres, whose
 * sum over the pixels is the cells' light; what falls off the SCA is lost,
 * as for a drawn wing.
 *
 * A star with a halo is drawn out to its radius rounded up to a ladder of
 * FAR_STEPS radii per octave from 22 pixels (far_radius: a few per cent
 * more pixels, its wing no less), and the light beyond (with
 * psf-halo-far=spikes also the baseline between its base radius and its
 * radius, below the level in every pixel) is spread with the wing beyond
 * that radius: one list per thread of such deposits, binned at gather()
 * into a grid per radius present, each convolved with its own K (the
 * box's K with the disc taken out), in order of radius.
 */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

#define FAR_TOP 1125899906842624.0      /* counts/s per unit of the top counter, 2^50 */
#define FAR_HI 1024.0                   /* counts/s per unit of the high counter */
#define FAR_LO (1.0 / 1073741824.0)     /* counts/s per unit of the low one, 2^-30 */
#define FAR_EXACT 3                     /* cells summed pixel by pixel, at least */
#define FAR_MARGIN 96                   /* pixels of grid beyond each SCA edge */
#define FAR_R0 22.0                     /* the ladder's first radius */
#define FAR_COARSE 4                    /* coarse cells a side, in fine ones */
#define FAR_NEAR 8                      /* coarse cells the fine kernel reaches */
#define FAR_REL 1e-5                    /* a cell's share of the light kept at least */

/* The fine grid: n x n cells of side s, cell a's pixels [org + a s,
 * org + (a + 1) s); the coarse one, cells of FAR_COARSE s, over the same
 * pixels.  The fine kernel reaches FAR_NEAR coarse cells, the coarse one
 * the rest (far_level). */
void far_geometry(struct point *p)
{
	int s = p->far_cell, m = s * FAR_COARSE * ((FAR_MARGIN + s * FAR_COARSE - 1) /
						   (s * FAR_COARSE));

	p->far_org = -m;
	p->far_n = (WFS_SCA_SIDE + 2 * m + s * FAR_COARSE - 1) / (s * FAR_COARSE) * FAR_COARSE;
}

/* One level of the grid: cells of side s from pixel org, n a side; its
 * kernel (2 H + 1)^2 cells; the square its kernel leaves to the level
 * below, |dx|, |dy| < hole (the box for the fine level, the fine
 * kernel's reach for the coarse one); exact, the rings of cells about the
 * hole summed pixel by pixel (every other pixel on the coarse level). */
struct level {
	int s, n, H, exact, step;
	long org;
	double hole;
};

static void far_level(const struct point *p, int coarse, double box, struct level *l)
{
	int s = p->far_cell, hn = FAR_NEAR * FAR_COARSE;

	l->org = p->far_org;
	if (!coarse) {
		l->s = s;
		l->n = p->far_n;
		l->H = hn;
		l->hole = box;
		l->exact = FAR_EXACT;
		l->step = 1;
	} else {
		l->s = s * FAR_COARSE;
		l->n = p->far_n / FAR_COARSE;
		l->H = l->n - 1;
		l->hole = (hn + 0.5) * s;
		l->exact = 1;
		l->step = 2;
	}
}

/* Cell coordinate of pixel position x on level l: cell a's centre is at a. */
static inline double level_u(const struct level *l, double x)
{
	return (x - l->org - 0.5 * (l->s - 1)) / l->s;
}

/* Cell coordinate of pixel position x: cell a's centre is at a. */
static inline double far_u(const struct point *p, double x)
{
	return (x - p->far_org - 0.5 * (p->far_cell - 1)) / p->far_cell;
}

double far_radius(const struct point *p, double r)
{
	double k, q;

	if (p->diffuse != DIFFUSE_GRID || !(r > FAR_R0))
		return r;
	k = ceil(FAR_STEPS * log2(r / FAR_R0) - 1e-9);
	q = ceil(FAR_R0 * exp2(k / FAR_STEPS));
	return q < p->extent_max ? q : p->extent_max > r ? p->extent_max : r;
}

/* v counts/s (>= 0) into cell c of the counters: cnt[3 c] its whole units
 * of FAR_TOP, cnt[3 c + 1] the remainder's whole units of FAR_HI,
 * cnt[3 c + 2] what is left in units of FAR_LO, side by side so that a
 * deposit touches one cache line per cell (up to the 1e32 counts/s a
 * source may have) */
static inline void far_add(int64_t *cnt, size_t c, double v)
{
	double t = floor(v / FAR_TOP), h;

	v -= t * FAR_TOP;
	h = floor(v / FAR_HI);
	cnt[3 * c] += (int64_t)t;
	cnt[3 * c + 1] += (int64_t)h;
	cnt[3 * c + 2] += (int64_t)((v - h * FAR_HI) / FAR_LO + 0.5);
}

/* The light of cell c of the counters cnt. */
static inline double far_light(const int64_t *cnt, size_t c)
{
	return (double)cnt[3 * c] * FAR_TOP + (double)cnt[3 * c + 1] * FAR_HI +
	       (double)cnt[3 * c + 2] * FAR_LO;
}

/* The four cells about (x, y) and their bilinear weights. */
static void far_cic(const struct point *p, double x, double y, size_t c[4], double w[4])
{
	int n = p->far_n;
	double u = far_u(p, x), v = far_u(p, y), fx, fy;
	long a, b;

	/* beyond the grid's margin, the edge cells */
	u = u < 0 ? 0 : u > n - 1 ? n - 1 : u;
	v = v < 0 ? 0 : v > n - 1 ? n - 1 : v;
	a = lfloor(u);
	b = lfloor(v);
	a = a > n - 2 ? n - 2 : a;
	b = b > n - 2 ? n - 2 : b;
	fx = u - a;
	fy = v - b;
	w[0] = (1 - fx) * (1 - fy);
	w[1] = fx * (1 - fy);
	w[2] = (1 - fx) * fy;
	w[3] = fx * fy;
	for (int k = 0; k < 4; k++)
		c[k] = (size_t)(b + (k >> 1)) * n + a + (k & 1);
}

/* A held deposit q into the counters cnt of its SCA (n cells a row). */
static inline void far_pend_add(int64_t *cnt, const struct far_pend *q, int n)
{
	for (int k = 0; k < 4; k++)
		far_add(cnt, q->c0 + (size_t)(k >> 1) * n + (k & 1), q->v[k]);
}

/* One more deposit in the thread's list. */
static int dep_push(struct point *p, struct tally *t, struct far_dep d)
{
	if (t->ndep == t->capdep) {
		size_t cap = t->capdep ? 2 * t->capdep : 256;
		struct far_dep *nd = realloc(t->dep, cap * sizeof(*nd));

		if (!nd)
			return p->host->error(p->host->ctx, "out of memory");
		t->dep = nd;
		t->capdep = cap;
	}
	t->dep[t->ndep++] = d;
	return 0;
}

int far_deposit(struct point *p, const struct wfs_source *src, double light, double r, int slot)
{
	struct tally *t = tally_of(p);
	int n = p->far_n, sca = src->sca;
	struct far_pend *q;
	size_t c[4];
	double w[4];

	if (!t)
		return p->host->error(p->host->ctx, "out of memory");
	if (!(light > 0))
		return 0;
	t->spread += light;
	if (r > 0)
		return dep_push(p, t, (struct far_dep){ .k = INT_MIN, .sca = (short)sca,
						 .slot = (short)slot, .r = r, .x = src->x,
						 .y = src->y, .light = light });
	if (!t->cnt[sca] && !(t->cnt[sca] = calloc((size_t)3 * n * n, sizeof(int64_t))))
		return p->host->error(p->host->ctx, "out of memory");
	far_cic(p, src->x, src->y, c, w);
	/* the deposit FAR_RING ago added now, its cells fetched by then;
	 * this one's asked for (two cells a row, 48 bytes: two lines at most) */
	q = &t->ring[t->nring % FAR_RING];
	if (t->nring++ >= FAR_RING)
		far_pend_add(t->cnt[q->sca], q, n);
	q->sca = sca;
	q->c0 = (uint32_t)c[0];
	for (int k = 0; k < 4; k++)
		q->v[k] = light * w[k];
	for (int r = 0; r < 2; r++) {
		const char *a = (const char *)(t->cnt[sca] + 3 * c[2 * r]);

		__builtin_prefetch(a, 1);
		__builtin_prefetch(a + 47, 1);
	}
	return 0;
}

/* psf-halo-near=level: light left out of the halo's array by a source of
 * level step k, spread with the array's pixels below that step (of halo
 * slot's array). */
int far_deposit_near(struct point *p, const struct wfs_source *src, double light, int k, int slot)
{
	struct tally *t = tally_of(p);

	if (!t)
		return p->host->error(p->host->ctx, "out of memory");
	if (!(light > 0))
		return 0;
	t->spread += light;
	return dep_push(p, t, (struct far_dep){ .k = k, .sca = (short)src->sca, .slot = (short)slot,
					   .r = 0, .x = src->x, .y = src->y, .light = light });
}

/* The model's value at pixel offset (dx, dy) outside the box of half-width
 * hb (|dx| < hb and |dy| < hb inside), else 0. */
static inline double wing_at(const struct halo *h, double dx, double dy, double hb)
{
	if (fabs(dx) < hb && fabs(dy) < hb)
		return 0;
	return halo_value(h, dx, dy);
}

/* Whether cell_sum's points of the cell (p, q) (spacing b, offsets ox and
 * oy) all fall on samples of the array within its plain part (d < R -
 * taper, where halo_value() is the bilinear read alone) and outside the
 * hole of half-width hb. */
static int cell_plain(const struct halo *h, int s, long p, long q, int k, double hb, double b,
		      double ox, double oy)
{
	double x0 = p * s - 0.5 * s + ox * b, y0 = q * s - 0.5 * s + oy * b;
	double x1 = x0 + (k - 1) * b, y1 = y0 + (k - 1) * b, o = h->over;
	double mx = fmax(fabs(x0), fabs(x1)), my = fmax(fabs(y0), fabs(y1));
	double nx = x0 <= 0 && x1 >= 0 ? 0 : fmin(fabs(x0), fabs(x1));
	double ny = y0 <= 0 && y1 >= 0 ? 0 : fmin(fabs(y0), fabs(y1));

	return o * x0 == floor(o * x0) && o * y0 == floor(o * y0) && o * b == floor(o * b) &&
	       sqrt(mx * mx + my * my) < h->R - h->taper && (nx >= hb || ny >= hb);
}

/* The sum of the wing over the s x s pixels of the cell (p, q) away from
 * a source at a cell's centre, on a k x k lattice of sub-blocks (k = s:
 * every pixel).  s is even, so a source at a cell's centre sits on a
 * pixel corner and its pixels are at half-integer offsets.  A lattice
 * coarser than 4 pixels is shifted within its sub-blocks by an amount that
 * changes from cell to cell (the golden ratio's multiples), so that a
 * diffraction spike, a few pixels wide, is not caught by every cell along
 * it or by none: the cells' sums along a spike then hold its light on
 * average. */
static double cell_sum(const struct halo *h, int s, long p, long q, int k, double hb)
{
	double b = (double)s / k, sum = 0, ox = 0.5, oy = 0.5;

	if (b > 4) {
		ox = fmod(0.5 + 0.6180339887 * (double)(p * 7 + q * 13), 1.0);
		oy = fmod(0.5 + 0.7548776662 * (double)(p * 11 + q * 5), 1.0);
		ox += ox < 0;
		oy += oy < 0;
	}
	if (cell_plain(h, s, p, q, k, hb, b, ox, oy)) {
		/* every point a sample of the array's plain part, outside the
		 * hole: halo_value()'s bilinear read there is the sample */
		long o = h->over, u0 = h->c + lround(o * (p * s - 0.5 * s + ox * b));
		long w0 = h->c + lround(o * (q * s - 0.5 * s + oy * b)), ob = lround(o * b);

		for (int j = 0; j < k; j++) {
			const float *row = h->a + (w0 + ob * j) * h->n + u0;

			for (int i = 0; i < k; i++)
				sum += h->s * row[ob * i];
		}
		return sum * b * b;
	}
	for (int j = 0; j < k; j++)
		for (int i = 0; i < k; i++)
			sum += wing_at(h, p * s - 0.5 * s + (i + ox) * b, q * s - 0.5 * s + (j + oy) * b, hb);
	return sum * b * b;
}

/* The light per unit length along each spike of the tail, at unit
 * distance: lam[k] for the spike of direction h->spk[k].  A spike's profile
 * across is narrowed by rb / d and raised by d / rb (halo_tail), so its
 * integral across at distance d is (2 pi / NT) d^(1 - alpha) times the sum
 * of S over its bins. */
static void spike_lambda(const struct halo *h, double *lam)
{
	int n = 0;

	for (int k = 0; k < HALO_NT && n < h->nspk; k++) {
		double sum = 0;

		if (h->cen[k] != k)
			continue;
		for (int j = -HALO_SW; j <= HALO_SW; j++) {
			int b = (k + j + HALO_NT) % HALO_NT;

			if (h->cen[b] == k)
				sum += h->S[b];
		}
		lam[n++] = sum * 2 * M_PI / HALO_NT;
	}
}

/* Whether the cell (p, q) away on level l is wholly in the tail and
 * summed there from the tail's parts (level_kernel). */
static int tail_cell(const struct halo *h, const struct level *l, long near, long p, long q)
{
	double ax = fabs((double)p * l->s) - 0.5 * l->s, ay = fabs((double)q * l->s) - 0.5 * l->s;

	ax = ax > 0 ? ax : 0;
	ay = ay > 0 ? ay : 0;
	return h->nspk >= 0 && !(labs(p) <= near && labs(q) <= near) &&
	       ax * ax + ay * ay >= (h->R + 1) * (h->R + 1);
}

/* The model's light outside the box of half-width hb: its total less what
 * it puts in the box for a source on a pixel corner. */
static double light_outside(const struct halo *h, double hb)
{
	double inbox = 0;

	for (double dy = 0.5 - ceil(hb); dy < hb; dy++)
		for (double dx = 0.5 - ceil(hb); dx < hb; dx++)
			inbox += halo_value(h, dx, dy);
	return h->total - inbox;
}

/*
 * Level l's kernel: the wing outside its hole summed over each of its
 * cells, into raw ((2 H + 1)^2, centre at (H, H)).  Cells that meet the
 * hole or lie within l->exact rings of it are summed pixel by pixel (every
 * l->step pixels), cells the halo's array reaches every other pixel (with
 * too many spikes to keep apart, the rest on 4 x 4 points).  A cell wholly
 * in the tail takes the tail's baseline at its centre, and the light of
 * the spikes that cross it: each spike's ray is followed a pixel at a
 * time, the light of each step (per unit length the integral of the
 * tail's spike part across, spike_lambda, times d^(1 - alpha)) going to
 * the cell its middle lies in.
 */
static void level_kernel(const struct halo *h, const struct level *l, double *raw)
{
	int s = l->s, H = l->H, kn = 2 * H + 1;
	long near = (long)ceil(l->hole / s) + l->exact;
	double lam[HALO_MAXSPK], lmax = (H + 1) * s * M_SQRT2;

	for (long q = -H; q <= H; q++)
		for (long pp = -H; pp <= H; pp++) {
			double ax = fabs((double)pp * s) - 0.5 * s, ay = fabs((double)q * s) - 0.5 * s, v;

			ax = ax > 0 ? ax : 0;
			ay = ay > 0 ? ay : 0;
			if (fabs((double)pp * s) + 0.5 * s <= l->hole &&
			    fabs((double)q * s) + 0.5 * s <= l->hole)
				v = 0;  /* wholly in the hole */
			else if (labs(pp) <= near && labs(q) <= near)
				v = cell_sum(h, s, pp, q, s / l->step, l->hole);
			else if (ax * ax + ay * ay < (h->R + 1) * (h->R + 1))
				v = cell_sum(h, s, pp, q, s / 2, l->hole);
			else if (h->nspk < 0)
				v = cell_sum(h, s, pp, q, 4, l->hole);
			else
				v = (double)s * s * halo_tail_base(h, pp * s, q * s);
			raw[(size_t)(q + H) * kn + pp + H] = v;
		}
	if (h->nspk <= 0)
		return;
	spike_lambda(h, lam);
	for (int k = 0; k < h->nspk; k++)
		for (double d = floor(h->R); d < lmax; d++) {
			double m = d + 0.5, x = h->spk[k][0] * m, y = h->spk[k][1] * m;
			long pp = lround(x / s), q = lround(y / s);

			if (labs(pp) > H || labs(q) > H || !tail_cell(h, l, near, pp, q))
				continue;
			raw[(size_t)(q + H) * kn + pp + H] +=
				lam[k] * (h->alpha == 3 ? 1 / d - 1 / (d + 1) :
					  (pow(d, 2 - h->alpha) - pow(d + 1, 2 - h->alpha)) / (h->alpha - 2));
		}
}

/* The model's light beyond radius r and outside the box of half-width
 * hb, given outbox, its light outside the box. */
static double light_beyond(const struct halo *h, double hb, double outbox, double r)
{
	double in = 0, r2 = r * r;
	long m = (long)ceil(r);

	if (r >= h->R)
		return h->atot * pow(r, 2 - h->alpha) / (h->alpha - 2);
	for (double dy = 0.5 - m; dy < m; dy++)
		for (double dx = 0.5 - m; dx < m; dx++)
			if (dx * dx + dy * dy <= r2)
				in += wing_at(h, dx, dy, hb);
	return outbox - in;
}

/* Level l's kernel of the wing beyond radius r (r = 0: all of it) from its
 * raw sums into kern, over out: a cell wholly beyond r keeps its sum, one
 * wholly within is nought, one that r crosses is summed pixel by pixel
 * (every l->step pixels). */
static void level_disc(const struct halo *h, const struct level *l, double r, double out,
		       const double *raw, double *kern)
{
	int s = l->s, H = l->H, kn = 2 * H + 1, st = l->step;
	double r2 = r * r;

	if (r <= 0) {
		for (size_t c = 0; c < (size_t)kn * kn; c++)
			kern[c] = raw[c] / out;
		return;
	}
	for (long q = -H; q <= H; q++)
		for (long pp = -H; pp <= H; pp++) {
			/* the cell's nearest and farthest points */
			double ax = fabs((double)pp * s) - 0.5 * s, ay = fabs((double)q * s) - 0.5 * s;
			double bx = ax + s, by = ay + s, v;
			size_t c = (size_t)(q + H) * kn + pp + H;

			ax = ax > 0 ? ax : 0;
			ay = ay > 0 ? ay : 0;
			if (ax * ax + ay * ay > r2)
				v = raw[c];
			else if (bx * bx + by * by <= r2)
				v = 0;
			else {
				v = 0;
				for (int j = 0; j < s; j += st)
					for (int i = 0; i < s; i += st) {
						double dx = pp * s - 0.5 * s + i + 0.5 * st;
						double dy = q * s - 0.5 * s + j + 0.5 * st;

						if (dx * dx + dy * dy > r2)
							v += wing_at(h, dx, dy, l->hole);
					}
				v *= st * st;
			}
			kern[c] = v / out;
		}
}

static int dep_cmp(const void *a, const void *b)
{
	const struct far_dep *u = a, *v = b;
	double x = u->r, y = v->r;

	if (u->slot != v->slot)
		return (u->slot > v->slot) - (u->slot < v->slot);
	if (u->k != v->k)
		return (u->k > v->k) - (u->k < v->k);
	return (x > y) - (x < y);
}

/* The deposits of SCA sca of every thread, sorted by halo slot (the
 * default's first), level step and radius (*nd of them; NULL with *nd 0
 * when none, or after an error). */
static struct far_dep *deposits_of(struct point *p, int sca, size_t *nd)
{
	struct far_dep *d;
	size_t n = 0;

	*nd = 0;
	for (struct tally *t = p->tallies; t; t = t->next)
		for (size_t i = 0; i < t->ndep; i++)
			n += t->dep[i].sca == sca;
	if (!n || !(d = malloc(n * sizeof(*d))))
		return NULL;
	for (struct tally *t = p->tallies; t; t = t->next)
		for (size_t i = 0; i < t->ndep; i++)
			if (t->dep[i].sca == sca)
				d[(*nd)++] = t->dep[i];
	qsort(d, n, sizeof(*d), dep_cmp);
	return d;
}

/* What gather() works with: the halo whose shape it spreads (slot, as in
 * far_dep; INT_MIN before the first), its box hb, the two levels and
 * their raw kernels, the kernel being convolved, the fine grid's light
 * and the coarse one's. */
struct work {
	const struct halo *h;
	int slot;
	struct level l[2];
	double *raw[2], *kern, *g, *gc;
	size_t nkern;           /* kern's size */
	double hb, outbox;
};

/* The kernels of halo slot of SCA sca into w, unless they are there:
 * built once per slot, by the one thread that gathers the SCA its slots
 * belong to, into the same buffers (one slot's at a time). */
static int work_slot(struct point *p, int sca, struct work *w, int slot)
{
	const struct hslot *hs = hslot_at(p, sca, slot);

	if (w->slot == slot)
		return 0;
	if (!hs || (slot < 0 && !atomic_load(&hs->ready)))
		return p->host->error(p->host->ctx, "diffuse light of a halo never set up");
	w->slot = slot;
	w->h = &hs->h;
	w->hb = hs->chalf[WFS_PSF_NORMAL] > 0 ? hs->chalf[WFS_PSF_NORMAL] : 21;
	far_level(p, 0, w->hb, &w->l[0]);
	far_level(p, 1, w->hb, &w->l[1]);
	if (!((w->outbox = light_outside(w->h, w->hb)) > 0))
		return p->host->error(p->host->ctx, "the halo holds no light outside a %g-pixel "
				      "box", 2 * w->hb);
	level_kernel(w->h, &w->l[0], w->raw[0]);
	level_kernel(w->h, &w->l[1], w->raw[1]);
	return 0;
}

/* The light of the fine grid g (light per cell) spread with the wing
 * beyond r (0: outside the box) over out, added to c: the fine level's
 * kernel, and the coarse level's on g's cells moved to the coarse grid
 * with bilinear weights, interpolated back to the fine cells' centres. */
static int level_spread(struct point *p, void *thread, const struct halo *h, struct work *w,
			double r, double out, double *c)
{
	const struct level *f = &w->l[0], *k = &w->l[1];
	int n = f->n, m = k->n, kf = 2 * f->H + 1, kc = 2 * k->H + 1;
	size_t nc = (size_t)n * n;
	double *t = w->g + nc;  /* the fine grid's copy, convolved */

	memcpy(t, w->g, nc * sizeof(double));
	level_disc(h, f, r, out, w->raw[0], w->kern);
	if (p->host->convolve(p->host->ctx, thread, t, n, n, w->kern, kf) < 0)
		return -1;
	for (size_t i = 0; i < nc; i++)
		c[i] += t[i];
	memset(w->gc, 0, (size_t)m * m * 2 * sizeof(double));
	for (int b = 0; b < n; b++)
		for (int a = 0; a < n; a++) {
			double v = w->g[(size_t)b * n + a], u, z, fu, fz;
			long ia, ib;

			if (v == 0)
				continue;
			u = level_u(k, f->org + a * f->s + 0.5 * (f->s - 1));
			z = level_u(k, f->org + b * f->s + 0.5 * (f->s - 1));
			ia = lfloor(u);
			ib = lfloor(z);
			ia = ia < 0 ? 0 : ia > m - 2 ? m - 2 : ia;
			ib = ib < 0 ? 0 : ib > m - 2 ? m - 2 : ib;
			fu = u - ia;
			fz = z - ib;
			w->gc[(size_t)ib * m + ia] += v * (1 - fu) * (1 - fz);
			w->gc[(size_t)ib * m + ia + 1] += v * fu * (1 - fz);
			w->gc[(size_t)(ib + 1) * m + ia] += v * (1 - fu) * fz;
			w->gc[(size_t)(ib + 1) * m + ia + 1] += v * fu * fz;
		}
	level_disc(h, k, r, out, w->raw[1], w->kern);
	if (p->host->convolve(p->host->ctx, thread, w->gc, m, m, w->kern, kc) < 0)
		return -1;
	/* the coarse cells' light per fine cell, at the fine cells' centres */
	for (int b = 0; b < n; b++) {
		double z = level_u(k, f->org + b * f->s + 0.5 * (f->s - 1)), fz;
		long ib = lfloor(z);

		ib = ib < 0 ? 0 : ib > m - 2 ? m - 2 : ib;
		fz = z - ib;
		for (int a = 0; a < n; a++) {
			double u = level_u(k, f->org + a * f->s + 0.5 * (f->s - 1)), fu;
			long ia = lfloor(u);
			const double *g0;

			ia = ia < 0 ? 0 : ia > m - 2 ? m - 2 : ia;
			fu = u - ia;
			g0 = w->gc + (size_t)ib * m + ia;
			c[(size_t)b * n + a] += ((1 - fz) * ((1 - fu) * g0[0] + fu * g0[1]) +
						 fz * ((1 - fu) * g0[m] + fu * g0[m + 1])) /
						(FAR_COARSE * FAR_COARSE);
		}
	}
	return 0;
}

/* psf-halo-near=level's kernels: the light of the array's pixels (phase
 * 0, within its disc, outside the box hb) per fine cell about a source at
 * a cell's centre, one plane per step (hist, (2 pc + 1)^2 cells a plane);
 * acc the planes below step next summed. */
struct nearker {
	double *hist, *acc;
	int pc, next;
};

static int near_hist(const struct point *p, const struct halo *h, const struct near *n, double hb,
		     struct nearker *nk)
{
	int s = p->far_cell, pc = (int)ceil((h->R + 1 + 0.5 * s) / s), side = 2 * pc + 1;
	size_t plane = (size_t)side * side;

	nk->pc = pc;
	nk->next = n->kmin;
	if (!(nk->hist = calloc((size_t)(n->kmax - n->kmin + 1) * plane, sizeof(double))) ||
	    !(nk->acc = calloc(plane, sizeof(double))))
		return -1;
	for (int dy = -n->rc; dy <= n->rc; dy++)
		for (int dx = -n->rc; dx <= n->rc; dx++) {
			int st = n->st[(size_t)(dy + n->rc) * n->side + dx + n->rc];
			long a, b;
			double d, v;

			if (st < n->kmin || (double)dx * dx + (double)dy * dy >= h->R * h->R ||
			    (abs(dx) < hb && abs(dy) < hb))
				continue;
			a = lfloor((dx + 0.5 + 0.5 * s) / s);
			b = lfloor((dy + 0.5 + 0.5 * s) / s);
			/* within the plain part halo_value()'s read is the sample */
			d = sqrt((double)dx * dx + (double)dy * dy);
			v = d < h->R - h->taper ? halo_pixel(h, dx, dy) : halo_value(h, dx, dy);
			nk->hist[(size_t)(st - n->kmin) * plane + (size_t)(b + pc) * side + a + pc] += v;
		}
	return 0;
}

/* The light of the fine grid g spread with the array's pixels below step
 * k, added to c. */
static int near_spread(struct point *p, void *thread, struct work *w, const struct near *n,
		       struct nearker *nk, int k, double *c)
{
	const struct level *f = &w->l[0];
	/* the kernel reaches the array's disc: beyond the fine level's
	 * reach with small cells (psf-diffuse-cell=8) */
	int side = 2 * nk->pc + 1, H = f->H > nk->pc ? f->H : nk->pc, kf = 2 * H + 1, nn = f->n;
	size_t plane = (size_t)side * side, nc = (size_t)nn * nn;
	double sum = 0, *t = w->g + nc;

	if ((size_t)kf * kf > w->nkern)
		return p->host->error(p->host->ctx, "the halo's array is too large for the "
				      "diffuse grid's kernels");

	for (; nk->next < k && nk->next <= n->kmax; nk->next++)
		for (size_t i = 0; i < plane; i++)
			nk->acc[i] += nk->hist[(size_t)(nk->next - n->kmin) * plane + i];
	for (size_t i = 0; i < plane; i++)
		sum += nk->acc[i];
	if (!(sum > 0))
		return 0;
	memset(w->kern, 0, (size_t)kf * kf * sizeof(double));
	for (int b = 0; b < side; b++)
		for (int a = 0; a < side; a++)
			w->kern[(size_t)(b - nk->pc + H) * kf + a - nk->pc + H] =
				nk->acc[(size_t)b * side + a] / sum;
	memcpy(t, w->g, nc * sizeof(double));
	if (p->host->convolve(p->host->ctx, thread, t, nn, nn, w->kern, kf) < 0)
		return -1;
	for (size_t i = 0; i < nc; i++)
		c[i] += t[i];
	return 0;
}

/* The deposits dep (nd, sorted by step and radius) in groups of one step
 * and radius, each group's grid spread with its own kernel into c. */
static int spread_groups(struct point *p, void *thread, int sca, struct work *w,
			 const struct far_dep *dep, size_t nd, int64_t *cnt, double *c)
{
	int n = p->far_n, rc = -1;
	size_t nc = (size_t)n * n;
	struct nearker nk = { 0 };

	for (size_t i = 0; i < nd;) {
		size_t j = i;
		double r = dep[i].r, out;
		int k = dep[i].k, slot = dep[i].slot;

		/* a new halo's shape: its kernels, and its lists' when needed */
		if (slot != w->slot) {
			if (work_slot(p, sca, w, slot) < 0)
				goto out;
			free(nk.hist);
			free(nk.acc);
			nk = (struct nearker){ 0 };
		}
		memset(cnt, 0, 3 * nc * sizeof(int64_t));
		for (; j < nd && dep[j].r == r && dep[j].k == k && dep[j].slot == slot; j++) {
			size_t cc[4];
			double wt[4];

			far_cic(p, dep[j].x, dep[j].y, cc, wt);
			for (int q = 0; q < 4; q++)
				far_add(cnt, cc[q], dep[j].light * wt[q]);
		}
		for (size_t q = 0; q < nc; q++)
			w->g[q] = far_light(cnt, q);
		i = j;
		if (k != INT_MIN) {
			const struct hslot *hs = hslot_at(p, sca, slot);
			const struct near *nr = &hs->near;

			if (!atomic_load(&hs->near_ready) ||
			    (!nk.hist && near_hist(p, w->h, nr, w->hb, &nk) < 0)) {
				p->host->error(p->host->ctx, "out of memory for the diffuse light");
				goto out;
			}
			if (near_spread(p, thread, w, nr, &nk, k, c) < 0)
				goto out;
			continue;
		}
		if (!((out = light_beyond(w->h, w->hb, w->outbox, r)) > 0)) {
			p->host->error(p->host->ctx, "the halo holds no light beyond %g pixels", r);
			goto out;
		}
		if (level_spread(p, thread, w->h, w, r, out, c) < 0)
			goto out;
	}
	rc = 0;
out:
	free(nk.hist);
	free(nk.acc);
	return rc;
}

int far_gather(void *state, void *thread, int sca)
{
	struct point *p = state;
	int n = p->far_n, dense = 0, rc = -1;
	size_t nc = (size_t)n * n, nd = 0;
	int64_t *cnt = NULL;
	double *c = NULL;
	struct far_dep *dep = NULL;
	struct work w = { .slot = INT_MIN };

	if (p->diffuse != DIFFUSE_GRID || !atomic_load(&p->hs[sca].ready))
		return 0;
	for (struct tally *t = p->tallies; t; t = t->next)
		dense |= t->cnt[sca] != NULL;
	for (struct tally *t = p->tallies; t; t = t->next)
		for (size_t i = 0; i < t->ndep; i++)
			nd += t->dep[i].sca == sca;
	if (!dense && !nd)
		return 0;
	/* the kernels' sizes do not depend on the box */
	far_level(p, 0, 21, &w.l[0]);
	far_level(p, 1, 21, &w.l[1]);
	{
		size_t k0 = (size_t)(2 * w.l[0].H + 1) * (2 * w.l[0].H + 1);
		size_t k1 = (size_t)(2 * w.l[1].H + 1) * (2 * w.l[1].H + 1);
		size_t m2 = (size_t)w.l[1].n * w.l[1].n;

		if (!(cnt = calloc(3 * nc, sizeof(int64_t))) || !(c = calloc(nc, sizeof(double))) ||
		    !(w.g = malloc(2 * nc * sizeof(double))) ||
		    !(w.gc = malloc(2 * m2 * sizeof(double))) ||
		    !(w.raw[0] = malloc(k0 * sizeof(double))) ||
		    !(w.raw[1] = malloc(k1 * sizeof(double))) ||
		    !(w.kern = malloc((w.nkern = k0 > k1 ? k0 : k1) * sizeof(double))) ||
		    (nd && !(dep = deposits_of(p, sca, &nd)))) {
			p->host->error(p->host->ctx, "out of memory for the diffuse light");
			goto out;
		}
	}
	/* the faint sources' grid (the default halo's shape): integer sums,
	 * the same in any order */
	if (dense) {
		if (work_slot(p, sca, &w, -1) < 0)
			goto out;
		for (struct tally *t = p->tallies; t; t = t->next) {
			unsigned long long h = t->nring > FAR_RING ? t->nring - FAR_RING : 0;

			if (t->cnt[sca])
				for (size_t i = 0; i < 3 * nc; i++)
					cnt[i] += t->cnt[sca][i];
			/* and the deposits still held (read only: SCAs are
			 * gathered on several threads at once) */
			for (; h < t->nring; h++)
				if (t->ring[h % FAR_RING].sca == sca)
					far_pend_add(cnt, &t->ring[h % FAR_RING], n);
		}
		for (size_t i = 0; i < nc; i++)
			w.g[i] = far_light(cnt, i);
		if (level_spread(p, thread, w.h, &w, 0, w.outbox, c) < 0)
			goto out;
	}
	/* each radius's grid, in order of radius, then each level step's */
	if (nd && spread_groups(p, thread, sca, &w, dep, nd, cnt, c) < 0)
		goto out;
	/* light per pixel at the cells' centres; nought where it is below
	 * both psf-diffuse-floor times the drawing level and FAR_REL of the
	 * SCA's diffuse light in the cell, so that a tile whose cells are all
	 * below need not be drawn (the same values for any tiling): a lone
	 * faint star keeps its wing out to some 440 pixels, a crowded field
	 * all of it */
	{
		double lev = p->diffuse_floor * p->extent_noise * p->sigma, all = 0, rel;

		for (size_t i = 0; i < nc; i++)
			all += c[i];
		rel = FAR_REL * all / ((double)p->far_cell * p->far_cell);
		for (size_t i = 0; i < nc; i++) {
			c[i] /= (double)p->far_cell * p->far_cell;
			c[i] = c[i] >= lev || c[i] >= rel ? c[i] : 0;
		}
	}
	p->far[sca] = c;
	c = NULL;
	rc = 1;
out:
	free(cnt);
	free(c);
	free(w.g);
	free(w.gc);
	free(w.raw[0]);
	free(w.raw[1]);
	free(w.kern);
	free(dep);
	return rc;
}

SIMD_CLONES("avx2,fma", "default")
int far_spread(void *state, void *thread, int sca, const struct wfs_window *win)
{
	struct point *p = state;
	const double *c = p->far[sca];
	int n = p->far_n, nr = 0, *rs;
	long *ia;
	double *fx, *rv;
	long a0, a1;

	if (!c)
		return 0;
	if (!win->pix) {
		/* worth a tile: a cell about it that is lit (far_gather) */
		long xa = lfloor(far_u(p, win->x0)), xb = lceil(far_u(p, win->x0 + win->nx - 1));
		long ya = lfloor(far_u(p, win->y0)), yb = lceil(far_u(p, win->y0 + win->ny - 1));

		xa = xa < 0 ? 0 : xa;
		ya = ya < 0 ? 0 : ya;
		xb = xb > n - 1 ? n - 1 : xb;
		yb = yb > n - 1 ? n - 1 : yb;
		for (long b = ya; b <= yb; b++)
			for (long a = xa; a <= xb; a++)
				if (c[(size_t)b * n + a] > 0)
					return 1;
		return 0;
	}
	if (!(ia = p->host->scratch(thread, (size_t)win->nx * (sizeof(long) + sizeof(double)) +
				    (size_t)n * sizeof(double) +
				    (size_t)(win->nx + 1) * sizeof(int))))
		return p->host->error(p->host->ctx, "out of scratch memory");
	fx = (double *)(ia + win->nx);
	rv = fx + win->nx;
	rs = (int *)(rv + n);
	/* the columns in runs between two cells' centres, rs[q] to
	 * rs[q + 1], the same for every row */
	for (int i = 0; i < win->nx; i++) {
		double u = far_u(p, win->x0 + i);
		long a = lfloor(u);

		a = a < 0 ? 0 : a > n - 2 ? n - 2 : a;
		ia[i] = a;
		fx[i] = u - a;
		if (!i || a != ia[i - 1])
			rs[nr++] = i;
	}
	rs[nr] = win->nx;
	a0 = ia[0];
	a1 = ia[win->nx - 1] + 1;
	for (int j = 0; j < win->ny; j++) {
		double v = far_u(p, win->y0 + j), fy;
		long b = lfloor(v);
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		const double *c0, *c1;

		b = b < 0 ? 0 : b > n - 2 ? n - 2 : b;
		fy = v - b;
		c0 = c + (size_t)b * n;
		c1 = c0 + n;
		for (long a = a0; a <= a1; a++)
			rv[a] = c0[a] + fy * (c1[a] - c0[a]);
		/* a run at a time, so that the loop vectorises */
		for (int q = 0; q < nr; q++) {
			long a = ia[rs[q]];
			double r0 = rv[a], dr = rv[a + 1] - rv[a];

			for (int k = rs[q]; k < rs[q + 1]; k++)
				row[k] += r0 + fx[k] * dr;
		}
	}
	return 0;
}

void far_free(struct point *p)
{
	for (int s = 0; s < SCA_SLOTS; s++) {
		free(p->far[s]);
		p->far[s] = NULL;
	}
}
