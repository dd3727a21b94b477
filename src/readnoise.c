/*
 * readnoise.c - correlated read noise (readnoise.h) and the reference
 * correction of level 2.
 *
 * A pink series of N samples (N = (last read + 2) x 4096 rows) is the
 * inverse real FFT of coefficients X_j = (a_j + i b_j) sqrt(K / j), j = 1
 * .. N/2, a_j, b_j standard normal deviates keyed by (seed, filter, SCA,
 * series) and j (rng_normal_fill: any slice gives the same numbers), X_0 =
 * 0: power 1/f from 1/(N t_row) to the row rate's Nyquist frequency, and a
 * sample's variance sum_j 4 K / j (the Nyquist term K / (N/2)), which sets
 * K for the amplitude asked.  Read k of row y is sample k 4096 + y.
 *
 * The slow part of a pixel: knots Y_0 .. Y_J at reads 0, RN_KNOT, ...,
 * Y_0 = slow z_0, Y_j = rho Y_j-1 + slow sqrt(1 - rho^2) z_j, rho =
 * exp(-RN_KNOT read_time / slow_tau): stationary, of variance slow^2 and
 * covariance slow^2 exp(-|t| / slow_tau) between knots.  Read k takes
 * (1 - f) Y_j + f Y_j+1, j = k / RN_KNOT, f = (k mod RN_KNOT) / RN_KNOT;
 * a resultant the mean of its reads', a fixed sum over the knots its reads
 * span (kc).  z_j of pixel c is deviate c of the domain of knot j.
 */
#include <fftw3.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "data.h"
#include "err.h"
#include "readnoise.h"
#include "rng.h"
#include "rng_domains.h"
#include "simd.h"

static uint32_t rn_domain(const struct ramp_key *k, int purpose, int group)
{
	return rng_domain(purpose, k->filter, k->sca, group);
}

int rnoise_par_get(int sca, struct rnoise_par *par, struct err *e)
{
	struct tsv t;
	char name[16];
	int found = 0;

	memset(par, 0, sizeof(*par));
	snprintf(name, sizeof(name), "WFI%02d", sca);
	if (tsv_parse(&t, "readnoise.tsv") < 0)
		return e ? err_set(e, EXIT_SYSTEM, "readnoise.tsv: table missing from the build") : -1;
	int cd = tsv_col(&t, "cds"), cs = tsv_col(&t, "sca"), cw = tsv_col(&t, "white"), cp = tsv_col(&t, "ped"),
	    cc = tsv_col(&t, "cpink"), cu = tsv_col(&t, "upink"), ca = tsv_col(&t, "acn"),
	    cl = tsv_col(&t, "slow"), ct = tsv_col(&t, "slow_tau"), cT = tsv_col(&t, "total");

	for (int r = 1; r < t.nrow && cs >= 0 && cw >= 0 && cp >= 0 && cc >= 0 && cu >= 0 && ca >= 0 && cd >= 0
	     && cl >= 0 && ct >= 0 && cT >= 0; r++)
		if (!strcmp(t.cell[r][cs], name)) {
			par->cds = strtod(t.cell[r][cd], NULL);
			par->white = strtod(t.cell[r][cw], NULL);
			par->ped = strtod(t.cell[r][cp], NULL);
			par->cpink = strtod(t.cell[r][cc], NULL);
			par->upink = strtod(t.cell[r][cu], NULL);
			par->acn = strtod(t.cell[r][ca], NULL);
			par->slow = strtod(t.cell[r][cl], NULL);
			par->slow_tau = strtod(t.cell[r][ct], NULL);
			par->total = strtod(t.cell[r][cT], NULL);
			found = 1;
		}
	tsv_free(&t);
	if (!found || !(par->cds > 0) || !(par->white >= 0) || !(par->ped >= 0) || !(par->cpink >= 0) ||
	    !(par->upink >= 0) || !(par->acn >= 0) || !(par->slow >= 0) || !(par->slow_tau > 0) ||
	    !(par->total > 0))
		return e ? err_set(e, EXIT_SYSTEM, "readnoise.tsv: no or bad row for %s", name) : -1;
	return 0;
}

/* The planner runs under this lock and FFTW's own (other modules plan in
 * other threads: fftw_make_planner_thread_safe, as fftconv.c). */
