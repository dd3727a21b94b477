/*
 * noise.c - backgrounds, noise and detector residuals; see noise.h.
 *
 * The model is STIPS' (the paper, section 2.4; Instrument.addError), in its
 * order, with its defects fixed.  Per pixel, with S the rendered signal in
 * counts/s, B the background and t the exposure time:
 *
 *   c = (S + B) t                       counts
 *   c = Poisson(c)                      poisson: a true Poisson count
 *   c = c + R z1                        readnoise: R = 12 e-, own stream
 *   c = c f(x, y)                       flat: f = 1 + s_f z2, fixed field
 *   c = c + Poisson(D t) + s_d t z3     dark: current with shot noise plus
 *                                       the fixed residual field (with
 *                                       poisson on, D t joins that count)
 *   c = c + r sum(hits)                 cosmic: two populations, r = 0.01
 *   out = c / t  (or c with counts)
 *
 * z1, z2, z3 are independent N(0, 1) deviates.  Every number is Philox
 * keyed by the seed and counted by (cell, draw, domain), where the cell is
 * the absolute pixel y * 4088 + x (for cosmic rays, a segment of 64 hit
 * centres of a row: (y + 1) * 64 + (x + 1) / 64, since centres reach one
 * pixel beyond the detector, or in long exposures the centre itself,
 * (y + 1) * 4090 + x + 1) and the domain is (stage, filter, SCA).  So
 * each stage, filter and SCA has its own numbers, and the image does not
 * depend on the tiling, threads or split runs.
 *
 * The fixed fields are the seed's "detector": the flat residual f is keyed
 * by (filter, SCA), since flats depend on wavelength; the dark residual by
 * SCA alone, since dark current does not see the filter.  The Poisson, read
 * and cosmic-ray numbers are keyed by filter and SCA.
 */
#include <math.h>
#include <string.h>

#include "err.h"
#include "instrument.h"
#include "noise.h"
#include "rng.h"
#include "rng_domains.h"
#include "simd.h"


#define CR_PIXEL_AREA 1e-6      /* cm^2: 10 micron pixels */
#define CR_E_LOW 600.0          /* e-, STIPS' "galactic" population */
#define CR_E_HIGH 5000.0        /* e-, STIPS' "solar" population */
#define CR_FWHM 0.9             /* px, of the 3x3 Gaussian template */
#define CR_SPAN (WFS_NPIX + 2)  /* the grid of hit centres, -1 .. 4088 */
#define CHUNK 256               /* pixels per pass of a row */

static uint32_t domain(int stage, int filter, int sca)
{
	return rng_domain(stage, filter, sca, 0);
}

void noise_opts_default(struct noise_opts *o)
{
	memset(o, 0, sizeof(*o));
	o->exptime = 1;
	o->readnoise = NOISE_READNOISE;
	o->dark_current = NOISE_DARK_CURRENT;
	o->cosmic_rate = NOISE_COSMIC_RATE;
	o->cosmic_residual = NOISE_COSMIC_RESIDUAL;
	o->dark_residual = NOISE_DARK_RESIDUAL;
	o->flat_residual = NOISE_FLAT_RESIDUAL;
}

static int bad_value(double v, int may_be_zero)
{
	return !isfinite(v) || v < 0 || (!may_be_zero && v == 0);
}

int noise_check(const struct noise_opts *o, struct err *e)
{
	if (bad_value(o->exptime, 0))
		return err_set(e, EXIT_INPUT, "--exptime: must be a positive number of seconds: '%g'",
			       o->exptime);
	if (!isfinite(o->background))
		return err_set(e, EXIT_INPUT, "--background: not a finite number: '%g'",
			       o->background);
	if (bad_value(o->readnoise, 1))
		return err_set(e, EXIT_INPUT, "--readnoise: must be a non-negative number of electrons: '%g'",
			       o->readnoise);
	if (bad_value(o->dark_current, 1))
		return err_set(e, EXIT_INPUT, "--dark-current: must be a non-negative rate: '%g'",
			       o->dark_current);
	if (bad_value(o->cosmic_rate, 1))
		return err_set(e, EXIT_INPUT, "--cosmic-rate: must be a non-negative rate: '%g'",
			       o->cosmic_rate);
	if (bad_value(o->cosmic_residual, 1) || o->cosmic_residual > 1)
		return err_set(e, EXIT_INPUT, "--cosmic-residual: must be a fraction between 0 and 1: '%g'",
			       o->cosmic_residual);
	if (bad_value(o->dark_residual, 1))
		return err_set(e, EXIT_INPUT, "--dark-residual: must be a non-negative sigma: '%g'",
			       o->dark_residual);
	if (bad_value(o->flat_residual, 1))
		return err_set(e, EXIT_INPUT, "--flat-residual: must be a non-negative sigma: '%g'",
			       o->flat_residual);
	return 0;
}

