/*
 * noise_tiles - the image does not depend on how it is cut into tiles, in
 * which order or on how many threads they are processed, and it stays
 * finite under extreme settings.
 */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "noise.h"
#include "instrument.h"
#include "rng.h"

enum { W = 700, H = 600, PW = 128, PH = 64 };

/* A region of SCA sca with corner (rx, ry), with some signal in it. */
struct region {
	int sca, rx, ry;
	double *a;
};

static void fill_signal(double *a)
{
	struct rng g;

	rng_init(&g, 1, 1);
	for (int i = 0; i < W * H; i++) {
		uint32_t w[4];

		rng_bits(&g, (uint32_t)i, 0, w);
		a[i] = 50 * rng_u01(w[0], w[1]) * rng_u01(w[2], w[3]);
	}
}

/* Process region r cut into tw x th tiles, last tile first if reverse. */
static int tiles(const struct noise_opts *o, struct region *r, int tw, int th,
		 int reverse, int part, int parts)
{
	int ntx = (W + tw - 1) / tw, nty = (H + th - 1) / th, n = ntx * nty;

	for (int k = 0; k < n; k++) {
		int j = reverse ? n - 1 - k : k;
		int tx = j % ntx, ty = j / ntx;
		int x = tx * tw, y = ty * th;
		int nx = W - x < tw ? W - x : tw, ny = H - y < th ? H - y : th;

		if (j % parts != part)
			continue;
		if (noise_tile(o, r->sca, r->rx + x, r->ry + y, nx, ny,
			       r->a + (size_t)y * W + x, W))
			return -1;
	}
	return 0;
}

/* Process the wx x wy window at (x, y) of region r pixel by pixel. */
static void pixels(const struct noise_opts *o, struct region *r, int x, int y, int wx, int wy)
{
	for (int j = y; j < y + wy; j++)
		for (int i = x; i < x + wx; i++)
			noise_tile(o, r->sca, r->rx + i, r->ry + j, 1, 1, r->a + (size_t)j * W + i, W);
}

/* Do a and b hold the same bytes in the wx x wy window at (x, y)? */
static int same_window(const double *a, const double *b, int x, int y, int wx, int wy)
{
	for (int j = y; j < y + wy; j++)
		if (memcmp(a + (size_t)j * W + x, b + (size_t)j * W + x, wx * sizeof(*a)))
			return 0;
	return 1;
}

struct job {
	const struct noise_opts *o;
	struct region *r;
	int part;
};

static void *worker(void *arg)
{
	struct job *j = arg;

	tiles(j->o, j->r, 64, 64, j->part, j->part, 2);
	return NULL;
}

static struct noise_opts opts_all(void)
{
	struct noise_opts o;

	noise_opts_default(&o);
	o.stages = NOISE_ALL;
	o.background = 0.54;
	o.exptime = 1000;
	o.seed = 7;
	o.filter = F129;
	return o;
}

static int scan_finite(const double *a, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (!isfinite(a[i]))
			return 0;
	return 1;
}

int main(void)
{
	static const int corners[3][2] = { { 0, 0 }, { WFS_NPIX - W, WFS_NPIX - H }, { 1701, 333 } };
	struct noise_opts o = opts_all();
	size_t bytes = (size_t)W * H * sizeof(double);
	struct region whole = { 0 }, cut = { 0 };

	whole.a = malloc(bytes);
	cut.a = malloc(bytes);
	/* 1000 s, and 1e6 s where cosmic rays are drawn per centre. */
	for (int c = 0; c < 6; c++) {
		o = opts_all();
		o.exptime = c < 3 ? 1000 : 1e6;
		whole.sca = cut.sca = 1 + 7 * (c % 3);
		whole.rx = cut.rx = corners[c % 3][0];
		whole.ry = cut.ry = corners[c % 3][1];
		fill_signal(whole.a);
		tiles(&o, &whole, W, H, 0, 0, 1);
		ok(scan_finite(whole.a, (size_t)W * H), "region %d (%g s) finite", c, o.exptime);

		fill_signal(cut.a);
		tiles(&o, &cut, 128, 128, 0, 0, 1);
		ok(!memcmp(whole.a, cut.a, bytes), "region %d: 128x128 tiles = one tile", c);
		fill_signal(cut.a);
		tiles(&o, &cut, 97, 61, 1, 0, 1);
		ok(!memcmp(whole.a, cut.a, bytes), "region %d: 97x61 tiles, reversed = one tile", c);
		/* Pixel by pixel, every pixel a tile's edge, in two corners:
		 * two segments of cosmic-ray centres wide, and the SCA's edges
		 * in regions 0 and 1.  (The whole region so took 2/3 of the
		 * test's time.) */
		fill_signal(cut.a);
		pixels(&o, &cut, 0, 0, PW, PH);
		pixels(&o, &cut, W - PW, H - PH, PW, PH);
		ok(same_window(whole.a, cut.a, 0, 0, PW, PH) &&
		   same_window(whole.a, cut.a, W - PW, H - PH, PW, PH),
		   "region %d: 1x1 tiles in two corners = one tile", c);
		{
			pthread_t th[2];
			struct job j[2] = { { &o, &cut, 0 }, { &o, &cut, 1 } };

			fill_signal(cut.a);
			for (int i = 0; i < 2; i++)
				pthread_create(&th[i], NULL, worker, &j[i]);
			for (int i = 0; i < 2; i++)
				pthread_join(th[i], NULL);
			ok(!memcmp(whole.a, cut.a, bytes), "region %d: two threads = one tile", c);
		}
	}

	/* Extreme exposure times and backgrounds, every stage, both units:
	 * no Inf or NaN anywhere, and the mean stays where it should. */
	{
		static const double ts[] = { 1e-3, 1, 1e6 };
		static const double bs[] = { 0, 0.54, 1e6 };

		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				for (int u = 0; u < 2; u++) {
					struct region r = { 18, 0, 0, whole.a };
					double m = 0;

					o = opts_all();
					o.exptime = ts[i];
					o.background = bs[j];
					o.counts = u;
					memset(r.a, 0, bytes);
					tiles(&o, &r, 256, 256, 0, 0, 1);
					for (int k = 0; k < W * H; k++)
						m += r.a[k];
					m /= W * H;
					ok(scan_finite(r.a, (size_t)W * H) && isfinite(m),
					   "exptime %g s, background %g, %s: finite (mean %g)",
					   ts[i], bs[j], u ? "counts" : "counts/s", m);
				}
		/* A signal of 1e9 counts/s for 1e6 s: Poisson means of 1e15. */
		o = opts_all();
		o.exptime = 1e6;
		for (int k = 0; k < W * H; k++)
			whole.a[k] = 1e9;
		tiles(&o, &whole, 256, 256, 0, 0, 1);
		ok(scan_finite(whole.a, (size_t)W * H), "1e15 counts per pixel stay finite");
	}
	free(whole.a);
	free(cut.a);
	return done_testing();
}