static pthread_mutex_t plan_lock = PTHREAD_MUTEX_INITIALIZER;

/* One pink series of n samples, variance sigma^2, into out[0 .. n). */
static int pink_series(const struct rng *g, long n, double sigma, double *out)
{
	long h = n / 2;
	fftw_complex *X = fftw_malloc(sizeof(fftw_complex) * (size_t)(h + 1));
	double *z = malloc(sizeof(double) * (size_t)(2 * h + 2));
	double sum = 0, K;
	fftw_plan pl;

	if (!X || !z) {
		fftw_free(X);
		free(z);
		return -1;
	}
	for (long j = 1; j < h; j++)
		sum += 4.0 / (double)j;
	sum += 1.0 / (double)h;
	K = sigma * sigma / sum;
	rng_normal_fill(g, 0, (size_t)(2 * h + 2), z);
	X[0][0] = X[0][1] = 0;
	for (long j = 1; j <= h; j++) {
		double s = sqrt(K / (double)j);

		X[j][0] = z[2 * j] * s;
		X[j][1] = j == h ? 0 : z[2 * j + 1] * s;
	}
	if (h * 2 == n)
		X[h][0] = z[2 * h] * sqrt(K / (double)h);
	pthread_mutex_lock(&plan_lock);
	fftw_make_planner_thread_safe();
	pl = fftw_plan_dft_c2r_1d((int)n, X, out, FFTW_ESTIMATE);
	pthread_mutex_unlock(&plan_lock);
	if (!pl) {
		fftw_free(X);
		free(z);
		return -1;
	}
	fftw_execute(pl);       /* unnormalised: x_n = sum over the spectrum */
	pthread_mutex_lock(&plan_lock);
	fftw_destroy_plan(pl);
	pthread_mutex_unlock(&plan_lock);
	fftw_free(X);
	free(z);
	return 0;
}

/* The least m' >= m that is a product of 2, 3 and 5 alone: a fast FFT
 * length. */
static long fft_length(long m)
{
	for (;; m++) {
		long q = m;

		while (q % 2 == 0)
			q /= 2;
		while (q % 3 == 0)
			q /= 3;
		while (q % 5 == 0)
			q /= 5;
		if (q == 1)
			return m;
	}
}

/* R->pink: each resultant r's (reads fa[r]..la[r]) mean of the shared and
 * each channel's own pink series over n samples.  0 or -1 (memory). */
static int rn_pink(struct rnoise *R, int nr, const int *fa, const int *la, long n,
		   const struct rnoise_par *par, const struct ramp_key *k)
{
	size_t plane = (size_t)RN_NCHAN * (RN_ROWS + 1);
	double *shared = malloc(sizeof(double) * (size_t)n), *own = malloc(sizeof(double) * (size_t)n);
	struct rng g;
	int rc = -1;

	if (!shared || !own)
		goto out;
	rng_init(&g, k->seed, rn_domain(k, DOM_RN_PINK, 0));
	if (pink_series(&g, n, par->cpink, shared) < 0)
		goto out;
	for (int c = 0; c < RN_NCHAN; c++) {
		rng_init(&g, k->seed, rn_domain(k, DOM_RN_PINK, 1 + c));
		if (pink_series(&g, n, par->upink, own) < 0)
			goto out;
		for (int r = 0; r < nr; r++) {
			float *dst = R->pink + (size_t)r * plane + (size_t)c * (RN_ROWS + 1);
			double inv = 1.0 / (la[r] - fa[r] + 1);

			for (int y = 0; y <= RN_ROWS; y++) {
				double s = 0;

				for (int rd = fa[r]; rd <= la[r]; rd++) {
					long i = (long)rd * RN_ROWS + y;

					s += shared[i] + own[i];
				}
				dst[y] = (float)(s * inv);
			}
		}
	}
	rc = 0;
out:
	free(shared);
	free(own);
	return rc;
}

/* R->off: the offsets of each read, the pedestal and alternating columns,
 * averaged over each resultant's reads. */
