/*
 * sersic_fftconv.c - the host's FFT convolution service against a direct
 * sum: odd kernels, zero outside the image, sizes that are and are not
 * FFT-friendly, and two threads sharing one plan cache.
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
