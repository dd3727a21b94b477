/*
 * rng.h - a counter-based random number generator and the samplers the
 * noise stages need.
 *
 * The generator is Philox4x32-10 (Salmon, Moraes, Dror & Shaw, "Parallel
 * random numbers: as easy as 1, 2, 3", SC11), implemented here from the
 * published algorithm and checked against the Random123 known-answer
 * vectors.  It is a pure function of a 128-bit counter and a 64-bit key, so
 * there is no state to share between threads and a number depends only on
 * what it is for: key = seed, counter = (cell, draw, domain, version), where
 * a cell is usually an absolute pixel and a domain names the stage, filter
 * and SCA.  Tiles, threads and split runs therefore see identical numbers.
 */
#ifndef WFS_RNG_H
#define WFS_RNG_H

#include <stddef.h>
#include <stdint.h>

/* A keyed generator: the seed and the two domain words of the counter. */
struct rng {
	uint32_t key[2];
	uint32_t dom[2];
};

/* The domain of a stream: the purpose (rng_domains.h) in bits 0-7, the
 * filter in 8-15, the SCA in 16-23 and a group in 24-31. */
static inline uint32_t rng_domain(int purpose, int filter, int sca, int group)
{
	return (uint32_t)(purpose & 0xff) | (uint32_t)(filter & 0xff) << 8 |
	       (uint32_t)(sca & 0xff) << 16 | (uint32_t)(group & 0xff) << 24;
}

/* The key for seed and the domain dom (rng_domain()). */
void rng_init(struct rng *g, uint64_t seed, uint32_t dom);

/* Philox4x32-10 of counter ctr with key key, the raw primitive. */
void rng_philox(const uint32_t ctr[4], const uint32_t key[2], uint32_t out[4]);

/* The 128 random bits of (cell, draw) in generator g. */
void rng_bits(const struct rng *g, uint32_t cell, uint32_t draw, uint32_t out[4]);

/* The 128 bits of cells cell0 .. cell0 + n - 1 at draw into out, eight
 * Philox calls at a time (SSE2 where available). */
void rng_bits_n(const struct rng *g, uint32_t cell0, uint32_t draw, size_t n,
		uint32_t (*out)[4]);

/* The 128 bits of cells cells[0 .. n-1] (any cells) at draw into out,
 * eight Philox calls at a time where SSE2 is available: the numbers of
 * rng_bits(g, cells[k], draw), for the rare draws that are not in a row. */
void rng_bits_cells(const struct rng *g, const uint32_t *cells, uint32_t draw, size_t n,
		    uint32_t (*out)[4]);

/* 53-bit uniforms from two 32-bit words: in [0, 1) and in (0, 1]. */
static inline double rng_u01(uint32_t hi, uint32_t lo)
{
	return (double)((((uint64_t)hi << 32) | lo) >> 11) * 0x1p-53;
}

static inline double rng_u01_open0(uint32_t hi, uint32_t lo)
{
	return (double)(((((uint64_t)hi << 32) | lo) >> 11) + 1) * 0x1p-53;
}

/* The numbers of one cell: a stream of uniforms, two per Philox call, from
 * draw number first on.  Cheap to set up on the stack per pixel. */
struct rng_cell {
	const struct rng *g;
	uint32_t cell, draw;
	double buf[2];
	int left;
};

/* A cell whose first Philox call (draw 0) was made already, in bulk: w
 * holds its bits, and the stream goes on at draw 1. */
static inline void rng_cell_preload(struct rng_cell *c, const struct rng *g,
				    uint32_t cell, const uint32_t w[4])
{
	c->g = g;
	c->cell = cell;
	c->draw = 1;
	c->buf[0] = rng_u01(w[0], w[1]);
	c->buf[1] = rng_u01(w[2], w[3]);
	c->left = 2;
}

static inline void rng_cell_init(struct rng_cell *c, const struct rng *g,
				 uint32_t cell, uint32_t first_draw)
{
	c->g = g;
	c->cell = cell;
	c->draw = first_draw;
	c->left = 0;
}

void rng_cell_refill(struct rng_cell *c);

