/*
 * halo.h - the far wing ("halo") of a point source: the model point.c draws
 * a bright star with beyond its ePSF box, shared with the measurement
 * program contrib/bench/halo.c so that both evaluate the same numbers.
 *
 * The host lends a halo array: the built-in ePSF computed on a larger field
 * (+-R pixels) at a coarser sampling (`over` = 2 samples per pixel) than the
 * grids of the core (4), one node per SCA.  A sample is, as in the core's
 * ePSF, the fraction of the flux in a detector pixel centred at that offset.
 * The model of a pixel at distance d from the source, in the direction t:
 *
 *   d <= R - taper   the array, interpolated bilinearly (the pixels of a
 *                    source share one sub-sample phase, so one set of four
 *                    weights per source)
 *   d >= R           a power-law tail A(t) d^-alpha: A(t) is the mean of
 *                    value * d^alpha over the outer band of the array
 *                    (HALO_BAND R to R) in HALO_NT bins of direction,
 *                    interpolated linearly between bins, so the diffraction
 *                    spikes carry on outward (wider in pixels than the real
 *                    ones, with the same light per unit length: see
 *                    BENCHMARKS.md)
 *   in between       a linear blend of the two, so nothing jumps at R
 *
 * The optical model normalises each wavelength's PSF to 1 over the array,
 * which leaves out the light beyond it; the model's total (the array's disc
 * plus the tail integrated to infinity) is scaled back to the array's own
 * total, so the tail's light is taken from the array in proportion.
 */
#ifndef WFS_HALO_H
#define WFS_HALO_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define HALO_NT 1024            /* direction bins of the tail */
#define HALO_BAND 0.6           /* inner edge of the band A(t) is measured in, / R */
#define HALO_SW 8               /* half-width of a spike, bins, at most */
#define HALO_MAXSPK 128         /* spikes kept apart; more: none kept apart */
#define HALO_BIN_EDGE 0.004     /* halo_bin() this near a bin's edge: atan2() */

struct halo {
	const float *a;
	int n, over, c;
	double R;               /* the array's disc, pixels */
	double taper;           /* width of the hand-over to the tail, pixels */
	double alpha;           /* the tail's power */
	double s;               /* scale on the array's values */
	double A[HALO_NT + 1];  /* the tail's amplitude (s included); A[NT] = A[0] */
	double amax;
	int nenv;
	double *env;            /* env[r], r < nenv: the largest value at d >= r */
	double *cum;            /* cum[r]: the light within d < r + 1/2 (phase 0) */
	double total;           /* the model's total: the array's square sum */
	double atot;            /* the integral of A(t) over the turn */
	/* A = B + S: the baseline B (the least of A within HALO_SW bins) and
	 * the spikes S above it; cen[k] is the bin position of the spike
	 * bin k belongs to (-1: none); rb the band's mean radius */
	double B[HALO_NT + 1], S[HALO_NT + 1], cen[HALO_NT];
	double rb, bmax, smax;
	double envend;          /* the tail's largest value at d = nenv */
	/* the spikes' directions (cos, sin), and what the tail is away from
	 * them: its largest amplitude (nmax) and its integral over the turn
	 * (btot), so that beyond halo_base_radius() only the spikes rise
	 * above a level (halo_spike_span) */
	int nspk;
	double spk[HALO_MAXSPK][2];
	double nmax, btot;
};

static inline double halo_bilinear(const struct halo *h, double u, double v)
{
	int i = (int)floor(u), j = (int)floor(v);
	double fu = u - i, fv = v - j;
	const float *p;

	if (i < 0 || j < 0 || i + 1 >= h->n || j + 1 >= h->n)
		return 0;
	p = h->a + (size_t)j * h->n + i;
	return (1 - fv) * ((1 - fu) * p[0] + fu * p[1]) + fv * ((1 - fu) * p[h->n] + fu * p[h->n + 1]);
}

/* atan2(y, x) + pi in turns of HALO_NT bins, to 2.7e-4 of a bin (a
 * minimax polynomial for atan on [0, 1], within 1.7e-6 rad of it there;
 * the bins are 1e-3 of a turn). */
