/*
 * noise_norng - a scene with no noise stage runs no random-number code.
 *
 * This program defines every external symbol of src/rng.c itself, as
 * counters, so the linker never takes rng.o from libwfs.a: each call that
 * noise.c makes into the generator lands here.  (Should noise.c start using
 * an rng symbol missing below, rng.o would be linked as well and the
 * duplicate symbols would stop the build: the test cannot pass silently.)
 * noise_tile with no stage, for any background, exposure time and unit,
 * must make no call; with any stage it must make some, which shows that
 * the counters do see the calls.
 */
#include <stdlib.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "noise.h"
#include "rng.h"

static long calls;
static const double zig[257];

const double *const rng_zig_x = zig;

void rng_init(struct rng *g, uint64_t seed, uint32_t dom)
{
	calls++;
	g->key[0] = (uint32_t)seed;
	g->key[1] = (uint32_t)(seed >> 32);
	g->dom[0] = dom;
	g->dom[1] = 0;
}

void rng_philox(const uint32_t ctr[4], const uint32_t key[2], uint32_t out[4])
{
	calls++;
	out[0] = out[1] = out[2] = out[3] = ctr[0] ^ key[0];
}

void rng_bits(const struct rng *g, uint32_t cell, uint32_t draw, uint32_t out[4])
{
	calls++;
	out[0] = out[1] = out[2] = out[3] = cell ^ draw ^ g->dom[0];
}

void rng_bits_n(const struct rng *g, uint32_t cell0, uint32_t draw, size_t n,
		uint32_t (*out)[4])
{
	calls++;
	for (size_t i = 0; i < n; i++)
		out[i][0] = out[i][1] = out[i][2] = out[i][3] = (cell0 + (uint32_t)i) ^ draw;
}

void rng_cell_refill(struct rng_cell *c)
{
	calls++;
	c->buf[0] = c->buf[1] = 0.5;
	c->left = 2;
}

void rng_poisson_setup(struct rng_poisson *p, double mu)
{
	calls++;
	p->mu = mu;
	p->method = mu > 0;
	p->ncdf = 0;
}

void rng_poisson_tabulate(struct rng_poisson *p)
{
	calls++;
}

double rng_poisson_draw(struct rng_poisson *p, struct rng_cell *c)
{
	calls++;
	return p->mu;
}

double rng_poisson(double mu, struct rng_cell *c)
{
	calls++;
	return mu;
}

void rng_poisson_fill(const struct rng *g, uint32_t cell0, size_t n,
		      const double *mu, double *out)
{
	calls++;
	for (size_t i = 0; i < n; i++)
		out[i] = mu[i];
}

void rng_poisson_fill_approx(const struct rng *g, uint32_t cell0, size_t n,
			     const double *mu, double *out, double normal_above)
{
	calls++;
	for (size_t i = 0; i < n; i++)
		out[i] = mu[i];
}

int rng_poisson_invert(double u, double mu, double emu)
{
	calls++;
	return 0;
}

double rng_normal_slow(const struct rng *g, uint32_t cell, int i, double u)
{
	calls++;
	return 0;
}

void rng_normal_fill(const struct rng *g, uint64_t first, size_t n, double *out)
{
	calls++;
	for (size_t i = 0; i < n; i++)
		out[i] = 0;
}

enum { SIDE = 64 };

/* Calls made by noise_tile for one SIDE x SIDE tile with these settings. */
static long run(unsigned stages, double bkg, double t, int counts)
{
	struct noise_opts o;
	static double a[SIDE * SIDE];

	noise_opts_default(&o);
	o.stages = stages;
	o.background = bkg;
	o.exptime = t;
	o.counts = counts;
	o.seed = 7;
	o.filter = F129;
	for (int i = 0; i < SIDE * SIDE; i++)
		a[i] = 3;
	calls = 0;
	if (noise_tile(&o, 9, 100, 200, SIDE, SIDE, a, SIDE) < 0)
		return -1;
	return calls;
}

int main(void)
{
	static const double bkg[] = { 0, 0.54, 1e6 };
	static const double t[] = { 1e-3, 139.8, 1e6 };
	static const struct {
		unsigned bits;
		const char *name;
	} stage[] = {
		{ NOISE_POISSON, "poisson" }, { NOISE_READ, "readnoise" },
		{ NOISE_DARK, "dark" }, { NOISE_FLAT, "flat" },
		{ NOISE_COSMIC, "cosmic" }, { NOISE_ALL, "all" },
	};
	int none = 1;

	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			for (int u = 0; u < 2; u++) {
				long n = run(0, bkg[i], t[j], u);

				if (n != 0)
					diag("background %g, exptime %g, %s: %ld calls", bkg[i],
					     t[j], u ? "counts" : "counts/s", n);
				none &= n == 0;
			}
	ok(none, "no stage: no call into the generator for any background, "
	   "exposure time or unit");
	for (size_t s = 0; s < sizeof(stage) / sizeof(stage[0]); s++) {
		/* cosmic rays need a long enough exposure to hit the tile */
		long n = run(stage[s].bits, 0.54, 1e6, 0);

		ok(n > 0, "--noise %s calls the generator (%ld calls)", stage[s].name, n);
	}
	return done_testing();
}
