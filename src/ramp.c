/*
 * ramp.c - level-1 resultants and level-2 ramp fits; see ramp.h.
 *
 * Level 1, per pixel.  The charge collected since the reset, S(t), grows by
 * Poisson arrivals of rate r = light + dark; read k happens at t_k = k dt
 * (dt the read time) and measures
 *
 *   m_k = NL(P + S(t_k)) + n_k,    NL(x) = x + beta x^2, clipped at the
 *                                  saturation level,
 *
 * with P = pedestal + reset noise (once per pixel), n_k read noise.  A
 * resultant is the mean of the m_k of its reads, rounded to DN.
 *
 * Reads are not drawn one by one.  For a group of N consecutive reads
 * starting from charge S0, let d_1 .. d_N be the arrivals in each read's
 * interval; the group needs
 *
 *   D = sum d_j                        (the charge at its last read)
 *   W = sum_j (N - j + 1) d_j          (sum over reads of the charge)
 *
 * D is one Poisson draw of mean r N dt: exact.  Given D the arrivals are
 * placed independently and uniformly among the N intervals (the multinomial
 * split of a Poisson sum), so W is D plus a sum of D independent uniforms
 * on {0 .. N-1}: for D <= split_exact_max (default 4) it is drawn that way,
 * exactly; above, by the normal of the same mean D (N + 1) / 2 and variance
 * D (N^2 - 1) / 12, rounded (the Irwin-Hall sum is symmetric, and its excess
 * kurtosis -1.2 / D (N^2 + 1) / (N^2 - 1) is below 0.25 there; the read
 * noise, sqrt(D) times larger than a discreteness step, hides the rest).
 * Then the mean of the reads of the charge is S0 + W / N exactly.
 *
 * Non-linearity of a mean: mean NL(x_k) = NL(mean x) + beta var_k(x); var_k
 * is replaced by its expectation (D / N)^2 (N^2 - 1) / 12 (a term of at most
 * ~50 e- at 1e5 e-).  A group that reaches saturation is evaluated read by
 * read along the straight line from S0 to S0 + D.  Read noise of the mean is
 * sigma / sqrt(N) z.  The sum is clipped at the saturation level (reads at
 * saturation read exactly the saturation level) and rounded to DN.
 *
 * Cosmic rays: two populations of rate R hits/cm^2/s each over pixels of
 * area A, so a pixel is hit Poisson(2 R A T) times in the exposure T; each
 * hit lands at a uniformly chosen read and brings Poisson(E) electrons of
 * its population into that pixel (the charge the scene's --noise cosmic
 * spreads over 3x3 stays in the pixel here).
 *
 * The random numbers: Philox keyed by the seed, counted by the absolute
 * pixel (y * 4096 + x) in a domain that names the purpose, the group, the
 * filter and the SCA (purpose in bits 0-7, filter 8-15, SCA 16-23, group
 * 24-31), so a pixel's resultants never depend on who computes them.
 *
 * The Poisson counts of a row are ramp_pois.c's; level 2, the fit of each
 * pixel's ramp, is ramp_fit.c.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "data.h"
#include "err.h"
#include "persist.h"
#include "ramp.h"
#include "ramp_pois.h"
#include "rng.h"
#include "rng_domains.h"
#include "simd.h"


#define RATE_MAX 1e12           /* e-/s: beyond this a pixel is as saturated */
#define CR_MAX 1024             /* hits remembered per row call */

static uint32_t domain(const struct ramp_key *k, int purpose, int group)
{
	return rng_domain(purpose, k->filter, k->sca, group);
}

/* ---- tables ---- */

int ramp_pattern_finish(struct ramp_pattern *p)
{
	int prev = 0;

	if (p->nres < 1 || p->nres > RAMP_MAX_RES || !(p->read_time > 0))
		return -1;
	for (int i = 0; i < p->nres; i++) {
		int a = p->first[i], b = p->last[i], n = b - a + 1;
		double sum = 0, tau = 0;

		if (a <= prev || b < a)
			return -1;
		prev = b;
		p->nread[i] = n;
		for (int k = a; k <= b; k++)
			sum += k;
		p->tbar[i] = p->read_time * sum / n;
		/* tau = (1/N^2) sum_{k,l} min(t_k, t_l): the k-th of the
		 * sorted reads is the smaller of 2 (N - k) + 1 pairs. */
		for (int k = 0; k < n; k++)
			tau += (2.0 * (n - 1 - k) + 1) * (a + k);
		p->tau[i] = p->read_time * tau / ((double)n * n);
	}
	p->exptime = p->last[p->nres - 1] * p->read_time;
	return 0;
}

int ramp_pattern_get(int table, struct ramp_pattern *p, struct err *e)
{
	struct tsv t;
	char list[256] = "";
	size_t len = 0;

	memset(p, 0, sizeof(*p));
	if (tsv_parse(&t, "ma_tables.tsv") < 0)
		return err_set(e, EXIT_SYSTEM, "ma_tables.tsv: table missing from the build");
	for (int r = 1; r < t.nrow; r++) {
		int n = atoi(t.cell[r][0]);
		const char *s = t.cell[r][4];

		if (len < sizeof(list) - 8)
			len += (size_t)snprintf(list + len, sizeof(list) - len, "%s%d",
						r > 1 ? ", " : "", n);
		if (n != table || p->nres)
			continue;
		p->table = n;
		p->read_time = 3.16247;
		while (*s && p->nres < RAMP_MAX_RES) {
			char *end;

			p->first[p->nres] = (int)strtol(s, &end, 10);
			p->last[p->nres] = *end == '-' ? (int)strtol(end + 1, &end, 10)
						       : p->first[p->nres];
			p->nres++;
			s = *end == ';' ? end + 1 : end;
			if (*end && *end != ';')
				break;
		}
	}
	tsv_free(&t);
	if (!p->nres)
		return err_set(e, EXIT_INPUT, "--ma-table: no MultiAccum table %d "
			       "(there are %s)", table, list);
	{
		struct ramp_det d;

		if (ramp_det_get(1, &d, NULL) == 0)
			p->read_time = d.read_time;
	}
	if (ramp_pattern_finish(p) < 0)
		return err_set(e, EXIT_SYSTEM, "ma_tables.tsv: table %d: bad read pattern", table);
	return 0;
}

int ramp_det_finish(struct ramp_det *d)
{
	double m;

	if (!(d->gain > 0) || !(d->saturation > 0) || !(d->read_time > 0) ||
	    !(d->beta <= 0) || d->read_noise < 0 || d->dark < 0 || d->pedestal < 0 ||
	    d->reset_noise < 0 || !(d->jump_threshold > 0))
		return -1;
	m = d->sat_e = d->saturation * d->gain;
	/* NL rises up to x = -1 / (2 beta); saturation must come before. */
	if (d->beta < 0 && 1 + 4 * d->beta * m <= 0)
		return -1;
	d->sat_true = 2 * m / (1 + sqrt(1 + 4 * d->beta * m));
	return 0;
}