static inline double halo_bin(double y, double x)
{
	double ax = fabs(x), ay = fabs(y), mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax;
	double a = mx > 0 ? mn / mx : 0, a2 = a * a;
	double t = a * (0.99997726 + a2 * (-0.33262347 + a2 * (0.19354346 +
	           a2 * (-0.11643287 + a2 * (0.05265332 + a2 * -0.01172120)))));

	if (ay > ax)
		t = M_PI_2 - t;
	if (x < 0)
		t = M_PI - t;
	if (y < 0)
		t = -t;
	return (t + M_PI) * (HALO_NT / (2 * M_PI));
}

/* The bin k of angle t (halo_bin()) and the fraction f toward bin k + 1,
 * held to the table's ends. */
static inline int halo_bin_at(double t, double *f)
{
	int k = (int)t;

	*f = t - k;
	if (k >= HALO_NT) {
		k = HALO_NT - 1;
		*f = 1;
	} else if (k < 0) {
		k = 0;
		*f = 0;
	}
	return k;
}

/*
 * The tail at (dx, dy): (B(t) + S(t') d / rb) d^-alpha.  A spike keeps its
 * width in pixels as it goes out, as the optics' do (a strut's edge
 * diffracts into a line of fixed width whose light falls as d^-2 along
 * it): its angular profile measured at rb is narrowed about its centre by
 * rb / d and raised by d / rb, which keeps its light per unit length.
 */
static inline double halo_tail(const struct halo *h, double dx, double dy)
{
	double d2 = dx * dx + dy * dy, t = halo_bin(dy, dx), d = sqrt(d2), f, a;
	int k = halo_bin_at(t, &f);

	a = h->B[k] + f * (h->B[k + 1] - h->B[k]);
	if (h->cen[k] < 0)      /* no spike here: the rest of A as it is */
		a += h->S[k] + f * (h->S[k + 1] - h->S[k]);
	else {
		double q = d / h->rb, c = h->cen[k], o = t - c, u;
		int ku;

		o = (o > HALO_NT / 2 ? o - HALO_NT : (o < -HALO_NT / 2 ? o + HALO_NT : o)) * q;
		if (fabs(o) >= HALO_SW)
			goto out;
		u = c + o;
		u = u < 0 ? u + HALO_NT : (u >= HALO_NT ? u - HALO_NT : u);
		ku = (int)u;
		if (ku >= HALO_NT)
			ku = HALO_NT - 1;
		a += q * (h->S[ku] + (u - ku) * (h->S[ku + 1] - h->S[ku]));
	}
out:
	return h->alpha == 3 ? a / (d2 * d) : a * pow(d, -h->alpha);
}

/* The tail at (dx, dy) less its spikes' part: halo_tail() where no spike
 * is kept apart, the baseline B alone where one is. */
static inline double halo_tail_base(const struct halo *h, double dx, double dy)
{
	double d = sqrt(dx * dx + dy * dy), t = halo_bin(dy, dx), f, a;
	int k = halo_bin_at(t, &f);

	a = h->B[k] + f * (h->B[k + 1] - h->B[k]);
	if (h->cen[k] < 0)
		a += h->S[k] + f * (h->S[k + 1] - h->S[k]);
	return h->alpha == 3 ? a / (d * d * d) : a * pow(d, -h->alpha);
}

/* The array's value of the pixel at whole offset (dx, dy) from a source
 * on a pixel's centre (phase 0): its sample there, times s, which is what
 * halo_value()'s bilinear read gives inside the array's plain part. */
static inline double halo_pixel(const struct halo *h, long dx, long dy)
{
	return h->s * h->a[(size_t)(h->c + h->over * dy) * h->n + h->c + h->over * dx];
}

/* The model's value of a pixel at offset (dx, dy) from the source. */
static inline double halo_value(const struct halo *h, double dx, double dy)
{
	double d = sqrt(dx * dx + dy * dy), w;

	if (d >= h->R)
		return halo_tail(h, dx, dy);
	w = h->taper > 0 ? (d - (h->R - h->taper)) / h->taper : -1;
	double v = h->s * halo_bilinear(h, h->c + h->over * dx, h->c + h->over * dy);
	return w <= 0 ? v : (1 - w) * v + w * halo_tail(h, dx, dy);
}

