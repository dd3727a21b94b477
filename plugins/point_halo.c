/*
 * point_halo.c - psf-extent=noise: each source drawn out to where its
 * model sinks below psf-extent-noise of the noise per pixel, its ePSF box
 * (point_epsf.c) scaled to the halo's light in it and the halo model of
 * halo.h drawn over the rest of that disc.
 */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "point.h"

/* The centre pixel of an SCA (model.h's coordinates). */
#define SCA_CENTRE ((WFS_SCA_SIDE - 1) / 2.0)

/* The geometry of halo arrays of n x n samples, over per pixel (halo.h),
 * made on first use; NULL when out of memory or for another shape than
 * the first's (halo_setup then makes its own). */
static const struct halo_geom *geom_of(struct point *p, int n, int over)
{
	if (!atomic_load_explicit(&p->geom_ready, memory_order_acquire)) {
		pthread_mutex_lock(&p->geom_lock);
		if (!atomic_load_explicit(&p->geom_ready, memory_order_relaxed) &&
		    halo_geom_make(&p->geom, n, over, p->halo_power) == 0)
			atomic_store_explicit(&p->geom_ready, 1, memory_order_release);
		pthread_mutex_unlock(&p->geom_lock);
		if (!atomic_load_explicit(&p->geom_ready, memory_order_acquire))
			return NULL;
	}
	return p->geom.n == n && p->geom.over == over ? &p->geom : NULL;
}

/* Set up slot s's halo from the host's array a (n x n, over per pixel),
 * or with g > 0 from the blend (1 - g) a + g b into s->arr; its lock held.
 * 0, or -1 when out of memory or the array is too small. */
static int slot_setup(struct point *p, struct hslot *s, const float *a, const float *b,
		      double g, int n, int over)
{
	const struct halo_geom *geom = geom_of(p, n, over);

	if (g > 0) {
		size_t nn = (size_t)n * n;

		if (!(s->arr = malloc(nn * sizeof(float))))
			return -1;
		for (size_t i = 0; i < nn; i++)
			s->arr[i] = (float)((1 - g) * a[i] + g * b[i]);
		a = s->arr;
	}
	return halo_setup(&s->h, a, n, over, p->halo_power, p->halo_taper, geom);
}

static int slot_fail(struct point *p, int sca, int n, int over)
{
	return p->host->error(p->host->ctx, "halo of SCA %d: %d samples at %d per pixel are "
			      "too few (or out of memory)", sca, n, over);
}

/* The default spectrum's halo of the source's SCA, set up on first use by
 * one thread under that SCA's lock. */
static struct hslot *slot_default(struct point *p, const struct wfs_source *src)
{
	struct hslot *s = &p->hs[src->sca];
	struct wfs_epsf e;
	int ok = 1;

	if (atomic_load_explicit(&s->ready, memory_order_acquire))
		return s;
	if (p->host->epsf(p->host->ctx, src->sca, src->x, src->y, WFS_PSF_HALO, &e) < 0)
		return NULL;
	pthread_mutex_lock(&p->hs_lock[src->sca]);
	if (!atomic_load_explicit(&s->ready, memory_order_relaxed)) {
		if ((ok = slot_setup(p, s, e.node[0], NULL, 0, e.n, e.over) == 0))
			atomic_store_explicit(&s->ready, 1, memory_order_release);
	}
	pthread_mutex_unlock(&p->hs_lock[src->sca]);
	if (!ok) {
		slot_fail(p, src->sca, e.n, e.over);
		return NULL;
	}
	return s;
}

/* The index of a source's colour halo among its SCA's (psf-halo-colour-
 * steps N): the lower class a of its pair (point_pair) and its blend
 * rounded to j / N, j < N (j = N is the next class's j = 0); -1 for the
 * default's. */
static int colour_index(const struct point *p, const struct wfs_source *src)
{
	double c = point_colour(p, src), f;
	int a, j, N = p->halo_steps;

	if (!p->chs || !(c >= 0))
		return -1;
	point_pair(p, c, &a, &f);
	j = (int)(f * N + 0.5);
	if (j >= N) {
		a++;
		j = 0;
	}
	return a >= 0 && a < p->nclasses ? a * N + j : -1;
}

static _Atomic(struct hslot *) *colour_at(const struct point *p, int sca, int idx)
{
	return &p->chs[(size_t)sca * p->nclasses * p->halo_steps + idx];
}