int ramp_det_get(int sca, struct ramp_det *d, struct err *e)
{
	struct tsv t;
	char name[16];
	int have = 0;

	memset(d, 0, sizeof(*d));
	snprintf(name, sizeof(name), "WFI%02d", sca);
	if (tsv_parse(&t, "detector.tsv") < 0)
		return e ? err_set(e, EXIT_SYSTEM, "detector.tsv: table missing from the build") : -1;
	for (int r = 1; r < t.nrow; r++) {
		const char *kind = t.cell[r][0], *key = t.cell[r][1];
		double v = strtod(t.cell[r][2], NULL);
		static const struct {
			const char *key;
			size_t off;
		} c[] = {
			{ "read_time", offsetof(struct ramp_det, read_time) },
			{ "gain", offsetof(struct ramp_det, gain) },
			{ "saturation", offsetof(struct ramp_det, saturation) },
			{ "nonlinearity_beta", offsetof(struct ramp_det, beta) },
			{ "pedestal", offsetof(struct ramp_det, pedestal) },
			{ "reset_noise", offsetof(struct ramp_det, reset_noise) },
			{ "cosmic_rate", offsetof(struct ramp_det, cosmic_rate) },
			{ "cosmic_e_low", offsetof(struct ramp_det, cosmic_e[0]) },
			{ "cosmic_e_high", offsetof(struct ramp_det, cosmic_e[1]) },
			{ "pixel_area", offsetof(struct ramp_det, pixel_area) },
			{ "jump_threshold", offsetof(struct ramp_det, jump_threshold) },
			{ "nonlinear_flag", offsetof(struct ramp_det, nonlinear_flag) },
		};

		if (!strcmp(kind, "const")) {
			for (size_t i = 0; i < sizeof(c) / sizeof(c[0]); i++)
				if (!strcmp(key, c[i].key)) {
					*(double *)((char *)d + c[i].off) = v;
					have++;
				}
		} else if (!strcmp(kind, "ipc")) {
			int dx = atoi(key), dy = atoi(strchr(key, ',') ? strchr(key, ',') + 1 : "9");

			if (dx >= -1 && dx <= 1 && dy >= -1 && dy <= 1) {
				d->ipc[dy + 1][dx + 1] = v;
				have++;
			}
		} else if (!strcmp(key, name) && !strcmp(kind, "readnoise")) {
			d->read_noise = v;
			have++;
		} else if (!strcmp(key, name) && !strcmp(kind, "dark")) {
			d->dark = v;
			have++;
		}
	}
	tsv_free(&t);
	if (have != 12 + 9 + 2 || ramp_det_finish(d) < 0)
		return e ? err_set(e, EXIT_SYSTEM, "detector.tsv: incomplete or bad for WFI%02d", sca) : -1;
	return 0;
}

double ramp_nl(const struct ramp_det *d, double s)
{
	if (!(s < d->sat_true))
		return d->sat_e;
	return s + d->beta * s * s;
}

double ramp_nl_inverse(const struct ramp_det *d, double m)
{
	double disc = 1 + 4 * d->beta * m;

	/* the smaller root of beta s^2 + s - m = 0, in the form that does
	 * not cancel; beyond the top of the parabola, its top */
	if (disc < 0)
		return -1 / (2 * d->beta);
	return 2 * m / (1 + sqrt(disc));
}

/* ---- level 1 ---- */

/* nearbyint() in the default rounding mode (to nearest, ties to even),
 * without the call (x86-64 has no rounding instruction below SSE4.1):
 * adding and taking back 1.5 x 2^52 leaves no fraction bits, exactly, for
 * |x| < 2^51; larger doubles are integers already (or NaN/inf). */
static inline double round_even(double x)
{
	const double c = 0x1.8p52;

	return fabs(x) < 0x1p51 ? (x + c) - c : x;
}

struct cr_hit {
	int pix, read;
	double e;
};

/* The cosmic-ray hits of the row, in pixel order. */
static int cr_hits(const struct ramp_pattern *p, const struct ramp_det *d,
		   const struct ramp_key *k, uint32_t cell0, int n, struct cr_hit *h)
{
	double lambda = 2 * d->cosmic_rate * d->pixel_area * p->exptime, emu;
	int last = p->last[p->nres - 1], nh = 0;
	uint64_t thr;
	struct rng g, gd;
	uint32_t w[64][4];

	if (!(lambda > 0))
		return 0;
	/* u < exp(-lambda) (no hit) exactly when its 53-bit integer is below
	 * ceil(exp(-lambda) 2^53) */
	emu = exp(-lambda);
	thr = (uint64_t)ceil(emu * 0x1p53);
	rng_init(&g, k->seed, domain(k, DOM_CR, 0));
	rng_init(&gd, k->seed, domain(k, DOM_CR_DETAIL, 0));
	for (int i0 = 0; i0 < n; i0 += 64) {
		int m = n - i0 < 64 ? n - i0 : 64;

		rng_bits_n(&g, cell0 + (uint32_t)i0, 0, (size_t)m, w);
		for (int i = 0; i < m; i++) {
			uint64_t b = ((uint64_t)w[i][0] << 32 | w[i][1]) >> 11;
			int hits;
			struct rng_cell c;

			if (b < thr)
				continue;
			/* the count by inversion, from the u that said "some" */
			hits = rng_poisson_invert(b * 0x1p-53, lambda, emu);
			rng_cell_init(&c, &gd, cell0 + (uint32_t)(i0 + i), 0);
			for (int j = 0; j < hits && nh < CR_MAX; j++) {
				int pop = rng_cell_u01(&c) < 0.5;

				h[nh].pix = i0 + i;
				h[nh].read = 1 + (int)(rng_cell_u01(&c) * last);
				h[nh].e = rng_poisson(d->cosmic_e[pop], &c);
				nh++;
			}
		}
	}
	return nh;
}

void ramp_scratch_init(double *scratch)
{
	(void)scratch;
}

/* The state of one row's level1() call, shared by its steps. */
#define RAMP_SLOWZ 16

