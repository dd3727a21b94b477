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

/* One FFTW plan of the pruned 2-D transform (fftconv_convolve_sum), of a
 * fixed batch whatever the problem's other side, so that a scene plans a
 * few per transform length, not one per pair of sides and count of rows:
 * FFTCONV_RB 1-D real transforms of length nx along contiguous rows,
 * forward (r2c) or back (c2r), executed on each group of FFTCONV_RB rows;
 * or FFTCONV_CB complex transforms of length nx interleaved in a buffer
 * (stride FFTCONV_CB), forward or back, in place, on each group of
 * FFTCONV_CB columns gathered there. */
enum { PLAN_ROWS_FWD, PLAN_ROWS_INV, PLAN_COLS_FWD, PLAN_COLS_INV };
#define FFTCONV_RB 4
#define FFTCONV_CB 8

struct fftconv_plan {
	int kind, nx, m;                /* m: the batch */
	fftw_plan p;
	struct fftconv_plan *next;
};

/* The plans in lists by a hash of their key, each growing only at its
 * head: an entry is made whole, then put at the head under the lock with
 * release order; readers walk a list from an acquire load of its head,
 * without the lock. */
#define FFTCONV_BUCKETS 1024

struct fftconv {
	pthread_mutex_t lock;           /* guards adding plans and the FFTW planner */
	_Atomic(struct fftconv_plan *) plans[FFTCONV_BUCKETS];
};

static unsigned plan_bucket(int kind, int nx, int m)
{
	unsigned h = (unsigned)kind * 2654435761u ^ (unsigned)nx * 40503u ^ (unsigned)m * 2246822519u;

	return (h ^ h >> 15) % FFTCONV_BUCKETS;
}

static struct fftconv_plan *plan_find(struct fftconv_plan *p, int kind, int nx, int m)
{
	for (; p; p = p->next)
		if (p->kind == kind && p->nx == nx && p->m == m)
			return p;
	return NULL;
}

struct fftconv_thread {
	size_t nreal, ncplx, ncol;      /* capacity of the buffers, in elements */
	double *rimg;
	fftw_complex *cimg, *cker, *cacc;
	fftw_complex *col;              /* FFTCONV_CB columns, interleaved */
};

int fftconv_nplans(struct fftconv *fc)
{
	int n = 0;

	pthread_mutex_lock(&fc->lock);
	for (int b = 0; b < FFTCONV_BUCKETS; b++)
		for (const struct fftconv_plan *p = atomic_load(&fc->plans[b]); p; p = p->next)
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
	for (int b = 0; b < FFTCONV_BUCKETS; b++)
		for (struct fftconv_plan *p = atomic_load(&fc->plans[b]), *next; p; p = next) {
			next = p->next;
			fftw_destroy_plan(p->p);
			free(p);
		}
	pthread_mutex_destroy(&fc->lock);
	free(fc);
}

struct fftconv_thread *fftconv_thread_new(void)
{
	return calloc(1, sizeof(struct fftconv_thread));
}

static void thread_release(struct fftconv_thread *t)
{
	fftw_free(t->rimg);
	fftw_free(t->cimg);
	fftw_free(t->cker);
	fftw_free(t->cacc);
	fftw_free(t->col);
	t->rimg = NULL;
	t->cimg = t->cker = t->cacc = t->col = NULL;
	t->nreal = t->ncplx = t->ncol = 0;
}

void fftconv_thread_free(struct fftconv_thread *t)
{
	if (!t)
		return;
	thread_release(t);
	free(t);
}

/* ny rounded up to whole batches of rows. */
static int rows_up(int ny)
{
	return (ny + FFTCONV_RB - 1) / FFTCONV_RB * FFTCONV_RB;
}

/* Grow the thread's buffers to hold a padded nx x ny problem (its rows
 * rounded up to whole batches). */