/* Colour halo idx of the source's SCA: the host's halo of class a, or the
 * blend of a's and a + 1's at step j / N, set up on first use under its
 * place's lock (the host's arrays asked for outside it, as building them takes
 * seconds). */
static struct hslot *slot_colour(struct point *p, const struct wfs_source *src, int idx)
{
	_Atomic(struct hslot *) *at = colour_at(p, src->sca, idx);
	struct hslot *s = atomic_load_explicit(at, memory_order_acquire);
	int N = p->halo_steps, a = idx / N, j = idx % N, ok = 1;
	struct wfs_epsf ea, eb;

	if (s)
		return s;
	if (p->host->epsf_colour(p->host->ctx, src->sca, SCA_CENTRE, SCA_CENTRE, WFS_PSF_HALO,
				 a, &ea) < 0 ||
	    (j > 0 && p->host->epsf_colour(p->host->ctx, src->sca, SCA_CENTRE, SCA_CENTRE,
					   WFS_PSF_HALO, a + 1, &eb) < 0))
		return NULL;
	if (j > 0 && (eb.n != ea.n || eb.over != ea.over))
		return p->host->error(p->host->ctx, "halos of spectral classes %d and %d differ "
				      "in size", a, a + 1), NULL;
	pthread_mutex_lock(set_lock_of(p, at));
	if (!(s = atomic_load_explicit(at, memory_order_relaxed))) {
		if ((s = calloc(1, sizeof(*s)))) {
			s->cls = a;
			s->step = j;
		}
		if (!s || slot_setup(p, s, ea.node[0], j ? eb.node[0] : NULL, (double)j / N, ea.n,
				     ea.over) < 0) {
			if (s) {
				halo_free(&s->h);
				free(s->arr);
				free(s);
			}
			s = NULL;
			ok = 0;
		} else
			atomic_store_explicit(at, s, memory_order_release);
	}
	pthread_mutex_unlock(set_lock_of(p, at));
	if (!ok)
		slot_fail(p, src->sca, ea.n, ea.over);
	return s;
}

/* The halo a prepared source is drawn with (render(): set up already). */
static const struct hslot *slot_drawn(const struct point *p, const struct wfs_source *src)
{
	if (src->aux[0] < 0)
		return atomic_load_explicit(colour_at(p, src->sca, colour_index(p, src)),
					    memory_order_acquire);
	return &p->hs[src->sca];
}

void hslot_free_all(struct point *p)
{
	for (int i = 0; i < SCA_SLOTS; i++) {
		halo_free(&p->hs[i].h);
		near_free(&p->hs[i].near);
	}
	int made = 0;

	for (size_t i = 0; p->chs && i < (size_t)SCA_SLOTS * p->nclasses * p->halo_steps; i++) {
		struct hslot *s = atomic_load(&p->chs[i]);

		if (s) {
			halo_free(&s->h);
			near_free(&s->near);
			free(s->arr);
			free(s);
			made++;
		}
	}
	if (made)
		p->host->log(p->host->ctx, 1, "point: %d halos of spectra (SCA, class and step)",
			     made);
	free(p->chs);
	p->chs = NULL;
	halo_geom_free(&p->geom);
	atomic_store(&p->geom_ready, 0);
}

/* The core's light within its box less one pixel all round (see
 * core_scale) at the node of e nearest the SCA's centre, and that box's
 * half-width. */
static double core_light(const struct wfs_epsf *e, int *half)
{
	double fine = 0;
	int k0 = 0;

	*half = e->centre / e->over - 1;
	for (int k = 1; k < 4; k++)
		if (e->weight[k] > e->weight[k0])
			k0 = k;
	for (int j = -*half + 1; j < *half; j++)
		for (int i = -*half + 1; i < *half; i++)
			fine += e->node[k0][(size_t)(e->centre + e->over * j) * e->n + e->centre +
					    e->over * i];
	return fine;
}

/*
 * The core's scale for slot s and the source's class: the halo's light in
 * the class's box over the core's own (the cores are normalised within
 * their boxes, so they hold the light beyond them too), both for a source
 * on a pixel centre, from the node nearest the SCA's centre; for a colour
 * halo the core of its class, or the blend of its pair's at its step.  The
 * box is the class's less one pixel all round: the grids' outermost
 * samples stand about 20% below their neighbours (a 10.5 mag star on a
 * whole pixel in F129 drew its box's last column 3.5 sigma below the
 * halo beside it, a seam the demo's image showed), so the halo draws
 * that ring.
 */
