/*
 * halo_amplitude.c - the halo's set-up sums (plugins/halo.h,
 * halo_setup_amplitude) against the plain reading of what they are: every
 * sample of the array tested on its own, its distance from the centre by
 * the same expression, summed into the square, the disc (d < R) and the
 * band's direction bins (HALO_BAND R <= d < R) in the array's order.  The
 * set-up finds the disc and the band as ranges of each row, from a
 * geometry made once for the array's shape (struct halo_geom); the sums
 * must be the same bits, for odd and even arrays, two and four samples a
 * pixel, and tails of power 3 (d^alpha tabulated) and 2.5.  Likewise the
 * envelope and the light at phase 0 (halo_setup_envelope, by the
 * geometry's runs of samples at each whole radius) against every sample
 * tested on its own, with the scale s positive and negative.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "../../plugins/halo.h"

/* A halo-like array: a core and a d^-3 wing with four spikes, times a
 * ripple from a small generator, so that no two samples are alike. */
static float *make_array(int n, int over, uint64_t seed)
{
	float *a = malloc((size_t)n * n * sizeof(float));
	double c = (n - 1) / 2.0;

	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double dx = (i - c) / over, dy = (j - c) / over, d = sqrt(dx * dx + dy * dy);
			double spike = fabs(dx) < 0.7 || fabs(dy) < 0.7 ? 20 : 1;

			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			a[(size_t)j * n + i] = (float)(spike / (1 + d * d * d) *
						       (1 + 0.3 * (double)(seed >> 40) / (1 << 24)));
		}
	return a;
}

/* The sums sample by sample: A[k] the band's bins before their means. */
static void reference(const struct halo *h, double A[HALO_NT], long cnt[HALO_NT],
		      double *square, double *disc)
{
	int n = h->n, c = h->c, over = h->over;
	double R = h->R;

	memset(A, 0, HALO_NT * sizeof(double));
	memset(cnt, 0, HALO_NT * sizeof(long));
	*square = *disc = 0;
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double dx = (double)(i - c) / over, dy = (double)(j - c) / over;
			double d = sqrt(dx * dx + dy * dy), v = h->a[(size_t)j * n + i];

			*square += v;
			if (d < R)
				*disc += v;
			if (d >= HALO_BAND * R && d < R) {
				double t = halo_bin(dy, dx), fr = t - floor(t);
				int k = fr > HALO_BIN_EDGE && fr < 1 - HALO_BIN_EDGE ?
						(int)t :
						(int)((atan2(dy, dx) + M_PI) * (HALO_NT / (2 * M_PI)));

				k = k >= HALO_NT ? HALO_NT - 1 : k;
				A[k] += v * pow(d, h->alpha);
				cnt[k]++;
			}
		}
}

/* The set-up's A after its means and its half-bin shift, from the
 * reference's sums, as halo_setup_amplitude() ends. */
static void finish(double A[HALO_NT + 1], const long cnt[HALO_NT])
{
	double prev;

	for (int k = 0; k < HALO_NT; k++)
		A[k] = cnt[k] > 0 ? A[k] / cnt[k] : (k > 0 ? A[k - 1] : 0);
	prev = A[HALO_NT - 1];
	for (int k = 0; k < HALO_NT; k++) {
		double cur = A[k];

		A[k] = 0.5 * (prev + cur);
		prev = cur;
	}
	A[HALO_NT] = A[0];
}

/* The envelope and the light at phase 0 sample by sample, as
 * halo_setup_envelope() defines them, into env and cum (nenv each). */
