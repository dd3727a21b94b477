/*
 * sersic_quick.c - the sersic-quick model: a Sérsic galaxy sampled at
 * points, with more points per pixel where the profile changes fast, then
 * convolved with the local ePSF.  The mathematics is in sersic.h.
 *
 * Cell integration: the cells within one cell of the centre (where the cusp
 * of n > 1, or a galaxy smaller than a cell, defeats any sampling) by wedges
 * from the centre (sersic_rect_rel), to 1e-4 of the cell; a cell small
 * against the profile's length scale ell (sersic_scale) from the value and
 * curvature at its centre (quick_taylor); a cell the truncation ellipse
 * cuts by the midpoint rule on an N x N grid, N = ceil(h / (QUICK_STEP
 * ell)), whose error on a smooth cell of side h is about (h/N)^2 / (24
 * ell^2), within about 1% with QUICK_STEP = 0.5; every other cell by the
 * N-point Gauss-Legendre rule in each direction, N the fewest whose error
 * for a profile of length scale ell, c_N (h / ell)^2N with
 * c_N = (N!)^4 / ((2N + 1) ((2N)!)^3), is within the midpoint rule's
 * QUICK_STEP^2 / 24 (c_1 = 1/24: one point is the midpoint rule).  Gauss's
 * rule reaches it with far fewer points: 2 x 2 up to h = 2.6 ell, where
 * the midpoint rule takes 6 x 6.  A cell that would need more than
 * QUICK_NMAX midpoints a side (a needle, q r_e far below a pixel, which
 * points would step over) goes to the wedges too, to 1e-3 of its light.
 * The measured total-flux error is below 1% for n <= 4 (BENCHMARKS.md).
 *
 * Settings: quick_settings below (each one's meaning and range), and
 * sersic.h's shared ones.
 */
#include <pthread.h>
#include <stdatomic.h>

#include "sersic.h"
#include "vmath.h"
#include "../src/simd.h"

#define QUICK_TRUNC 1e-3
#define QUICK_STEP 0.5
#define QUICK_NMAX 16
#define QUICK_TAYLOR 1
#define QUICK_NOISE_CUT 0.01
#define QUICK_NOISE_EPS 0.2
#define QUICK_PSF_CUT 0.1
#define QUICK_WING_BLOCK 4
#define QUICK_MOMENT_CUT 0.1
#define QUICK_CENTRE_CUT 0.01
#define QUICK_GAUSS 6
/* The most points of one cell's rule (quick_midpoint, quick_gauss). */
#define QUICK_PTS (QUICK_NMAX * QUICK_NMAX)
/* The largest ePSF half-width psf_rings handles (a 4x-sampled ePSF of
 * 181 samples has 22). */
#define PSF_HMAX 256

/* One ePSF node's ring sums (psf_rings), kept for the run in a list that
 * only grows at its head. */
struct quick_rings {
	const float *node;
	int hp, n;
	double ring[PSF_HMAX + 1];
	struct quick_rings *next;
};

struct quick {
	const struct wfs_host *host;
	double trunc;
	int convolve;
	double psf_core;
	int core_k;
	double taylor;          /* sersic-taylor: largest h / ell of the Taylor form */
	double noise_cut;       /* sersic-noise-cut: fraction of the pixel noise */
	double noise_eps;       /* sersic-noise-eps: the most light that cut leaves out */
	double psf_cut;         /* sersic-psf-cut: fraction of the pixel noise */
	double wing_block;      /* sersic-wing-block: side of a faint wing's blocks, pixels */
	double moment_cut;      /* sersic-moment-cut: fraction of the pixel noise */
	double centre_cut;      /* sersic-centre-cut: fraction of the pixel noise */
	double centre_abs;      /* a cell's share of it, counts/s (quick_centre) */
	double block_sb;        /* the surface brightness below which blocks are used */
	double sigma;           /* the host's pixel-sigma, counts/s per pixel */
	double gauss_t[QUICK_GAUSS];    /* gauss_tmax of each rule */
	/* node_rings' cache, read by prepare() on any thread: an entry is
	 * made whole outside the list, then put at its head under lock with
	 * release order; readers walk it from an acquire load of the head */
	_Atomic(struct quick_rings *) rings;
	pthread_mutex_t lock;
};

/*
 * The integral of the profile over a cell from its value and curvature at
 * the centre: int I = w_x w_y (I + (w_x^2 I_xx + w_y^2 I_yy) / 24), the
 * cell's sides w_x, w_y, exact to second order (the midpoint rule at one
 * point is the first term).  With rho^2 = u^2 ia2 + v^2 ib2 and
 * I = I0 exp(f), f = -b (rho^2)^(1/2n):
 *   f' = df / d rho^2 = -p / (2n rho^2),   f'' = f' (1/2n - 1) / rho^2,
 *   I_xx = I ((f'^2 + f'') (d_x rho^2)^2 + f' d_xx rho^2),
 * d_x rho^2 = 2 (u ia2 c - v ib2 s), d_xx rho^2 = 2 qa (y alike); the
 * gradient I f' grad rho^2 comes with it, for the wing's first-moment term.
 * Its error is fourth order, about (h / ell)^4 / 500 of the cell at the
 * profile's length scale ell (BENCHMARKS.md has the measured errors).  The
 * cell must hold no cusp (not near the centre) and not reach the
 * truncation ellipse.
 */