static int thread_reserve(struct fftconv_thread *t, int nx, int ny)
{
	int nyb = rows_up(ny);
	size_t nreal = (size_t)nx * nyb, ncplx = (size_t)nyb * (nx / 2 + 1);
	size_t ncol = (size_t)FFTCONV_CB * nyb;

	if (nreal <= t->nreal && ncplx <= t->ncplx && ncol <= t->ncol)
		return 0;
	thread_release(t);
	t->rimg = fftw_malloc(nreal * sizeof(double));
	t->cimg = fftw_malloc(ncplx * sizeof(fftw_complex));
	t->cker = fftw_malloc(ncplx * sizeof(fftw_complex));
	t->cacc = fftw_malloc(ncplx * sizeof(fftw_complex));
	t->col = fftw_malloc(ncol * sizeof(fftw_complex));
	if (!t->rimg || !t->cimg || !t->cker || !t->cacc || !t->col) {
		thread_release(t);
		return -1;
	}
	t->nreal = nreal;
	t->ncplx = ncplx;
	t->ncol = ncol;
	return 0;
}

/* A plan of `kind` (PLAN_*) for transforms of length nx, made on first
 * use: FFTCONV_RB rows, or FFTCONV_CB columns in t->col.  Planning runs
 * on the thread's buffers (large enough for the problem): with
 * FFTW_ESTIMATE the planner does not write to them.  A row plan is
 * executed on groups of rows FFTCONV_RB apart, whose offsets (FFTCONV_RB
 * nx doubles, FFTCONV_RB (nx / 2 + 1) complex) keep fftw_malloc's
 * alignment; a column plan only on t->col. */