/* The tail's largest value at distance d (d^-alpha of the baseline's
 * largest, and d^(1 - alpha) of the spikes'). */
static inline double halo_tail_max(const struct halo *h, double d)
{
	return (h->bmax + h->smax * d / h->rb) * pow(d, -h->alpha);
}

static inline void halo_free(struct halo *h)
{
	free(h->env);
	free(h->cum);
	h->env = h->cum = NULL;
}

/*
 * What halo_setup_amplitude() reads of an array's shape alone (n, over
 * and alpha; R follows from n and over): the same for every array of that
 * shape, so a caller setting up many halos makes it once (halo_geom_make)
 * and passes it to each halo_setup().  Per sample row j, the disc is |i -
 * c| <= ur[j] (ur[j] < 0: none) and the band ub[j] <= |i - c| <= ur[j];
 * bin[] holds the direction bin of each of the band's samples, in the
 * order halo_setup_amplitude() visits them; cnt[k] how many fall in bin
 * k; dpow[u (c + 1) + w] is d^alpha of sample offset (u, w) within the
 * band.  For halo_setup_envelope(): in row j the samples |i - c| = u at
 * whole pixel distance r (int d) below nenv form runs of u, r from er0[j]
 * on, the last u of each eu[eoff[j]] .. eu[eoff[j + 1] - 1] (d never
 * falls as u grows, and grows by under a pixel a sample); and rr[] the
 * whole radius (floor(d + 1/2), -1 at nenv or beyond) of each sample a
 * whole number of pixels from the centre, in the array's order.
 */
struct halo_geom {
	int n, over;
	double alpha;
	int *ur, *ub, *er0, *eoff;
	int16_t *bin, *eu, *rr;
	double *dpow;
	int cnt[HALO_NT];
};

static inline void halo_geom_free(struct halo_geom *g)
{
	free(g->ur);
	free(g->bin);
	free(g->dpow);
	free(g->eu);
	free(g->rr);
	g->ur = g->ub = g->er0 = g->eoff = NULL;
	g->bin = g->eu = g->rr = NULL;
	g->dpow = NULL;
}

/* u / over, by a product where over is a power of two (then exactly the
 * quotient, without the division's latency). */
static inline double halo_per(int u, int over)
{
	return over & (over - 1) ? (double)u / over : u * (1.0 / over);
}

/* The distance of sample offset (u, dy over) from the centre, in pixels,
 * as halo_geom_make() and the envelope test it. */
static inline double halo_dist(int u, double dy, int over)
{
	double dx = halo_per(u, over);

	return sqrt(dx * dx + dy * dy);
}

/* The envelope's runs of g (struct halo_geom: er0, eoff, eu) for nenv
 * whole radii.  0, or -1 when out of memory. */
static inline int halo_geom_rings(struct halo_geom *g, int nenv)
{
	int n = g->n, over = g->over, c = (n - 1) / 2, umax = n - 1 - c > c ? n - 1 - c : c;
	size_t t = 0;

	/* a row holds at most nenv runs (one a radius below nenv) */
	if (!(g->eu = malloc(((size_t)n * nenv + 1) * sizeof(*g->eu))))
		return -1;
	for (int j = 0; j < n; j++) {
		double dy = halo_per(j - c, over);
		int u = 0, r = (int)halo_dist(0, dy, over);

		g->er0[j] = r;
		g->eoff[j] = (int)t;
		while (r < nenv && u <= umax) {
			/* the run's last u: from where d would reach r + 1, then
			 * moved to it by the same test as every sample's */
			double e = (double)(r + 1) * (r + 1) - dy * dy;
			int ue = e > 0 ? (int)(sqrt(e) * over) : u;

			ue = ue < u ? u : ue > umax ? umax : ue;
			while (ue > u && (int)halo_dist(ue, dy, over) > r)
				ue--;
			while (ue + 1 <= umax && (int)halo_dist(ue + 1, dy, over) == r)
				ue++;
			g->eu[t++] = (int16_t)ue;
			u = ue + 1;
			r = u <= umax ? (int)halo_dist(u, dy, over) : nenv;
		}
	}
	g->eoff[n] = (int)t;
	/* the phase-0 samples' whole radii */
	t = 0;
	if (!(g->rr = malloc(((size_t)(n / over + 1) * (n / over + 1)) * sizeof(*g->rr))))
		return -1;
	for (int j = c % over; j < n; j += over)
		for (int i = c % over; i < n; i += over) {
			double d = halo_dist(i - c, halo_per(j - c, over), over);
			int r = (int)d, rr = (int)floor(d + 0.5);

			g->rr[t++] = (int16_t)(r < nenv && rr < nenv ? rr : -1);
		}
	return 0;
}