static double core_scale(struct point *p, const struct wfs_source *src, struct hslot *s)
{
	int cls = src->psf_class, half;
	_Atomic int *ready = &s->cfac_ready[cls];
	const struct halo *h = &s->h;
	struct wfs_epsf e;
	double fine, far = 0;

	if (atomic_load_explicit(ready, memory_order_acquire))
		return s->cfac[cls];
	/* from the node nearest the SCA's centre (the largest weight there),
	 * whichever source asks first, so that the scale is the same for any
	 * order of the sources and any thread: each thread that finds it
	 * unset computes it, and the first one stores it */
	if ((s->cls < 0 ? p->host->epsf(p->host->ctx, src->sca, SCA_CENTRE, SCA_CENTRE, cls, &e) :
			  p->host->epsf_colour(p->host->ctx, src->sca, SCA_CENTRE, SCA_CENTRE, cls,
					       s->cls, &e)) < 0)
		return -1;
	fine = core_light(&e, &half);
	if (s->step > 0) {
		double g = (double)s->step / p->halo_steps;

		if (p->host->epsf_colour(p->host->ctx, src->sca, SCA_CENTRE, SCA_CENTRE, cls,
					 s->cls + 1, &e) < 0)
			return -1;
		fine = (1 - g) * fine + g * core_light(&e, &half);
	}
	/* a box wider than the array (psf-halo-radius below the box's
	 * half-width) takes the model's tail where the array has no sample */
	for (int j = -half + 1; j < half; j++)
		for (int i = -half + 1; i < half; i++)
			far += abs(h->over * i) <= h->c && abs(h->over * j) <= h->c ?
				       halo_pixel(h, i, j) : halo_value(h, i, j);
	pthread_mutex_lock(&p->lock);
	if (!atomic_load_explicit(ready, memory_order_relaxed)) {
		s->cfac[cls] = fine > 0 && far > 0 ? far / fine : 1;
		s->chalf[cls] = half;
		atomic_store_explicit(ready, 1, memory_order_release);
	}
	pthread_mutex_unlock(&p->lock);
	return s->cfac[cls];
}

/* The drawing level of a source of flux fl, over its flux: psf-extent-noise
 * of the noise; with psf-halo-near=F, F times that rounded down to a level
 * step, *k (else INT_MIN). */
double halo_level(const struct point *p, double fl, int *k)
{
	double lev = p->extent_noise * p->sigma / fl;

	*k = INT_MIN;
	if (!psf_near(p) || !(lev > 0) || !isfinite(lev))
		return lev;
	/* clamped so that the conversion stays defined when halo_near * lev
	 * underflows to 0 or overflows: from above the step map's INT16_MIN,
	 * the mark of offsets with no step, which a k at or below it would
	 * draw (a k beyond the map's steps draws as their end does) */
	double t = floor(FAR_STEPS * log2(p->halo_near * lev));

	*k = !(t > INT16_MIN) ? INT16_MIN + 1 : t > (1 << 20) ? (1 << 20) : (int)t;
	return exp2((double)*k / FAR_STEPS);
}

/* The light a source with a halo of radius r leaves out, of level lev
 * (step k): the light beyond r and, beyond the base radius, the light away
 * from the spikes; with psf-halo-near=level, within the array's disc the
 * light of the pixels below the level, and beyond the disc what the
 * drawing there leaves out.  With psf-diffuse=grid spread once per tile
 * (point_far.c), the baseline with the wing beyond the base radius.  The
 * light is the source's own halo's (hs), and the grid spreads it in that
 * halo's shape (point_far.c). */
static int halo_left(struct point *p, const struct wfs_source *src, struct hslot *hs,
		     double r, double lev, int k, struct tally *t)
{
	const struct halo *h = &hs->h;
	double fl = src->flux, base = 0, rb = r, left, under = 0;
	const struct near *n = NULL;
	int slot;

	if (k != INT_MIN) {
		struct wfs_source ns = *src;

		/* the lists leave out the normal class's box, as the grid does */
		ns.psf_class = WFS_PSF_NORMAL;
		if (core_scale(p, &ns, hs) < 0 || !(n = near_of(p, hs, hs->chalf[WFS_PSF_NORMAL])))
			return -1;
		under = fl * near_under(n, k);
		if (r < h->R)
			r = h->R;       /* beyond the disc, all left out */
	}
	left = fl * halo_beyond(h, r);
	if (psf_spikes(p) && r > h->R) {
		rb = halo_base_radius(h, lev, r);
		base = fl * halo_base_between(h, rb, r);
	}
	t->left += left + base + under;
	if (p->diffuse != DIFFUSE_GRID)
		return 0;
	slot = hs->cls < 0 ? -1 : hs->cls * p->halo_steps + hs->step;
	if (far_deposit(p, src, left, r, slot) < 0 ||
	    (base > 0 && far_deposit(p, src, base, far_radius(p, rb), slot) < 0) ||
	    (under > 0 && far_deposit_near(p, src, under, k, slot) < 0))
		return -1;
	return 0;
}

