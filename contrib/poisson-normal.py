#!/usr/bin/python3
"""The error of the normal approximations of a Poisson count (rng.h,
rng_poisson_normal; --set poisson-normal), against the exact distribution.

For a mean mu, the count is k = round(x(z)) with z standard normal and
  plain:   x = mu + sqrt(mu) z
  skewed:  x = mu + sqrt(mu) z + (z^2 - 1) / 6     (what wfiscene draws)
P(k <= K) is then Phi(z_K), z_K the root of x(z) = K + 1/2, computed here
exactly (no sampling); the table is the largest |P(k <= K) - F(K; mu)| over
K, F the Poisson distribution function from scipy.  About 1/D^2 draws of
one mean are needed to see a difference D.
"""
import numpy as np
from scipy import optimize, stats


def x_of(z, mu, skew):
    x = mu + np.sqrt(mu) * z
    return x + (z * z - 1) / 6 if skew else x


def distance(mu, skew):
    s = np.sqrt(mu)
    worst = 0.0
    for k in range(max(0, int(mu - 12 * s)), int(mu + 12 * s) + 1):
        exact = stats.poisson.cdf(k, mu)
        # the skewed x(z) rises for z > -3 sqrt(mu), beyond any draw that matters
        try:
            z = optimize.brentq(lambda z: x_of(z, mu, skew) - (k + 0.5), -14, 14)
        except ValueError:
            continue
        worst = max(worst, abs(stats.norm.cdf(z) - exact))
    return worst


def main():
    print("| mean | plain normal | skew-corrected (wfiscene) | x mean |")
    print("|---:|---:|---:|---:|")
    for mu in (10, 32, 100, 256, 1000, 1e4, 1e5):
        p, q = distance(mu, False), distance(mu, True)
        print(f"| {mu:g} | {p:.2e} | {q:.2e} | {q * mu:.4f} |")


if __name__ == "__main__":
    main()