struct l1row {
	const struct ramp_pattern *p;
	const struct ramp_det *d;
	const struct ramp_key *k;
	uint32_t cell0;
	int n, light;
	uint16_t *out;
	size_t plane;
	double *ch;
	float *own;
	size_t cplane;
	/* in the caller's scratch, per pixel: the rate r, the true charge S
	 * collected so far, the reset level P, the means mu, the group's arrivals D, the reset level seen
	 * through the NL Q, and w the read call of 256 pixels */
	double *r, *S, *P, *mu, *D, *Q;
	uint32_t (*w)[4];
	/* 0: the default 4; below 0: never exact (the normal for every split) */
	double exact_max;
	double normal_above;
	struct cr_hit *hits;    /* CR_MAX of them, nh in pixel order */
	int nh;
	/* the afterglow (NULL: none), and per pixel its arrivals in the
	 * group Dx and their sum over the group's reads Wx (as D and W),
	 * zero where there is none */
	const struct ramp_glow *glow;
	double *Dx, *Wx;
	/* read8_avx512()'s lanes whose only slow case is the read noise's
	 * deviate, put off to be drawn RAMP_SLOWZ at a time */
	int nz;
	int zpix[RAMP_SLOWZ], zlayer[RAMP_SLOWZ];
	uint32_t zcell[RAMP_SLOWZ];
	double zu[RAMP_SLOWZ], zmm[RAMP_SLOWZ];
};

/* Before the first read: the rates (the dark current added where light
 * falls), the reset level of each pixel and the row's cosmic-ray hits. */
static void level1_start(struct l1row *R, const double *rate)
{
	const struct ramp_det *d = R->d;
	const struct ramp_key *k = R->k;
	double *r = R->r, *S = R->S, *P = R->P;
	int n = R->n, light = R->light;
	struct rng g;

	for (int i = 0; i < n; i++) {
		double v = light ? rate[i] : 0;

		v = isfinite(v) ? (v > 0 ? v : 0) : (v > 0 ? RATE_MAX : 0);
		r[i] = (v < RATE_MAX ? v : RATE_MAX) + (light ? d->dark : 0);
		S[i] = 0;
	}
	rng_init(&g, k->seed, domain(k, DOM_RESET, 0));
	rng_normal_fill(&g, R->cell0, (size_t)n, P);
	for (int i = 0; i < n; i++)
		P[i] = d->pedestal + d->reset_noise * P[i];
	if (R->ch)
		for (int i = 0; i < n; i++)
			R->Q[i] = ramp_nl(d, P[i]);
	R->nh = light ? cr_hits(R->p, d, k, R->cell0, n, R->hits) : 0;
}

/* The charge of group gi: into S what arrived in the skipped reads since
 * the previous group (the last read prev), Poisson counts and cosmic rays;
 * into D the Poisson count of each pixel's arrivals during the group's
 * reads, which level1_reads() spreads over them. */
#ifdef SIMD_X86
__attribute__((target("avx512f"))) static int
scale_row_avx512(const double *r, double a, double b, double *out, int n)
{
	int i = 0;

	for (; i + 8 <= n; i += 8)
		_mm512_storeu_pd(out + i, _mm512_mul_pd(_mm512_mul_pd(_mm512_loadu_pd(r + i),
								      _mm512_set1_pd(a)),
							_mm512_set1_pd(b)));
	return i;
}
#endif

/* out[i] = r[i] a b, the products in that order (eight at a time where
 * the machine can: the same numbers). */
static void scale_row(const double *r, double a, double b, double *out, int n)
{
	int i = 0;

#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX512)
		i = scale_row_avx512(r, a, b, out, n);
#endif
	for (; i < n; i++)
		out[i] = r[i] * a * b;
}

/*
 * The afterglow of the reads prev + 1 .. last[gi]: a Poisson count per
 * read and glow pixel of the charge the curve releases since the read
 * before, those of the reads skipped before the group into S, those of the
 * group's reads into Dx (their sum) and Wx (each counted in the group's
 * reads from its own on, as W counts the light's arrivals).
 */
static void level1_glow(struct l1row *R, int gi, int prev)
{
	const struct ramp_glow *gl = R->glow;
	const struct persist_curve *c = gl->curve;
	const struct ramp_key *k = R->k;
	int a = R->p->first[gi], b = R->p->last[gi];
	double dt = R->p->read_time;
	/* the two exponentials' factors from one read to the next */
	double qa = exp(-c->b * dt), qd = exp(-c->e * dt);
	double ka = c->a / c->b * -expm1(-c->b * dt), kd = c->d / c->e * -expm1(-c->e * dt);

	for (int q = 0; q < gl->n; q++) {
		int i = (int)(gl->pix[q] - gl->base);
		double lag = gl->t0 - gl->tend[q], s = gl->scale[q], D = 0, W = 0;
		/* the curve's integral over read j's interval, (lag + (j - 1) dt,
		 * lag + j dt], by the exponentials' recurrence while the
		 * interval is within the curve, exactly (persist_charge) at
		 * its end */
		double ea = exp(-c->b * (lag + prev * dt)), ed = exp(-c->e * (lag + prev * dt));

		for (int j = prev + 1; j <= b; j++, ea *= qa, ed *= qd) {
			double m, cnt;
			struct rng g;
			struct rng_cell cell;

			if (lag + j * dt <= c->tmax && lag + (j - 1) * dt >= 0)
				m = s * (ka * ea + kd * ed + c->c * dt);
			else
				m = persist_charge(c, s, lag + (j - 1) * dt, lag + j * dt);
			if (!(m > 0))
				continue;
			/* read j's numbers: its low 8 bits in the domain, the
			 * rest in the draw (tables of up to 309 reads) */
			rng_init(&g, k->seed, domain(k, DOM_GLOW, j));
			rng_cell_init(&cell, &g, R->cell0 + (uint32_t)i, (uint32_t)(j >> 8) << 16);
			cnt = rng_poisson(m, &cell);
			if (j < a) {
				R->S[i] += cnt;
			} else {
				D += cnt;
				W += cnt * (b - j + 1);
			}
		}
		R->Dx[i] = D;
		R->Wx[i] = W;
	}
}

static void level1_arrivals(struct l1row *R, int gi, int prev)
{
	const struct ramp_key *k = R->k;
	int a = R->p->first[gi], N = R->p->last[gi] - a + 1, gap = a - prev - 1, n = R->n;
	double dt = R->p->read_time, *r = R->r, *S = R->S, *mu = R->mu, *D = R->D;
	struct rng g;

	if (gap > 0 && R->light) {
		scale_row(r, gap, dt, mu, n);
		rng_init(&g, k->seed, domain(k, DOM_GAP, gi));
		ramp_pois_row(&g, R->cell0, n, mu, mu, R->normal_above);
		for (int i = 0; i < n; i++)
			S[i] += mu[i];
	}
	for (int h = 0; h < R->nh; h++)
		if (R->hits[h].read > prev && R->hits[h].read < a)
			S[R->hits[h].pix] += R->hits[h].e;
	if (R->light) {
		scale_row(r, N, dt, mu, n);
		rng_init(&g, k->seed, domain(k, DOM_POIS, gi));
		ramp_pois_row(&g, R->cell0, n, mu, D, R->normal_above);
	} else {
		memset(D, 0, (size_t)n * sizeof(*D));
	}
	if (R->glow && R->glow->n)
		level1_glow(R, gi, prev);
}