static const struct {
	const char *name;
	unsigned bit;
} stage_names[] = {
	{ "poisson", NOISE_POISSON },
	{ "readnoise", NOISE_READ },
	{ "read", NOISE_READ },
	{ "dark", NOISE_DARK },
	{ "flat", NOISE_FLAT },
	{ "cosmic", NOISE_COSMIC },
};

int noise_parse(const char *s, unsigned *stages, struct err *e)
{
	unsigned bits = 0;
	const char *p = s;

	if (!strcmp(s, "all")) {
		*stages = NOISE_ALL;
		return 0;
	}
	if (!strcmp(s, "none")) {
		*stages = 0;
		return 0;
	}
	for (;;) {
		size_t len = strcspn(p, ",");
		size_t i, n = sizeof(stage_names) / sizeof(stage_names[0]);

		for (i = 0; i < n; i++)
			if (strlen(stage_names[i].name) == len &&
			    !strncmp(p, stage_names[i].name, len))
				break;
		if (i == n)
			return err_set(e, EXIT_INPUT,
				       "--noise: unknown stage '%.*s' in '%s' (expected all, none, or a list of poisson, readnoise, dark, flat, cosmic)",
				       (int)len, p, s);
		bits |= stage_names[i].bit;
		if (!p[len])
			break;
		p += len + 1;
	}
	*stages = bits;
	return 0;
}

/*
 * poisson_sign: the Poisson stage draws a count for each mean m in counts.
 * Negative means have no Poisson distribution (they come only from negative
 * catalog fluxes or backgrounds); they get the mirror image -Poisson(-m),
 * which keeps STIPS' variance |m|.  NaN and infinities pass through.
 */

/*
 * The 3x3 cosmic-ray template of STIPS (GetCrTemplate): a Gaussian of FWHM
 * 0.9 px sampled at the pixel centres and normalised to 1; sigma =
 * 0.9 / (2 sqrt(2 ln 2)) = 0.3822 px, weights 0.88127 (centre), 0.02875
 * (edges), 0.00094 (corners).
 */
static void cr_template(double w[3][3])
{
	double s = CR_FWHM / (2 * sqrt(2 * log(2.0))), sum = 0;

	for (int dy = -1; dy <= 1; dy++)
		for (int dx = -1; dx <= 1; dx++)
			sum += w[dy + 1][dx + 1] = exp(-(dx * dx + dy * dy) / (2 * s * s));
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			w[i][j] /= sum;
}

/*
 * Cosmic rays: each population is a Poisson process of rate `rate`
 * hits/cm^2/s over pixels of 1e-6 cm^2, so a pixel is the centre of
 * Poisson(lambda) hits, lambda = rate * 1e-6 * t, independently for the two
 * populations (STIPS draws both from one seed, so they land on the same
 * pixels).  A hit deposits Poisson(E) electrons (STIPS: E + sqrt(E) z, the
 * same mean and variance, but never negative), spread by the template over
 * the 3x3 pixels around its centre, and a fraction r of it is left.
 *
 * Centres run over -1 .. 4088, one pixel beyond the science area: the H4RG
 * has a 4-pixel border of reference pixels there that cosmic rays hit too,
 * and their charge spreads into the edge pixels, so every science pixel
 * receives the same expected dose.  A hit on an edge pixel loses the part
 * of its template that falls off the science area (STIPS drops such hits
 * whole).  The tile looks at the centres one pixel around itself.
 *
 * Hits are rare (lambda = 5e-4 in 100 s), so they are drawn per segment of
 * CR_SEG centres of a row rather than per pixel: a segment of n centres
 * holds Poisson(n lambda) hits of a population, each at a uniformly chosen
 * centre of the segment.  That is the same Poisson process (a Poisson
 * count with uniform positions; per-pixel counts independent Poisson(lambda)
 * by the splitting property), with one Philox call per 64 centres instead
 * of one per centre.  The numbers of a segment are its own (cell = row *
 * 64 + segment), so every tile that sees a segment sees the same hits.
 *
 * That costs a few draws per hit, so its time grows with the exposure:
 * 1.7e8 hits per SCA at 1e6 s, 1.7e11 at 1e9 s.  From lambda >= 1 per
 * centre (2e5 s at the default rate) each centre is drawn instead: its
 * count n ~ Poisson(lambda) and, when n > 0, the electrons of its n hits
 * together, Poisson(n E) (a sum of independent Poisson counts is one), all
 * at the template's place.  The same distribution as hit by hit, at a cost
 * that no longer grows with the exposure time.  Counts and energies have
 * their own domains, counted by centre ((cy + 1) * 4090 + cx + 1).
 */