static void rn_offsets(struct rnoise *R, int nr, const int *fa, const int *la,
		       const struct rnoise_par *par, const struct ramp_key *k)
{
	struct rng g;

	rng_init(&g, k->seed, rn_domain(k, DOM_RN_OFF, 0));
	for (int r = 0; r < nr; r++) {
		double inv = 1.0 / (la[r] - fa[r] + 1);

		for (int c = 0; c < RN_NCHAN; c++)
			for (int par2 = 0; par2 < 2; par2++) {
				double s = 0;

				for (int rd = fa[r]; rd <= la[r]; rd++) {
					double z[2];

					/* the pedestal, shared by the parities; the odd
					 * columns acn z apart from the even ones */
					rng_normal_fill(&g, ((uint64_t)rd * 64 + (uint64_t)c) * 2, 2, z);
					s += par->ped * z[0] + par->acn * (par2 ? 0.5 : -0.5) * z[1];
				}
				R->off[((size_t)r * RN_NCHAN + c) * 2 + par2] = (float)(s * inv);
			}
	}
}

/* R->kc: each resultant's weights on the slow part's knots (every RN_KNOT
 * reads, linear between).  0 or -1 (memory). */
static int rn_knots(struct rnoise *R, int nr, const int *fa, const int *la)
{
	if (!(R->kc = calloc((size_t)nr * (size_t)R->nknot, sizeof(double))))
		return -1;
	for (int r = 0; r < nr; r++) {
		double *kc = R->kc + (size_t)r * R->nknot, inv = 1.0 / (la[r] - fa[r] + 1);

		R->kj0[r] = fa[r] / RN_KNOT;
		R->kj1[r] = la[r] / RN_KNOT + 1;
		for (int rd = fa[r]; rd <= la[r]; rd++) {
			int j = rd / RN_KNOT;
			double f = (double)(rd % RN_KNOT) / RN_KNOT;

			kc[j] += (1 - f) * inv;
			kc[j + 1] += f * inv;
		}
	}
	return 0;
}

int rnoise_init(struct rnoise *R, const struct ramp_pattern *p, const struct rnoise_par *par,
		const struct ramp_key *k, int nlast, struct err *e)
{
	int last = nlast > p->last[p->nres - 1] ? nlast : p->last[p->nres - 1];
	/* frames enough for the reads and the next row start */
	long n = fft_length(last + 2) * RN_ROWS;
	size_t plane = (size_t)RN_NCHAN * (RN_ROWS + 1);
	int fa[RAMP_MAX_RES + 1], la[RAMP_MAX_RES + 1], nr = p->nres + 1;

	memset(R, 0, sizeof(*R));
	R->par = *par;
	R->nres = p->nres;
	R->nsamp = n;
	R->row_time = p->read_time / RN_ROWS;
	/* the resultants, and after them the reset read (read 0) */
	for (int r = 0; r < p->nres; r++) {
		fa[r] = p->first[r];
		la[r] = p->last[r];
	}
	fa[p->nres] = la[p->nres] = 0;
	R->pink = calloc((size_t)nr * plane, sizeof(float));
	R->off = calloc((size_t)nr * RN_NCHAN * 2, sizeof(float));
	if (!R->pink || !R->off || rn_pink(R, nr, fa, la, n, par, k) < 0)
		goto nomem;
	rn_offsets(R, nr, fa, la, par, k);
	/* the slow part */
	R->seed = k->seed;
	R->slow_dom = rn_domain(k, DOM_RN_SLOW, 0);
	R->nknot = last / RN_KNOT + 2;
	if (R->nknot > RN_MAX_KNOT) {
		rnoise_free(R);
		return e ? err_set(e, EXIT_INPUT, "correlated read noise: %d reads, at most %d",
				   last, (RN_MAX_KNOT - 1) * RN_KNOT - 1) : -1;
	}
	R->rho = exp(-RN_KNOT * p->read_time / par->slow_tau);
	R->s1 = par->slow * sqrt(1 - R->rho * R->rho);
	if (rn_knots(R, nr, fa, la) < 0)
		goto nomem;
	return 0;
nomem:
	rnoise_free(R);
	return e ? err_sys(e, "correlated read noise: memory") : -1;
}

void rnoise_free(struct rnoise *R)
{
	free(R->pink);
	free(R->off);
	free(R->kc);
	R->pink = NULL;
	R->off = NULL;
	R->kc = NULL;
}