/*
 * The next base-N digit of a uniform 64-bit x: floor(x N / 2^64), x
 * becoming the rest (x N mod 2^64).  The digits of x, taken so, are those
 * of floor(x N^k / 2^64), which is uniform on 0 .. N^k - 1 but for a bias
 * of at most N^k / 2^64: k independent uniform digits.  Two 32 x 32 bit
 * products, exact (N < 2^32).
 */
static inline int next_digit(uint64_t *x, uint32_t N)
{
	uint64_t lo = (*x & 0xffffffff) * N, hi = (*x >> 32) * N + (lo >> 32);

	*x = hi << 32 | (lo & 0xffffffff);
	return (int)(hi >> 32);
}

/*
 * W, the sum over a group of N reads of the arrivals in the group before
 * each, for Di arrivals: each arrival falls in one of the N reads, a
 * uniform digit of 0 .. N-1 (next_digit).  The digits come from the 64
 * bits of words 2-3 of the pixel's DOM_READ call wd, per of them from
 * each 64 bits (N^per <= 2^32, so that their bias stays below 2^-32;
 * per >= 4 for N <= 256), further 64 bits from the pixel's own DOM_SPLIT
 * calls (gs), two to a call.  Beyond exact_max arrivals the normal of the
 * sum (mean Di (N + 1) / 2, variance Di kvar, its root sq[Di] below
 * SPLIT_SQ) from words 2-3 (gz for the ziggurat's slow cases).  Inline:
 * it is the body of level1_reads()'s pixel loop.
 */
#define SPLIT_SQ 64            /* sqrt(D kvar) tabulated for D below */

static inline double split_arrivals(double Di, int N, int per, double kvar, const double *sq,
				    double exact_max, const uint32_t wd[4], const struct rng *gs,
				    const struct rng *gz, uint32_t cell)
{
	double W;

	if (Di == 0 || N == 1) {
		W = Di * N;
	} else if (Di <= exact_max) {
		uint64_t x = (uint64_t)wd[2] << 32 | wd[3];
		int nd = (int)Di, sum = 0;

		if (nd <= 4 && per >= 4) {
			/* the common case in four steps, without a
			 * branch on the count */
			for (int q = 0; q < 4; q++) {
				int dg = next_digit(&x, (uint32_t)N);

				sum += q < nd ? dg : 0;
			}
		} else {
			uint32_t bits[4];

			for (int q = 0; q < nd; q++) {
				int word = q / per;

				if (word && q % per == 0) {
					if (word & 1)
						rng_bits(gs, cell, (uint32_t)(word >> 1), bits);
					x = (uint64_t)bits[(word & 1) ? 0 : 2] << 32 |
					    bits[(word & 1) ? 1 : 3];
				}
				sum += next_digit(&x, (uint32_t)N);
			}
		}
		/* the arrival in the group's read s (0 .. N-1) counts in
		 * N - s of its reads */
		W = Di * N - sum;
	} else {
		double zs = rng_normal_bits(gz, cell, wd[2], wd[3]);
		double sd = Di < SPLIT_SQ ? sq[(int)Di] : sqrt(Di * kvar);

		W = round_even(Di * (N + 1) / 2 + sd * zs);
		if (W < Di)
			W = Di;
		if (W > Di * N)
			W = Di * N;
	}
	return W;
}

/* The constants of one group's reads, shared by level1_reads()'s paths. */
struct l1grp {
	int gi, a, b, N, per;
	double sn, kvar, inv_n, bk, exact_max, inv_g;
	double sq[SPLIT_SQ];
	struct rng g, gs, gz;
};

/* Resultant gi of pixel i from its arrivals D[i] and its DOM_READ call w:
 * how they fall among the group's reads, the cosmic rays within it (*hp
 * the next hit, in pixel order), the non-linearity, saturation and the
 * read noise; as DN into out or split into ch and own. */
static inline void read_pixel(struct l1row *R, const struct l1grp *G, int i,
			      const uint32_t w[4], int *hp)
{
	const struct ramp_det *d = R->d;
	const struct cr_hit *hits = R->hits;
	int a = G->a, b = G->b, N = G->N, nh = R->nh;
	uint32_t cell = R->cell0 + (uint32_t)i;
	double Di = R->D[i], W, s0 = R->P[i] + R->S[i], send, mm, nz, v;
	double z = rng_normal_bits(&G->g, cell, w[0], w[1]);

	/* W: the sum over the group's reads of the arrivals in the group
	 * before each */
	W = split_arrivals(Di, N, G->per, G->kvar, G->sq, G->exact_max, w, &G->gs, &G->gz, cell);
	/* a cosmic ray's charge counts from its read on (the hits are in
	 * pixel order) */
	for (; *hp < nh && hits[*hp].pix <= i; ++*hp)
		if (hits[*hp].pix == i && hits[*hp].read >= a && hits[*hp].read <= b) {
			W += hits[*hp].e * (b - hits[*hp].read + 1);
			Di += hits[*hp].e;
		}
	/* the afterglow's arrivals, as a cosmic ray's */
	if (R->glow) {
		W += R->Wx[i];
		Di += R->Dx[i];
	}
	send = s0 + Di;
	if (send < d->sat_true) {
		mm = ramp_nl(d, s0 + W * G->inv_n) + G->bk * Di * Di;
		nz = G->sn * z;
	} else {
		/* reads at saturation read the level exactly; the read noise
		 * is that of the others */
		int nfree = 0;

		mm = 0;
		for (int q = 1; q <= N; q++) {
			double x = s0 + Di * q / N;

			mm += ramp_nl(d, x);
			nfree += x < d->sat_true;
		}
		mm *= G->inv_n;
		nz = d->read_noise * sqrt((double)nfree) * z * G->inv_n;
	}
	R->S[i] += Di;
	if (R->ch) {
		size_t o = (size_t)G->gi * R->cplane + (size_t)i;

		R->ch[o] = mm - R->Q[i];
		R->own[o] = (float)(R->Q[i] + nz);
		return;
	}
	v = mm + nz;
	if (v > d->sat_e)
		v = d->sat_e;
	v = round_even(v * G->inv_g);
	R->out[(size_t)G->gi * R->plane + (size_t)i] =
		(uint16_t)(v < 0 ? 0 : v > 65535 ? 65535 : v);
}

#ifdef SIMD_X86
/*
 * split_arrivals() for the eight lanes of read8_avx512(): W from the
 * arrivals Di and words 2-3 of each lane's call (w23): none to place,
 * digits, or the normal.  A lane it does not cover (a split of more digits
 * than one number's, a ziggurat's slow case, a count beyond the root
 * table) is added to *bad.  The same operations in the same order.
 */