static inline double quick_taylor_at(const struct sersic_gal *g, double wx, double wy, double u,
				     double v, double r2, double p, double in, double *gx,
				     double *gy)
{
	double f1 = -0.5 * p * g->inv_n / r2, f2 = f1 * (0.5 * g->inv_n - 1.0) / r2;
	double dx = 2 * (u * g->ia2 * g->ct - v * g->ib2 * g->st);
	double dy = 2 * (u * g->ia2 * g->st + v * g->ib2 * g->ct);
	double c = f1 * f1 + f2;
	double ixx = in * (c * dx * dx + 2 * f1 * g->qa), iyy = in * (c * dy * dy + 2 * f1 * g->qc);

	*gx = in * f1 * dx;
	*gy = in * f1 * dy;
	return wx * wy * (in + (wx * wx * ixx + wy * wy * iyy) / 24.0);
}

/* The Taylor form of the cell from its centre: rho^2 there, p = b rho^(1/n)
 * and I, then quick_taylor_at. */
static double quick_taylor(const struct sersic_gal *g, double x0, double x1, double y0,
			   double y1, double *gx, double *gy)
{
	double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
	double u = g->ct * cx + g->st * cy, v = g->ct * cy - g->st * cx;
	double r2 = u * u * g->ia2 + v * v * g->ib2;
	double p = g->b * exp(0.5 * g->inv_n * log(r2));

	return quick_taylor_at(g, x1 - x0, y1 - y0, u, v, r2, p, exp(g->lni0 - p), gx, gy);
}

/* Gauss-Legendre rules of 1 to QUICK_GAUSS points on [-1/2, 1/2]: rule n's
 * nodes gauss_x[n - 1][0..n-1] and weights gauss_w (summing to 1). */
static const double gauss_x[QUICK_GAUSS][QUICK_GAUSS] = {
	{ 0 },
	{ -0.288675134594812882254574390251, 0.288675134594812882254574390251 },
	{ -0.387298334620741688517926539978, 0, 0.387298334620741688517926539978 },
	{ -0.430568155797026287612789271622, -0.169990521792428132401161714056,
	  0.169990521792428132401161714056, 0.430568155797026287612789271622 },
	{ -0.453089922969331996296843904655, -0.269234655052841545475025074600, 0,
	  0.269234655052841545475025074600, 0.453089922969331996296843904655 },
	{ -0.466234757101576013906150777246, -0.330604693233132256830699797845,
	  -0.119309593041598454315250860053, 0.119309593041598454315250860053,
	  0.330604693233132256830699797845, 0.466234757101576013906150777246 },
};
static const double gauss_w[QUICK_GAUSS][QUICK_GAUSS] = {
	{ 1 },
	{ 0.5, 0.5 },
	{ 5.0 / 18, 8.0 / 18, 5.0 / 18 },
	{ 0.173927422568726928686531974611, 0.326072577431273071313468025389,
	  0.326072577431273071313468025389, 0.173927422568726928686531974611 },
	{ 0.118463442528094543757132020359, 0.239314335249683234020645757336, 64.0 / 225,
	  0.239314335249683234020645757336, 0.118463442528094543757132020359 },
	{ 0.085662246189585172520148071086, 0.180380786524069303784916756919,
	  0.233956967286345523694935171995, 0.233956967286345523694935171995,
	  0.180380786524069303784916756919, 0.085662246189585172520148071086 },
};

/* The largest h / ell each Gauss rule takes: c_n t^2n = QUICK_STEP^2 / 24,
 * c_n = (n!)^4 / ((2n + 1) ((2n)!)^3) (the rule's error term for a
 * profile whose k-th derivative is ell^-k times its value). */
static double gauss_tmax(int n)
{
	double f = 1, f2 = 1;

	for (int k = 1; k <= n; k++)
		f *= k;
	for (int k = 1; k <= 2 * n; k++)
		f2 *= k;
	double c = f * f * f * f / ((2 * n + 1) * f2 * f2 * f2);
	return pow(QUICK_STEP * QUICK_STEP / (24 * c), 1.0 / (2 * n));
}

/* p = b rho^(1/n) and I = exp(lni0 - p) at n points from rho^2 (vmath.h's
 * exp and log: the same bytes in the vector code and the plain), inlined
 * into a plain copy and one built for AVX2 and FMA. */
static inline __attribute__((always_inline)) void
quick_profile_loop(int n, const double *restrict r2, double b, double h, double lni0,
		   double *restrict p, double *restrict in)
{
	for (int j = 0; j < n; j++) {
		p[j] = b * vm_exp(h * vm_log(r2[j]));
		in[j] = vm_exp(lni0 - p[j]);
	}
}