#define CR_SEG 64
#define CR_NSEG ((CR_SPAN + CR_SEG - 1) / CR_SEG)
#define CR_PER_CENTRE 1.0       /* lambda from which centres are drawn one by one */


struct cr_tile {
	double tw[3][3], resid;
	int x0, y0, nx, ny;
	double *pix;
	ptrdiff_t stride;
};

static void cr_deposit(const struct cr_tile *t, int cx, int cy, double e)
{
	e *= t->resid;
	for (int dy = -1; dy <= 1; dy++) {
		int y = cy + dy;

		if (y < t->y0 || y >= t->y0 + t->ny)
			continue;
		for (int dx = -1; dx <= 1; dx++) {
			int x = cx + dx;

			if (x >= t->x0 && x < t->x0 + t->nx)
				t->pix[(ptrdiff_t)(y - t->y0) * t->stride + (x - t->x0)] +=
					e * t->tw[dy + 1][dx + 1];
		}
	}
}

/* The hits of population g (energy E) in segment cell of row cy, whose
 * first centre is cx0 and which has n centres; u decided the count. */
static void cr_segment(const struct cr_tile *t, const struct rng *g, double energy,
		       struct rng_poisson *big, double lambda, double emu, double u,
		       uint32_t cell, int cx0, int n, int cy)
{
	struct rng_cell c;
	double hits;

	rng_cell_init(&c, g, cell, 0);
	/* n lambda >= 10 needs t > 3e4 s; then PTRS on the stream. */
	if (lambda < 10)
		hits = rng_poisson_invert(u, lambda, emu);
	else
		hits = rng_poisson_draw(big, &c);
	for (double h = 0; h < hits; h++) {
		int cx = cx0 + (int)(rng_cell_u01(&c) * n);
		double e = rng_poisson(energy, &c);

		/* Only hits that reach the tile matter, but every hit
		 * takes its numbers, so the stream is the same for all. */
		if (cx >= t->x0 - 1 && cx <= t->x0 + t->nx &&
		    cy >= t->y0 - 1 && cy <= t->y0 + t->ny)
			cr_deposit(t, cx, cy, e);
	}
}

/* Long exposures: every centre of the tile's ring drawn by itself. */
static void cosmic_per_centre(const struct noise_opts *o, const struct cr_tile *t,
			      int sca, double lambda)
{
	static const double energy[2] = { CR_E_LOW, CR_E_HIGH };
	static const int dom_n[2] = { DOM_SC_CR_LOW_N, DOM_SC_CR_HIGH_N };
	static const int dom_e[2] = { DOM_SC_CR_LOW_E, DOM_SC_CR_HIGH_E };
	int xa = t->x0 - 1, xb = t->x0 + t->nx, ya = t->y0 - 1, yb = t->y0 + t->ny;
	double lam[CR_SPAN], n[CR_SPAN];
	size_t len;

	if (xb > WFS_NPIX)
		xb = WFS_NPIX;
	if (yb > WFS_NPIX)
		yb = WFS_NPIX;
	len = (size_t)(xb - xa + 1);
	for (size_t i = 0; i < len; i++)
		lam[i] = lambda;
	for (int p = 0; p < 2; p++) {
		struct rng gn, ge;

		rng_init(&gn, o->seed, domain(dom_n[p], o->filter, sca));
		rng_init(&ge, o->seed, domain(dom_e[p], o->filter, sca));
		for (int cy = ya; cy <= yb; cy++) {
			uint32_t cell0 = (uint32_t)(cy + 1) * CR_SPAN + (uint32_t)(xa + 1);

			rng_poisson_fill(&gn, cell0, len, lam, n);
			for (size_t i = 0; i < len; i++) {
				struct rng_cell c;

				if (n[i] == 0)
					continue;
				rng_cell_init(&c, &ge, cell0 + (uint32_t)i, 0);
				cr_deposit(t, xa + (int)i, cy, rng_poisson(n[i] * energy[p], &c));
			}
		}
	}
}