/* How a source is drawn with halo hs (plan()): the core's scale c, the
 * drawing level lev (step k), the halo's radius r, the box's cap, and
 * whether the box holds everything above the level (faint). */
struct plan {
	struct hslot *hs;
	double c, lev, r, cap;
	int k, faint;
};

static int plan_with(struct point *p, const struct wfs_source *src, struct hslot *hs,
		     struct plan *q)
{
	const struct halo *h = &hs->h;
	double fl = src->flux;

	q->hs = hs;
	q->k = INT_MIN;
	if ((q->c = core_scale(p, src, hs)) < 0)
		return -1;
	q->lev = fl > 0 ? halo_level(p, fl, &q->k) : 0;
	q->r = fl > 0 ? halo_radius(h, q->lev, p->extent_max) : 1;
	if (q->r < 1)
		q->r = 1;
	/* the box: core_scale's unless psf-extent-min lets it shrink toward r */
	q->cap = hs->chalf[src->psf_class];
	if (p->extent_min > 0 && fmax(q->r, p->extent_min) < q->cap)
		q->cap = fmax(q->r, p->extent_min);
	/* no halo when the box holds everything above the level; the core's
	 * own values at the box's edge may stand a few per cent above the
	 * halo's (it is sampled twice as finely), so the halo takes over
	 * once the envelope there reaches half the level. */
	q->faint = q->r <= q->cap && (q->k == INT_MIN ?
				      fl * halo_envelope(h, q->cap - 1) <
					      0.5 * p->extent_noise * p->sigma :
				      halo_envelope(h, q->cap - 1) < 0.5 * q->lev);
	return 0;
}

/* The plan of a source: with its SCA's default halo; a source with a
 * spectrum (psf-halo-colour-steps > 0) that this finds bright is planned
 * again with its colour's halo, and drawn with it unless that finds it
 * faint, so that only bright stars' classes need halos. */
static int plan(struct point *p, const struct wfs_source *src, struct plan *q)
{
	struct hslot *hs = slot_default(p, src);
	struct plan qc;
	int idx;

	if (!hs || plan_with(p, src, hs, q) < 0)
		return -1;
	if (q->faint || (idx = colour_index(p, src)) < 0)
		return 0;
	if (!(hs = slot_colour(p, src, idx)) || plan_with(p, src, hs, &qc) < 0)
		return -1;
	if (!qc.faint)
		*q = qc;
	return 0;
}

/* Whether a source of flux fl (the SCA and size class of src) is planned
 * faint with its SCA's default halo, and for reach, also reaches no
 * farther than XBRIGHT_HALF (noise_reach): 1, 0, or -1. */
static int faint_inside(struct point *p, const struct wfs_source *src, double fl, int reach)
{
	struct wfs_source t = *src;
	struct hslot *hs;
	struct plan q;

	t.flux = fl;
	if (!(hs = slot_default(p, &t)) || plan_with(p, &t, hs, &q) < 0)
		return -1;
	return q.faint && (!reach || far_radius(p, halo_radius(&hs->h, q.lev, p->extent_max)) +
						 1 <= XBRIGHT_HALF);
}

/*
 * The flux at or below which every source of src's SCA and size class is
 * planned faint with the default halo (so a spectrum's halo is not looked
 * at), and for reach also reaches no farther than XBRIGHT_HALF: both hold
 * up to some flux and not beyond, as the drawing level falls and the
 * halo's radius grows with the flux (not with psf-extent-min, whose box
 * follows the radius: plan_skips() leaves it out).  Found once by
 * bisection, a flux where they hold (0 when they hold for none), so that
 * noise_prepare() and noise_reach() need not plan the faint sources: sky
 * rows are planned by reach() before they are placed, 10^7 of them for a
 * scene of 10^7 rows, and every source by prepare().  Any thread: each
 * that finds it unknown computes it, and the first stores it.  Returns 0
 * or -1.
 */