/* The knots 0 .. jmax of RN_SLOW_M pixels from cell c0 on (m of them
 * real: the rest of z holds zeros or a block's old deviates, whose sums
 * nobody reads) and their resultants r0 .. r1 - 1 added to dst.  Loops of
 * a fixed count, which the compiler vectorises; the same operations in
 * the same order on every pixel, so the same numbers either way. */
#define RN_SLOW_M 128
#define SLOW_BLOCK_BODY                                                                         \
	{                                                                                       \
		double Y[RN_MAX_KNOT][RN_SLOW_M], acc[RN_SLOW_M];                               \
		for (int j = 0; j <= jmax; j++) {                                               \
			struct rng g;                                                           \
			rng_init(&g, R->seed, R->slow_dom | (uint32_t)j << 24);                 \
			rng_normal_fill(&g, c0, (size_t)m, z);                                  \
			if (!j)                                                                 \
				for (int i = 0; i < RN_SLOW_M; i++)                             \
					Y[0][i] = R->par.slow * z[i];                           \
			else                                                                    \
				for (int i = 0; i < RN_SLOW_M; i++)                             \
					Y[j][i] = R->rho * Y[j - 1][i] + R->s1 * z[i];          \
		}                                                                               \
		for (int r = r0; r < r1; r++) {                                                 \
			const double *kc = R->kc + (size_t)r * R->nknot;                        \
			float *o = dst + (size_t)(r - r0) * plane;                              \
			int j = R->kj0[r];                                                      \
			for (int i = 0; i < RN_SLOW_M; i++)                                     \
				acc[i] = kc[j] * Y[j][i];                                       \
			for (j++; j <= R->kj1[r]; j++)                                          \
				for (int i = 0; i < RN_SLOW_M; i++)                             \
					acc[i] += kc[j] * Y[j][i];                              \
			if (m == RN_SLOW_M)                                                     \
				for (int i = 0; i < RN_SLOW_M; i++)                             \
					o[i] += (float)acc[i];                                  \
			else                                                                    \
				for (int i = 0; i < m; i++)                                     \
					o[i] += (float)acc[i];                                  \
		}                                                                               \
	}

static void slow_block(const struct rnoise *R, uint32_t c0, int m, int jmax, int r0, int r1,
		       double *z, float *dst, size_t plane)
SLOW_BLOCK_BODY

#ifdef SIMD_X86
__attribute__((target("avx512f"))) static void
slow_block_avx512(const struct rnoise *R, uint32_t c0, int m, int jmax, int r0, int r1,
		  double *z, float *dst, size_t plane)
SLOW_BLOCK_BODY
#endif

void rnoise_slow_add(const struct rnoise *R, uint32_t cell0, int n, int r0, int r1, float *dst,
		     size_t plane)
{
	double z[RN_SLOW_M] = { 0 };
	int jmax = 0;
#ifdef SIMD_X86
	int wide = (simd_flags() & SIMD_AVX512) != 0;
#endif

	if (!(R->par.slow > 0) || r1 <= r0)
		return;
	for (int r = r0; r < r1; r++)
		jmax = R->kj1[r] > jmax ? R->kj1[r] : jmax;
	for (int i0 = 0; i0 < n; i0 += RN_SLOW_M) {
		int m = n - i0 < RN_SLOW_M ? n - i0 : RN_SLOW_M;
		uint32_t c0 = cell0 + (uint32_t)i0;

#ifdef SIMD_X86
		if (wide)
			slow_block_avx512(R, c0, m, jmax, r0, r1, z, dst + i0, plane);
		else
#endif
			slow_block(R, c0, m, jmax, r0, r1, z, dst + i0, plane);
	}
}

/* dst[i] += v[x & 1] + b x for the columns x = x0 + i, i < n: the plain
 * loop, and the same sums eight (sixteen) lanes at a time in GCC's vector
 * types, each lane's operations those of the plain loop (no fused
 * multiply-add), so the same floats.  Returns the columns done. */
static inline int add_span(const float v[2], float b, int x0, int n, float *dst)
{
	for (int i = 0; i < n; i++) {
		int x = x0 + i;

		dst[i] += v[x & 1] + b * (float)x;
	}
	return n;
}

#ifdef SIMD_X86
typedef float v16f __attribute__((vector_size(64)));
typedef int v16i __attribute__((vector_size(64)));