static void cosmic_tile(const struct noise_opts *o, int sca, int x0, int y0,
			int nx, int ny, double *pix, ptrdiff_t stride)
{
	double lambda = o->cosmic_rate * CR_PIXEL_AREA * o->exptime;
	struct cr_tile t = { .resid = o->cosmic_residual, .x0 = x0, .y0 = y0,
			     .nx = nx, .ny = ny, .pix = pix, .stride = stride };
	struct rng hit, pop[2];
	static const double energy[2] = { CR_E_LOW, CR_E_HIGH };
	/* Segments are full but the last of a row (4090 = 63 * 64 + 58). */
	int nlast = CR_SPAN - (CR_NSEG - 1) * CR_SEG;
	struct rng_poisson big[2][2];
	double lam[2], emu[2];
	uint64_t thr[2];
	uint32_t w[CR_NSEG][4];
	int ya = y0 - 1 < -1 ? -1 : y0 - 1, yb = y0 + ny;
	int sa = (x0 - 1 + 1) / CR_SEG, sb = (x0 + nx + 1) / CR_SEG;

	if (!(lambda > 0) || t.resid == 0)
		return;
	cr_template(t.tw);
	if (lambda >= CR_PER_CENTRE) {
		cosmic_per_centre(o, &t, sca, lambda);
		return;
	}
	if (yb > WFS_NPIX)
		yb = WFS_NPIX;
	if (sb > CR_NSEG - 1)
		sb = CR_NSEG - 1;
	rng_init(&hit, o->seed, domain(DOM_SC_CR_HIT, o->filter, sca));
	rng_init(&pop[0], o->seed, domain(DOM_SC_CR_LOW, o->filter, sca));
	rng_init(&pop[1], o->seed, domain(DOM_SC_CR_HIGH, o->filter, sca));
	/* [0]: a full segment, [1]: the last, shorter one. */
	for (int k = 0; k < 2; k++) {
		lam[k] = lambda * (k ? nlast : CR_SEG);
		emu[k] = exp(-lam[k]);
		/* u = m 2^-53 < exp(-lambda) (no hit) exactly when the
		 * 53-bit integer m < ceil(exp(-lambda) 2^53): scaling by 2^53
		 * is exact. */
		thr[k] = (uint64_t)ceil(emu[k] * 0x1p53);
		for (int p = 0; p < 2; p++)
			rng_poisson_setup(&big[k][p], lam[k]);
	}
	for (int cy = ya; cy <= yb; cy++) {
		uint32_t cell0 = (uint32_t)(cy + 1) * CR_NSEG + (uint32_t)sa;

		rng_bits_n(&hit, cell0, 0, (size_t)(sb - sa + 1), w);
		for (int sg = sa; sg <= sb; sg++) {
			const uint32_t *wd = w[sg - sa];
			int last = sg == CR_NSEG - 1;
			int n = last ? nlast : CR_SEG;

			for (int p = 0; p < 2; p++) {
				uint64_t m = ((uint64_t)wd[2 * p] << 32 | wd[2 * p + 1]) >> 11;

				if (m < thr[last])
					continue;
				cr_segment(&t, &pop[p], energy[p], &big[last][p], lam[last],
					   emu[last], rng_u01(wd[2 * p], wd[2 * p + 1]),
					   cell0 + (uint32_t)(sg - sa), -1 + sg * CR_SEG, n, cy);
			}
		}
	}
}

/*
 * The Poisson stage's counts of means below POIS_FAST (all but a star's
 * core), eight at a time without a call to exp() per pixel.  The count of
 * rng_poisson_fill_approx() for a mean m < 10 is the inversion k = min{k :
 * u < F(k)} of u from words 0-1 of the cell's draw 0, F built from e =
 * exp(-m) by F(0) = e, F(k) = F(k-1) + p(k), p(k) = p(k-1) m (1/k)
 * (rng_poisson_invert).  Rounded products and sums are monotone in each
 * argument, so F built the same way from a bracket e_lo <= e <= e_hi
 * brackets F; e is approximated here (range reduction by ln 2 and a
 * degree-12 Taylor polynomial, relative error below 1e-15) and bracketed
 * by 2^-40 either side.  Where the counts of the two brackets agree the
 * count is the exact one; a lane where they do not (u within 1e-12 of a
 * step of F: never seen in practice) or that needs more than POIS_STEPS
 * terms takes rng_poisson_invert() with libm's exp.  So the same counts as
 * before, bit for bit, with libm's exp() per pixel (a sky varies by pixel
 * area: the mean changes at every pixel) gone.
 */
