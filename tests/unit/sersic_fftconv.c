/*
 * sersic_fftconv.c - the host's FFT convolution service against a direct
 * sum: odd kernels, zero outside the image, sizes that are and are not
 * FFT-friendly, two threads sharing one plan cache, and both of its ways
 * (the transform of the lit block, the direct sum over the lit pixels,
 * scattered through the kernel for a block narrower than it or by rows for
 * a wide one) on images lit only in part, as a galaxy's stamp is.
 */
#include "fftconv.h"
#include "tap.h"

#include <pthread.h>
#include <string.h>

static void direct(const double *img, int nx, int ny, const double *k, int kn, double *out)
{
	int h = (kn - 1) / 2;

	for (int y = 0; y < ny; y++)
		for (int x = 0; x < nx; x++) {
			double s = 0;
			for (int yy = 0; yy < ny; yy++)
				for (int xx = 0; xx < nx; xx++) {
					int kx = x - xx + h, ky = y - yy + h;
					if (kx < 0 || ky < 0 || kx >= kn || ky >= kn)
						continue;
					s += img[yy * nx + xx] * k[ky * kn + kx];
				}
			out[y * nx + x] = s;
		}
}

static double max_diff(struct fftconv *fc, struct fftconv_thread *t, int nx, int ny, int kn, unsigned seed)
{
	double *img = malloc(sizeof(double) * nx * ny), *ref = malloc(sizeof(double) * nx * ny);
	double *k = malloc(sizeof(double) * kn * kn), d = 0;

	for (int i = 0; i < nx * ny; i++)
		img[i] = (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24);
	for (int i = 0; i < kn * kn; i++)
		k[i] = (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24) - 0.3;
	direct(img, nx, ny, k, kn, ref);
	if (fftconv_convolve(fc, t, img, nx, ny, k, kn))
		d = INFINITY;
	for (int i = 0; i < nx * ny; i++)
		d = fmax(d, fabs(img[i] - ref[i]));
	free(img);
	free(ref);
	free(k);
	return d;
}

/* An nx x ny image dark but for the block [x0, x0 + w) x [y0, y0 + v),
 * every other pixel of which is lit when sparse: the largest difference
 * from the direct sum when convolved the given way, or -1 when a pixel
 * the light cannot reach is not zero. */
static double part_diff(struct fftconv *fc, struct fftconv_thread *t, int nx, int ny, int x0,
			int y0, int w, int v, int sparse, int kn, int method, unsigned seed)
{
	double *img = calloc((size_t)nx * ny, sizeof(double)), *ref = malloc(sizeof(double) * nx * ny);
	double *k = malloc(sizeof(double) * kn * kn), d = 0;
	int h = (kn - 1) / 2;

	for (int y = y0; y < y0 + v; y++)
		for (int x = x0; x < x0 + w; x++)
			if (!sparse || (x + y) % 2 == 0)
				img[y * nx + x] = 1 + (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24);
	for (int i = 0; i < kn * kn; i++)
		k[i] = (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24) - 0.3;
	direct(img, nx, ny, k, kn, ref);
	fftconv_force(method);
	if (fftconv_convolve(fc, t, img, nx, ny, k, kn))
		d = INFINITY;
	fftconv_force(FFTCONV_AUTO);
	for (int y = 0; y < ny; y++)
		for (int x = 0; x < nx; x++) {
			int far = x < x0 - h || x >= x0 + w + h || y < y0 - h || y >= y0 + v + h;

			if (far && img[y * nx + x] != 0)
				d = -1;
			if (d >= 0)
				d = fmax(d, fabs(img[y * nx + x] - ref[y * nx + x]));
		}
	free(img);
	free(ref);
	free(k);
	return d;
}

struct job { struct fftconv *fc; double d; };

static void *worker(void *arg)
{
	struct job *j = arg;
	struct fftconv_thread *t = fftconv_thread_new();

	j->d = 0;
	for (int r = 0; r < 20; r++)
		j->d = fmax(j->d, max_diff(j->fc, t, 17 + r, 23 + 2 * r, 9, 7u + r));
	fftconv_thread_free(t);
	return NULL;
}