static inline __attribute__((always_inline)) int
add_span16(const float v[2], float b, int x0, int n, float *dst)
{
	const v16i lane = { 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15 };
	v16f f0, f1;
	v16i v0, v1;
	int i = 0;

	for (int q = 0; q < 16; q++) {
		f0[q] = v[0];
		f1[q] = v[1];
	}
	v0 = (v16i)f0;
	v1 = (v16i)f1;

	for (; i + 16 <= n; i += 16) {
		v16i x = lane + (x0 + i), odd = -(x & 1);
		v16f d, a = (v16f)((v0 & ~odd) | (v1 & odd));

		memcpy(&d, dst + i, sizeof(d));
		d += a + b * __builtin_convertvector(x, v16f);
		memcpy(dst + i, &d, sizeof(d));
	}
	return i;
}

__attribute__((target("avx512f"))) static int
add_span_avx512(const float v[2], float b, int x0, int n, float *dst)
{
	return add_span16(v, b, x0, n, dst);
}

__attribute__((target("avx2"))) static int
add_span_avx2(const float v[2], float b, int x0, int n, float *dst)
{
	return add_span16(v, b, x0, n, dst);
}
#endif

void rnoise_add(const struct rnoise *R, int r, int c, int y, int x0, int n, float *dst)
{
	const float *pk = R->pink + ((size_t)r * RN_NCHAN + c) * (RN_ROWS + 1) + y;
	const float *of = R->off + ((size_t)r * RN_NCHAN + c) * 2;
	/* the value at readout position j: a + b j; with x's column parity */
	float b = (pk[1] - pk[0]) / (RN_COLS + RN_OVERHEAD), a = pk[0];
	float v[2];
	int i = 0;

	if (c & 1) {            /* j = 127 - x */
		a += b * (RN_COLS - 1);
		b = -b;
	}
	v[0] = a + of[0];
	v[1] = a + of[1];
#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX512)
		i = add_span_avx512(v, b, x0, n, dst);
	else if (simd_flags() & SIMD_AVX2)
		i = add_span_avx2(v, b, x0, n, dst);
#endif
	add_span(v, b, x0 + i, n - i, dst + i);
}

void rnoise_add_frame(const struct rnoise *R, int r, int y, int fx0, int n, float *dst)
{
	int fx = fx0, end = fx0 + n;

	while (fx < end) {
		int c = fx / RN_COLS, x = fx % RN_COLS;
		int m = RN_COLS - x < end - fx ? RN_COLS - x : end - fx;

		rnoise_add(R, r, c, y, x, m, dst + (fx - fx0));
		fx += m;
	}
}

/* out[r * plane + i] += v[r][i] / gain, rounded, clipped to 16 bits */
static void dn_add(int nres, const float *v, size_t vplane, double gain, int m, uint16_t *out,
		   size_t plane)
{
	for (int r = 0; r < nres; r++) {
		uint16_t *o = out + (size_t)r * plane;
		const float *vr = v + (size_t)r * vplane;

		for (int i = 0; i < m; i++) {
			double dn = floor(o[i] + vr[i] / gain + 0.5);

			o[i] = (uint16_t)(dn < 0 ? 0 : dn > 65535 ? 65535 : dn);
		}
	}
}

void rnoise_add_amp33_dn(const struct rnoise *R, double gain, int y, uint16_t *out, size_t plane)
{
	float v[RAMP_MAX_RES][RN_COLS];

	memset(v, 0, sizeof(v));
	for (int r = 0; r < R->nres; r++)
		rnoise_add(R, r, RN_NCHAN - 1, y, 0, RN_COLS, v[r]);
	rnoise_slow_add(R, RN_AMP33_CELL + (uint32_t)y * RN_COLS, RN_COLS, 0, R->nres, v[0], RN_COLS);
	dn_add(R->nres, v[0], RN_COLS, gain, RN_COLS, out, plane);
}