__attribute__((target("avx512f,avx512dq"))) static inline __m512d
split8_avx512(const struct l1grp *G, __m512d Di, __m512i w23, __mmask8 *bad)
{
	const __m512i b8 = _mm512_set1_epi64(0xff), one = _mm512_set1_epi64(1);
	const __m512d sgn = _mm512_set1_pd(-0.0), scale = _mm512_set1_pd(0x1p-52);
	const double *zx = rng_zig_x;
	int N = G->N;
	__m512d W = _mm512_mul_pd(Di, _mm512_set1_pd(N));
	__mmask8 easy, exact, nrm;

	easy = _mm512_cmp_pd_mask(Di, _mm512_setzero_pd(), _CMP_EQ_OQ) | (N == 1 ? 0xff : 0);
	exact = ~easy & _mm512_cmp_pd_mask(Di, _mm512_set1_pd(G->exact_max), _CMP_LE_OQ);
	nrm = ~easy & ~exact;
	if (exact) {
		const __m512i nv = _mm512_set1_epi64(N), m32 = _mm512_set1_epi64(0xffffffff);
		__m512i nd = _mm512_cvttpd_epi64(Di), sum = _mm512_setzero_si512(), xx = w23;

		*bad |= exact & (G->per < 4 ? 0xff : _mm512_cmpgt_epi64_mask(nd, _mm512_set1_epi64(4)));
		for (int q = 0; q < 4; q++) {
			__m512i lo = _mm512_mul_epu32(xx, nv);
			__m512i hi = _mm512_add_epi64(_mm512_mul_epu32(_mm512_srli_epi64(xx, 32), nv),
						      _mm512_srli_epi64(lo, 32));

			xx = _mm512_or_si512(_mm512_slli_epi64(hi, 32), _mm512_and_si512(lo, m32));
			sum = _mm512_mask_add_epi64(sum, _mm512_cmpgt_epi64_mask(nd, _mm512_set1_epi64(q)),
						    sum, _mm512_srli_epi64(hi, 32));
		}
		W = _mm512_mask_sub_pd(W, exact, W, _mm512_cvtepi64_pd(sum));
	}
	if (nrm) {
		__m512d zs, sd, c, zx0, zx1, lim = _mm512_set1_pd(SPLIT_SQ);
		__m512i si, li = _mm512_and_si512(w23, b8);

		zx0 = _mm512_i64gather_pd(li, zx, 8);
		zx1 = _mm512_i64gather_pd(_mm512_add_epi64(li, one), zx, 8);
		zs = _mm512_mul_pd(_mm512_mul_pd(_mm512_cvtepi64_pd(_mm512_srai_epi64(w23, 11)),
						 scale), zx0);
		*bad |= nrm & _mm512_cmp_pd_mask(_mm512_andnot_pd(sgn, zs), zx1, _CMP_NLT_UQ);
		*bad |= nrm & _mm512_cmp_pd_mask(Di, lim, _CMP_NLT_UQ);
		si = _mm512_maskz_cvttpd_epi64(nrm & _mm512_cmp_pd_mask(Di, lim, _CMP_LT_OQ), Di);
		sd = _mm512_i64gather_pd(si, G->sq, 8);
		c = _mm512_add_pd(_mm512_div_pd(_mm512_mul_pd(Di, _mm512_set1_pd(N + 1)),
						_mm512_set1_pd(2)), _mm512_mul_pd(sd, zs));
		/* round_even: to nearest, ties to even, below 2^51 */
		c = _mm512_mask_roundscale_pd(c, _mm512_cmp_pd_mask(_mm512_andnot_pd(sgn, c),
								    _mm512_set1_pd(0x1p51), _CMP_LT_OQ),
					      c, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
		c = _mm512_mask_mov_pd(c, _mm512_cmp_pd_mask(c, Di, _CMP_LT_OQ), Di);
		c = _mm512_mask_mov_pd(c, _mm512_cmp_pd_mask(c, W, _CMP_GT_OQ), W);
		W = _mm512_mask_mov_pd(W, nrm, c);
	}
	return W;
}

/* The read noise's deviates put off by read8_slow_noise(), drawn together
 * (rng_normal_slow_n: the numbers rng_normal_bits() gives), into what
 * they change (the charge does not hold them). */
static void read8_slow_flush(struct l1row *R, const struct l1grp *G)
{
	const struct ramp_det *d = R->d;
	double zq[RAMP_SLOWZ];

	rng_normal_slow_n(&G->g, R->zcell, R->zlayer, R->zu, (size_t)R->nz, zq);
	for (int k = 0; k < R->nz; k++) {
		int i = R->zpix[k];
		double v;

		if (R->ch) {
			size_t o = (size_t)G->gi * R->cplane + (size_t)i;

			R->own[o] = (float)(R->Q[i] + G->sn * zq[k]);
			continue;
		}
		v = R->zmm[k] + G->sn * zq[k];
		if (v > d->sat_e)
			v = d->sat_e;
		v = round_even(v * G->inv_g);
		R->out[(size_t)G->gi * R->plane + (size_t)i] =
			(uint16_t)(v < 0 ? 0 : v > 65535 ? 65535 : v);
	}
	R->nz = 0;
}

/* The lanes q of read8_avx512() whose only slow case is the read noise's
 * deviate (badz): that deviate put off, as read_pixel() would draw it;
 * mm the lanes' measured means. */
static void read8_slow_noise(struct l1row *R, const struct l1grp *G, int i,
			     const uint32_t (*w)[4], unsigned badz, const double mm[8])
{
	for (int q = 0; q < 8; q++) {
		int k = R->nz;

		if (!(badz >> q & 1))
			continue;
		R->zpix[k] = i + q;
		R->zcell[k] = R->cell0 + (uint32_t)(i + q);
		R->zlayer[k] = rng_zig_layer(w[q][0], w[q][1], &R->zu[k]);
		R->zmm[k] = mm[q];
		if (++R->nz == RAMP_SLOWZ)
			read8_slow_flush(R, G);
	}
}

/*
 * read_pixel() for the eight pixels i .. i+7, none hit by a cosmic ray,
 * with AVX-512: the same operations in the same order on each lane (no
 * fused multiply-add), so the same numbers.  A lane the common path does
 * not cover (a ziggurat's slow case, a split of more digits than one
 * number's or a count beyond the root table, a group reaching saturation)
 * is left alone, its bit in the mask returned for read_pixel().
 */
__attribute__((target("avx512f,avx512dq"))) static unsigned
read8_avx512(struct l1row *R, const struct l1grp *G, int i, const uint32_t (*w)[4])
{
	const struct ramp_det *d = R->d;
	const __m512i ev = _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0);
	const __m512i od = _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1);
	const __m512i b8 = _mm512_set1_epi64(0xff), one = _mm512_set1_epi64(1);
	const __m512d sgn = _mm512_set1_pd(-0.0), scale = _mm512_set1_pd(0x1p-52);
	const double *zx = rng_zig_x;
	__m512i lo4 = _mm512_loadu_si512(w[0]), hi4 = _mm512_loadu_si512(w[4]);
	/* words 0:1 and 2:3 of each call as 64-bit numbers, word 0 high */
	__m512i w01 = _mm512_ror_epi64(_mm512_permutex2var_epi64(lo4, ev, hi4), 32);
	__m512i w23 = _mm512_ror_epi64(_mm512_permutex2var_epi64(lo4, od, hi4), 32);
	__m512d Di = _mm512_loadu_pd(R->D + i);
	__m512d s0 = _mm512_add_pd(_mm512_loadu_pd(R->P + i), _mm512_loadu_pd(R->S + i));
	__m512d z, W, mm, nz, x, zx0, zx1;
	__m512i li;
	__mmask8 bad = 0, badz;

	/* the read noise's deviate (rng_normal_bits) */
	li = _mm512_and_si512(w01, b8);
	zx0 = _mm512_i64gather_pd(li, zx, 8);
	zx1 = _mm512_i64gather_pd(_mm512_add_epi64(li, one), zx, 8);
	z = _mm512_mul_pd(_mm512_mul_pd(_mm512_cvtepi64_pd(_mm512_srai_epi64(w01, 11)), scale),
			  zx0);
	badz = _mm512_cmp_pd_mask(_mm512_andnot_pd(sgn, z), zx1, _CMP_NLT_UQ);
	/* the split (split_arrivals) */
	W = split8_avx512(G, Di, w23, &bad);
	/* the afterglow's arrivals, after the light's split, as read_pixel()
	 * adds them */
	if (R->glow) {
		W = _mm512_add_pd(W, _mm512_loadu_pd(R->Wx + i));
		Di = _mm512_add_pd(Di, _mm512_loadu_pd(R->Dx + i));
	}
	/* saturation within the group: read_pixel() */
	bad |= _mm512_cmp_pd_mask(_mm512_add_pd(s0, Di), _mm512_set1_pd(d->sat_true), _CMP_NLT_UQ);
	x = _mm512_add_pd(s0, _mm512_mul_pd(W, _mm512_set1_pd(G->inv_n)));
	mm = _mm512_add_pd(x, _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(d->beta), x), x));
	mm = _mm512_add_pd(mm, _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(G->bk), Di), Di));
	nz = _mm512_mul_pd(_mm512_set1_pd(G->sn), z);
	_mm512_mask_storeu_pd(R->S + i, ~bad, _mm512_add_pd(_mm512_loadu_pd(R->S + i), Di));
	if (R->ch) {
		size_t o = (size_t)G->gi * R->cplane + (size_t)i;
		__m512d q = _mm512_loadu_pd(R->Q + i);

		/* a bad lane's are written again by read_pixel() */
		_mm512_storeu_pd(R->ch + o, _mm512_sub_pd(mm, q));
		_mm256_storeu_ps(R->own + o, _mm512_cvtpd_ps(_mm512_add_pd(q, nz)));
	} else {
		__m512d v = _mm512_min_pd(_mm512_add_pd(mm, nz), _mm512_set1_pd(d->sat_e));

		v = _mm512_roundscale_pd(_mm512_mul_pd(v, _mm512_set1_pd(G->inv_g)),
					 _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
		v = _mm512_min_pd(_mm512_max_pd(v, _mm512_setzero_pd()), _mm512_set1_pd(65535));
		_mm_storeu_si128((__m128i *)(R->out + (size_t)G->gi * R->plane + (size_t)i),
				 _mm512_cvtepi64_epi16(_mm512_cvttpd_epi64(v)));
	}
	/* a lane whose only slow case is the read noise's deviate */
	badz &= ~bad;
	if (badz) {
		double mq[8];

		_mm512_storeu_pd(mq, mm);
		read8_slow_noise(R, G, i, w, badz, mq);
	}
	return bad;
}