static void reference_envelope(const struct halo *h, int nenv, double *env, double *cum)
{
	int n = h->n, c = h->c, over = h->over;

	memset(env, 0, (size_t)nenv * sizeof(double));
	memset(cum, 0, (size_t)nenv * sizeof(double));
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double dx = (double)(i - c) / over, dy = (double)(j - c) / over;
			double d = sqrt(dx * dx + dy * dy), v = h->s * h->a[(size_t)j * n + i];
			int r = (int)d;

			if (r >= nenv)
				continue;
			if (v > env[r])
				env[r] = v;
			if ((i - c) % over == 0 && (j - c) % over == 0) {
				int rr = (int)floor(d + 0.5);

				if (rr < nenv)
					cum[rr] += v;
			}
		}
	for (int r = nenv - 2; r >= 0; r--)
		if (env[r + 1] > env[r])
			env[r] = env[r + 1];
	for (int r = 0; r < nenv; r++) {
		double t = halo_tail_max(h, r > h->R - h->taper ? r : h->R - h->taper);

		if (env[r] < t)
			env[r] = t;
	}
	for (int r = 1; r < nenv; r++)
		cum[r] += cum[r - 1];
}

/* halo_setup()'s envelope and cum against the reference, with s as set
 * up and with s negated */
static void check_envelope(const float *a, int n, int over, double alpha,
			   const struct halo_geom *g)
{
	struct halo h = { 0 };

	if (halo_setup(&h, a, n, over, alpha, 16, g) < 0) {
		ok(0, "n %d, over %d: halo_setup", n, over);
		return;
	}
	for (int neg = 0; neg < 2; neg++) {
		double *env = malloc((size_t)h.nenv * sizeof(double));
		double *cum = malloc((size_t)h.nenv * sizeof(double));

		if (neg && !g) {        /* (the envelope alone needs one) */
			free(env);
			free(cum);
			break;
		}
		if (neg) {
			halo_free(&h);
			h.s = -h.s;
			if (halo_setup_envelope(&h, g) < 0) {
				ok(0, "n %d, over %d: halo_setup_envelope", n, over);
				free(env);
				free(cum);
				break;
			}
		}
		reference_envelope(&h, h.nenv, env, cum);
		ok(!memcmp(env, h.env, (size_t)h.nenv * sizeof(double)) &&
		   !memcmp(cum, h.cum, (size_t)h.nenv * sizeof(double)),
		   "n %d, over %d, s %s: the envelope and the light at phase 0, the same bits", n,
		   over, neg ? "negative" : "positive");
		free(env);
		free(cum);
	}
	halo_free(&h);
}

static void check(int n, int over, double alpha, uint64_t seed)
{
	struct halo h = { 0 };
	struct halo_geom g;
	double A[HALO_NT + 1], square, disc, sq, di;
	long cnt[HALO_NT];
	float *a = make_array(n, over, seed);

	if (halo_geom_make(&g, n, over, alpha) < 0) {
		ok(0, "n %d, over %d: the geometry", n, over);
		free(a);
		return;
	}

	h.a = a;
	h.n = n;
	h.over = over;
	h.c = (n - 1) / 2;
	h.R = (double)h.c / over - 1;
	h.alpha = alpha;
	halo_setup_amplitude(&h, &g, &sq, &di);
	reference(&h, A, cnt, &square, &disc);
	finish(A, cnt);
	ok(sq == square && di == disc, "n %d, over %d: the square and disc sums (%.17g, %.17g)",
	   n, over, sq, di);
	ok(!memcmp(A, h.A, sizeof(A)), "n %d, over %d, power %g: the %d bins, the same bits", n,
	   over, alpha, HALO_NT);
	check_envelope(a, n, over, alpha, &g);
	/* and with no geometry given: halo_setup() makes its own */
	check_envelope(a, n, over, alpha, NULL);
	halo_geom_free(&g);
	free(a);
}

int main(void)
{
	check(65, 2, 3, 1);
	check(66, 2, 3, 2);
	check(129, 4, 3, 3);
	check(130, 4, 2.5, 4);
	check(513, 2, 3, 5);
	check(1025, 2, 3, 6);
	check(1024, 2, 2.5, 7);
	check(705, 4, 3, 8);
	return done_testing();
}
