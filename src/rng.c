/* rng.c - Philox4x32-10 and the Poisson and normal samplers; see rng.h. */
#include <math.h>

#include "rng.h"

/*
 * Philox4x32: each round multiplies words 0 and 2 by two constants (32x32 ->
 * 64 bits), swaps the halves across the words and XORs in the round key;
 * the key is bumped by two Weyl constants (golden ratio and sqrt(3) - 1)
 * between rounds.  Ten rounds pass BigCrush with a wide margin (the paper,
 * Table 2).  Constants from the paper.
 */
#define PHILOX_M0 0xD2511F53u
#define PHILOX_M1 0xCD9E8D57u
#define PHILOX_W0 0x9E3779B9u
#define PHILOX_W1 0xBB67AE85u

/* The version word of every counter: change it if the meaning of the
 * streams changes, so old and new images never share numbers by accident. */
#define RNG_VERSION 0x57465331u /* "WFS1" */

void rng_philox(const uint32_t ctr[4], const uint32_t key[2], uint32_t out[4])
{
	uint32_t c0 = ctr[0], c1 = ctr[1], c2 = ctr[2], c3 = ctr[3];
	uint32_t k0 = key[0], k1 = key[1];

	for (int r = 0; r < 10; r++) {
		uint64_t p0 = (uint64_t)PHILOX_M0 * c0;
		uint64_t p1 = (uint64_t)PHILOX_M1 * c2;
		uint32_t n0 = (uint32_t)(p1 >> 32) ^ c1 ^ k0;
		uint32_t n2 = (uint32_t)(p0 >> 32) ^ c3 ^ k1;

		c1 = (uint32_t)p1;
		c3 = (uint32_t)p0;
		c0 = n0;
		c2 = n2;
		k0 += PHILOX_W0;
		k1 += PHILOX_W1;
	}
	out[0] = c0;
	out[1] = c1;
	out[2] = c2;
	out[3] = c3;
}

void rng_init(struct rng *g, uint64_t seed, uint32_t dom)
{
	g->key[0] = (uint32_t)seed;
	g->key[1] = (uint32_t)(seed >> 32);
	g->dom[0] = dom;
	g->dom[1] = RNG_VERSION;
}

void rng_bits(const struct rng *g, uint32_t cell, uint32_t draw, uint32_t out[4])
{
	uint32_t ctr[4] = { cell, draw, g->dom[0], g->dom[1] };

	rng_philox(ctr, g->key, out);
}

double rng_cell_u01(struct rng_cell *c)
{
	if (!c->left) {
		uint32_t w[4];

		rng_bits(c->g, c->cell, c->draw++, w);
		c->buf[0] = rng_u01(w[0], w[1]);
		c->buf[1] = rng_u01(w[2], w[3]);
		c->left = 2;
	}
	return c->buf[2 - c->left--];
}

/* log k! for k < 10, exactly rounded. */
static const double log_fact[10] = {
	0.0, 0.0, 0.69314718055994531, 1.7917594692280550,
	3.1780538303479458, 4.7874917427820458, 6.5792512120101012,
	8.5251613610654147, 10.604602902745251, 12.801827480081469,
};

/*
 * Stirling's series for the error of Stirling's formula,
 *   s(k) = log k! - [(k + 1/2) log k - k + log(2 pi) / 2]
 *        = 1/(12k) - 1/(360k^3) + 1/(1260k^5) - 1/(1680k^7) + 1/(1188k^9) ...
 * (Bernoulli numbers B_2j / (2j(2j-1) k^(2j-1))).  The series is asymptotic
 * with alternating terms, so the error is below the first omitted term,
 * 691/(360360 k^11) < 2e-14 for k >= 10.
 */
static double stirling_err(double k)
{
	double r = 1.0 / k, r2 = r * r;

	return r * (1.0 / 12 - r2 * (1.0 / 360 - r2 * (1.0 / 1260 -
		r2 * (1.0 / 1680 - r2 * (1.0 / 1188)))));
}

/*
 * The deviance term  bd0(k, mu) = k log(k/mu) + mu - k  >= 0, without the
 * cancellation of the direct formula when k is close to mu (at mu = 1e12 the
 * three terms are ~1e13 and the result ~1).  With d = k - mu and
 * v = d / (k + mu), k/mu = (1 + v)/(1 - v), so
 *   k log(k/mu) = 2k atanh(v) = 2k (v + v^3/3 + v^5/5 + ...)
 * and since 2kv - d = d v,
 *   bd0 = d v + 2k (v^3/3 + v^5/5 + ...),
 * a sum of terms of one sign.  The same idea as C. Loader's "Fast and
 * accurate computation of binomial probabilities" (2000).  For |v| < 0.1 the
 * terms fall by v^2 < 0.01, so 8 terms reach 1e-17 relative; otherwise the
 * direct formula loses nothing because bd0 is not small against k.
 * d must be computed exactly by the caller (k and mu are both large).
 */
static double bd0(double k, double mu, double d)
{
	double v = d / (k + mu);

	if (fabs(v) < 0.1) {
		double v2 = v * v, t = v * v2, s = t / 3;

		for (int j = 2; j <= 9; j++) {
			t *= v2;
			s += t / (2 * j + 1);
		}
		return d * v + 2 * k * s;
	}
	return k * log(k / mu) + mu - k;
}

/* log P(k; mu) = k log mu - mu - log k!, accurate for any mu >= 10 and
 * integer k >= 0; d = k - mu computed exactly. */
static double poisson_logpmf(double k, double mu, double log_mu, double d)
{
	if (k < 10)
		return k * log_mu - mu - log_fact[(int)k];
	return -bd0(k, mu, d) - 0.5 * log(2 * M_PI * k) - stirling_err(k);
}