/* sq[q] = sqrt(q kvar) for q < SPLIT_SQ, eight at a time. */
__attribute__((target("avx512f,avx512dq"))) static void sq_avx512(double *sq, double kvar)
{
	_Static_assert(SPLIT_SQ % 8 == 0, "root table in eights");
	for (int q = 0; q < SPLIT_SQ; q += 8) {
		__m512i qi = _mm512_add_epi64(_mm512_set1_epi64(q),
					      _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0));

		_mm512_storeu_pd(sq + q, _mm512_sqrt_pd(_mm512_mul_pd(_mm512_cvtepi64_pd(qi),
								       _mm512_set1_pd(kvar))));
	}
}
#endif

/* Resultant gi of every pixel from its arrivals D (read_pixel()), eight
 * at a time where the machine has AVX-512.  The row's hot loop. */
static void level1_reads(struct l1row *R, int gi)
{
	const struct ramp_det *d = R->d;
	const struct ramp_key *k = R->k;
	struct l1grp G;
	uint32_t cell0 = R->cell0, (*w)[4] = R->w;
	int n = R->n, hp = 0;
#ifdef SIMD_X86
	int nh = R->nh, wide = (simd_flags() & SIMD_AVX512) != 0;
#endif

	G.gi = gi;
	G.a = R->p->first[gi];
	G.b = R->p->last[gi];
	G.N = G.b - G.a + 1;
	G.sn = d->read_noise / sqrt(G.N);
	G.kvar = (G.N * (double)G.N - 1) / 12;
	G.inv_n = 1.0 / G.N;
	G.bk = d->beta * G.kvar * G.inv_n * G.inv_n;
	G.exact_max = R->exact_max;
	G.inv_g = 1 / d->gain;
	/* the split's normal: the square root of a count's variance, the
	 * very one it would compute, without the wait for a root per pixel
	 * (eight at a time where the machine can: the same roots) */
#ifdef SIMD_X86
	if (wide)
		sq_avx512(G.sq, G.kvar);
	else
#endif
		for (int q = 0; q < SPLIT_SQ; q++)
			G.sq[q] = sqrt(q * G.kvar);
	/* digits of 0 .. N-1 from 64 bits while N^per <= 2^32 */
	G.per = 1;
	for (double np = G.N; G.N > 1 && np * G.N <= 0x1p32; np *= G.N)
		G.per++;
	/*
	 * One Philox call per pixel (domain DOM_READ) gives the read noise
	 * (words 0-1, a ziggurat deviate) and the split of the group's
	 * arrivals among its reads (words 2-3): the digits of one 64-bit
	 * number, more from the pixel's own DOM_SPLIT calls, or the normal
	 * of the sum beyond exact_max arrivals.  The ziggurat's rare slow
	 * cases take numbers from DOM_READ (read noise) and DOM_SPLIT_N
	 * (split) cells at draws 1, 2, ...
	 */
	rng_init(&G.g, k->seed, domain(k, DOM_READ, gi));
	rng_init(&G.gs, k->seed, domain(k, DOM_SPLIT, gi));
	rng_init(&G.gz, k->seed, domain(k, DOM_SPLIT_N, gi));
	for (int i0 = 0; i0 < n; i0 += 256) {
		int m = n - i0 < 256 ? n - i0 : 256, j = 0;

		rng_bits_n(&G.g, cell0 + (uint32_t)i0, 0, (size_t)m, w);
#ifdef SIMD_X86
		/* eight at a time but where a cosmic ray hits */
		for (; wide && j + 8 <= m; j += 8) {
			int i = i0 + j;
			unsigned bad;

			if (hp < nh && R->hits[hp].pix < i + 8) {
				/* the eight one by one where a hit falls in
				 * this group's reads; a hit of another group
				 * (in S, or still to come) changes nothing
				 * here */
				int h = hp, mine = 0;

				for (; h < nh && R->hits[h].pix < i + 8; h++)
					mine |= R->hits[h].read >= G.a && R->hits[h].read <= G.b;
				if (mine) {
					for (int q = 0; q < 8; q++)
						read_pixel(R, &G, i + q, w[j + q], &hp);
					continue;
				}
				hp = h;
			}
			bad = read8_avx512(R, &G, i, w + j);
			for (int q = 0; bad; q++, bad >>= 1)
				if (bad & 1)
					read_pixel(R, &G, i + q, w[j + q], &hp);
		}
#endif
		for (; j < m; j++)
			read_pixel(R, &G, i0 + j, w[j], &hp);
	}
#ifdef SIMD_X86
	if (R->nz)
		read8_slow_flush(R, &G);
#endif
}