/* The direction bin of sample offset (dx, dy) in pixels: halo_bin() is
 * within 2.7e-4 bins of atan2's for any direction (its polynomial's
 * largest error on [0, 1]), so away from a bin's edges its floor is the
 * same; near them (0.4 % of the samples, the axes and diagonals among
 * them), atan2 itself (a third of the set-up's time before). */
static inline int halo_sample_bin(double dx, double dy)
{
	double t = halo_bin(dy, dx), fr = t - floor(t);
	int k = fr > HALO_BIN_EDGE && fr < 1 - HALO_BIN_EDGE ?
			(int)t : (int)((atan2(dy, dx) + M_PI) * (HALO_NT / (2 * M_PI)));

	return k >= HALO_NT ? HALO_NT - 1 : k;
}

/* Make g for arrays of n x n samples, over per pixel, tail power alpha.
 * 0, or -1 when out of memory. */
static inline int halo_geom_make(struct halo_geom *g, int n, int over, double alpha)
{
	int c = (n - 1) / 2;
	double R = (double)c / over - 1;        /* as halo_setup() sets it */
	size_t nb = 0, q = 0;

	memset(g, 0, sizeof(*g));
	g->n = n;
	g->over = over;
	g->alpha = alpha;
	if (!(g->ur = malloc((4 * (size_t)n + 1) * sizeof(int))) ||
	    !(g->dpow = malloc((size_t)(c + 1) * (c + 1) * sizeof(double)))) {
		halo_geom_free(g);
		return -1;
	}
	g->ub = g->ur + n;
	g->er0 = g->ub + n;
	g->eoff = g->er0 + n;
	if (halo_geom_rings(g, (int)ceil(R) + 1) < 0) {
		halo_geom_free(g);
		return -1;
	}
	/* d^alpha depends on |i - c| and |j - c| alone, the same for the
	 * eight samples they stand for: taken once for each, into a table of
	 * one quadrant; only the band's are read (the same d and test below) */
	for (int u = 0; u <= c; u++)
		for (int w = 0; w <= u; w++) {
			double dx = halo_per(u, over), dy = halo_per(w, over);
			double d = sqrt(dx * dx + dy * dy);

			if (d >= HALO_BAND * R && d < R)
				g->dpow[(size_t)u * (c + 1) + w] = g->dpow[(size_t)w * (c + 1) + u] =
					pow(d, alpha);
		}
	/* d by sqrt rather than hypot (a third of the set-up's time): for the
	 * grids' power-of-two oversampling dx^2 + dy^2 is exact, and the two
	 * agree.  d grows with |i - c| along a row, so the disc (d < R) and
	 * the band (d >= HALO_BAND R) are ranges of |i - c|, found with the
	 * same test at their ends (halo_dist) */
	for (int j = 0; j < n; j++) {
		double dy = (double)(j - c) / over;
		int ur = -1, ub = 0;

		if (halo_dist(0, dy, over) < R) {
			ur = (int)(sqrt(fmax(0, R * R - dy * dy)) * over);
			ur = ur > c ? c : ur;
			while (ur < c && halo_dist(ur + 1, dy, over) < R)
				ur++;
			while (ur > 0 && !(halo_dist(ur, dy, over) < R))
				ur--;
		}
		if (ur >= 0) {
			/* the first u in 0 .. ur at or beyond the band's inner
			 * edge (ur + 1: none), from an estimate */
			ub = (int)(sqrt(fmax(0, HALO_BAND * R * HALO_BAND * R - dy * dy)) * over);
			ub = ub > ur + 1 ? ur + 1 : ub;
			while (ub > 0 && halo_dist(ub - 1, dy, over) >= HALO_BAND * R)
				ub--;
			while (ub <= ur && !(halo_dist(ub, dy, over) >= HALO_BAND * R))
				ub++;
			if (ub <= ur)
				nb += 2 * (size_t)(ur - ub + 1) - (ub == 0);
		}
		g->ur[j] = ur;
		g->ub[j] = ub;
	}
	if (!(g->bin = malloc((nb ? nb : 1) * sizeof(*g->bin)))) {
		halo_geom_free(g);
		return -1;
	}
	/* the band's samples left of the centre, then right of it */
	for (int j = 0; j < n; j++) {
		double dy = (double)(j - c) / over;
		int ur = g->ur[j], ub = g->ub[j];

		if (ur < 0 || ub > ur)
			continue;
		for (int side = 0; side < 2; side++) {
			int lo = side ? (ub ? c + ub : c + 1) : c - ur, hi = side ? c + ur : c - ub;

			for (int i = lo; i <= hi; i++) {
				int k = halo_sample_bin(halo_per(i - c, over), dy);

				g->bin[q++] = (int16_t)k;
				g->cnt[k]++;
			}
		}
	}
	return 0;
}

