/*
 * fftconv.c - FFT convolution for the plugins' convolve service; see
 * fftconv.h for the threading and planning rules.
 */
#include "fftconv.h"

#include <fftw3.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

struct fftconv_plan {
	int nx, ny;                     /* padded real size */
	fftw_plan fwd, inv;             /* r2c and c2r, out of place */
	struct fftconv_plan *next;
};

struct fftconv {
	pthread_mutex_t lock;           /* guards plans and the FFTW planner */
	struct fftconv_plan *plans;
};

struct fftconv_thread {
	size_t nreal, ncplx;            /* capacity of the buffers, in elements */
	double *rimg, *rker;
	fftw_complex *cimg, *cker;
};

int fftconv_nplans(struct fftconv *fc)
{
	int n = 0;

	pthread_mutex_lock(&fc->lock);
	for (const struct fftconv_plan *p = fc->plans; p; p = p->next)
		n++;
	pthread_mutex_unlock(&fc->lock);
	return n;
}

int fftconv_good_size(int n)
{
	if (n < 1)
		return 1;
	for (int m = n;; m++) {
		int r = m;
		while (r % 2 == 0) r /= 2;
		while (r % 3 == 0) r /= 3;
		while (r % 5 == 0) r /= 5;
		while (r % 7 == 0) r /= 7;
		if (r == 1)
			return m;
	}
}

/* The ladder: 2^k times 1, 5/4, 3/2, 7/4 (at most 25 % above n, for n >=
 * 16), so a scene of galaxies of every size plans a few dozen sizes, not one
 * per galaxy: FFTW_ESTIMATE planning of a 2-D pair costs as much as several
 * transforms of that size (the deep-field mix planned 982 sizes for 1000
 * galaxies). */
int fftconv_size(int n)
{
	int p = 16;

	if (n <= 16)
		return n < 1 ? 1 : fftconv_good_size(n);
	while (p < n && p < (1 << 20)) {
		if (p * 5 / 4 >= n)
			return p * 5 / 4;
		if (p * 3 / 2 >= n)
			return p * 3 / 2;
		if (p * 7 / 4 >= n)
			return p * 7 / 4;
		p *= 2;
	}
	return p >= n ? p : fftconv_good_size(n);
}

struct fftconv *fftconv_new(void)
{
	struct fftconv *fc = calloc(1, sizeof(*fc));

	if (!fc)
		return NULL;
	if (pthread_mutex_init(&fc->lock, NULL)) {
		free(fc);
		return NULL;
	}
	/* Other modules (the optics) may run the planner in other threads. */
	fftw_make_planner_thread_safe();
	return fc;
}

void fftconv_free(struct fftconv *fc)
{
	if (!fc)
		return;
	for (struct fftconv_plan *p = fc->plans, *next; p; p = next) {
		next = p->next;
		fftw_destroy_plan(p->fwd);
		fftw_destroy_plan(p->inv);
		free(p);
	}
	pthread_mutex_destroy(&fc->lock);
	free(fc);
}

struct fftconv_thread *fftconv_thread_new(void)
{
	return calloc(1, sizeof(struct fftconv_thread));
}

void fftconv_thread_free(struct fftconv_thread *t)
{
	if (!t)
		return;
	fftw_free(t->rimg);
	fftw_free(t->rker);
	fftw_free(t->cimg);
	fftw_free(t->cker);
	free(t);
}

/* Grow the thread's buffers to hold a padded nx x ny problem. */
static int thread_reserve(struct fftconv_thread *t, int nx, int ny)
{
	size_t nreal = (size_t)nx * ny, ncplx = (size_t)ny * (nx / 2 + 1);

	if (nreal <= t->nreal && ncplx <= t->ncplx)
		return 0;
	fftw_free(t->rimg);
	fftw_free(t->rker);
	fftw_free(t->cimg);
	fftw_free(t->cker);
	t->rimg = fftw_malloc(nreal * sizeof(double));
	t->rker = fftw_malloc(nreal * sizeof(double));
	t->cimg = fftw_malloc(ncplx * sizeof(fftw_complex));
	t->cker = fftw_malloc(ncplx * sizeof(fftw_complex));
	if (!t->rimg || !t->rker || !t->cimg || !t->cker) {
		fftw_free(t->rimg);
		fftw_free(t->rker);
		fftw_free(t->cimg);
		fftw_free(t->cker);
		memset(t, 0, sizeof(*t));
		return -1;
	}
	t->nreal = nreal;
	t->ncplx = ncplx;
	return 0;
}