void rng_poisson_setup(struct rng_poisson *p, double mu)
{
	p->mu = mu;
	if (!(mu > 0)) {
		p->method = 0;
	} else if (mu < 10) {
		p->method = 1;
		p->emu = exp(-mu);
	} else if (mu <= RNG_POISSON_EXACT_MAX) {
		/* Hormann's constants, fitted in the paper for mu >= 10. */
		p->method = 2;
		p->smu = sqrt(mu);
		p->b = 0.931 + 2.53 * p->smu;
		p->a = -0.059 + 0.02483 * p->b;
		p->inv_alpha = 1.1239 + 1.1328 / (p->b - 3.4);
		p->vr = 0.9277 - 3.6224 / (p->b - 2);
		p->log_mu = log(mu);
		p->log_ia = log(p->inv_alpha);
	} else {
		p->method = 3;
		p->smu = sqrt(mu);
	}
}

/*
 * Small means (mu < 10): inversion by sequential search (Devroye,
 * "Non-Uniform Random Variate Generation", 1986, X.3.3): the smallest k with
 * u < F(k), building F from p(0) = exp(-mu) and p(k) = p(k-1) mu / k.  Exact
 * up to the rounding of F (k ulps, k < 40 in practice); expected mu + 1
 * steps.  The cap at 200 only guards against u within an ulp of 1, where the
 * rounded F may never exceed it; P(k >= 200) < 1e-200 for mu < 10.
 *
 * Means 10 .. 2^52: PTRS, the transformed rejection with squeeze of
 * W. Hormann, "The transformed rejection method for generating Poisson
 * random variables", Insurance: Mathematics and Economics 12 (1993) 39-45.
 * A hat built from the inverse of a fitted rational transformation covers
 * the pmf for every mu >= 10; 1.1 to 1.2 uniform pairs per draw, and most
 * draws are accepted by the squeeze (us >= 0.07, v <= vr) without a
 * logarithm.  The acceptance test needs log P(k) to absolute accuracy
 * ~1e-12 even at mu = 1e12, hence bd0 and Stirling's series above, and k is
 * formed as floor(mu) + floor(frac(mu) + ...) so that it is an exact integer
 * up to 2^53.
 *
 * Above 2^52 a double cannot even hold every integer near mu (the spacing
 * is 1, then 2 above 2^53), and the count is mu + sqrt(mu) z rounded.  The
 * Edgeworth expansion bounds the distance between the two distribution
 * functions by about |1 - z^2| phi(z) / (6 sqrt(mu)) + 1/sqrt(2 pi mu) (the
 * lattice term) < 1e-8 for mu > 2^52, a difference that needs ~1e16
 * samples to see: far beyond any image.
 */
double rng_poisson_draw(const struct rng_poisson *p, struct rng_cell *c)
{
	switch (p->method) {
	case 0:
		return 0;
	case 1: {
		double u = rng_cell_u01(c), pk = p->emu, f = pk;
		int k = 0;

		while (u >= f && k < 200) {
			k++;
			pk *= p->mu / k;
			f += pk;
		}
		return k;
	}
	case 2: {
		double m_int = floor(p->mu), m_frac = p->mu - m_int;

		for (;;) {
			double u = rng_cell_u01(c) - 0.5;
			double v = rng_cell_u01(c);
			double us = 0.5 - fabs(u);
			double j = floor((2 * p->a / us + p->b) * u + m_frac + 0.43);
			double k = m_int + j;

			if (us >= 0.07 && v <= p->vr)
				return k;
			if (!(k >= 0) || (us < 0.013 && v > us))
				continue;
			if (log(v) + p->log_ia - log(p->a / (us * us) + p->b) <=
			    poisson_logpmf(k, p->mu, p->log_mu, j - m_frac))
				return k;
		}
	}
	default: {
		double u1 = 1.0 - rng_cell_u01(c), u2 = rng_cell_u01(c);
		double z = sqrt(-2 * log(u1)) * cos(2 * M_PI * u2);

		return nearbyint(p->mu + p->smu * z);
	}
	}
}

double rng_poisson(double mu, struct rng_cell *c)
{
	struct rng_poisson p;

	if (!(mu > 0))
		return 0;
	if (mu < 10) {
		/* The set-up of the inversion is one exp; skip the rest. */
		p.mu = mu;
		p.method = 1;
		p.emu = exp(-mu);
		return rng_poisson_draw(&p, c);
	}
	rng_poisson_setup(&p, mu);
	return rng_poisson_draw(&p, c);
}

/*
 * Box-Muller (Box & Muller 1958): for u1 in (0, 1] and u2 in [0, 1),
 * sqrt(-2 log u1) (cos 2 pi u2, sin 2 pi u2) are two independent N(0, 1).
 * With 53-bit u1 the largest |z| is sqrt(106 log 2) = 8.57, so the tails
 * beyond 8.57 sigma (probability 1e-17) are missing.  Deviate 2m and 2m+1
 * share Philox call m.
 */
void rng_normal_fill(const struct rng *g, uint64_t first, size_t n, uint32_t draw,
		     double *out)
{
	uint64_t i = first, end = first + n;
	uint32_t w[4];

	while (i < end) {
		uint32_t pair = (uint32_t)(i >> 1);
		double r, s, co;

		rng_bits(g, pair, draw, w);
		r = sqrt(-2 * log(rng_u01_open0(w[0], w[1])));
		s = 2 * M_PI * rng_u01(w[2], w[3]);
		co = cos(s);
		if (!(i & 1)) {
			*out++ = r * co;
			if (++i == end)
				break;
		}
		*out++ = r * sin(s);
		i++;
	}
}