/* The tail's amplitude A(t): the mean of value * d^alpha over the band's
 * samples in each direction bin, from every sample of the array, over g
 * (halo_geom_make, for this array's shape); *square and *disc get the
 * sample sums of the whole array and of the disc, for the normalisation.
 * Each sum takes its samples in the order of the array. */
static inline void halo_setup_amplitude(struct halo *h, const struct halo_geom *g,
					double *square_out, double *disc_out)
{
	const float *a = h->a;
	int n = h->n, c = h->c;
	double square = 0, disc = 0;
	size_t q = 0;

	for (int k = 0; k <= HALO_NT; k++)
		h->A[k] = 0;
	/* each row in one pass, so that the three sums' chains of additions
	 * run side by side: before the disc, its left band, its middle, its
	 * right band, after it */
	for (int j = 0; j < n; j++) {
		const float *row = a + (size_t)j * n;
		const double *dp = g->dpow + (size_t)abs(j - c);
		int ur = g->ur[j], ub = g->ub[j], i = 0;
		/* the bands' ends: [c - ur, bl] and [br, c + ur], none when ub > ur */
		int band = ur >= 0 && ub <= ur, bl = band ? c - ub : c - ur - 1;
		int br = band ? (ub ? c + ub : c + 1) : c + ur + 1;

		if (ur < 0) {
			for (; i < n; i++)
				square += row[i];
			continue;
		}
		for (; i < c - ur; i++)
			square += row[i];
		for (; i <= bl; i++) {
			square += row[i];
			disc += row[i];
			h->A[g->bin[q++]] += row[i] * dp[(size_t)(c - i) * (c + 1)];
		}
		for (; i < br; i++) {
			square += row[i];
			disc += row[i];
		}
		for (; i <= c + ur; i++) {
			square += row[i];
			disc += row[i];
			h->A[g->bin[q++]] += row[i] * dp[(size_t)(i - c) * (c + 1)];
		}
		for (; i < n; i++)
			square += row[i];
	}
	/* A bin is a direction's mean; an empty one (a small array) takes
	 * its neighbour's */
	for (int k = 0; k < HALO_NT; k++)
		h->A[k] = g->cnt[k] > 0 ? h->A[k] / g->cnt[k] : (k > 0 ? h->A[k - 1] : 0);
	/* the bins are centred half a bin on: shift so that A[k] is the value
	 * at the bin's start, as halo_tail() reads it */
	double prev = h->A[HALO_NT - 1];

	for (int k = 0; k < HALO_NT; k++) {
		double cur = h->A[k];

		h->A[k] = 0.5 * (prev + cur);
		prev = cur;
	}
	h->A[HALO_NT] = h->A[0];
	*square_out = square;
	*disc_out = disc;
}

/* The scale s on the array's values that makes the model's total (the
 * disc plus the tail integrated to infinity) the array's own square sum,
 * applied to A; and A's largest value and integral over the turn. */