#define POIS_FAST 10.0
#define POIS_STEPS 48
_Static_assert(POIS_STEPS <= RNG_RECIP, "the steps' 1/k from rng_recip");

/* Eight lanes in GCC's vector types, compiled for AVX-512 and for AVX2
 * (two halves) below, into which the functions on them are inlined. */
typedef double v8d __attribute__((vector_size(64)));
typedef long long v8l __attribute__((vector_size(64)));

/* exp(-m) for 0 <= m < POIS_FAST, relative error below 1e-15.  The
 * polynomial by Estrin's scheme (pairs of terms, then pairs of pairs, by
 * r^2, r^4 and r^8): a chain of 4 multiply-adds instead of Horner's 12,
 * so eight lanes wait a third as long; its rounding differs from Horner's
 * by a few ulps, far inside the 2^-40 by which pois_fast8() widens the
 * brackets, so the counts are the same. */
static inline __attribute__((always_inline)) void exp_neg8(const v8d *mp, v8d *out)
{
	const double magic = 0x1.8p52;
	v8d x = -*mp, t = x * 1.4426950408889634 + magic, nd = t - magic, r, r2, r4, r8, p;
	v8d q0, q1, q2, q3, q4, q5, s0, s1, s2;
	v8l sc;

	/* r = x - n ln 2 (Cody-Waite: ln 2 in two parts, the first exact
	 * times n) */
	r = (x - nd * 0x1.62e42fee00000p-1) - nd * 0x1.a39ef35793c76p-33;
	r2 = r * r;
	r4 = r2 * r2;
	r8 = r4 * r4;
	/* sum_k r^k / k!, k = 0 .. 12 */
	q0 = r + 1.0;
	q1 = r * (1.0 / 6) + 0.5;
	q2 = r * (1.0 / 120) + 1.0 / 24;
	q3 = r * (1.0 / 5040) + 1.0 / 720;
	q4 = r * (1.0 / 362880) + 1.0 / 40320;
	q5 = r * (1.0 / 39916800) + 1.0 / 3628800;
	s0 = q1 * r2 + q0;
	s1 = q3 * r2 + q2;
	s2 = q5 * r2 + q4;
	s0 = s1 * r4 + s0;
	s2 = r4 * (1.0 / 479001600) + s2;
	p = s2 * r8 + s0;
	/* 2^n from t's low bits (n = -15 .. 0) */
	sc = ((v8l)t - 0x4338000000000000LL + 1023) << 52;
	*out = p * (v8d)sc;
}

/* Counts of the eight means m (0 <= m < POIS_FAST) from the uniforms u
 * into out; the lanes it leaves (a bracket that does not decide, or too
 * many terms) in the mask returned. */
static inline __attribute__((always_inline)) unsigned
pois_fast8(const v8d *mp, const v8d *up, double *out)
{
	v8d m = *mp, u = *up, e, plo, phi, flo, fhi, ka = { 0 }, kb = { 0 };
	v8l go;
	unsigned left = 0;
	int k = 1;

	exp_neg8(mp, &e);
	plo = e * (1 - 0x1p-40);
	phi = e * (1 + 0x1p-40);
	flo = plo;
	fhi = phi;

	for (;; k++) {
		v8l a = u >= fhi, b = u >= flo;
		v8d mk;

		/* ka counts the F_hi(j) <= u, kb the F_lo(j) <= u */
		ka -= (v8d)__builtin_convertvector(a, v8d);
		kb -= (v8d)__builtin_convertvector(b, v8d);
		go = b;
		{
			/* whether any lane goes on: the OR of the eight by
			 * halves (a lane at a time took a chain of extracts) */
			v8l h = go | __builtin_shuffle(go, (v8l){ 4, 5, 6, 7, 0, 1, 2, 3 });

			h |= __builtin_shuffle(h, (v8l){ 2, 3, 0, 1, 6, 7, 4, 5 });
			h |= __builtin_shuffle(h, (v8l){ 1, 0, 3, 2, 5, 4, 7, 6 });
			if (!h[0] || k == POIS_STEPS)
				break;
		}
		mk = m * rng_recip[k];
		plo *= mk;
		phi *= mk;
		flo += plo;
		fhi += phi;
	}
	for (int q = 0; q < 8; q++) {
		left |= (unsigned)(ka[q] != kb[q] || go[q] != 0) << q;
		out[q] = kb[q];
	}
	return left;
}