/* The next uniform in [0, 1) of the cell. */
static inline double rng_cell_u01(struct rng_cell *c)
{
	if (!c->left)
		rng_cell_refill(c);
	return c->buf[2 - c->left--];
}

/* Poisson sampling for a mean fixed across many draws (the dark current,
 * cosmic-ray rates): the set-up is done once. */
struct rng_poisson {
	double mu;
	int method;             /* 0 zero, 1 inversion, 2 PTRS, 3 normal */
	double emu;             /* exp(-mu) for inversion */
	double smu, b, a, vr;   /* PTRS constants */
	double log_mu;          /* log mu, 0 until the first slow test */
	double inv_alpha;       /* set with log_mu */
	int ncdf;               /* entries of cdf, 0 until tabulated */
	double cdf[64];         /* F(0) .. F(63) for inversion */
};

void rng_poisson_setup(struct rng_poisson *p, double mu);

/* For a mean below 10 drawn many times: tabulate the distribution
 * function once, so that a draw is a few comparisons.  The table holds the
 * very numbers the sequential search would compute, so the counts do not
 * change. */
void rng_poisson_tabulate(struct rng_poisson *p);

/* A Poisson count with the set-up mean, using the uniforms of cell c.
 * Caches log mu in *p the first time it is needed: one rng_poisson per
 * thread.
 * Exact (to the precision of the double arithmetic) for every mean up to
 * RNG_POISSON_EXACT_MAX; see rng.c for the methods and the argument. */
double rng_poisson_draw(struct rng_poisson *p, struct rng_cell *c);

/* Same, for a mean used once. */
double rng_poisson(double mu, struct rng_cell *c);

/* Poisson counts for cells cell0 .. cell0 + n - 1 with means mu[0 .. n-1]
 * into out: the very numbers rng_poisson gives with rng_cell_init(c, g,
 * cell, 0), faster.  Means must be finite; below 0 they give 0.  out may
 * be mu. */
void rng_poisson_fill(const struct rng *g, uint32_t cell0, size_t n,
		      const double *mu, double *out);

/* Above this mean the count is a rounded Gaussian (see rng.c). */
#define RNG_POISSON_EXACT_MAX 0x1p52

/* The same as rng_poisson_fill, but means at or above normal_above get
 * the skew-corrected normal approximation rng_poisson_normal() from the
 * first two words of their cell's draw 0 (an approximation: its error
 * against the exact count is in BENCHMARKS.md; normal_above = INFINITY
 * gives rng_poisson_fill's numbers). */
void rng_poisson_fill_approx(const struct rng *g, uint32_t cell0, size_t n,
			     const double *mu, double *out, double normal_above);

/*
 * A Poisson count of mean mu from a standard normal deviate z: the
 * Cornish-Fisher quantile with the skewness term, mu + sqrt(mu) z +
 * (z^2 - 1) / 6, rounded to the nearest count (never below 0).  Its
 * distribution function is within 0.012 / mu of the exact one (the
 * largest difference over all counts; 1.2e-5 at mu = 1000), against
 * 0.066 / sqrt(mu) for the plain rounded normal.
 */
static inline double rng_poisson_normal(double mu, double z)
{
	double k = __builtin_nearbyint(mu + __builtin_sqrt(mu) * z + (z * z - 1) * (1.0 / 6));

	return k > 0 ? k : 0;
}

/*
 * The smallest k with u < F(k; mu), F the Poisson distribution function,
 * by sequential search from p(0) = emu = exp(-mu) (Devroye, "Non-Uniform
 * Random Variate Generation", 1986, X.3.3): expected mu + 1 steps, exact
 * up to the rounding of F.  For small means (below ~64); the count is
 * capped at RNG_INVERT_MAX, which only u within ulps of 1 can reach.  The
 * one inversion loop of the project: rng.c, ramp.c, ramp_pois.c and noise.c use it.
 */
#define RNG_INVERT_MAX 400
int rng_poisson_invert(double u, double mu, double emu);

/* 1/k for k < RNG_RECIP, correctly rounded (rng_recip[0] is 0), which
 * the inversions multiply by instead of dividing: rng.c's and the
 * vector ones of noise.c, so that they make the same products. */