/* rnoise_add_dn for resultants r0 .. r1 - 1 (r = nres: the reset read) */
static void add_dn(const struct rnoise *R, int r0, int r1, double gain, int y, int fx0, int n,
		   uint16_t *out, size_t plane)
{
	enum { M = RN_COLS * 2 };
	float v[RAMP_MAX_RES][M];

	for (int i0 = 0; i0 < n; i0 += M) {
		int m = n - i0 < M ? n - i0 : M;

		for (int r = r0; r < r1; r++) {
			memset(v[r - r0], 0, sizeof(float) * (size_t)m);
			rnoise_add_frame(R, r, y, fx0 + i0, m, v[r - r0]);
		}
		rnoise_slow_add(R, (uint32_t)y * RN_ROWS + (uint32_t)(fx0 + i0), m, r0, r1, v[0], M);
		dn_add(r1 - r0, v[0], M, gain, m, out + i0, plane);
	}
}

void rnoise_add_dn(const struct rnoise *R, double gain, int y, int fx0, int n, uint16_t *out,
		   size_t plane)
{
	add_dn(R, 0, R->nres, gain, y, fx0, n, out, plane);
}

void rnoise_add_read0_dn(const struct rnoise *R, double gain, int y, int fx0, int n, uint16_t *out)
{
	add_dn(R, R->nres, R->nres + 1, gain, y, fx0, n, out, 0);
}

int rnoise_ref_init(struct rnoise_ref *C, const struct rnoise *R, const struct ramp_pattern *p,
		    const struct ramp_det *d, const struct ramp_key *k, struct err *e)
{
	int nres = p->nres;
	size_t plane = RN_ROWS;
	uint16_t *row = malloc(sizeof(uint16_t) * (size_t)nres * plane);
	double *scr = malloc(sizeof(double) * RAMP_SCRATCH(RN_ROWS));
	double *side = malloc(sizeof(double) * (size_t)nres * RN_ROWS);
	double tbm = 0;

	memset(C, 0, sizeof(*C));
	C->nres = nres;
	C->tb = calloc((size_t)nres * 32 * 2, sizeof(double));
	C->side = calloc((size_t)nres * RN_ROWS, sizeof(double));
	if (!row || !scr || !side || !C->tb || !C->side) {
		free(row);
		free(scr);
		free(side);
		rnoise_ref_free(C);
		return e ? err_sys(e, "reference correction: memory") : -1;
	}
	ramp_scratch_init(scr);
	/* the top and bottom reference rows: per channel and parity */
	for (int yy = 0; yy < 8; yy++) {
		int y = yy < 4 ? yy : RN_ROWS - 8 + yy;

		ramp_level1_row(p, d, k, (uint32_t)y * RN_ROWS, RN_ROWS, NULL, 0, row, plane, scr);
		rnoise_add_dn(R, d->gain, y, 0, RN_ROWS, row, plane);
		for (int r = 0; r < nres; r++)
			for (int x = 0; x < RN_ROWS; x++)
				C->tb[((size_t)r * 32 + x / RN_COLS) * 2 + (x & 1)] +=
					row[(size_t)r * plane + x] / (8.0 * RN_COLS / 2);
	}
	/* the corrections keep the pedestal: their mean level stays */
	for (size_t i = 0; i < (size_t)nres * 64; i++)
		tbm += C->tb[i];
	tbm /= (double)nres * 64;
	for (size_t i = 0; i < (size_t)nres * 64; i++)
		C->tb[i] -= tbm;
	/* the left and right reference columns of every row, less the top and
	 * bottom correction of their channel */
	for (int y = 0; y < RN_ROWS; y++) {
		uint16_t *o = row;
		double level = tbm;

		ramp_level1_row(p, d, k, (uint32_t)y * RN_ROWS, 4, NULL, 0, o, plane, scr);
		ramp_level1_row(p, d, k, (uint32_t)y * RN_ROWS + RN_ROWS - 4, 4, NULL, 0, o + 4,
				plane, scr);
		rnoise_add_dn(R, d->gain, y, 0, 4, o, plane);
		rnoise_add_dn(R, d->gain, y, RN_ROWS - 4, 4, o + 4, plane);
		for (int r = 0; r < nres; r++) {
			double s = 0;

			for (int i = 0; i < 8; i++) {
				int fx = i < 4 ? i : RN_ROWS - 8 + i;

				s += o[(size_t)r * plane + i] - level -
				     C->tb[((size_t)r * 32 + fx / RN_COLS) * 2 + (fx & 1)];
			}
			side[(size_t)r * RN_ROWS + y] = s / 8;
		}
	}
	/* smoothed over rows: a running mean, shortened at the frame's ends */
	for (int r = 0; r < nres; r++) {
		const double *s = side + (size_t)r * RN_ROWS;

		for (int y = 0; y < RN_ROWS; y++) {
			int a = y - RN_SIDE_HALF < 0 ? 0 : y - RN_SIDE_HALF;
			int b = y + RN_SIDE_HALF >= RN_ROWS ? RN_ROWS - 1 : y + RN_SIDE_HALF;
			double m = 0;

			for (int i = a; i <= b; i++)
				m += s[i];
			C->side[(size_t)r * RN_ROWS + y] = m / (b - a + 1);
		}
	}
	free(row);
	free(scr);
	free(side);
	return 0;
}