/* The plan pair for a padded size, made on first use.  Planning runs on the
 * caller's buffers: with FFTW_ESTIMATE the planner does not write to them,
 * and they have fftw_malloc's alignment, like every buffer executed later. */
static struct fftconv_plan *plan_get(struct fftconv *fc, struct fftconv_thread *t,
				     int nx, int ny)
{
	struct fftconv_plan *p;

	pthread_mutex_lock(&fc->lock);
	for (p = fc->plans; p; p = p->next)
		if (p->nx == nx && p->ny == ny)
			goto out;
	p = calloc(1, sizeof(*p));
	if (!p)
		goto out;
	p->nx = nx;
	p->ny = ny;
	/* FFTW's dimensions are slowest first: (rows, columns) = (ny, nx). */
	p->fwd = fftw_plan_dft_r2c_2d(ny, nx, t->rimg, t->cimg, FFTW_ESTIMATE);
	p->inv = fftw_plan_dft_c2r_2d(ny, nx, t->cimg, t->rimg, FFTW_ESTIMATE);
	if (!p->fwd || !p->inv) {
		if (p->fwd)
			fftw_destroy_plan(p->fwd);
		if (p->inv)
			fftw_destroy_plan(p->inv);
		free(p);
		p = NULL;
		goto out;
	}
	p->next = fc->plans;
	fc->plans = p;
out:
	pthread_mutex_unlock(&fc->lock);
	return p;
}

int fftconv_convolve(struct fftconv *fc, struct fftconv_thread *t,
		     double *img, int nx, int ny, const double *kernel, int kn)
{
	if (!fc || !t || !img || !kernel || nx < 1 || ny < 1 || kn < 1 || !(kn & 1) ||
	    nx > (1 << 20) || ny > (1 << 20) || kn > (1 << 20))
		return -1;

	int h = (kn - 1) / 2;
	int px = fftconv_size(nx + kn - 1), py = fftconv_size(ny + kn - 1);

	if (thread_reserve(t, px, py))
		return -1;
	struct fftconv_plan *p = plan_get(fc, t, px, py);
	if (!p)
		return -1;

	/* The image at the origin, zero beyond it up to the padded size. */
	memset(t->rimg, 0, (size_t)px * py * sizeof(double));
	for (int y = 0; y < ny; y++)
		memcpy(t->rimg + (size_t)y * px, img + (size_t)y * nx, nx * sizeof(double));

	/* The kernel with its centre moved to (0, 0) and negative offsets
	 * wrapped to the far end: sample (h + dx, h + dy) goes to
	 * (dx mod px, dy mod py).  px >= nx + kn - 1 keeps every output pixel
	 * of the image free of wrapped light. */
	memset(t->rker, 0, (size_t)px * py * sizeof(double));
	for (int ky = 0; ky < kn; ky++) {
		int y = ky - h < 0 ? ky - h + py : ky - h;
		for (int kx = 0; kx < kn; kx++) {
			int x = kx - h < 0 ? kx - h + px : kx - h;
			t->rker[(size_t)y * px + x] = kernel[(size_t)ky * kn + kx];
		}
	}

	fftw_execute_dft_r2c(p->fwd, t->rimg, t->cimg);
	fftw_execute_dft_r2c(p->fwd, t->rker, t->cker);
	size_t nc = (size_t)py * (px / 2 + 1);
	double scale = 1.0 / ((double)px * py);
	for (size_t i = 0; i < nc; i++) {
		double ar = t->cimg[i][0], ai = t->cimg[i][1];
		double br = t->cker[i][0], bi = t->cker[i][1];
		t->cimg[i][0] = (ar * br - ai * bi) * scale;
		t->cimg[i][1] = (ar * bi + ai * br) * scale;
	}
	fftw_execute_dft_c2r(p->inv, t->cimg, t->rimg);

	for (int y = 0; y < ny; y++)
		memcpy(img + (size_t)y * nx, t->rimg + (size_t)y * px, nx * sizeof(double));
	return 0;
}