/*
 * The resultants of a row.  With out, as DN; with ch (and own), split for
 * IPC: ch[r * cplane + i] the measured charge that resultant r of pixel i
 * collected (non-linearity and saturation applied, its own reset level
 * taken out), own[r * cplane + i] that reset level seen through the
 * non-linearity plus the read noise; ramp_level1_finish() joins them.
 */
static void level1(const struct ramp_pattern *p, const struct ramp_det *d,
		   const struct ramp_key *k, uint32_t cell0, int n,
		   const double *rate, int light, const struct ramp_glow *glow,
		   uint16_t *out, size_t plane, double *ch, float *own, size_t cplane,
		   double *scratch)
{
	struct l1row R = {
		.p = p, .d = d, .k = k, .cell0 = cell0, .n = n, .light = light,
		.out = out, .plane = plane, .ch = ch, .own = own, .cplane = cplane,
		.exact_max = k->split_exact_max > 0 ? k->split_exact_max :
			     k->split_exact_max < 0 ? 0 : 4,
		.normal_above = k->poisson_normal > 0 ? k->poisson_normal :
				RAMP_POISSON_NORMAL,
	};
	struct cr_hit hits[CR_MAX];
	int prev = 0;

	R.hits = hits;
	R.r = scratch;
	R.S = R.r + n;
	R.P = R.S + n;
	R.mu = R.P + n;
	R.D = R.mu + n;
	R.Q = R.D + n + 512;
	R.w = (uint32_t (*)[4])(R.D + n);
	R.glow = light && glow && glow->n ? glow : NULL;
	R.Dx = R.Q + n;
	R.Wx = R.Dx + n;
	if (R.glow) {
		memset(R.Dx, 0, (size_t)n * sizeof(*R.Dx));
		memset(R.Wx, 0, (size_t)n * sizeof(*R.Wx));
	}
	level1_start(&R, rate);
	for (int gi = 0; gi < p->nres; gi++) {
		level1_arrivals(&R, gi, prev);
		level1_reads(&R, gi);
		prev = p->last[gi];
	}
}

void ramp_level1_row(const struct ramp_pattern *p, const struct ramp_det *d,
		     const struct ramp_key *k, uint32_t cell0, int n,
		     const double *rate, int light, uint16_t *out, size_t plane,
		     double *scratch)
{
	level1(p, d, k, cell0, n, rate, light, NULL, out, plane, NULL, NULL, 0, scratch);
}

void ramp_level1_charge(const struct ramp_pattern *p, const struct ramp_det *d,
			const struct ramp_key *k, uint32_t cell0, int n,
			const double *rate, double *ch, float *own, size_t cplane,
			double *scratch)
{
	level1(p, d, k, cell0, n, rate, 1, NULL, NULL, 0, ch, own, cplane, scratch);
}

void ramp_level1_charge_glow(const struct ramp_pattern *p, const struct ramp_det *d,
			     const struct ramp_key *k, uint32_t cell0, int n,
			     const double *rate, const struct ramp_glow *glow, double *ch,
			     float *own, size_t cplane, double *scratch)
{
	level1(p, d, k, cell0, n, rate, 1, glow, NULL, 0, ch, own, cplane, scratch);
}

/* IPC of one resultant at the pixels x0 .. x1-1 (none at the row's ends),
 * kr[j] the kernel row ipc[j] that acts on the row src[j] (a row off the
 * array: the centre row with a kernel row of zeros, which adds zeros, so
 * the sums are those of ramp_level1_finish()'s edge pixels' order). */
static void ipc_span(const double *const src[3], const double kr[3][3], const float *ow,
		     double sat_e, double inv_g, int x0, int x1, uint16_t *dn)
{
	const double *a = src[0], *b = src[1], *c = src[2];

	for (int x = x0; x < x1; x++) {
		double v = kr[0][0] * a[x + 1] + kr[0][1] * a[x] + kr[0][2] * a[x - 1];

		v += kr[1][0] * b[x + 1] + kr[1][1] * b[x] + kr[1][2] * b[x - 1];
		v += kr[2][0] * c[x + 1] + kr[2][1] * c[x] + kr[2][2] * c[x - 1];
		v += ow[x];
		if (v > sat_e)
			v = sat_e;
		v = round_even(v * inv_g);
		dn[x] = (uint16_t)(v < 0 ? 0 : v > 65535 ? 65535 : v);
	}
}

#ifdef SIMD_X86
/* ipc_span() eight pixels at a time with AVX2, the same operations in the
 * same order (no fused multiply-add), so the same DN; returns the first
 * pixel it left to the caller. */