void rnoise_ref_free(struct rnoise_ref *C)
{
	free(C->tb);
	free(C->side);
	C->tb = C->side = NULL;
}

/* One channel's columns lo .. hi - 1 of a resultant (lo even): oc[x] less
 * k[x & 1], clipped to 0 .. 65534, 65535 (saturated) kept; the plain loop. */
static inline int ref_span(uint16_t *oc, int lo, int hi, const int k[2])
{
	for (int x = lo; x < hi; x++) {
		int v = oc[x], w = v - k[x & 1];

		w = w < 0 ? 0 : w;
		w = w > 65534 ? 65534 : w;
		/* saturated: as it is */
		oc[x] = (uint16_t)(v == 65535 ? v : w);
	}
	return hi;
}

#ifdef SIMD_X86
typedef unsigned short v16u16 __attribute__((vector_size(32)));

/* ref_span() sixteen columns at a time: the same integers; returns the
 * first column left. */
static inline __attribute__((always_inline)) int
ref_span16(uint16_t *oc, int lo, int hi, const int k[2])
{
	const v16i kv = { k[0], k[1], k[0], k[1], k[0], k[1], k[0], k[1],
			  k[0], k[1], k[0], k[1], k[0], k[1], k[0], k[1] };
	int x = lo;

	for (; x + 16 <= hi; x += 16) {
		v16u16 h;
		v16i v, w, lt, gt, sat;

		memcpy(&h, oc + x, sizeof(h));
		v = __builtin_convertvector(h, v16i);
		w = v - kv;
		lt = w < 0;
		w &= ~lt;
		gt = w > 65534;
		w = (w & ~gt) | (65534 & gt);
		sat = v == 65535;
		w = (w & ~sat) | (v & sat);
		h = __builtin_convertvector(w, v16u16);
		memcpy(oc + x, &h, sizeof(h));
	}
	return x;
}

__attribute__((target("avx512f"))) static int
ref_span_avx512(uint16_t *oc, int lo, int hi, const int k[2])
{
	return ref_span16(oc, lo, hi, k);
}

__attribute__((target("avx2"))) static int
ref_span_avx2(uint16_t *oc, int lo, int hi, const int k[2])
{
	return ref_span16(oc, lo, hi, k);
}
#endif

void rnoise_ref_apply(const struct rnoise_ref *C, int y, uint16_t *dn, size_t plane, int nres)
{
#ifdef SIMD_X86
	int f = simd_flags();
#endif

	for (int r = 0; r < nres; r++) {
		uint16_t *o = dn + (size_t)r * plane - 4;       /* o[fx] */
		const double *tb = C->tb + (size_t)r * 64;
		double sd = C->side[(size_t)r * RN_ROWS + y];

		for (int c = 0; c < 32; c++) {
			/* floor(v - t + 0.5) = v - ceil(t - 0.5) for an integer v:
			 * one integer a column parity */
			int k[2], lo = c ? 0 : 4, hi = c == 31 ? RN_COLS - 4 : RN_COLS, x = lo;
			uint16_t *oc = o + c * RN_COLS;

			for (int q = 0; q < 2; q++)
				k[q] = (int)ceil(tb[c * 2 + q] + sd - 0.5);
#ifdef SIMD_X86
			if (f & SIMD_AVX512)
				x = ref_span_avx512(oc, lo, hi, k);
			else if (f & SIMD_AVX2)
				x = ref_span_avx2(oc, lo, hi, k);
#endif
			ref_span(oc, x, hi, k);
		}
	}
}
