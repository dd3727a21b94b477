/*
 * fftconv.c - FFT convolution for the plugins' convolve service; see
 * fftconv.h for the threading and planning rules.
 */
#include "fftconv.h"

#include <fftw3.h>
#include <pthread.h>
#include <stdlib.h>
#include <math.h>
#include <stdatomic.h>
#include <string.h>

#include "simd.h"

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

/* out[0, n) += v k[0, n): the direct sum's one loop, plain and with AVX2
 * (no FMA: a product then a sum, as the plain loop, so the same bytes). */
static void axpy_plain(double *restrict out, const double *restrict k, double v, int n)
{
	for (int i = 0; i < n; i++)
		out[i] += v * k[i];
}

#ifdef SIMD_X86
__attribute__((target("avx2"))) static void axpy_avx2(double *restrict out,
							const double *restrict k, double v, int n)
{
	__m256d vv = _mm256_set1_pd(v);
	int i = 0;

	for (; i + 4 <= n; i += 4)
		_mm256_storeu_pd(out + i, _mm256_add_pd(_mm256_loadu_pd(out + i),
							_mm256_mul_pd(vv, _mm256_loadu_pd(k + i))));
	for (; i < n; i++)
		out[i] += v * k[i];
}
#endif

static void (*axpy_choose(void))(double *restrict, const double *restrict, double, int)
{
#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX2)
		return axpy_avx2;
#endif
	return axpy_plain;
}

/* The part of the image that is not zero: [*x0, *x1] x [*y0, *y1] and how
 * many pixels it has that are not.  0 when the whole image is zero. */
static size_t image_support(const double *img, int nx, int ny, int *x0, int *x1, int *y0,
			    int *y1)
{
	size_t nnz = 0;

	*x0 = nx;
	*x1 = -1;
	*y0 = ny;
	*y1 = -1;
	for (int y = 0; y < ny; y++) {
		const double *r = img + (size_t)y * nx;
		int a = 0, b = nx - 1;

		while (a < nx && r[a] == 0)
			a++;
		if (a == nx)
			continue;
		while (r[b] == 0)
			b--;
		for (int x = a; x <= b; x++)
			nnz += r[x] != 0;
		*x0 = a < *x0 ? a : *x0;
		*x1 = b > *x1 ? b : *x1;
		*y0 = y < *y0 ? y : *y0;
		*y1 = y;
	}
	return nnz;
}

/*
 * The cost of the direct sum, in multiply-adds with a call's overhead
 * counted as 16 of them: scattering nnz lit pixels through the kernel's
 * rows (nnz kn calls of kn), or the block's rows through its taps (v kn^2
 * calls of w).  *rows says which is less.
 */
static double direct_cost(size_t nnz, int w, int v, int kn, int *rows)
{
	double scatter = (double)nnz * kn * (kn + 16), byrow = (double)v * kn * kn * (w + 16);

	*rows = byrow < scatter;
	return *rows ? byrow : scatter;
}

/*
 * Whether the direct sum costs less than the transforms of px x py: three
 * transforms of px py log2(px py) butterflies and the padding and product
 * around them.  FFTCONV_DIRECT_COST is the ratio of the two unit costs,
 * measured on the development machine (BENCHMARKS.md, "Sérsic galaxies");
 * the crossing is flat, so a factor of two either way costs little.
 */
#define FFTCONV_DIRECT_COST 0.6

static int direct_cheaper(double cost, int px, int py)
{
	double n = (double)px * py;

	return FFTCONV_DIRECT_COST * cost < 3 * n * log2(n) + 8 * n;
}

static atomic_int forced = FFTCONV_AUTO;

void fftconv_force(int method)
{
	atomic_store(&forced, method);
}

/* The sum over the lit block [bx0, bx1] x [by0, by1] into the output block
 * [ox0, ox1] x [oy0, oy1] (out, ow wide), one of two ways:
 *  - scattered: each lit pixel times the kernel's rows (kn calls of kn),
 *    the better way for a block narrower than the kernel;
 *  - by rows: output row y + ky - h gains tap (kx, ky) times the block's
 *    row shifted by kx - h (kn^2 calls of the block's width). */