static void quick_profile_plain(int n, const double *restrict r2, double b, double h,
				double lni0, double *restrict p, double *restrict in)
{
	quick_profile_loop(n, r2, b, h, lni0, p, in);
}

#ifdef SIMD_X86
__attribute__((target("avx2,fma"))) static void
quick_profile_avx2(int n, const double *restrict r2, double b, double h, double lni0,
		   double *restrict p, double *restrict in)
{
	quick_profile_loop(n, r2, b, h, lni0, p, in);
}

/* Eight values per instruction: the same operations, so the same bytes. */
__attribute__((target("avx512f,avx2,fma"))) static void
quick_profile_avx512(int n, const double *restrict r2, double b, double h, double lni0,
		     double *restrict p, double *restrict in)
{
	quick_profile_loop(n, r2, b, h, lni0, p, in);
}
#endif

static void (*quick_profile)(int n, const double *restrict r2, double b, double h, double lni0,
			     double *restrict p, double *restrict in) = quick_profile_plain;

/* The profile (sersic_sb) at np points (dx[k], dy[k]) into v[k], those
 * inside the truncation and off the centre at once through quick_profile
 * (vmath.h's exp and log, in vector code where the CPU has it) when there
 * are at least four of them. */
static void quick_sb_points(const struct sersic_gal *g, int np, double *dx, double *dy, double *v)
{
	double r2[QUICK_PTS], pw[QUICK_PTS], in[QUICK_PTS];
	int at[QUICK_PTS], nf = 0;

	for (int k = 0; k < np; k++) {
		double r = sersic_rho2(g, dx[k], dy[k]);

		if (r >= g->rho_t2) {
			v[k] = 0;
		} else if (r <= 0) {
			v[k] = exp(g->lni0);
		} else {
			r2[nf] = r;
			at[nf++] = k;
		}
	}
	if (nf < 4) {
		/* fewer than a vector's four: libm's, cheaper one by one */
		for (int j = 0; j < nf; j++)
			v[at[j]] = exp(g->lni0 - g->b * exp(0.5 * g->inv_n * log(r2[j])));
		return;
	}
	quick_profile(nf, r2, g->b, 0.5 * g->inv_n, g->lni0, pw, in);
	for (int j = 0; j < nf; j++)
		v[at[j]] = in[j];
}

static double quick_gauss(const struct sersic_gal *g, double x0, double x1, double y0,
			  double y1, int n)
{
	double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1), wx = x1 - x0, wy = y1 - y0, s = 0;
	const double *nx = gauss_x[n - 1], *nw = gauss_w[n - 1];
	double dx[QUICK_GAUSS * QUICK_GAUSS], dy[QUICK_GAUSS * QUICK_GAUSS], v[QUICK_GAUSS * QUICK_GAUSS];

	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			dx[j * n + i] = cx + wx * nx[i];
			dy[j * n + i] = cy + wy * nx[j];
		}
	quick_sb_points(g, n * n, dx, dy, v);
	for (int j = 0; j < n; j++) {
		double r = 0;

		for (int i = 0; i < n; i++)
			r += nw[i] * v[j * n + i];
		s += nw[j] * r;
	}
	return s * wx * wy;
}

/* sersic_midpoint's rule, its points through quick_sb_points. */
static double quick_midpoint(const struct sersic_gal *g, double x0, double x1, double y0,
			     double y1, int n)
{
	double sx = (x1 - x0) / n, sy = (y1 - y0) / n, s = 0;
	double dx[QUICK_PTS], dy[QUICK_PTS], v[QUICK_PTS];

	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			dx[j * n + i] = x0 + (i + 0.5) * sx;
			dy[j * n + i] = y0 + (j + 0.5) * sy;
		}
	quick_sb_points(g, n * n, dx, dy, v);
	for (int k = 0; k < n * n; k++)
		s += v[k];
	return s * sx * sy;
}

/* The length scale of the cell at a lower bound on rho, the cell's
 * distance over r_e, which errs short: what sets the cell's rule. */
static double quick_scale_near(const struct sersic_gal *g, double x0, double x1, double y0,
			       double y1)
{
	double dx = x0 > 0 ? x0 : x1 < 0 ? -x1 : 0, dy = y0 > 0 ? y0 : y1 < 0 ? -y1 : 0;

	return sersic_cell_scale(g, sqrt(dx * dx + dy * dy) / g->re, x0, x1, y0, y1);
}

/* A cell's integral away from the centre and the needle cases, t its size
 * over quick_scale_near: the Taylor form where t is at most the
 * sersic-taylor setting and the cell stays inside the truncation ellipse
 * (*taylor set to 1, the gradient at the centre in gx, gy); else, inside
 * the ellipse, the Gauss rule of the fewest points for t (more than
 * QUICK_GAUSS: the largest); a cell the ellipse cuts, whose step no smooth
 * rule sees, by the midpoint rule on N x N points. */