__attribute__((target("avx2"))) static int
ipc_span_avx2(const double *const src[3], const double kr[3][3], const float *ow,
	      double sat_e, double inv_g, int x0, int x1, uint16_t *dn)
{
	__m256d k[3][3], sat = _mm256_set1_pd(sat_e), ig = _mm256_set1_pd(inv_g);
	__m256d zero = _mm256_setzero_pd(), top = _mm256_set1_pd(65535);
	int x = x0;

	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++)
			k[j][i] = _mm256_set1_pd(kr[j][i]);
	for (; x + 8 <= x1; x += 8) {
		__m128i q[2];

		for (int h = 0; h < 2; h++) {
			int xh = x + 4 * h;
			__m256d v = zero;

			for (int j = 0; j < 3; j++) {
				const double *r = src[j] + xh;
				__m256d t = _mm256_add_pd(_mm256_mul_pd(k[j][0], _mm256_loadu_pd(r + 1)),
							  _mm256_mul_pd(k[j][1], _mm256_loadu_pd(r)));

				t = _mm256_add_pd(t, _mm256_mul_pd(k[j][2], _mm256_loadu_pd(r - 1)));
				v = j ? _mm256_add_pd(v, t) : t;
			}
			v = _mm256_add_pd(v, _mm256_cvtps_pd(_mm_loadu_ps(ow + xh)));
			v = _mm256_min_pd(v, sat);
			v = _mm256_round_pd(_mm256_mul_pd(v, ig),
					    _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
			v = _mm256_min_pd(_mm256_max_pd(v, zero), top);
			q[h] = _mm256_cvttpd_epi32(v);
		}
		_mm_storeu_si128((__m128i *)(dn + x), _mm_packus_epi32(q[0], q[1]));
	}
	return x;
}

/* ipc_span_avx2() eight pixels at a time with AVX-512: the same
 * operations in the same order, so the same DN. */
__attribute__((target("avx512f,avx512dq"))) static int
ipc_span_avx512(const double *const src[3], const double kr[3][3], const float *ow,
		double sat_e, double inv_g, int x0, int x1, uint16_t *dn)
{
	__m512d k[3][3], sat = _mm512_set1_pd(sat_e), ig = _mm512_set1_pd(inv_g);
	__m512d zero = _mm512_setzero_pd(), top = _mm512_set1_pd(65535);
	int x = x0;

	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++)
			k[j][i] = _mm512_set1_pd(kr[j][i]);
	for (; x + 8 <= x1; x += 8) {
		__m512d v = zero;

		for (int j = 0; j < 3; j++) {
			const double *r = src[j] + x;
			__m512d t = _mm512_add_pd(_mm512_mul_pd(k[j][0], _mm512_loadu_pd(r + 1)),
						  _mm512_mul_pd(k[j][1], _mm512_loadu_pd(r)));

			t = _mm512_add_pd(t, _mm512_mul_pd(k[j][2], _mm512_loadu_pd(r - 1)));
			v = j ? _mm512_add_pd(v, t) : t;
		}
		v = _mm512_add_pd(v, _mm512_cvtps_pd(_mm256_loadu_ps(ow + x)));
		v = _mm512_min_pd(v, sat);
		v = _mm512_roundscale_pd(_mm512_mul_pd(v, ig),
					 _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
		v = _mm512_min_pd(_mm512_max_pd(v, zero), top);
		_mm_storeu_si128((__m128i *)(dn + x), _mm512_cvtepi64_epi16(_mm512_cvttpd_epi64(v)));
	}
	return x;
}
#endif

void ramp_level1_finish(const struct ramp_det *d, int nres, int n, const double *above,
			const double *row, const double *below, const float *own,
			size_t cplane, uint16_t *out, size_t plane)
{
	const double *rows[3] = { above, row, below };
	double inv_g = 1 / d->gain, dnmax = 65535, kr[3][3];
#ifdef SIMD_X86
	int avx2 = (simd_flags() & SIMD_AVX2) != 0, avx512 = (simd_flags() & SIMD_AVX512) != 0;
#endif

	/* kernel row dy + 1 acts on rows[1 - dy] */
	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++)
			kr[j][i] = rows[2 - j] ? d->ipc[j][i] : 0;
	for (int gi = 0; gi < nres; gi++) {
		size_t o = (size_t)gi * cplane;
		const float *ow = own + o;
		uint16_t *dn = out + (size_t)gi * plane;
		const double *src[3];
		int xa = 1;

		for (int j = 0; j < 3; j++)
			src[j] = (rows[2 - j] ? rows[2 - j] : row) + o;
#ifdef SIMD_X86
		if (avx512 && n > 2)
			xa = ipc_span_avx512(src, kr, ow, d->sat_e, inv_g, 1, n - 1, dn);
		else if (avx2 && n > 2)
			xa = ipc_span_avx2(src, kr, ow, d->sat_e, inv_g, 1, n - 1, dn);
#endif
		if (xa < n - 1)
			ipc_span(src, kr, ow, d->sat_e, inv_g, xa, n - 1, dn);
		/* the two end pixels, where the kernel reaches off the row */
		for (int x = 0; x < n; x += n - 1 > 0 ? n - 1 : 1) {
			double v = 0;

			/* the charge of pixel (x, y) is shared: pixel
			 * (x + dx, y + dy) receives ipc[dy][dx] of it; so
			 * pixel x gathers from x - dx of the row y - dy, a
			 * pixel off the array bringing nothing */
			for (int dy = -1; dy <= 1; dy++) {
				const double *rr = rows[1 - dy];

				if (!rr)
					continue;
				rr += o;
				for (int dx = -1; dx <= 1; dx++)
					if (x - dx >= 0 && x - dx < n)
						v += d->ipc[dy + 1][dx + 1] * rr[x - dx];
			}
			v += ow[x];
			if (v > d->sat_e)
				v = d->sat_e;
			v = round_even(v * inv_g);
			dn[x] = (uint16_t)(v < 0 ? 0 : v > dnmax ? dnmax : v);
		}
	}
}

/* The reference read: the reset level the resultants start from (the
 * same DOM_RESET numbers), through the non-linearity, with one read's
 * noise of its own. */
void ramp_reference_row(const struct ramp_det *d, const struct ramp_key *k, uint32_t cell0,
			int n, uint16_t *out, double *scratch)
{
	struct rng g;
	double *P = scratch, *z = scratch + n;

	rng_init(&g, k->seed, domain(k, DOM_RESET, 0));
	rng_normal_fill(&g, cell0, (size_t)n, P);
	rng_init(&g, k->seed, domain(k, DOM_REFREAD, 0));
	rng_normal_fill(&g, cell0, (size_t)n, z);
	for (int i = 0; i < n; i++) {
		double v = round_even((ramp_nl(d, d->pedestal + d->reset_noise * P[i]) +
				       d->read_noise * z[i]) / d->gain);

		out[i] = (uint16_t)(v < 0 ? 0 : v > 65535 ? 65535 : v);
	}
}