static fftw_plan plan_get(struct fftconv *fc, struct fftconv_thread *t, int kind, int nx)
{
	int m = kind == PLAN_ROWS_FWD || kind == PLAN_ROWS_INV ? FFTCONV_RB : FFTCONV_CB;
	_Atomic(struct fftconv_plan *) *head = &fc->plans[plan_bucket(kind, nx, m)];
	struct fftconv_plan *p = plan_find(atomic_load_explicit(head, memory_order_acquire), kind, nx, m);
	int nc = nx / 2 + 1;
	fftw_plan made = NULL;

	if (p)
		return p->p;
	pthread_mutex_lock(&fc->lock);
	if ((p = plan_find(atomic_load_explicit(head, memory_order_relaxed), kind, nx, m)))
		goto out;
	if (kind == PLAN_ROWS_FWD)
		made = fftw_plan_many_dft_r2c(1, &nx, m, t->rimg, NULL, 1, nx, t->cimg, NULL, 1, nc,
					      FFTW_ESTIMATE);
	else if (kind == PLAN_ROWS_INV)
		made = fftw_plan_many_dft_c2r(1, &nx, m, t->cacc, NULL, 1, nc, t->rimg, NULL, 1, nx,
					      FFTW_ESTIMATE);
	else
		made = fftw_plan_many_dft(1, &nx, m, t->col, NULL, 1, nx, t->col, NULL, 1, nx,
					  kind == PLAN_COLS_FWD ? FFTW_FORWARD : FFTW_BACKWARD,
					  FFTW_ESTIMATE);
	if (!made || !(p = calloc(1, sizeof(*p)))) {
		if (made)
			fftw_destroy_plan(made);
		p = NULL;
		goto out;
	}
	p->kind = kind;
	p->nx = nx;
	p->m = m;
	p->p = made;
	p->next = atomic_load_explicit(head, memory_order_relaxed);
	atomic_store_explicit(head, p, memory_order_release);
out:
	pthread_mutex_unlock(&fc->lock);
	return p ? p->p : NULL;
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

#ifdef SIMD_X86
__attribute__((target("avx512f"))) static void axpy_avx512(double *restrict out,
							     const double *restrict k, double v, int n)
{
	__m512d vv = _mm512_set1_pd(v);
	int i = 0;

	for (; i + 8 <= n; i += 8)
		_mm512_storeu_pd(out + i, _mm512_add_pd(_mm512_loadu_pd(out + i),
							_mm512_mul_pd(vv, _mm512_loadu_pd(k + i))));
	for (; i < n; i++)
		out[i] += v * k[i];
}
#endif

static void (*axpy_choose(void))(double *restrict, const double *restrict, double, int)
{
#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX512)
		return axpy_avx512;
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

/* The rows transformed for `rows` lit rows of a padded height py: whole
 * batches of FFTCONV_RB (the rows added are zero). */
static int rows_q(int rows, int py)
{
	int q = rows_up(rows);

	return q < rows_up(py) ? q : rows_up(py);
}

/*
 * The cost of the transforms, in the direct sum's unit: for each of
 * `count` images and its kernel the row transforms of their lit rows and
 * all the column transforms, and for the sum the columns and the rows
 * wanted back, each nx log2 nx butterflies a length-nx transform (a row
 * of reals counted half), and the passes over the arrays around them.
 * FFTCONV_DIRECT_COST is the ratio of the two unit costs, measured on the
 * development machines (BENCHMARKS.md, "Sérsic galaxies"); the crossing is
 * flat, so a factor of two either way costs little.
 */
#define FFTCONV_DIRECT_COST 0.6

static double fft_cost(int count, int wy, int kn, int oh, int px, int py)
{
	double lx = log2(px), ly = log2(py), nc = px / 2 + 1;
	double row = 0.5 * px * lx, col = nc * py * ly;
	double rows = count * (rows_q(wy, py) + rows_q(kn, py)) + rows_q(oh, py);

	return rows * row + (2 * count + 1) * col + (6.0 * count + 2) * px * py;
}

static int direct_cheaper(double cost, double fft)
{
	return FFTCONV_DIRECT_COST * cost < 2 * fft;
}

static atomic_int forced = FFTCONV_AUTO;

void fftconv_force(int method)
{
	atomic_store(&forced, method);
}

/* The sum over the lit block [bx0, bx1] x [by0, by1] added into the output
 * block [ox0, ox1] x [oy0, oy1] (out, ow wide), one of two ways:
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


/* The largest count fftconv_convolve_sum takes. */
#define FFTCONV_MAX 8

/* One image of a sum: its lit block and lit pixels. */
struct conv_part {
	double *img;
	const double *ker;
	size_t nnz;
	int bx0, bx1, by0, by1;
};

/* The column transforms of c (py rows of nc), FFTCONV_CB columns at a
 * time gathered into t->col: of its first `in` rows (the rest zero), and
 * only the first `out` rows written back. */
static void columns(struct fftconv_thread *t, fftw_plan plan, fftw_complex *c, int nc, int py,
		    int in, int out)
{
	double *b = (double *)t->col;

	for (int j0 = 0; j0 < nc; j0 += FFTCONV_CB) {
		int cw = nc - j0 < FFTCONV_CB ? nc - j0 : FFTCONV_CB;

		/* column j0 + j into b[j py ..], each contiguous; the columns
		 * past nc in the last group are zero */
		for (int y = 0; y < in; y++) {
			const double *r = (const double *)(c + (size_t)y * nc + j0);

			for (int j = 0; j < cw; j++) {
				b[2 * ((size_t)j * py + y)] = r[2 * j];
				b[2 * ((size_t)j * py + y) + 1] = r[2 * j + 1];
			}
		}
		for (int j = 0; j < FFTCONV_CB; j++) {
			if (j < cw)
				memset(b + 2 * ((size_t)j * py + in), 0, (size_t)(py - in) * sizeof(fftw_complex));
			else
				memset(b + 2 * (size_t)j * py, 0, (size_t)py * sizeof(fftw_complex));
		}
		fftw_execute_dft(plan, t->col, t->col);
		for (int y = 0; y < out; y++) {
			double *r = (double *)(c + (size_t)y * nc + j0);

			for (int j = 0; j < cw; j++) {
				r[2 * j] = b[2 * ((size_t)j * py + y)];
				r[2 * j + 1] = b[2 * ((size_t)j * py + y) + 1];
			}
		}
	}
}

/* The forward transform of a real block of w x v (rows apart by stride)
 * into c: placed at the origin of the px-wide rows of rimg, its rows
 * transformed (whole batches), the columns transformed with the rows
 * below taken as zero.  Returns 0 or -1 (no plan). */
static int forward(struct fftconv *fc, struct fftconv_thread *t, const double *src, size_t stride,
		   int w, int v, int px, int py, fftw_complex *c)
{
	int q = rows_q(v, py), nc = px / 2 + 1;
	fftw_plan rows = plan_get(fc, t, PLAN_ROWS_FWD, px), cols = plan_get(fc, t, PLAN_COLS_FWD, py);

	if (!rows || !cols)
		return -1;
	memset(t->rimg, 0, (size_t)px * q * sizeof(double));
	for (int y = 0; y < v; y++)
		memcpy(t->rimg + (size_t)y * px, src + (size_t)y * stride, w * sizeof(double));
	for (int y = 0; y < q; y += FFTCONV_RB)
		fftw_execute_dft_r2c(rows, t->rimg + (size_t)y * px, c + (size_t)y * nc);
	columns(t, cols, c, nc, py, q < py ? q : py, py);
	return 0;
}

/* acc[k] += a[k] b[k] over n complex numbers (re, im pairs): products
 * then sums, as the plain loop, in every clone. */
SIMD_CLONES("avx512f", "avx2", "default")
static void cmac(double *restrict acc, const double *restrict a, const double *restrict b, size_t n)
{
	for (size_t k = 0; k < 2 * n; k += 2) {
		double ar = a[k], ai = a[k + 1], br = b[k], bi = b[k + 1];

		acc[k] += ar * br - ai * bi;
		acc[k + 1] += ar * bi + ai * br;
	}
}

/*
 * The sum of the parts' convolutions by transforms: each lit image (the
 * union block bx0.., w x v, at the origin) and its kernel (unshifted, at
 * the origin) forward, their products summed, and one transform back.
 * Output pixel (bx0 + d - h, by0 + e - h) is the circular result at
 * (d, e), d < w + kn - 1 <= px: nothing wraps.  Rows and columns are
 * transformed apart so that the rows that are zero (most of a kernel's)
 * and the rows not wanted back are skipped.
 */
static int convolve_fft(struct fftconv *fc, struct fftconv_thread *t, const struct conv_part *pt,
			int count, int nx, int kn, int bx0, int by0, int w, int v, int ox0, int ox1,
			int oy0, int oy1, int px, int py)
{
	int h = (kn - 1) / 2, nc = px / 2 + 1;
	size_t ncp = (size_t)py * nc;
	int e1 = oy1 - by0 + h, q = rows_q(e1 + 1, py);
	fftw_plan cols = plan_get(fc, t, PLAN_COLS_INV, py), rows = plan_get(fc, t, PLAN_ROWS_INV, px);

	if (!cols || !rows)
		return -1;
	memset(t->cacc, 0, ncp * sizeof(fftw_complex));
	for (int i = 0; i < count; i++) {
		if (!pt[i].nnz)
			continue;
		if (forward(fc, t, pt[i].ker, kn, kn, kn, px, py, t->cker) ||
		    forward(fc, t, pt[i].img + (size_t)by0 * nx + bx0, nx, w, v, px, py, t->cimg))
			return -1;
		cmac((double *)t->cacc, (const double *)t->cimg, (const double *)t->cker, ncp);
	}
	columns(t, cols, t->cacc, nc, py, py, q < py ? q : py);
	if (q > py)
		memset(t->cacc + (size_t)py * nc, 0, (size_t)(q - py) * nc * sizeof(fftw_complex));
	for (int y = 0; y < q; y += FFTCONV_RB)
		fftw_execute_dft_c2r(rows, t->cacc + (size_t)y * nc, t->rimg + (size_t)y * px);
	double scale = 1.0 / ((double)px * py);
	double *out = pt[0].img;
	for (int y = oy0; y <= oy1; y++) {
		const double *r = t->rimg + (size_t)(y - by0 + h) * px + (h - bx0);
		double *o = out + (size_t)y * nx;

		for (int x = ox0; x <= ox1; x++)
			o[x] = r[x] * scale;
	}
	return 0;
}

/*
 * Only the lit part of the images is transformed: a block of w x v pixels
 * convolved with a kn-wide kernel lights w + kn - 1 x v + kn - 1 pixels,
 * and a circular transform at least that size holds them without wrapping.
 * A galaxy's stamp is its light grown by the ePSF's half-width on every
 * side, so this halves the side of most transforms; a block with few lit
 * pixels is summed directly instead.  The images share one block (the
 * union of theirs) and one transform back.
 */
int fftconv_convolve_sum(struct fftconv *fc, struct fftconv_thread *t, double *const *imgs,
			 const double *const *kernels, int count, int nx, int ny, int kn)
{
	struct conv_part pt[FFTCONV_MAX];
	int bx0 = nx, bx1 = -1, by0 = ny, by1 = -1, rows[FFTCONV_MAX];
	size_t nnz = 0;
	double cost = 0;

	if (!fc || !t || !imgs || !kernels || count < 1 || count > FFTCONV_MAX || nx < 1 || ny < 1 ||
	    kn < 1 || !(kn & 1) || nx > (1 << 20) || ny > (1 << 20) || kn > (1 << 20))
		return -1;
	for (int i = 0; i < count; i++)
		if (!imgs[i] || !kernels[i])
			return -1;
	for (int i = 0; i < count; i++) {
		struct conv_part *p = &pt[i];

		p->img = imgs[i];
		p->ker = kernels[i];
		p->nnz = image_support(p->img, nx, ny, &p->bx0, &p->bx1, &p->by0, &p->by1);
		if (!p->nnz)
			continue;
		nnz += p->nnz;
		cost += direct_cost(p->nnz, p->bx1 - p->bx0 + 1, p->by1 - p->by0 + 1, kn, &rows[i]);
		bx0 = p->bx0 < bx0 ? p->bx0 : bx0;
		bx1 = p->bx1 > bx1 ? p->bx1 : bx1;
		by0 = p->by0 < by0 ? p->by0 : by0;
		by1 = p->by1 > by1 ? p->by1 : by1;
	}
	if (!nnz)
		return 0;       /* dark in (imgs[0] too), dark out */

	int h = (kn - 1) / 2, wx = bx1 - bx0 + 1, wy = by1 - by0 + 1;
	/* the pixels the light reaches */
	int ox0 = bx0 - h > 0 ? bx0 - h : 0, ox1 = bx1 + h < nx - 1 ? bx1 + h : nx - 1;
	int oy0 = by0 - h > 0 ? by0 - h : 0, oy1 = by1 + h < ny - 1 ? by1 + h : ny - 1;
	int ow = ox1 - ox0 + 1, oh = oy1 - oy0 + 1;
	int px = fftconv_size(wx + kn - 1), py = fftconv_size(wy + kn - 1);
	int method = atomic_load(&forced);

	if (method == FFTCONV_AUTO)
		method = direct_cheaper(cost, fft_cost(count, wy, kn, oy1 - by0 + h + 1, px, py))
			 ? FFTCONV_DIRECT : FFTCONV_FFT;
	if (method == FFTCONV_DIRECT) {
		if (thread_reserve(t, ow, oh))
			return -1;
		memset(t->rimg, 0, (size_t)ow * oh * sizeof(double));
		for (int i = 0; i < count; i++)
			if (pt[i].nnz)
				convolve_direct(pt[i].img, nx, pt[i].bx0, pt[i].bx1, pt[i].by0, pt[i].by1,
						pt[i].ker, kn, t->rimg, ox0, ox1, oy0, oy1, rows[i]);
		for (int y = oy0; y <= oy1; y++)
			memcpy(imgs[0] + (size_t)y * nx + ox0, t->rimg + (size_t)(y - oy0) * ow,
			       ow * sizeof(double));
	} else if (thread_reserve(t, px, py) ||
		   convolve_fft(fc, t, pt, count, nx, kn, bx0, by0, wx, wy, ox0, ox1, oy0, oy1, px, py)) {
		return -1;
	}
	/* imgs[0] was dark outside the block written, which holds its lit
	 * block, and stays so */
	return 0;
}

int fftconv_convolve(struct fftconv *fc, struct fftconv_thread *t,
		     double *img, int nx, int ny, const double *kernel, int kn)
{
	return fftconv_convolve_sum(fc, t, &img, &kernel, 1, nx, ny, kn);
}