static double quick_points(const struct sersic_gal *g, const struct quick *p, double x0,
			   double x1, double y0, double y1, double t, int *taylor,
			   double *gx, double *gy)
{
	*taylor = 0;
	if (p && sersic_rho2_max(g, x0, x1, y0, y1) < g->rho_t2) {
		if (t <= p->taylor) {
			*taylor = 1;
			return quick_taylor(g, x0, x1, y0, y1, gx, gy);
		}
		int k = 1;

		while (k < QUICK_GAUSS && !(t <= p->gauss_t[k - 1]))
			k++;
		return quick_gauss(g, x0, x1, y0, y1, k);
	}
	double n = ceil(t / QUICK_STEP);
	return quick_midpoint(g, x0, x1, y0, y1, n < 1 ? 1 : n > QUICK_NMAX ? QUICK_NMAX : (int)n);
}

/*
 * The absolute floor, a fraction of the flux, to which the cells next to
 * the centre are integrated by wedges (sersic-centre-cut): the cut times
 * the pixel noise shared among the 4 x 4 cells that can lie there, so no
 * pixel, and no galaxy's flux, moves by more than the cut (as far as the
 * quadrature's own error estimates go); where it is looser than
 * 1e-4 of a cell's light (a galaxy below the noise) the wedges take the
 * 7-point rule first (sersic_rect_rel).
 */
static double quick_centre(const struct sersic_gal *g, const void *opt)
{
	const struct quick *p = opt;

	return p && p->centre_abs > 0 && g->flux > 0 ? fmax(1e-12, p->centre_abs / g->flux) : 1e-12;
}

static double quick_cell(const struct sersic_gal *g, const void *opt,
			 double x0, double x1, double y0, double y1, double h)
{
	double rmin = sersic_rho_min(g, x0, x1, y0, y1), gx, gy;
	int taylor;

	if (rmin >= g->rho_t)
		return 0.0;
	if (sersic_near_centre(x0, x1, y0, y1, h))
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-4, quick_centre(g, opt), 1);
	/* More points than QUICK_NMAX even at the cell's nearest point: a
	 * needle or a galaxy far below a pixel, which points would miss. */
	if (!(ceil(h / (QUICK_STEP * sersic_cell_scale(g, rmin, x0, x1, y0, y1))) <= QUICK_NMAX))
		return sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-3, 1e-12, 0);
	return quick_points(g, opt, x0, x1, y0, y1, h / quick_scale_near(g, x0, x1, y0, y1),
			    &taylor, &gx, &gy);
}

/* A wing pixel quick_wing_row does not take in its vector run: quick_cell and the smoothness test
 * and gradient of sersic_render_common in one pass, sharing rho_min, the
 * length scale at it and, for the Taylor form, the profile at the centre. */
static int quick_wing(const struct sersic_gal *g, const void *opt, double x0, double x1,
		      double y0, double y1, double *v, double *gx, double *gy)
{
	double rmin = sersic_rho_min(g, x0, x1, y0, y1);
	int taylor = 0;

	*gx = *gy = 0;
	if (rmin >= g->rho_t) {
		*v = 0;
		return 0;
	}
	double ell, near = 0;

	if (sersic_near_centre(x0, x1, y0, y1, 1.0)) {
		ell = sersic_cell_scale(g, rmin, x0, x1, y0, y1);
		*v = sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-4, quick_centre(g, opt), 1);
	} else {
		/* For n >= 1 the length scale grows with rho, so where the one
		 * at the lower bound passes both tests below (the needle's and
		 * the smooth light's), the one at rho_min does too and is not
		 * needed. */
		near = quick_scale_near(g, x0, x1, y0, y1);
		ell = g->n >= 1 && g->ib2 >= g->ia2 && near >= 1.0 / (QUICK_STEP * QUICK_NMAX) &&
		      near >= SERSIC_SMOOTH ? near : sersic_cell_scale(g, rmin, x0, x1, y0, y1);
		if (!(ceil(1.0 / (QUICK_STEP * ell)) <= QUICK_NMAX))
			*v = sersic_rect_rel(g, x0, x1, y0, y1, rmin, 1e-3, 1e-12, 0);
		else
			*v = quick_points(g, opt, x0, x1, y0, y1, 1.0 / near, &taylor, gx, gy);
	}
	if (*v == 0 || !(ell >= SERSIC_SMOOTH)) {
		*gx = *gy = 0;
		return 0;
	}
	if (!taylor)
		sersic_grad(g, 0.5 * (x0 + x1), 0.5 * (y0 + y1), gx, gy);
	return 1;
}