#define RNG_RECIP 64
static const double rng_recip[RNG_RECIP] = {
	0, 1.0 / 1, 1.0 / 2, 1.0 / 3, 1.0 / 4, 1.0 / 5, 1.0 / 6, 1.0 / 7,
	1.0 / 8, 1.0 / 9, 1.0 / 10, 1.0 / 11, 1.0 / 12, 1.0 / 13, 1.0 / 14, 1.0 / 15,
	1.0 / 16, 1.0 / 17, 1.0 / 18, 1.0 / 19, 1.0 / 20, 1.0 / 21, 1.0 / 22, 1.0 / 23,
	1.0 / 24, 1.0 / 25, 1.0 / 26, 1.0 / 27, 1.0 / 28, 1.0 / 29, 1.0 / 30, 1.0 / 31,
	1.0 / 32, 1.0 / 33, 1.0 / 34, 1.0 / 35, 1.0 / 36, 1.0 / 37, 1.0 / 38, 1.0 / 39,
	1.0 / 40, 1.0 / 41, 1.0 / 42, 1.0 / 43, 1.0 / 44, 1.0 / 45, 1.0 / 46, 1.0 / 47,
	1.0 / 48, 1.0 / 49, 1.0 / 50, 1.0 / 51, 1.0 / 52, 1.0 / 53, 1.0 / 54, 1.0 / 55,
	1.0 / 56, 1.0 / 57, 1.0 / 58, 1.0 / 59, 1.0 / 60, 1.0 / 61, 1.0 / 62, 1.0 / 63,
};

/* The ziggurat's layer edges x_0 .. x_256 and f(x_i) = exp(-x_i^2 / 2)
 * there (see rng.c). */
extern const double *const rng_zig_x;
extern const double *const rng_zig_f;

/* The ziggurat's rare cases (a wedge or the tail) for layer i and signed
 * uniform u, from cell's draws 1, 2, ... of g. */
double rng_normal_slow(const struct rng *g, uint32_t cell, int i, double u);

/* rng_normal_slow(g, cell[k], layer[k], u[k]) into out[k] for k < n, the
 * first Philox calls of the cells made eight at a time (rng_bits_cells):
 * the same numbers, for callers that can put their slow cases off. */
void rng_normal_slow_n(const struct rng *g, const uint32_t *cell, const int *layer,
		       const double *u, size_t n, double *out);

/* The layer and signed uniform of the 64 bits hi:lo, as
 * rng_normal_bits() reads them (for rng_normal_slow_n()). */
static inline int rng_zig_layer(uint32_t hi, uint32_t lo, double *u)
{
	uint64_t w = (uint64_t)hi << 32 | lo;

	*u = (double)((int64_t)w >> 11) * 0x1p-52;
	return (int)(w & 0xff);
}

/* A standard normal deviate from the 64 bits hi:lo by the ziggurat of
 * rng_normal_fill (8 bits pick the layer, the top 53 a signed uniform);
 * the rare slow cases take their numbers from cell's draws 1, 2, ... of g,
 * which must serve nothing else.  Inline: 99.3 % of deviates are a
 * multiplication and a comparison. */
static inline double rng_normal_bits(const struct rng *g, uint32_t cell, uint32_t hi,
				     uint32_t lo)
{
	uint64_t w = (uint64_t)hi << 32 | lo;
	int i = (int)(w & 0xff);
	double u = (double)((int64_t)w >> 11) * 0x1p-52;
	double x = u * rng_zig_x[i];

	if (__builtin_fabs(x) < rng_zig_x[i + 1])
		return x;
	return rng_normal_slow(g, cell, i, u);
}

/* Standard normal deviates number first .. first + n - 1 of generator g
 * into out, by the ziggurat method: deviate i comes from half of Philox
 * call (i / 2, draw 0), and in the rare slow cases from cell i, draws 1, 2,
 * ...; so any slice gives the same numbers as the whole.  One generator
 * (domain) serves one purpose: do not mix this with other uses of g. */
void rng_normal_fill(const struct rng *g, uint64_t first, size_t n, double *out);


#endif