static int faint_flux(struct point *p, const struct wfs_source *src, int reach, double *flux)
{
	int sca = src->sca, cls = src->psf_class;
	double lo = 1e-30, hi = 1e32;
	int in;

	if (atomic_load_explicit(&p->faint_known[reach][sca][cls], memory_order_acquire)) {
		*flux = p->faint_at[reach][sca][cls];
		return 0;
	}
	if ((in = faint_inside(p, src, lo, reach)) < 0)
		return -1;
	if (!in)
		lo = 0;
	else if ((in = faint_inside(p, src, hi, reach)) < 0)
		return -1;
	else if (in)
		lo = hi;
	for (int it = 0; lo > 0 && lo < hi && it < 200 && hi / lo > 1 + 1e-12; it++) {
		double mid = sqrt(lo) * sqrt(hi);

		if ((in = faint_inside(p, src, mid, reach)) < 0)
			return -1;
		if (in)
			lo = mid;
		else
			hi = mid;
	}
	pthread_mutex_lock(&p->lock);
	if (!atomic_load_explicit(&p->faint_known[reach][sca][cls], memory_order_relaxed)) {
		p->faint_at[reach][sca][cls] = lo;
		atomic_store_explicit(&p->faint_known[reach][sca][cls], 1, memory_order_release);
	}
	*flux = p->faint_at[reach][sca][cls];
	pthread_mutex_unlock(&p->lock);
	return 0;
}

/* Whether src may skip plan() as faint with its default halo (faint_flux,
 * for reach or not): 1, 0, or -1.  Never under psf-extent-min, whose box
 * is the halo's radius: the faint test is then not one way in the flux. */
static int plan_skips(struct point *p, const struct wfs_source *src, int reach)
{
	double faint;

	if (p->extent_min > 0 || !(src->flux > 0) || src->psf_class < 0 || src->psf_class > 2 || src->sca < 1 ||
	    src->sca >= SCA_SLOTS)
		return 0;
	if (faint_flux(p, src, reach, &faint) < 0)
		return -1;
	return src->flux <= faint;
}

/* point_reach() with psf-extent=noise: the radius the source's plan
 * draws to, when it is beyond *pixels. */
int noise_reach(struct point *p, const struct wfs_source *src, double *pixels)
{
	struct plan q;
	double r;
	int skip;

	if (*pixels >= XBRIGHT_HALF && (skip = plan_skips(p, src, 1)) != 0)
		return skip < 0 ? -1 : 0;
	if (plan(p, src, &q) < 0)
		return -1;
	r = far_radius(p, halo_radius(&q.hs->h, q.lev, p->extent_max)) + 1;
	if (r > *pixels)
		*pixels = r;
	return 0;
}

/*
 * prepare(), psf-extent=noise: the radius r beyond which the source's model
 * stays below psf-extent-noise of the noise per pixel (the halo's
 * envelope, spikes included); the core's box is the class's, or the
 * square of half-width r when that is smaller; the halo draws the disc of
 * radius r outside the box.  The core is scaled to the halo's light in its
 * box (core_scale).  aux[0] is negative when the halo is the source's
 * spectrum's (plan).
 */