/*
 * The fast wing pixels (stamp_setup, quick_wing_row).  quick_wing tests the
 * profile's length scale (sersic_cell_scale) of a pixel against three
 * levels: the Taylor form's (1 / sersic-taylor), the needle's and the
 * smooth light's.  The scale sersic_scale(rho) = minor / sqrt(A rho^al +
 * B rho^be), al = 2/n - 2, be = 1/n - 2, falls and rises at most once:
 * for n >= 1 both powers fall, so it only grows; for n < 1 the sum has one
 * least value, at rho^(1/n) = -B be / (A al) (none for n <= 1/2, where it
 * only falls).  So the scale passes all three levels on one interval of
 * rho, found here once a stamp by bisection; its ends' squares go to
 * g->method_lo2, method_hi2 (empty: lo2 infinite).  A pixel whose lower
 * bound on rho, (distance / r_e), and whose largest rho both lie in it,
 * away from the centre and inside the truncation ellipse, holds every rho
 * the tests look at inside it, so passes them all: it is the Taylor form
 * with its gradient, and quick_wing_row takes a row's such pixels
 * together.
 */
static double quick_bisect(const struct sersic_gal *g, double lo, double hi, double level,
			   int rising)
{
	/* the end of [lo, hi] where the scale passes level, moved in until
	 * the interval is 1e-12 of it */
	for (int it = 0; it < 100 && hi - lo > 1e-12 * hi; it++) {
		double mid = 0.5 * (lo + hi);

		if ((sersic_scale(g, mid) >= level) == rising)
			hi = mid;
		else
			lo = mid;
	}
	return rising ? hi : lo;
}

static void quick_stamp_setup(struct sersic_gal *g, const void *opt)
{
	const struct quick *p = opt;
	double level = fmax(fmax(1.0 / (QUICK_STEP * QUICK_NMAX), SERSIC_SMOOTH),
			    p->taylor > 0 ? 1.0 / p->taylor : INFINITY);
	double top = g->rho_t, peak = top, lo, hi;

	g->method_lo2 = INFINITY;
	g->method_hi2 = 0;
	if (!(level < INFINITY) || !(g->ib2 >= g->ia2) || !(g->n > 0))
		return;
	if (g->n < 1) {
		double al = 2 * g->inv_n - 2, be = g->inv_n - 2;
		double a = g->b * g->inv_n, bb = a * (g->inv_n - 1);

		peak = be < 0 ? exp(g->n * log(-bb * be / (a * a * al))) : 0;
		peak = peak < top ? peak : top;
	}
	if (!(sersic_scale(g, peak) >= level))
		return;
	lo = sersic_scale(g, 0) >= level ? 0 : quick_bisect(g, 0, peak, level, 1);
	hi = sersic_scale(g, top) >= level ? top : quick_bisect(g, peak, top, level, 0);
	g->method_lo2 = lo * lo;
	g->method_hi2 = hi * hi;
}

/* The pixels of a row taken at once, in pieces of QUICK_RUN. */
#define QUICK_RUN 64

static void quick_wing_row(const struct sersic_gal *g, const void *opt, int y, int xa, int xb,
			   double *img, double *gxi, double *gyi, double *lpi, int *any, int *rough)
{
	double y0 = y - 0.5 - g->yc, y1 = y + 0.5 - g->yc, cy = 0.5 * (y0 + y1);
	double dy = y0 > 0 ? y0 : y1 < 0 ? -y1 : 0;
	int ny = y0 - 1.0 <= 0 && y1 + 1.0 >= 0;        /* the row is near the centre's */
	double u[QUICK_RUN], v[QUICK_RUN], r2[QUICK_RUN], pw[QUICK_RUN], in[QUICK_RUN];
	int at[QUICK_RUN];

	for (int a = xa; a <= xb; a += QUICK_RUN) {
		int e = xb - a < QUICK_RUN - 1 ? xb : a + QUICK_RUN - 1, nf = 0;

		for (int x = a; x <= e; x++) {
			double x0 = x - 0.5 - g->xc, x1 = x + 0.5 - g->xc;
			double dx = x0 > 0 ? x0 : x1 < 0 ? -x1 : 0, rmax2;

			if ((dx * dx + dy * dy) * g->ia2 >= g->method_lo2 &&
			    !(ny && x0 - 1.0 <= 0 && x1 + 1.0 >= 0) &&
			    (rmax2 = sersic_rho2_max(g, x0, x1, y0, y1)) < g->rho_t2 &&
			    rmax2 <= g->method_hi2) {
				double cx = 0.5 * (x0 + x1);

				u[nf] = g->ct * cx + g->st * cy;
				v[nf] = g->ct * cy - g->st * cx;
				r2[nf] = u[nf] * u[nf] * g->ia2 + v[nf] * v[nf] * g->ib2;
				at[nf++] = x;
				continue;
			}
			double val, gx, gy;
			int smooth = quick_wing(g, opt, x0, x1, y0, y1, &val, &gx, &gy);

			sersic_wing_put(img, gxi, gyi, lpi, (size_t)(x - xa), val, gx, gy, smooth, any, rough);
		}
		quick_profile(nf, r2, g->b, 0.5 * g->inv_n, g->lni0, pw, in);
		for (int j = 0; j < nf; j++) {
			double gx, gy, val = quick_taylor_at(g, 1.0, 1.0, u[j], v[j], r2[j], pw[j], in[j],
							     &gx, &gy);

			if (val == 0)
				gx = gy = 0;
			sersic_wing_put(img, gxi, gyi, lpi, (size_t)(at[j] - xa), val, gx, gy, 1, any, rough);
		}
	}
}