/* The body of poisson_small_fill() for 8 lanes at a time. */
static inline __attribute__((always_inline)) int
pois_fill8(const double *m, const uint32_t (*w)[4], int n, double *out)
{
	int i = 0;

	for (; i + 8 <= n; i += 8) {
		v8d mv, uv;
		unsigned left;

		for (int q = 0; q < 8; q++) {
			/* a large mean's lane is drawn again by the caller */
			mv[q] = m[i + q] < POIS_FAST ? m[i + q] : 0;
			uv[q] = rng_u01(w[i + q][0], w[i + q][1]);
		}
		left = pois_fast8(&mv, &uv, out + i);
		for (int q = 0; left; q++, left >>= 1)
			if (left & 1)
				out[i + q] = rng_poisson_invert(uv[q], mv[q], exp(-mv[q]));
	}
	return i;
}

#ifdef SIMD_X86
__attribute__((target("avx512f,avx512dq"))) static int
pois_fill8_avx512(const double *m, const uint32_t (*w)[4], int n, double *out)
{
	return pois_fill8(m, w, n, out);
}

__attribute__((target("avx2"))) static int
pois_fill8_avx2(const double *m, const uint32_t (*w)[4], int n, double *out)
{
	return pois_fill8(m, w, n, out);
}
#endif

/*
 * rng_poisson_fill_approx(g, cell0, n, m, m, normal_above) for n <= CHUNK
 * means m >= 0 of which most are below POIS_FAST: those by pois_fast8(),
 * the runs of larger ones by rng_poisson_fill_approx() (a cell's numbers
 * are its own, so a run gives the counts the whole row would).  The same
 * counts, into m; w: CHUNK calls of scratch.
 */
static void poisson_small_fill(const struct rng *g, uint32_t cell0, int n, double *m,
			       double normal_above, uint32_t (*w)[4])
{
	double out[CHUNK];
	int i = 0, f = simd_flags();

	rng_bits_n(g, cell0, 0, (size_t)n, w);
#ifdef SIMD_X86
	if (f & SIMD_AVX512)
		i = pois_fill8_avx512(m, w, n, out);
	else if (f & SIMD_AVX2)
		i = pois_fill8_avx2(m, w, n, out);
#endif
	(void)f;
	for (; i < n; i++) {
		double u = rng_u01(w[i][0], w[i][1]);

		out[i] = m[i] > 0 && m[i] < POIS_FAST ? rng_poisson_invert(u, m[i], exp(-m[i])) : 0;
	}
	/* the large means, by runs, as rng_poisson_fill_approx draws them */
	for (i = 0; i < n; i++) {
		int e = i;

		while (e < n && !(m[e] < POIS_FAST))
			e++;
		if (e > i)
			rng_poisson_fill_approx(g, cell0 + (uint32_t)i, (size_t)(e - i), m + i,
						out + i, normal_above);
		i = e;
	}
	memcpy(m, out, (size_t)n * sizeof(*m));
}

/*
 * The passes of noise_tile() over a chunk of a row, with what each stage
 * needs.  pre: background and units, and with Poisson the mean (plus the
 * dark current) kept in the row and its |value| (0 where not finite) into
 * zp.  post: the Poisson count back with the mean's sign (non-finite
 * values kept), then the read noise, the flat residual and the dark
 * residual from their deviates zr, zf, zd, in that order.  Pixel by pixel
 * these are the operations of the separate loops they replace, so the
 * same numbers; eight lanes at a time in GCC's vector types where the CPU
 * has AVX2 or AVX-512, the plain loop for the rest.
 */
struct chunk_pass {
	double bkg, t, dark, rn, sf, sdt;
	int pois, read, flat, dfield;
};

static void pre_plain(const struct chunk_pass *p, double *c, double *zp, int i, int n)
{
	for (; i < n; i++) {
		c[i] = (c[i] + p->bkg) * p->t;
		if (p->pois) {
			c[i] += p->dark;
			zp[i] = isfinite(c[i]) ? fabs(c[i]) : 0;
		}
	}
}

static void post_plain(const struct chunk_pass *p, double *c, const double *zp,
		       const double *zr, const double *zf, const double *zd, int i, int n)
{
	for (; i < n; i++) {
		if (p->pois && isfinite(c[i]))
			c[i] = c[i] < 0 ? -zp[i] : zp[i];
		if (p->read)
			c[i] += p->rn * zr[i];
		if (p->flat)
			c[i] *= 1 + p->sf * zf[i];
		if (p->dfield)
			c[i] += p->sdt * zd[i];
	}
}