int noise_prepare(struct point *p, struct wfs_source *src)
{
	struct plan q;
	const struct halo *h;
	struct wfs_source fs;
	struct tally *t;
	double r, half, fl = src->flux, drawn = 0, left;
	struct zone box;
	int cut, skip;

	/* a faint source's plan, as plan() would make it (of which only the
	 * halo, the core's scale and the box are read below) */
	if ((skip = plan_skips(p, src, 0)) != 0) {
		if (skip < 0 || !(q.hs = slot_default(p, src)) ||
		    (q.c = core_scale(p, src, q.hs)) < 0)
			return -1;
		q.cap = q.hs->chalf[src->psf_class];
		q.faint = 1;
		q.r = q.lev = 0;
		q.k = INT_MIN;
	} else if (plan(p, src, &q) < 0) {
		return -1;
	}
	h = &q.hs->h;
	r = q.r;
	fs = *src;
	fs.flux = q.c * fl;
	/* Only a source with no halo may have its box cut by psf-extent-cut,
	 * which puts the light beyond the cut back into the box.  A box the
	 * SCA's edge crosses is not cut: the light put back would land on
	 * the SCA where the whole box's would partly fall off it */
	box = square(src->x, src->y, q.cap);
	cut = q.faint && box.x0 >= 0 && box.y0 >= 0 && box.x1 <= WFS_SCA_SIDE &&
	      box.y1 <= WFS_SCA_SIDE;
	if (epsf_prepare(p, &fs, q.cap, cut, &drawn) < 0)
		return -1;
	memcpy(src->aux, fs.aux, sizeof(src->aux));
	half = fs.aux[0];
	if (q.faint)
		r = 0;
	else if (r <= half)
		r = half + 1;
	r = far_radius(p, r);   /* psf-diffuse=grid: a radius of the ladder */
	src->aux[0] = (q.hs->cls >= 0 && r > 0 ? -1 : 1) * (half + HALO_PACK * r);
	if (!(t = tally_of(p)))
		return p->host->error(p->host->ctx, "out of memory");
	t->requested += fabs(fl);
	t->npoint++;
	t->nhalo += r > 0;
	if (r > 0)
		return halo_left(p, src, q.hs, r, q.lev, q.k, t);
	left = fl * h->total - drawn;
	t->left += left;
	/* a source whose box misses the SCA is dropped by the host, its
	 * light with it */
	if (box.x1 <= 0 || box.y1 <= 0 || box.x0 >= WFS_SCA_SIDE || box.y0 >= WFS_SCA_SIDE)
		return 0;
	return p->diffuse == DIFFUSE_GRID ? far_deposit(p, src, left, 0, -1) : 0;
}

/* Whether the pixel at (dx, dy), in the tail, is drawn beyond the base
 * radius: when it or one of its four neighbours reaches lev (in the
 * model's units), so that every drawn pixel beside an undrawn one is
 * below lev (no edge above the level). */
static inline int spike_drawn(const struct halo *h, double dx, double dy, double lev, double *v)
{
	*v = halo_value(h, dx, dy);
	return *v >= lev || halo_value(h, dx - 1, dy) >= lev || halo_value(h, dx + 1, dy) >= lev ||
	       halo_value(h, dx, dy - 1) >= lev || halo_value(h, dx, dy + 1) >= lev;
}

/*
 * Beyond the base radius rb (halo_base_radius) up to r, only the spikes
 * rise above the level: the pixels of the window in their strips (two
 * pixels wider than the spike part of the tail, so that the neighbours of
 * every pixel above lev are in them), each row's strips merged so that no
 * pixel is drawn twice, and of those the pixels spike_drawn() keeps.
 */
static void spike_render(const struct halo *h, double flux, double x, double y, double rb,
			 double r, double lev, const struct wfs_window *win)
{
	double w = halo_spike_width(h) + 2, rb2 = rb * rb, r2 = r * r;
	double lo[HALO_MAXSPK], hi[HALO_MAXSPK];

	for (int j = 0; j < win->ny; j++) {
		double dy = win->y0 + j - y, dy2 = dy * dy;
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		int ns = 0;

		if (dy2 > r2)
			continue;
		/* the strips on this row, in window columns, sorted by start */
		for (int k = 0; k < h->nspk; k++) {
			double a, b;
			int at;

			if (!halo_spike_span(h, k, dy, w, &a, &b))
				continue;
			a = fmax(ceil(x + a) - win->x0, 0);
			b = fmin(floor(x + b) - win->x0, win->nx - 1);
			if (a > b)
				continue;
			for (at = ns; at > 0 && lo[at - 1] > a; at--) {
				lo[at] = lo[at - 1];
				hi[at] = hi[at - 1];
			}
			lo[at] = a;
			hi[at] = b;
			ns++;
		}
		for (int k = 0, next = 0; k < ns; k++) {
			int i = (int)lo[k] > next ? (int)lo[k] : next;

			for (; i <= (int)hi[k]; i++) {
				double dx = win->x0 + i - x, d2 = dx * dx + dy2, v;

				if (d2 > rb2 && d2 <= r2 && spike_drawn(h, dx, dy, lev, &v))
					row[i] += flux * v;
			}
			next = i > next ? i : next;
		}
	}
}

/*
 * The halo of a source: every pixel of the window within radius r of it,
 * outside its box (the zone box) and not within rs, flux times the halo
 * model.  Inside the
 * array's disc less the taper, the bilinear read with one set of weights
 * for the source (its pixels share one sub-sample phase); elsewhere
 * halo_value().
 */