/*
 * A block of B x B wing pixels (sersic_method.block_fn, sersic-wing-block):
 * dark when the truncation ellipse misses it; integrated as one cell by the
 * Taylor form and spread over its pixels when the truncation does not cut
 * it, it holds no cusp, the profile's length scale is at least B (and
 * B / ell within sersic-taylor) and its surface brightness is nowhere above
 * sersic-noise-cut times the pixel noise.  There a pixel's linear share
 * errs by the curvature over 1.5 pixels, under 1/8 of its value (ell >= 4)
 * and so under 1/800 of the noise; the block's sum is the Taylor integral.
 */
static int quick_block(const struct sersic_gal *g, const void *opt, double x0, double x1,
		       double y0, double y1, double *v, double *gx, double *gy)
{
	const struct quick *p = opt;
	double rmin = sersic_rho_min(g, x0, x1, y0, y1), h = fmax(x1 - x0, y1 - y0);

	if (rmin >= g->rho_t)
		return -1;
	if (!(p->block_sb > 0) || !(rmin > 0) || sersic_near_centre(x0, x1, y0, y1, 1.0) ||
	    sersic_rho2_max(g, x0, x1, y0, y1) >= g->rho_t2 ||
	    !(h <= fmin(p->taylor, 1.0) * sersic_cell_scale(g, rmin, x0, x1, y0, y1)) ||
	    !(exp(g->lni0 - g->b * exp(log(rmin) / g->n)) <= p->block_sb))
		return 0;
	*v = quick_taylor(g, x0, x1, y0, y1, gx, gy);
	return 1;
}

/* The vector profile (AVX-512 or AVX2 with FMA) where the CPU has it and
 * simd_flags() allows it (WFISCENE_NO_SIMD=avx512 keeps AVX2; the tests
 * compare them): chosen once per process, as a run with
 * several exposures makes a state per exposure while others draw. */
static pthread_once_t quick_profile_once = PTHREAD_ONCE_INIT;

static void quick_profile_choose(void)
{
#ifdef SIMD_X86
	if ((simd_flags() & (SIMD_AVX2 | SIMD_FMA)) == (SIMD_AVX2 | SIMD_FMA))
		quick_profile = simd_flags() & SIMD_AVX512 ? quick_profile_avx512 : quick_profile_avx2;
#endif
}

static int quick_init(const struct wfs_host *host, void **state)
{
	pthread_once(&quick_profile_once, quick_profile_choose);
	struct quick *p = calloc(1, sizeof(*p));

	if (!p)
		return host->error(host->ctx, "out of memory");
	p->host = host;
	pthread_mutex_init(&p->lock, NULL);
	if (sersic_setting_num(host, "sersic-trunc", 1e-12, 0.5, QUICK_TRUNC, &p->trunc) ||
	    sersic_setting_num(host, "psf-core", 0, 1e3, SERSIC_PSF_CORE, &p->psf_core) ||
	    sersic_setting_num(host, "sersic-taylor", 0, 4, QUICK_TAYLOR, &p->taylor) ||
	    sersic_setting_num(host, "sersic-noise-cut", 0, 1, QUICK_NOISE_CUT, &p->noise_cut) ||
	    sersic_setting_num(host, "sersic-noise-eps", 0, 0.5, QUICK_NOISE_EPS, &p->noise_eps) ||
	    sersic_setting_num(host, "sersic-psf-cut", 0, 10, QUICK_PSF_CUT, &p->psf_cut) ||
	    sersic_setting_num(host, "sersic-wing-block", 1, 16, QUICK_WING_BLOCK, &p->wing_block) ||
	    sersic_setting_num(host, "sersic-moment-cut", 0, 10, QUICK_MOMENT_CUT, &p->moment_cut) ||
	    sersic_setting_num(host, "sersic-centre-cut", 0, 10, QUICK_CENTRE_CUT, &p->centre_cut) ||
	    sersic_setting_core(host, &p->core_k) ||
	    sersic_setting_convolve(host, &p->convolve)) {
		pthread_mutex_destroy(&p->lock);
		free(p);
		return -1;
	}
	const char *ps = host->setting ? host->setting(host->ctx, "pixel-sigma") : NULL;
	p->sigma = ps ? strtod(ps, NULL) : 0;
	if (!(p->sigma > 0) || !isfinite(p->sigma))
		p->sigma = 0;
	if (p->wing_block != floor(p->wing_block)) {
		double b = p->wing_block;

		pthread_mutex_destroy(&p->lock);
		free(p);
		return host->error(host->ctx, "setting sersic-wing-block: %g is not a whole number of pixels", b);
	}
	p->block_sb = p->noise_cut * p->sigma;
	/* at most 4 x 4 cells lie next to the centre (sersic_near_centre: a
	 * centre on a cell's corner), all in one pixel when it is the
	 * pixel's centre */
	p->centre_abs = p->centre_cut * p->sigma / 16;
	for (int k = 0; k < QUICK_GAUSS; k++)
		p->gauss_t[k] = gauss_tmax(k + 1);
	*state = p;
	return 0;
}