static void convolve_direct(const double *img, int nx, int bx0, int bx1, int by0, int by1,
			    const double *kernel, int kn, double *out, int ox0, int ox1,
			    int oy0, int oy1, int rows)
{
	void (*axpy)(double *restrict, const double *restrict, double, int) = axpy_choose();
	int h = (kn - 1) / 2, ow = ox1 - ox0 + 1;

	memset(out, 0, (size_t)ow * (oy1 - oy0 + 1) * sizeof(double));
	if (!rows) {
		for (int y = by0; y <= by1; y++)
			for (int x = bx0; x <= bx1; x++) {
				double v = img[(size_t)y * nx + x];

				if (v == 0)
					continue;
				/* output (x + kx - h, y + ky - h) inside the block */
				int kx0 = ox0 - x + h > 0 ? ox0 - x + h : 0;
				int kx1 = ox1 - x + h < kn - 1 ? ox1 - x + h : kn - 1;
				int ky0 = oy0 - y + h > 0 ? oy0 - y + h : 0;
				int ky1 = oy1 - y + h < kn - 1 ? oy1 - y + h : kn - 1;

				for (int ky = ky0; ky <= ky1; ky++)
					axpy(out + (size_t)(y + ky - h - oy0) * ow + (x + kx0 - h - ox0),
					     kernel + (size_t)ky * kn + kx0, v, kx1 - kx0 + 1);
			}
		return;
	}
	for (int y = by0; y <= by1; y++) {
		const double *row = img + (size_t)y * nx;
		int ky0 = oy0 - y + h > 0 ? oy0 - y + h : 0;
		int ky1 = oy1 - y + h < kn - 1 ? oy1 - y + h : kn - 1;

		for (int ky = ky0; ky <= ky1; ky++) {
			double *orow = out + (size_t)(y + ky - h - oy0) * ow;

			for (int kx = 0; kx < kn; kx++) {
				double k = kernel[(size_t)ky * kn + kx];
				/* source x lands on x + kx - h, inside [ox0, ox1] */
				int x0 = ox0 - kx + h > bx0 ? ox0 - kx + h : bx0;
				int x1 = ox1 - kx + h < bx1 ? ox1 - kx + h : bx1;

				if (k != 0 && x0 <= x1)
					axpy(orow + (x0 + kx - h - ox0), row + x0, k, x1 - x0 + 1);
			}
		}
	}
}

/*
 * Only the lit part of the image is transformed: a block of w x v pixels
 * convolved with a kn-wide kernel lights w + kn - 1 x v + kn - 1 pixels,
 * and a circular transform at least that size holds them without wrapping.
 * A galaxy's stamp is its light grown by the ePSF's half-width on every
 * side, so this halves the side of most transforms; a block with few lit
 * pixels is summed directly instead.
 */
int fftconv_convolve(struct fftconv *fc, struct fftconv_thread *t,
		     double *img, int nx, int ny, const double *kernel, int kn)
{
	if (!fc || !t || !img || !kernel || nx < 1 || ny < 1 || kn < 1 || !(kn & 1) ||
	    nx > (1 << 20) || ny > (1 << 20) || kn > (1 << 20))
		return -1;

	int h = (kn - 1) / 2, bx0, bx1, by0, by1;
	size_t nnz = image_support(img, nx, ny, &bx0, &bx1, &by0, &by1);

	if (!nnz)
		return 0;       /* dark in, dark out */

	int wx = bx1 - bx0 + 1, wy = by1 - by0 + 1;
	/* the pixels the light reaches */
	int ox0 = bx0 - h > 0 ? bx0 - h : 0, ox1 = bx1 + h < nx - 1 ? bx1 + h : nx - 1;
	int oy0 = by0 - h > 0 ? by0 - h : 0, oy1 = by1 + h < ny - 1 ? by1 + h : ny - 1;
	int ow = ox1 - ox0 + 1, oh = oy1 - oy0 + 1;
	int px = fftconv_size(wx + kn - 1), py = fftconv_size(wy + kn - 1), rows;
	int method = atomic_load(&forced);
	double cost = direct_cost(nnz, wx, wy, kn, &rows);

	if (method == FFTCONV_AUTO)
		method = direct_cheaper(cost, px, py) ? FFTCONV_DIRECT : FFTCONV_FFT;
	if (method == FFTCONV_DIRECT) {
		if (thread_reserve(t, ow, oh))
			return -1;
		convolve_direct(img, nx, bx0, bx1, by0, by1, kernel, kn, t->rimg, ox0, ox1, oy0, oy1,
				rows);
		for (int y = oy0; y <= oy1; y++)
			memcpy(img + (size_t)y * nx + ox0, t->rimg + (size_t)(y - oy0) * ow,
			       ow * sizeof(double));
		return 0;
	}

	if (thread_reserve(t, px, py))
		return -1;
	struct fftconv_plan *p = plan_get(fc, t, px, py);
	if (!p)
		return -1;

	/* The lit block at the origin, zero beyond it up to the padded size. */
	memset(t->rimg, 0, (size_t)px * py * sizeof(double));
	for (int y = 0; y < wy; y++)
		memcpy(t->rimg + (size_t)y * px, img + (size_t)(by0 + y) * nx + bx0,
		       wx * sizeof(double));

	/* The kernel with its centre moved to (0, 0) and negative offsets
	 * wrapped to the far end: sample (h + dx, h + dy) goes to
	 * (dx mod px, dy mod py). */
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

	/* Output pixel (bx0 + d, by0 + e), d in [-h, wx - 1 + h], is the
	 * circular result at (d mod px, e mod py). */
	for (int y = oy0; y <= oy1; y++) {
		int e = y - by0 < 0 ? y - by0 + py : y - by0;
		const double *r = t->rimg + (size_t)e * px;
		double *o = img + (size_t)y * nx;

		for (int x = ox0; x <= ox1; x++) {
			int d = x - bx0 < 0 ? x - bx0 + px : x - bx0;
			o[x] = r[d];
		}
	}
	return 0;
}