static void halo_render(const struct halo *h, double flux, double x, double y, double r,
			double rs, struct zone box, const struct wfs_window *win)
{
	double ux = h->c + h->over * (win->x0 - x), uy = h->c + h->over * (win->y0 - y);
	long iu = (long)floor(ux), iv = (long)floor(uy);
	double fu = ux - iu, fv = uy - iv;
	double w00 = flux * h->s * (1 - fu) * (1 - fv), w10 = flux * h->s * fu * (1 - fv);
	double w01 = flux * h->s * (1 - fu) * fv, w11 = flux * h->s * fu * fv;
	double rin = h->R - h->taper, rin2 = rin * rin, r2 = r * r, R2 = h->R * h->R, rs2 = rs * rs;
	long n = h->n, o = h->over;

	for (int j = 0; j < win->ny; j++) {
		double dy = win->y0 + j - y, dy2 = dy * dy;
		double *row = win->pix + (ptrdiff_t)j * win->stride;
		long jj = win->y0 + j;
		int inbox = jj >= box.y0 && jj < box.y1;
		double span, lo, hi;

		if (dy2 > r2)
			continue;
		span = sqrt(r2 - dy2);
		lo = ceil(x - span) - win->x0;
		hi = floor(x + span) - win->x0;
		if (lo < 0)
			lo = 0;
		if (hi > win->nx - 1)
			hi = win->nx - 1;
		for (int i = (int)lo; i <= (int)hi; i++) {
			long ii = win->x0 + i;
			double dx = ii - x, d2 = dx * dx + dy2;

			if (inbox && ii >= box.x0 && ii < box.x1) {
				i = (int)(box.x1 - win->x0) - 1;
				continue;
			}
			if (d2 < rs2) { /* within rs: drawn by near_render */
				int e = (int)(ceil(x + sqrt(rs2 - dy2)) - win->x0) - 1;

				i = e > i ? e : i;
				continue;
			}
			if (d2 < rin2) {
				const float *q = h->a + (iv + o * j) * n + iu + o * i;

				row[i] += w00 * q[0] + w10 * q[1] + w01 * q[n] + w11 * q[n + 1];
			} else if (d2 >= R2)
				row[i] += flux * halo_tail(h, dx, dy);
			else
				row[i] += flux * halo_value(h, dx, dy);
		}
	}
}

/* render(), psf-extent=noise: the window's part of the box, its flux scaled
 * as prepare() found (core_scale), then the halo over the rest of the disc.
 * Built twice, for AVX2 and for any x86-64, and chosen at load time, as
 * point_render was before the split (without, a 2-mag star's render took
 * 1.3 times as long); not under the sanitizers (see epsf_render). */
SIMD_CLONES("avx2,fma", "default")
int noise_render(struct point *p, const struct wfs_source *src, const struct wfs_window *win)
{
	struct wfs_source fs = *src;
	struct wfs_window sub;
	struct zone box, w;
	double r = halo_radius_of(src), half = box_half_of(src);
	const struct hslot *hs = slot_drawn(p, src);

	fs.aux[0] = half;
	fs.flux = src->flux * hs->cfac[src->psf_class];
	box = square(src->x, src->y, half);
	w = meet(box, (struct zone){ win->x0, win->x0 + win->nx, win->y0, win->y0 + win->ny });
	if (!zone_empty(w)) {
		sub.pix = win->pix + (w.y0 - win->y0) * win->stride + (w.x0 - win->x0);
		sub.stride = win->stride;
		sub.x0 = (int)w.x0;
		sub.y0 = (int)w.y0;
		sub.nx = (int)(w.x1 - w.x0);
		sub.ny = (int)(w.y1 - w.y0);
		if (epsf_render(p, &fs, &sub) < 0)
			return -1;
	}
	if (r > 0) {
		const struct halo *h = &hs->h;
		int k;
		double lev = halo_level(p, src->flux, &k), rs = 0;
		double rb = psf_spikes(p) ? halo_base_radius(h, lev, r) : r;

		if (k != INT_MIN) {
			near_render(h, &hs->near, src->flux, src->x, src->y, r, k, box, win);
			rs = h->R;
		}
		if (r > rs)
			halo_render(h, src->flux, src->x, src->y, rb < r ? rb : r, rs, box, win);
		if (rb < r)
			spike_render(h, src->flux, src->x, src->y, rb, r, lev, win);
	}
	return 0;
}