static void quick_fini(void *state)
{
	struct quick *p = state;

	for (struct quick_rings *r = atomic_load(&p->rings), *next; r; r = next) {
		next = r->next;
		free(r);
	}
	pthread_mutex_destroy(&p->lock);
	free(p);
}

/*
 * The ePSF's samples at whole-pixel offsets (dx, dy) from its centre summed
 * over squares: ring[h] the sum over max(|dx|, |dy|) = h, for h = 0..hp.
 * Their running sum is the light the ePSF carries within half-width h.
 * The sums are linear in the nodes' weights, so they are kept for each
 * node the run meets (node_rings) and blended with the galaxy's weights:
 * four times hp + 1 products a galaxy instead of (2 hp + 1)^2 blended
 * samples.  Only prepare() reads them, on whichever thread runs it.
 */
static const struct quick_rings *rings_find(const struct quick_rings *r, const float *node,
					    int hp, int n)
{
	for (; r; r = r->next)
		if (r->node == node && r->hp == hp && r->n == n)
			return r;
	return NULL;
}

static const double *node_rings(struct quick *p, const struct wfs_epsf *e, int k, int hp)
{
	const float *node = e->node[k];
	const struct quick_rings *had;
	struct quick_rings *r, *head;
	int over = e->over;

	if ((had = rings_find(atomic_load_explicit(&p->rings, memory_order_acquire), node, hp, e->n)))
		return had->ring;
	if (!(r = malloc(sizeof(*r))))
		return NULL;
	r->node = node;
	r->hp = hp;
	r->n = e->n;
	for (int h = 0; h <= hp; h++)
		r->ring[h] = 0;
	for (int dy = -hp; dy <= hp; dy++)
		for (int dx = -hp; dx <= hp; dx++) {
			int h = abs(dx) > abs(dy) ? abs(dx) : abs(dy);

			r->ring[h] += node[(size_t)(e->centre + over * dy) * e->n + e->centre + over * dx];
		}
	/* another thread may have put the same sums in meanwhile: keep one */
	pthread_mutex_lock(&p->lock);
	head = atomic_load_explicit(&p->rings, memory_order_relaxed);
	if ((had = rings_find(head, node, hp, e->n))) {
		free(r);
	} else {
		r->next = head;
		atomic_store_explicit(&p->rings, r, memory_order_release);
		had = r;
	}
	pthread_mutex_unlock(&p->lock);
	return had->ring;
}

static int psf_rings(struct quick *p, const struct wfs_epsf *e, double *ring, int hp)
{
	for (int h = 0; h <= hp; h++)
		ring[h] = 0;
	for (int k = 0; k < 4; k++) {
		const double *nr;

		if (e->weight[k] == 0)
			continue;
		if (!(nr = node_rings(p, e, k, hp)))
			return p->host->error(p->host->ctx, "out of memory");
		for (int h = 0; h <= hp; h++)
			ring[h] += e->weight[k] * nr[h];
	}
	return 0;
}

/*
 * The cut of the ePSF by the noise (sersic-psf-cut): the smallest
 * half-width h at which the light the ePSF would still carry beyond h, the
 * galaxy's flux times the absolute values of its rings beyond h, is at most
 * psf_cut times the noise of one pixel.  That light is less than the cut
 * in every pixel, and all of it together is too; render() scales the
 * ePSF within h to its whole light (AUX_PSFALL), so
 * the flux stays whole and no pixel moves by more than the cut.  A faint
 * galaxy is thus convolved with the part of the ePSF its light is seen
 * through, as a faint star's box is cut (psf-box=adaptive); a bright one
 * keeps all of it.
 */
static int quick_psf_cut(struct quick *p, struct wfs_source *src)
{
	struct wfs_epsf e;
	double ring[PSF_HMAX + 1], beyond[PSF_HMAX + 2];
	int hp, h;

	if (!p->convolve || !(p->psf_cut > 0) || !(p->sigma > 0) || !(src->flux > 0))
		return 0;
	if (sersic_epsf(p->host, src, &e))
		return -1;
	hp = sersic_psf_half(&e);
	if (hp > PSF_HMAX)
		return 0;
	if (psf_rings(p, &e, ring, hp) < 0)
		return -1;
	beyond[hp + 1] = 0;
	for (h = hp; h >= 0; h--)
		beyond[h] = beyond[h + 1] + fabs(ring[h]);
	/* never inside the core's pixels and one beyond (sersic_core_add) */
	for (h = p->core_k + 1; h < hp; h++)
		if (src->flux * beyond[h + 1] <= p->psf_cut * p->sigma)
			break;
	if (h < hp) {
		double all = 0;

		for (int k = 0; k <= hp; k++)
			all += ring[k];
		if (all > 0) {
			src->aux[AUX_PSFH] = h;
			src->aux[AUX_PSFALL] = all;
		}
	}
	return 0;
}

