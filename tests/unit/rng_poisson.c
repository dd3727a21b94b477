/*
 * rng_poisson - the Poisson sampler against the Poisson distribution for
 * means from 0 to 2^53: mean, variance and a chi-square test of the whole
 * distribution.  Fixed seeds, tolerances of 5 sampling sigmas: the test is
 * deterministic and would fail only if the sampler were wrong.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "tap.h"
#include "rng.h"

enum { N = 1000000 };

/* P(K <= k) for Poisson(mu): an exact sum for mu <= 1e5; for larger mu the
 * normal law with continuity correction and the first Edgeworth term,
 * whose error (~1/mu) is far below what 1e6 samples resolve. */
static double poisson_cdf(double k, double mu)
{
	if (k < 0)
		return 0;
	if (mu <= 1e5) {
		double s = 0;

		for (double j = 0; j <= k; j++)
			s += exp(j * log(mu) - mu - lgamma(j + 1));
		return s > 1 ? 1 : s;
	}
	{
		double x = (k + 0.5 - mu) / sqrt(mu);
		double phi = exp(-0.5 * x * x) / sqrt(2 * M_PI);

		return 0.5 * erfc(-x / sqrt(2)) - (x * x - 1) * phi / (6 * sqrt(mu));
	}
}

/* Chi-square of the samples against Poisson(mu), in bins of expected
 * count >= 50 built from integer ranges; returns chi^2 and sets *dof. */
static double chi_square(const double *k, int n, double mu, int *dof)
{
	double sd = sqrt(mu), lo = floor(mu - 7 * sd), hi = ceil(mu + 7 * sd);
	double step = sd > 20 ? floor(sd / 20) : 1;
	int nb = 0, cap = 4096;
	double *edge = malloc(cap * sizeof(double)), *cnt, chi = 0;
	double prev = 0;

	if (lo < 0)
		lo = 0;
	/* Bin j holds integers in (edge[j-1], edge[j]]; the last is open. */
	for (double e = lo; e < hi && nb < cap - 1; e += step) {
		double f = poisson_cdf(e, mu);

		if ((f - prev) * n >= 50 && (1 - f) * n >= 50) {
			edge[nb++] = e;
			prev = f;
		}
	}
	edge[nb++] = INFINITY;
	cnt = calloc(nb, sizeof(double));
	for (int i = 0; i < n; i++) {
		int a = 0, b = nb - 1;

		while (a < b) {
			int m = (a + b) / 2;

			if (k[i] <= edge[m])
				b = m;
			else
				a = m + 1;
		}
		cnt[a]++;
	}
	prev = 0;
	for (int j = 0; j < nb; j++) {
		double f = j == nb - 1 ? 1 : poisson_cdf(edge[j], mu);
		double e = (f - prev) * n;

		chi += (cnt[j] - e) * (cnt[j] - e) / e;
		prev = f;
	}
	*dof = nb - 1;
	free(edge);
	free(cnt);
	return chi;
}

int main(void)
{
	static const double means[] = {
		1e-3, 0.5, 3, 9.999, 10, 30, 300, 3000, 1e4, 1e9, 1e12,
	};
	static double k[N];
	struct rng g;

	rng_init(&g, 20260101, 1);
	{
		struct rng_cell c;

		rng_cell_init(&c, &g, 0, 0);
		ok(rng_poisson(0, &c) == 0, "mean 0 gives 0");
	}
	for (size_t m = 0; m < sizeof(means) / sizeof(means[0]); m++) {
		double mu = means[m], s1 = 0, s2 = 0, chi;
		int dof, integral = 1;
		struct rng_poisson p;

		rng_poisson_setup(&p, mu);
		for (int i = 0; i < N; i++) {
			struct rng_cell c;

			rng_cell_init(&c, &g, (uint32_t)(i + m * N), 0);
			k[i] = rng_poisson_draw(&p, &c);
			integral &= k[i] == floor(k[i]) && k[i] >= 0;
			s1 += k[i] - mu;
		}
		s1 /= N;
		for (int i = 0; i < N; i++)
			s2 += (k[i] - mu - s1) * (k[i] - mu - s1);
		s2 /= N - 1;
		ok(integral, "mean %g: counts are non-negative integers", mu);
		/* Sampling sigma of the mean sqrt(mu/N), of the variance
		 * sqrt((mu + 2 mu^2) / N) (fourth central moment mu + 3 mu^2). */
		is_near(s1, 0, 5 * sqrt(mu / N), "mean %g: sample mean", mu);
		is_near(s2 / mu, 1, 5 * sqrt((mu + 2 * mu * mu) / N) / mu,
			"mean %g: sample variance / mean", mu);
		chi = chi_square(k, N, mu, &dof);
		ok(dof > 0 && chi < dof + 5 * sqrt(2.0 * dof) + 5,
		   "mean %g: chi-square %.1f over %d dof", mu, chi, dof);
	}

	/* rng_poisson_fill gives rng_poisson's numbers bit for bit, for
	 * means in every regime, at any start and length. */
	{
		static const double pick[] = { 0, 1e-3, 0.5, 5, 9.999, 10, 10.5, 30, 75,
					       3000, 1e6, 1e12, 0x1p52, 1e16 };
		int npick = sizeof(pick) / sizeof(pick[0]), same = 1;
		enum { M = 300000 };
		double *mu = malloc(M * sizeof(double)), *a = malloc(M * sizeof(double));

		for (int i = 0; i < M; i++)
			mu[i] = i % 3 ? pick[(i / 3) % npick] : 10 + 1e4 * (i % 1013) / 1013.0;
		rng_poisson_fill(&g, 77, 1000, mu, a);
		rng_poisson_fill(&g, 1077, M - 1000, mu + 1000, a + 1000);
		for (int i = 0; i < M; i++) {
			struct rng_cell c;

			rng_cell_init(&c, &g, (uint32_t)(77 + i), 0);
			same &= rng_poisson(mu[i], &c) == a[i];
		}
		ok(same, "rng_poisson_fill = rng_poisson, bit for bit");
		free(mu);
		free(a);
	}

	/* Beyond 2^52: the rounded normal; check its first two moments. */
	{
		double mu = 0x1p53 + 12345, s1 = 0, s2 = 0;
		int n = 200000;

		for (int i = 0; i < n; i++) {
			struct rng_cell c;
			double x;

			rng_cell_init(&c, &g, (uint32_t)i, 7);
			x = rng_poisson(mu, &c) - mu;
			s1 += x;
			s2 += x * x;
		}
		is_near(s1 / n / sqrt(mu), 0, 5 * sqrt(1.0 / n), "mean 2^53: mean");
		is_near(s2 / n / mu, 1, 5 * sqrt(2.0 / n) + 1e-9, "mean 2^53: variance");
	}
	return done_testing();
}