static inline void halo_setup_scale(struct halo *h, double square, double disc)
{
	double tail = 0;

	/* samples are over^2 per pixel: a pixel sum is the sample sum / over^2 */
	square /= (double)h->over * h->over;
	disc /= (double)h->over * h->over;
	for (int k = 0; k < HALO_NT; k++)
		tail += h->A[k] * (2 * M_PI / HALO_NT);
	tail *= pow(h->R, 2 - h->alpha) / (h->alpha - 2);
	h->s = square / (disc + tail);
	h->total = square;
	h->amax = 0;
	h->atot = 0;
	for (int k = 0; k <= HALO_NT; k++) {
		h->A[k] *= h->s;
		if (h->A[k] > h->amax)
			h->amax = h->A[k];
		if (k < HALO_NT)
			h->atot += h->A[k] * (2 * M_PI / HALO_NT);
	}
}

/* A = B + S, the baseline (the least of A within HALO_SW bins) and the
 * spikes above it; then the spikes themselves: a local peak of S standing
 * above the baseline, each bin within HALO_SW of one belonging to the
 * nearest (cen). */
static inline void halo_setup_spikes(struct halo *h)
{
	h->rb = 0.5 * (1 + HALO_BAND) * h->R;
	h->bmax = h->smax = 0;
	for (int k = 0; k < HALO_NT; k++) {
		double m = h->A[k];

		for (int j = -HALO_SW; j <= HALO_SW; j++) {
			double v = h->A[(k + j + HALO_NT) % HALO_NT];

			m = v < m ? v : m;
		}
		h->B[k] = m;
		h->S[k] = h->A[k] - m;
		h->bmax = m > h->bmax ? m : h->bmax;
		h->smax = h->S[k] > h->smax ? h->S[k] : h->smax;
	}
	h->B[HALO_NT] = h->B[0];
	h->S[HALO_NT] = h->S[0];
	for (int k = 0; k < HALO_NT; k++)
		h->cen[k] = -1;
	for (int k = 0; k < HALO_NT; k++) {
		double v = h->S[k];
		int peak = v > h->B[k];

		for (int j = -HALO_SW; j <= HALO_SW && peak; j++)
			if (j && h->S[(k + j + HALO_NT) % HALO_NT] > v)
				peak = 0;
		if (!peak)
			continue;
		for (int j = -HALO_SW; j <= HALO_SW; j++) {
			int b = (k + j + HALO_NT) % HALO_NT;
			double c = h->cen[b];
			double dc = c < 0 ? 1e9 : fabs(remainder(b + 0.5 - c, HALO_NT));

			if (fabs((double)j) < dc)
				h->cen[b] = k;
		}
	}
}

/* The spikes' directions: bin c is at angle 2 pi c / NT - pi (see
 * halo_bin); and the tail away from them: the whole of A in a bin of no
 * spike (and the next, which the interpolation reads), B in one. */
static inline void halo_setup_directions(struct halo *h)
{
	h->nspk = 0;
	h->nmax = h->btot = 0;
	for (int k = 0; k < HALO_NT; k++) {
		double a = h->cen[k] < 0 ? fmax(h->A[k], h->A[k + 1]) : fmax(h->B[k], h->B[k + 1]);
		double phi = 2 * M_PI * k / HALO_NT - M_PI;

		h->nmax = a > h->nmax ? a : h->nmax;
		h->btot += (h->cen[k] < 0 ? h->A[k] : h->B[k]) * (2 * M_PI / HALO_NT);
		if (h->cen[k] != k)
			continue;
		if (h->nspk == HALO_MAXSPK) {
			h->nspk = -1;   /* too many to keep apart */
			break;
		}
		h->spk[h->nspk][0] = cos(phi);
		h->spk[h->nspk++][1] = sin(phi);
	}
}

/* The envelope env[r], from every sample (any phase) and the tail, and the
 * enclosed light cum[r] at phase 0.  Returns -1 when out of memory. */