int main(void)
{
	struct fftconv *fc = fftconv_new();
	struct fftconv_thread *t = fftconv_thread_new();

	ok(fc && t, "plan cache and thread buffers made");
	ok(fftconv_good_size(97) == 98 && fftconv_good_size(128) == 128 && fftconv_good_size(1) == 1,
	   "good sizes are 7-smooth and not smaller than asked");
	is_near(max_diff(fc, t, 1, 1, 1, 1), 0, 1e-12, "1x1 image, 1x1 kernel");
	is_near(max_diff(fc, t, 31, 20, 45, 2), 0, 1e-11, "kernel larger than the image");
	is_near(max_diff(fc, t, 64, 64, 5, 3), 0, 1e-11, "power-of-two image");
	is_near(max_diff(fc, t, 37, 53, 11, 4), 0, 1e-11, "prime-sized image");
	is_near(max_diff(fc, t, 37, 53, 11, 5), 0, 1e-11, "same size again, cached plan");

	/* A galaxy's stamp: a lit block in a dark margin of the kernel's
	 * half-width; lit blocks at an edge, in a corner, a single pixel;
	 * each the three ways. */
	static const struct { int nx, ny, x0, y0, w, v, sparse, kn; const char *what; } part[] = {
		{ 74, 80, 22, 22, 30, 36, 0, 45, "a 30x36 block in a margin of 22" },
		{ 74, 80, 22, 22, 30, 36, 1, 45, "the same block, every other pixel lit" },
		{ 60, 50, 0, 10, 12, 9, 0, 45, "a block at the left edge" },
		{ 60, 50, 50, 41, 10, 9, 0, 21, "a block in the far corner" },
		{ 45, 45, 22, 22, 1, 1, 0, 45, "one lit pixel" },
		{ 40, 40, 39, 0, 1, 1, 0, 45, "one lit pixel in a corner, kernel wider than the image" },
		{ 100, 30, 3, 3, 94, 24, 0, 7, "a wide block, small kernel" },
	};
	static const char *const way[] = { "chosen", "transform", "direct sum" };
	for (size_t i = 0; i < sizeof(part) / sizeof(part[0]); i++)
		for (int m = FFTCONV_AUTO; m <= FFTCONV_DIRECT; m++) {
			double d = part_diff(fc, t, part[i].nx, part[i].ny, part[i].x0, part[i].y0,
					     part[i].w, part[i].v, part[i].sparse, part[i].kn, m, 11u + i);
			ok(d >= 0 && d < 1e-11, "%s, %s: within %.2g of the direct sum, dark where "
			   "no light reaches", part[i].what, way[m], d);
		}
	{
		double dark[30 * 20] = { 0 }, k3[9] = { 1, 1, 1, 1, 1, 1, 1, 1, 1 };
		int lit = 0;

		for (int m = FFTCONV_AUTO; m <= FFTCONV_DIRECT; m++) {
			fftconv_force(m);
			lit |= fftconv_convolve(fc, t, dark, 30, 20, k3, 3) != 0;
			fftconv_force(FFTCONV_AUTO);
		}
		for (int i = 0; i < 30 * 20; i++)
			lit |= dark[i] != 0;
		ok(!lit, "a dark image stays dark, each way");
	}

	/* Three images, each its own kernel and lit block, summed: against the
	 * sum of three direct sums, both ways. */
	for (int m = FFTCONV_AUTO; m <= FFTCONV_DIRECT; m++) {
		enum { NX = 70, NY = 64, KN = 21 };
		static double im[3][NX * NY], ref[NX * NY], one[NX * NY], ks[3][KN * KN];
		double *imgs[3] = { im[0], im[1], im[2] }, d = 0;
		const double *kers[3] = { ks[0], ks[1], ks[2] };
		unsigned seed = 99u + m;
		int dark = 0;

		memset(im, 0, sizeof(im));
		memset(ref, 0, sizeof(ref));
		for (int i = 0; i < 3; i++) {
			for (int k = 0; k < KN * KN; k++)
				ks[i][k] = (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24) - 0.3;
			/* block i: [12 + 5i, 40 + 3i) x [15 + 2i, 30 + 6i) */
			for (int y = 15 + 2 * i; y < 30 + 6 * i; y++)
				for (int x = 12 + 5 * i; x < 40 + 3 * i; x++)
					im[i][y * NX + x] = (double)((seed = seed * 1103515245u + 12345u) >> 8) / (1 << 24);
			direct(im[i], NX, NY, ks[i], KN, one);
			for (int k = 0; k < NX * NY; k++)
				ref[k] += one[k];
		}
		fftconv_force(m);
		if (fftconv_convolve_sum(fc, t, imgs, kers, 3, NX, NY, KN))
			d = INFINITY;
		fftconv_force(FFTCONV_AUTO);
		for (int k = 0; k < NX * NY; k++) {
			d = fmax(d, fabs(im[0][k] - ref[k]));
			/* the blocks begin at x = 12, y = 15: no light reaches
			 * x < 2 or y < 5 (h = 10) */
			dark |= (k % NX < 2 || k / NX < 5) && im[0][k] != 0;
		}
		ok(d < 1e-11 && !dark, "three images with their own kernels summed, %s: within %.2g "
		   "of the direct sums, dark where no light reaches", way[m], d);
	}

	double img[4] = { 1, 2, 3, 4 }, k[2] = { 1, 1 };
	ok(fftconv_convolve(fc, t, img, 2, 2, k, 2) == -1 && img[3] == 4,
	   "even kernel refused, image unchanged");

	struct job j[2] = { { fc, 0 }, { fc, 0 } };
	pthread_t th[2];
	for (int i = 0; i < 2; i++)
		pthread_create(&th[i], NULL, worker, &j[i]);
	for (int i = 0; i < 2; i++)
		pthread_join(th[i], NULL);
	is_near(fmax(j[0].d, j[1].d), 0, 1e-11, "two threads planning and executing at once");

	fftconv_thread_free(t);
	fftconv_free(fc);
	fftconv_free(NULL);
	fftconv_thread_free(NULL);
	return done_testing();
}
