/*
 * fftconv.h - the host side of the plugins' convolve service: linear
 * (zero-padded) 2-D convolution of a small image with a small odd kernel
 * through FFTW real-to-complex transforms.
 *
 * FFTW's planner is not thread-safe, but fftw_execute_dft_r2c/c2r on arrays
 * other than the planned ones is ("the only thread-safe routine in FFTW is
 * fftw_execute (and the new-array variants thereof)").  So:
 *
 *   struct fftconv        one per scene, shared by all threads: a cache of
 *                         plans keyed by the transform's length (a fixed
 *                         batch of rows, or of columns gathered into a
 *                         buffer, whatever the other side), each made once,
 *                         under a mutex, with FFTW_ESTIMATE (the planner
 *                         never touches the arrays);
 *   struct fftconv_thread one per worker thread: fftw_malloc'd buffers that
 *                         grow to the largest size the thread has seen.
 *
 * Every plan is made out of place on fftw_malloc'd (SIMD-aligned) arrays and
 * executed with the new-array interface on the thread's own fftw_malloc'd
 * buffers, which have the same alignment, as FFTW requires.
 *
 * Only the image's lit part is transformed: the smallest block holding
 * every pixel that is not zero, w x v, padded to fftconv_size(w + kn - 1)
 * by fftconv_size(v + kn - 1), so the circular convolution of the padded
 * arrays equals the linear one on every pixel the light reaches: nothing
 * wraps around.  Where the lit pixels are few the sum is taken directly
 * instead (fftconv_force).  The result does not depend on the thread or
 * on which plans exist, only on the image and the kernel.
 */
#ifndef WFS_FFTCONV_H
#define WFS_FFTCONV_H

struct fftconv;
struct fftconv_thread;

/* A new, empty plan cache.  Also makes FFTW's planner thread-safe for the
 * process (fftw_make_planner_thread_safe), since other modules may plan
 * concurrently.  NULL when out of memory. */
struct fftconv *fftconv_new(void);

/* Destroy the cache and its plans.  NULL is a no-op.  No thread may be
 * inside fftconv_convolve. */
void fftconv_free(struct fftconv *fc);

/* How many plan pairs the cache has made (sizes planned): 0 for a scene
 * that convolved nothing.  Not while a thread is inside fftconv_convolve. */
int fftconv_nplans(struct fftconv *fc);

/* Per-thread buffers, initially empty.  NULL when out of memory. */
struct fftconv_thread *fftconv_thread_new(void);
void fftconv_thread_free(struct fftconv_thread *t);

/*
 * Convolve the nx x ny image img (row-major, row = y) in place with the
 * kn x kn kernel (kn odd, centre at (kn - 1) / 2):
 *
 *   out(x, y) = sum_{x', y'} img(x', y') kernel(x - x' + h, y - y' + h),
 *   h = (kn - 1) / 2,
 *
 * with img taken as zero outside the image.  So a kernel sample at
 * (h + dx, h + dy) is what a unit pixel sends to the pixel (dx, dy) away.
 * Safe to call from several threads at once, each with its own t.
 * Returns 0, or -1 on bad sizes or when out of memory (nothing is changed
 * then).
 */
int fftconv_convolve(struct fftconv *fc, struct fftconv_thread *t,
		     double *img, int nx, int ny, const double *kernel, int kn);

/*
 * The sum of count (1 to 8) such convolutions, each image with its own
 * kernel (all kn x kn), into imgs[0]:
 *
 *   imgs[0] <- sum_i imgs[i] * kernels[i],
 *
 * the other images left as they were.  The transforms of the images and
 * kernels are multiplied and summed, and the sum transformed back once.
 * Returns 0, or -1 on bad sizes or when out of memory (imgs[0] is then
 * unchanged).
 */
int fftconv_convolve_sum(struct fftconv *fc, struct fftconv_thread *t, double *const *imgs,
			 const double *const *kernels, int count, int nx, int ny, int kn);

/* How fftconv_convolve and fftconv_convolve_sum sum: FFTCONV_AUTO (the default) takes the direct
 * sum over the lit pixels where that costs less than the transforms, and
 * the FFT elsewhere; FFTCONV_FFT and FFTCONV_DIRECT force one way, for the
 * tests and the benchmarks that compare them.  Process-wide; not while a
 * thread is inside fftconv_convolve.  Both ways give the same sums to
 * rounding (the FFT's, about 1e-16 of the largest term). */
enum { FFTCONV_AUTO, FFTCONV_FFT, FFTCONV_DIRECT };
void fftconv_force(int method);

/* The smallest 2^a 3^b 5^c 7^d >= n.  Exposed for tests and cost models. */
int fftconv_good_size(int n);

/* The FFT size fftconv uses for a linear convolution of length n: the
 * smallest of 2^k, 5/4 2^k, 3/2 2^k, 7/4 2^k not below n (the 7-smooth
 * size up to 16), so that few sizes are planned. */
int fftconv_size(int n);

#endif