static inline int halo_setup_envelope(struct halo *h, const struct halo_geom *g)
{
	int n = h->n, over = h->over, c = h->c;
	double R = h->R;

	h->nenv = (int)ceil(R) + 1;
	if (!(h->env = calloc(h->nenv, sizeof(double))) ||
	    !(h->cum = calloc(h->nenv, sizeof(double)))) {
		halo_free(h);
		return -1;
	}
	/* the envelope: each ring's run of samples in each row, on both
	 * sides of the centre, its largest sample times s (the largest of
	 * the products, as s > 0) */
	for (int j = 0; h->s > 0 && j < n; j++) {
		const float *row = h->a + (size_t)j * n;

		for (int t = g->eoff[j]; t < g->eoff[j + 1]; t++) {
			int r = g->er0[j] + t - g->eoff[j], ua = t > g->eoff[j] ? g->eu[t - 1] + 1 : 0;
			int lo = c - g->eu[t], hi = c + g->eu[t];
			float m = -INFINITY;

			lo = lo < 0 ? 0 : lo;
			hi = hi > n - 1 ? n - 1 : hi;
			for (int i = lo; i <= c - ua; i++)
				m = row[i] > m ? row[i] : m;
			for (int i = c + ua; i <= hi; i++)
				m = row[i] > m ? row[i] : m;
			if (h->s * m > h->env[r])
				h->env[r] = h->s * m;
		}
	}
	/* (s <= 0: every sample's product, as the envelope is defined) */
	for (int j = 0; !(h->s > 0) && j < n; j++)
		for (int i = 0; i < n; i++) {
			double dx = (double)(i - c) / over, dy = (double)(j - c) / over;
			double d = sqrt(dx * dx + dy * dy), v = h->s * h->a[(size_t)j * n + i];
			int r = (int)d;

			if (r < h->nenv && v > h->env[r])
				h->env[r] = v;
		}
	/* the light at phase 0: the samples a whole number of pixels out, in
	 * the array's order */
	{
		size_t t = 0;

		for (int j = c % over; j < n; j += over)
			for (int i = c % over; i < n; i += over, t++)
				if (g->rr[t] >= 0)
					h->cum[g->rr[t]] += h->s * h->a[(size_t)j * n + i];
	}
	for (int r = h->nenv - 2; r >= 0; r--)
		if (h->env[r + 1] > h->env[r])
			h->env[r] = h->env[r + 1];
	/* the tail's largest value at d >= r is at max(r, R - taper): it
	 * only falls */
	for (int r = 0; r < h->nenv; r++) {
		double t = halo_tail_max(h, r > R - h->taper ? r : R - h->taper);

		if (h->env[r] < t)
			h->env[r] = t;
	}
	for (int r = 1; r < h->nenv; r++)
		h->cum[r] += h->cum[r - 1];
	h->envend = halo_tail_max(h, h->nenv);
	return 0;
}

/* Set up the model of array a (n x n, over samples per pixel, centre at
 * (n - 1) / 2), with g the geometry of arrays of its shape (NULL, or one
 * of another shape: made here for this one).  Returns 0, or -1 when out
 * of memory or the array is too small (R < 16 pixels). */
static inline int halo_setup(struct halo *h, const float *a, int n, int over,
			     double alpha, double taper, const struct halo_geom *g)
{
	int c = (n - 1) / 2;
	double R = (double)c / over, square, disc;
	struct halo_geom own;

	h->a = a;
	h->n = n;
	h->over = over;
	h->c = c;
	h->R = R - 1;           /* a bilinear read at R - 1 stays inside */
	h->taper = taper < h->R / 2 ? taper : h->R / 2;
	h->alpha = alpha;
	h->s = 1;
	if (R < 16 || alpha <= 2)
		return -1;
	if (!g || g->n != n || g->over != over || g->alpha != alpha) {
		if (halo_geom_make(&own, n, over, alpha) < 0)
			return -1;
		g = &own;
	}
	halo_setup_amplitude(h, g, &square, &disc);
	halo_setup_scale(h, square, disc);
	halo_setup_spikes(h);
	halo_setup_directions(h);
	int rc = halo_setup_envelope(h, g);

	if (g == &own)
		halo_geom_free(&own);
	return rc;
}

/* The largest value of the model at distance >= r. */
static inline double halo_envelope(const struct halo *h, double r)
{
	int k = (int)floor(r);

	if (k < 0)
		k = 0;
	if (k < h->nenv)
		return h->env[k];
	return halo_tail_max(h, r);
}