/* The largest half-light radius the quick model draws, pixels (31 degrees
 * at 0.11"): beyond some 1e7 its sums lose the profile's centre to
 * cancellation (a dip of 2 % at 1e7, negative pixels at 1e9), where
 * sersic-precise stays exact. */
#define QUICK_RE_MAX 1e6

static int quick_prepare(void *state, struct wfs_source *src)
{
	struct quick *p = state;
	double re = src->param[SERSIC_RE];

	if (re > QUICK_RE_MAX && isfinite(re))
		return p->host->error(p->host->ctx, "column 're': %.9g pixels is beyond what "
				      "--sersic quick draws (at most %g pixels, 31 degrees); "
				      "--sersic precise draws it", re, QUICK_RE_MAX);
	if (sersic_prepare_common(p->host, src, p->trunc, p->noise_cut * p->sigma, p->noise_eps) < 0)
		return -1;
	sersic_keep_sca_light(src);
	return quick_psf_cut(p, src);
}

static int quick_footprint(void *state, const struct wfs_source *src, struct wfs_box *box)
{
	struct quick *p = state;

	return sersic_footprint_common(p->host, src, box, p->convolve, p->core_k);
}

static int quick_render(void *state, void *tstate, void *thread,
			const struct wfs_source *src, const struct wfs_window *win)
{
	struct quick *p = state;
	struct sersic_method m = { quick_cell, p, p->convolve, p->psf_core, p->core_k,
				   quick_block, (int)p->wing_block, quick_wing_row, quick_stamp_setup,
				   p->moment_cut * p->sigma };

	return sersic_render_common(p->host, thread, src, win, &m);
}

static int quick_reach(void *state, const struct wfs_source *src, double *pixels)
{
	struct quick *p = state;

	return sersic_reach_common(p->host, src, p->trunc, p->convolve, p->core_k, pixels);
}

static const struct wfs_setting quick_settings[] = {
	{ "sersic-trunc", SERSIC_STR(QUICK_TRUNC), "number from 1e-12 to 0.5",
	  "fraction of the light allowed beyond the truncation radius" },
	{ "sersic-noise-cut", SERSIC_STR(QUICK_NOISE_CUT), "number from 0 to 1",
	  "cut each galaxy where its surface brightness falls below this fraction of the pixel noise, leaving out at most 1% of its light (more for faint galaxies: sersic-noise-eps), put back by renormalising (0: off)" },
	{ "sersic-noise-eps", SERSIC_STR(QUICK_NOISE_EPS), "number from 0 to 0.5",
	  "the most light the cut by sersic-noise-cut may leave out of a galaxy faint enough that renormalising raises none of its pixels by more than that cut (0.01 or less: 1% for every galaxy)" },
	{ "sersic-psf-cut", SERSIC_STR(QUICK_PSF_CUT), "number from 0 to 10",
	  "convolve each galaxy with the ePSF out to where the light left beyond is below this fraction of the noise summed over its pixels, that light put back by renormalising (0: the whole ePSF)" },
	{ "sersic-wing-block", SERSIC_STR(QUICK_WING_BLOCK), "whole number from 1 to 16",
	  "wing pixels fainter than sersic-noise-cut of the pixel noise, where the profile is smooth, are integrated in blocks of this many pixels a side and spread linearly over them (1: pixel by pixel)" },
	{ "sersic-moment-cut", SERSIC_STR(QUICK_MOMENT_CUT), "number from 0 to 10",
	  "leave out a galaxy's first-moment terms (its gradient through the ePSF's) where they can add no pixel more than this fraction of the pixel noise (0: always drawn)" },
	{ "sersic-centre-cut", SERSIC_STR(QUICK_CENTRE_CUT), "number from 0 to 10",
	  "integrate the cells next to a galaxy's centre to within this fraction of the pixel noise in any pixel, where that is looser than 1e-4 of their light (0: always 1e-4)" },
	{ "sersic-taylor", SERSIC_STR(QUICK_TAYLOR), "number from 0 to 4",
	  "cells with pixel size over the profile's length scale up to this are integrated from the value and curvature at their centre (0: points only)" },
	SERSIC_SETTINGS,
};

static const struct wfs_model quick_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "sersic-quick",
	.summary = "Sérsic galaxy, sampled with a sub-sampled core, convolved with the ePSF",
	.columns = sersic_columns,
	.ncolumns = SERSIC_NCOL,
	.init = quick_init,
	.fini = quick_fini,
	.prepare = quick_prepare,
	.footprint = quick_footprint,
	.render = quick_render,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = quick_settings,
	.nsettings = (int)(sizeof(quick_settings) / sizeof(quick_settings[0])),
	.reach = quick_reach,
	.flags = WFS_PARALLEL_PREPARE,
	.roman_type = "SER",
	.column_roles = sersic_roles,
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &quick_model : NULL;
}
