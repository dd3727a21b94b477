/*
 * tree_pixels.c - the HEALPix pixel test that decides which files of a
 * catalog tree are opened: the pixel-radius bound holds for every point,
 * and a pixel holding a disc's centre, or any point of the disc, is
 * always found to reach it.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include <chealpix.h>

#include "tap.h"
#include "tree.h"

static double angle(const double a[3], const double b[3])
{
	double c[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
			a[0] * b[1] - a[1] * b[0] };

	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
		     a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) * 180 / M_PI;
}

static void random_vec(unsigned *s, double v[3])
{
	double z = 2.0 * rand_r(s) / RAND_MAX - 1, ph = 2 * M_PI * rand_r(s) / RAND_MAX;
	double r = sqrt(1 - z * z);

	v[0] = r * cos(ph), v[1] = r * sin(ph), v[2] = z;
}

int main(void)
{
	unsigned seed = 12345;
	int bad = 0, missed = 0;
	double worst = 0;

	is_near(tree_max_pixrad(1), acos(2.0 / 3.0) * 180 / M_PI, 1e-12,
		"NSIDE 1: the base pixels reach acos(2/3) from their centres");
	ok(tree_max_pixrad(2) < tree_max_pixrad(1) && tree_max_pixrad(1024) < 0.06,
	   "the bound shrinks with NSIDE (%g deg at 1024)", tree_max_pixrad(1024));

	/* Every point lies within the bound of its pixel's centre. */
	for (int k = 0; k < 200000; k++) {
		double v[3], c[3], a;
		int64_t nside = 1 << (k % 6), p;

		random_vec(&seed, v);
		vec2pix_nest64(nside, v, &p);
		pix2vec_nest64(nside, p, c);
		a = angle(v, c) / tree_max_pixrad(nside);
		worst = fmax(worst, a);
		bad += a > 1 + 1e-9;
	}
	ok(!bad, "200000 points at NSIDE 1 to 32 lie within max_pixrad of their pixel's "
	   "centre (at most %.4f of it)", worst);

	/* A disc's centre and edge points are in pixels found to reach it. */
	for (int k = 0; k < 20000; k++) {
		double c[3], v[3], r = 0.001 + 2.0 * rand_r(&seed) / RAND_MAX;
		int64_t nside = 2 << (k % 4), p;

		random_vec(&seed, c);
		vec2pix_nest64(nside, c, &p);
		missed += !tree_pixel_reaches(nside, p, c, r);
		/* a point at distance 0.99 r from the centre */
		random_vec(&seed, v);
		{
			double d = c[0] * v[0] + c[1] * v[1] + c[2] * v[2], t[3], n;

			for (int i = 0; i < 3; i++)
				t[i] = v[i] - d * c[i];
			n = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
			for (int i = 0; i < 3; i++)
				v[i] = c[i] * cos(0.99 * r * M_PI / 180) +
				       t[i] / n * sin(0.99 * r * M_PI / 180);
		}
		vec2pix_nest64(nside, v, &p);
		missed += !tree_pixel_reaches(nside, p, c, r);
	}
	ok(!missed, "pixels holding a disc's centre or a point inside it reach the disc "
	   "(%d missed of 40000)", missed);

	/* Far pixels do not: the pixel opposite a small disc. */
	{
		double c[3] = { 0, 0, 1 };
		int64_t p;
		double v[3] = { 0, 0, -1 };

		vec2pix_nest64(2, v, &p);
		ok(!tree_pixel_reaches(2, p, c, 1.0), "the pixel at the south pole misses a "
		   "disc of 1 degree at the north pole");
	}
	return done_testing();
}