#ifdef SIMD_X86
#define ABS_BITS 0x7fffffffffffffffLL
#define SIGN_BIT ((long long)0x8000000000000000ULL)

static inline __attribute__((always_inline)) int
pre8(const struct chunk_pass *pp, double *c, double *zp, int n)
{
	const struct chunk_pass P = *pp, *p = &P; /* c's stores do not reach it */
	int i = 0;

	for (; i + 8 <= n; i += 8) {
		v8d v, a;

		memcpy(&v, c + i, sizeof(v));
		v = (v + p->bkg) * p->t;
		if (p->pois) {
			v = v + p->dark;
			a = (v8d)((v8l)v & ABS_BITS);
			/* a < inf: false for inf and NaN */
			a = (v8d)((v8l)a & (a < (double)INFINITY));
			memcpy(zp + i, &a, sizeof(a));
		}
		memcpy(c + i, &v, sizeof(v));
	}
	return i;
}

static inline __attribute__((always_inline)) int
post8(const struct chunk_pass *pp, double *c, const double *zp, const double *zr,
      const double *zf, const double *zd, int n)
{
	const struct chunk_pass P = *pp, *p = &P; /* c's stores do not reach it */
	int i = 0;

	for (; i + 8 <= n; i += 8) {
		v8d v, z;

		memcpy(&v, c + i, sizeof(v));
		if (p->pois) {
			v8l fin = (v8d)((v8l)v & ABS_BITS) < (double)INFINITY;
			v8l r;

			memcpy(&z, zp + i, sizeof(z));
			r = (v8l)z ^ ((v < 0) & SIGN_BIT);
			v = (v8d)((r & fin) | ((v8l)v & ~fin));
		}
		if (p->read) {
			memcpy(&z, zr + i, sizeof(z));
			v = v + p->rn * z;
		}
		if (p->flat) {
			memcpy(&z, zf + i, sizeof(z));
			v = v * (1 + p->sf * z);
		}
		if (p->dfield) {
			memcpy(&z, zd + i, sizeof(z));
			v = v + p->sdt * z;
		}
		memcpy(c + i, &v, sizeof(v));
	}
	return i;
}

__attribute__((target("avx512f,avx512dq"))) static int
pre8_avx512(const struct chunk_pass *p, double *c, double *zp, int n)
{
	return pre8(p, c, zp, n);
}

__attribute__((target("avx2"))) static int
pre8_avx2(const struct chunk_pass *p, double *c, double *zp, int n)
{
	return pre8(p, c, zp, n);
}

__attribute__((target("avx512f,avx512dq"))) static int
post8_avx512(const struct chunk_pass *p, double *c, const double *zp, const double *zr,
	     const double *zf, const double *zd, int n)
{
	return post8(p, c, zp, zr, zf, zd, n);
}

__attribute__((target("avx2"))) static int
post8_avx2(const struct chunk_pass *p, double *c, const double *zp, const double *zr,
	   const double *zf, const double *zd, int n)
{
	return post8(p, c, zp, zr, zf, zd, n);
}
#endif

static void chunk_pre(const struct chunk_pass *p, double *c, double *zp, int n)
{
	int i = 0, f = simd_flags();

#ifdef SIMD_X86
	if (f & SIMD_AVX512)
		i = pre8_avx512(p, c, zp, n);
	else if (f & SIMD_AVX2)
		i = pre8_avx2(p, c, zp, n);
#endif
	(void)f;
	pre_plain(p, c, zp, i, n);
}

static void chunk_post(const struct chunk_pass *p, double *c, const double *zp,
		       const double *zr, const double *zf, const double *zd, int n)
{
	int i = 0, f = simd_flags();

#ifdef SIMD_X86
	if (f & SIMD_AVX512)
		i = post8_avx512(p, c, zp, zr, zf, zd, n);
	else if (f & SIMD_AVX2)
		i = post8_avx2(p, c, zp, zr, zf, zd, n);
#endif
	(void)f;
	post_plain(p, c, zp, zr, zf, zd, i, n);
}