/* The smallest whole radius beyond which the model stays below level: the
 * envelope's, one pixel on (the bilinear read of a pixel at distance d
 * takes samples from d - 1/sqrt(2) on). */
static inline double halo_radius(const struct halo *h, double level, double cap)
{
	int lo = 0, hi;

	if (!(level > 0))
		return cap;
	if (h->envend >= level) {
		/* beyond the array: the tail's maximum falls monotonically */
		double a = h->nenv, b = 2 * a;

		while (b < cap && halo_tail_max(h, b) >= level) {
			a = b;
			b *= 2;
		}
		if (b >= cap)
			return cap;
		for (int it = 0; it < 40 && b - a > 0.5; it++) {
			double m = 0.5 * (a + b);

			if (halo_tail_max(h, m) >= level)
				a = m;
			else
				b = m;
		}
		b = ceil(b) + 1;
		return b < cap ? b : cap;
	}
	/* the first r with env[r] < level (env never rises) */
	hi = h->nenv;
	while (lo < hi) {
		int mid = (lo + hi) / 2;

		if (h->env[mid] >= level)
			lo = mid + 1;
		else
			hi = mid;
	}
	/* a pixel at distance d reads samples up to half a pixel nearer */
	lo++;
	return lo < cap ? lo : cap;
}

/*
 * The radius beyond which the model stays below level away from the
 * spikes' strips (halo_spike_span), two pixels on, and never inside the
 * array's disc plus two pixels (in the tail, where the strips are known):
 * the disc of this radius and the strips beyond it hold every pixel above
 * level and its neighbours.  With no spikes kept apart, cap.
 */
static inline double halo_base_radius(const struct halo *h, double level, double cap)
{
	double r;

	if (h->nspk < 0 || !(level > 0))
		return cap;
	r = pow(h->nmax / level, 1 / h->alpha);
	r = (r > h->R ? r : h->R) + 2;
	return r < cap ? r : cap;
}

/* Half the width of a spike's strip in pixels: the tail's spike part is
 * nought beyond HALO_SW bins at rb, narrowed by rb / d, i.e. beyond
 * HALO_SW 2 pi rb / NT pixels of the spike's axis. */
static inline double halo_spike_width(const struct halo *h)
{
	return HALO_SW * 2 * M_PI * h->rb / HALO_NT;
}

/*
 * The offsets dx in [*lo, *hi] at row offset dy within w of spike k's axis
 * and ahead of the source along it.  Returns 0 when there are none.
 */
static inline int halo_spike_span(const struct halo *h, int k, double dy, double w, double *lo,
				  double *hi)
{
	double c = h->spk[k][0], s = h->spk[k][1];

	*lo = -HUGE_VAL;
	*hi = HUGE_VAL;
	/* across the axis: |c dy - s dx| < w */
	if (fabs(s) > 1e-12) {
		double a = (c * dy - w) / s, b = (c * dy + w) / s;

		*lo = a < b ? a : b;
		*hi = a < b ? b : a;
	} else if (fabs(c * dy) >= w)
		return 0;
	/* along it: c dx + s dy > 0 */
	if (fabs(c) > 1e-12) {
		double t = -s * dy / c;

		if (c > 0 && t > *lo)
			*lo = t;
		if (c < 0 && t < *hi)
			*hi = t;
	} else if (s * dy <= 0)
		return 0;
	return *lo < *hi;
}

/* The model's light beyond radius rb away from the spikes' strips, up to
 * radius r (the light a source drawn in the disc of rb and the strips
 * beyond leaves out, besides halo_beyond(r)). */
static inline double halo_base_between(const struct halo *h, double rb, double r)
{
	if (!(r > rb) || rb < h->R)
		return 0;
	return h->btot * (pow(rb, 2 - h->alpha) - pow(r, 2 - h->alpha)) / (h->alpha - 2);
}

/* The model's light beyond distance r (a source centred on a pixel). */
static inline double halo_beyond(const struct halo *h, double r)
{
	if (r >= h->R)
		return h->atot * pow(r, 2 - h->alpha) / (h->alpha - 2);
	return h->total - h->cum[(int)floor(r)];
}

#endif