int noise_tile(const struct noise_opts *o, int sca, int x0, int y0, int nx,
	       int ny, double *pix, ptrdiff_t stride)
{
	unsigned st = o ? o->stages & NOISE_ALL : 0;
	double t, bkg, rn, sf, sdt;
	struct rng g_pois, g_read, g_flat, g_dshot, g_dfield;
	struct rng_poisson dark;
	double dark_in_poisson;
	double normal_above = o && o->poisson_normal > 0 ? o->poisson_normal : NOISE_POISSON_NORMAL;
	double zp[CHUNK], zr[CHUNK], zf[CHUNK], zd[CHUNK];
	uint32_t w[CHUNK][4];
	struct chunk_pass pass;

	if (!o || !pix || sca < 1 || sca > WFS_NSCA || nx < 0 || ny < 0 ||
	    x0 < 0 || y0 < 0 || x0 > WFS_NPIX - nx || y0 > WFS_NPIX - ny ||
	    stride < nx || !(o->exptime > 0) || !isfinite(o->exptime))
		return -1;
	t = o->exptime;
	bkg = o->background;

	/* No stage: background and units only, and no random-number code. */
	if (!st) {
		for (int y = 0; y < ny; y++) {
			double *r = pix + (ptrdiff_t)y * stride;

			if (o->counts)
				for (int x = 0; x < nx; x++)
					r[x] = (r[x] + bkg) * t;
			else
				for (int x = 0; x < nx; x++)
					r[x] += bkg;
		}
		return 0;
	}

	rn = o->readnoise;
	sf = o->flat_residual > 0 ? o->flat_residual : NOISE_FLAT_RESIDUAL;
	sdt = (o->dark_residual > 0 ? o->dark_residual : NOISE_DARK_RESIDUAL) * t;
	rng_init(&g_pois, o->seed, domain(DOM_SC_POISSON, o->filter, sca));
	rng_init(&g_read, o->seed, domain(DOM_SC_READ, o->filter, sca));
	rng_init(&g_flat, o->seed, domain(DOM_SC_FLAT_FIELD, o->filter, sca));
	rng_init(&g_dshot, o->seed, domain(DOM_SC_DARK_SHOT, o->filter, sca));
	rng_init(&g_dfield, o->seed, domain(DOM_SC_DARK_FIELD, DOM_ANY_FILTER, sca));
	/*
	 * With both poisson and dark, the dark current joins the light in
	 * one Poisson count: a sum of independent Poisson counts is a Poisson
	 * count of the summed mean, so the statistics are those of two draws
	 * at half the cost.  The dark electrons then also meet the flat
	 * residual, a change of order s_f D t (2e-3 e- in 100 s).
	 */
	dark_in_poisson = (st & NOISE_POISSON) && (st & NOISE_DARK) ?
			  o->dark_current * t : 0;
	rng_poisson_setup(&dark, dark_in_poisson > 0 ? 0 : o->dark_current * t);
	rng_poisson_tabulate(&dark);

	pass = (struct chunk_pass){ bkg, t, dark_in_poisson, rn, sf, sdt,
				    (st & NOISE_POISSON) != 0, (st & NOISE_READ) && rn > 0,
				    (st & NOISE_FLAT) != 0, (st & NOISE_DARK) != 0 };
	for (int y = 0; y < ny; y++) {
		double *row = pix + (ptrdiff_t)y * stride;
		uint64_t base = (uint64_t)(y0 + y) * WFS_NPIX + (uint64_t)x0;

		for (int x = 0; x < nx; x += CHUNK) {
			int n = nx - x < CHUNK ? nx - x : CHUNK;
			double *c = row + x;
			uint64_t cell = base + (uint64_t)x;

			/* |mean| to the Poisson draw, the sign and non-finite
			 * values restored after: see poisson_sign. */
			chunk_pre(&pass, c, zp, n);
			if (pass.pois)
				poisson_small_fill(&g_pois, (uint32_t)cell, n, zp, normal_above, w);
			if (pass.read)
				rng_normal_fill(&g_read, cell, n, zr);
			if (pass.flat)
				rng_normal_fill(&g_flat, cell, n, zf);
			if (pass.dfield)
				rng_normal_fill(&g_dfield, cell, n, zd);
			chunk_post(&pass, c, zp, zr, zf, zd, n);
			if ((st & NOISE_DARK) && dark.method) {
				rng_bits_n(&g_dshot, (uint32_t)cell, 0, n, w);
				for (int i = 0; i < n; i++) {
					struct rng_cell rc;

					rng_cell_preload(&rc, &g_dshot, (uint32_t)(cell + i), w[i]);
					c[i] += rng_poisson_draw(&dark, &rc);
				}
			}
		}
	}
	if (st & NOISE_COSMIC)
		cosmic_tile(o, sca, x0, y0, nx, ny, pix, stride);
	if (!o->counts)
		for (int y = 0; y < ny; y++) {
			double *r = pix + (ptrdiff_t)y * stride;

			for (int x = 0; x < nx; x++)
				r[x] /= t;
		}
	return 0;
}
