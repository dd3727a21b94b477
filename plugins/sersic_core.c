/*
 * sersic_core.c - the Sérsic mathematics both Sérsic plugins link in: the
 * regularised incomplete gamma functions, b_n, truncation, a galaxy
 * unpacked for integration, the exact integral over a rectangle by
 * wedges, and prepare(), footprint(), reach() and the settings they share.
 * The profile and its notation are sersic.h's.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sersic.h"

const struct wfs_column sersic_columns[SERSIC_NCOL] = {
	{ "n", NAN, 1, "Sérsic index, 0.05 to 20 (1 exponential disc, 4 de Vaucouleurs)" },
	{ "re", NAN, 1, "half-light radius along the major axis, pixels" },
	{ "phi", 0.0, 0, "orientation, degrees: 0 = major axis along +y, increasing toward -x" },
	{ "ratio", 1.0, 0, "axis ratio b/a, in (0, 1]" },
};

const int sersic_roles[SERSIC_NCOL] = {
	WFS_ROLE_SERSIC_INDEX, WFS_ROLE_HALF_LIGHT, WFS_ROLE_ANGLE, WFS_ROLE_AXIS_RATIO
};

/* ------------------------------------------------------------------ */
/* Regularised incomplete gamma functions.                             */

/* ln Gamma(a), a > 0.  lgamma() stores the sign in the global signgam, a
 * data race between the workers that render galaxies at once; lgamma_r
 * keeps it in a local. */
static inline double sersic_lgamma(double a)
{
	int sign;

	return lgamma_r(a, &sign);
}

/*
 * P(a, x) and Q(a, x) = 1 - P, each computed directly (never as 1 minus the
 * other) so the small one keeps full relative precision: the power series
 *   P = x^a e^-x / Gamma(a + 1) sum_k x^k / ((a + 1) ... (a + k))
 * converges fast for x < a + 1, and the continued fraction
 *   Q = x^a e^-x / Gamma(a) * 1 / (x + 1 - a - 1(1 - a) / (x + 3 - a - ...))
 * (evaluated by the modified Lentz method) for x >= a + 1.
 */
static double sersic_gamma_series(double a, double x, double lga)
{
	double term = 1.0 / a, sum = term;

	for (int k = 1; k < 10000; k++) {
		term *= x / (a + k);
		sum += term;
		if (fabs(term) < fabs(sum) * 1e-17)
			break;
	}
	return sum * exp(a * log(x) - x - lga);
}

static double sersic_gamma_cfrac(double a, double x, double lga)
{
	const double tiny = 1e-300;
	double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;

	for (int i = 1; i < 10000; i++) {
		double an = -i * (i - a);
		b += 2.0;
		d = an * d + b;
		if (fabs(d) < tiny)
			d = tiny;
		c = b + an / c;
		if (fabs(c) < tiny)
			c = tiny;
		d = 1.0 / d;
		double del = d * c;
		h *= del;
		/* two ulp: for x above ~1e16, b = x + 1 - a has lost its 1 and
		 * del never reaches 1 exactly (a 1e-16 test ran 10^4 steps) */
		if (fabs(del - 1.0) < 2.5e-16)
			break;
	}
	return exp(a * log(x) - x - lga) * h;
}

static double sersic_gamma_p_lg(double a, double lga, double x)
{
	if (!(x > 0))
		return 0.0;
	if (isinf(x))
		return 1.0;
	return x < a + 1.0 ? sersic_gamma_series(a, x, lga) : 1.0 - sersic_gamma_cfrac(a, x, lga);
}

/* Q(a, x), given lga = ln Gamma(a) (a galaxy's 2n is the same in every
 * call: struct sersic_gal keeps it). */
static double sersic_gamma_q_lg(double a, double lga, double x)
{
	if (!(x > 0))
		return 1.0;
	if (isinf(x))
		return 0.0;
	return x < a + 1.0 ? 1.0 - sersic_gamma_series(a, x, lga) : sersic_gamma_cfrac(a, x, lga);
}

static double sersic_gamma_q(double a, double x)
{
	return sersic_gamma_q_lg(a, sersic_lgamma(a), x);
}

/* d P(a, x) / dx = x^(a-1) e^-x / Gamma(a). */
static double sersic_gamma_pdf_lg(double a, double lga, double x)
{
	return x > 0 ? exp((a - 1.0) * log(x) - x - lga) : 0.0;
}

/*
 * Solve P(a, x) = p (p <= 1/2) or Q(a, x) = 1 - p (p > 1/2) for x: Newton's
 * method on the smaller of the two tails, in logarithms (so the step is
 * well scaled even where the tail is 1e-12), kept inside a bracket that
 * shrinks with every evaluation and bisected when Newton leaves it.
 * x0 is the starting guess.  Converges to a few ulp in < 10 steps from the
 * series starting points used below.
 */
static double sersic_gamma_inv(double a, double tail, int upper, double x0)
{
	/* Q(a, a + 60 + 60 sqrt(a)) < 1e-25, below any tail asked for. */
	double lo = 0.0, hi = a + 60.0 + 60.0 * sqrt(a), x = x0;
	double target = log(tail), lga = sersic_lgamma(a);      /* once, not twice a step */

	if (!(x > lo && x < hi))
		x = 0.5 * (lo + hi);
	for (int it = 0; it < 200; it++) {
		double t = upper ? sersic_gamma_q_lg(a, lga, x) : sersic_gamma_p_lg(a, lga, x);
		double f = log(t) - target;
		/* P rises and Q falls with x: move the bracket. */
		if ((f > 0) == !upper)
			hi = x;
		else
			lo = x;
		double dlog = sersic_gamma_pdf_lg(a, lga, x) / t * (upper ? -1.0 : 1.0);
		double nx = x - f / dlog;
		if (!(nx > lo && nx < hi) || !isfinite(nx))
			nx = 0.5 * (lo + hi);
		if (fabs(nx - x) <= 1e-15 * x || hi - lo <= 1e-15 * hi)
			return nx;
		x = nx;
	}
	return x;
}

/*
 * b_n: the root of P(2n, b) = 1/2.  Start from the asymptotic series of
 * Ciotti & Bertin (1999), b ~ 2n - 1/3 + 4/(405 n) + 46/(25515 n^2)
 * + 131/(1148175 n^3), which is good to 1e-6 above n = 0.36, and below that
 * from the polynomial fit of MacArthur, Courteau & Holtzman (2003); then
 * solve exactly.  Both are only starting points.
 */
static double sersic_bn(double n)
{
	double b0;

	if (n > 0.36)
		b0 = 2 * n - 1.0 / 3 + 4 / (405 * n) + 46 / (25515 * n * n)
		     + 131 / (1148175 * n * n * n);
	else
		b0 = 0.01945 - 0.8902 * n + 10.95 * n * n - 19.67 * n * n * n
		     + 13.43 * n * n * n * n;
	if (!(b0 > 0))
		b0 = 1e-3;
	return sersic_gamma_inv(2 * n, 0.5, 0, b0);
}

/* x_t with Q(2n, x_t) = eps: start a few standard deviations (sqrt(2n))
 * beyond the mean 2n of the gamma distribution. */
static double sersic_trunc_x(double n, double eps)
{
	double a = 2 * n, z = sqrt(-2.0 * log(eps));

	return sersic_gamma_inv(a, eps, 1, a + z * sqrt(a) + z * z / 3.0 + 1.0);
}

/*
 * The semi-axes a galaxy is drawn with: r_e and q r_e, each at least
 * SERSIC_AXIS_MIN pixels.  Below that nothing of the profile can be seen
 * or even represented: the light farther than 0.01 pixel from the centre
 * (or from the major axis) of a galaxy 1e-9 pixel across is below 3e-9 of
 * its flux at n = 20 and 1e-22 at n <= 10, so it is a point (or a line)
 * on the pixel grid whether its axis is 1e-9 or 1e-300 pixel; and a
 * pixel's offset along the minor axis carries a rounding error of 1e-16
 * of its distance from the centre (1e-12 pixel across an SCA), which a
 * narrower needle's 1/(q r_e) would magnify into darkness.  q r_e is
 * formed in logarithms, so that 1e-300 x 1e-300 does not underflow on the
 * way.
 */
#define SERSIC_AXIS_MIN 1e-9

static void sersic_axes(double re, double q, double *major, double *minor)
{
	*major = fmax(re, SERSIC_AXIS_MIN);
	*minor = fmin(fmax(exp(log(q) + log(re)), SERSIC_AXIS_MIN), *major);
}

void sersic_unpack(const struct wfs_source *src, struct sersic_gal *g)
{
	double th = (src->param[SERSIC_PHI] + 90.0) * (M_PI / 180.0);

	g->xc = src->x;
	g->yc = src->y;
	g->n = src->param[SERSIC_N];
	g->inv_n = 1.0 / g->n;
	sersic_axes(src->param[SERSIC_RE], src->param[SERSIC_RATIO], &g->re, &g->minor);
	g->ct = cos(th);
	g->st = sin(th);
	g->b = src->aux[AUX_B];
	g->lni0 = src->aux[AUX_LNI0];
	g->rho_t = src->aux[AUX_RHO_T];
	g->rho_t2 = g->rho_t * g->rho_t;
	g->xt = g->b * exp(log(g->rho_t) / src->param[SERSIC_N]);
	g->lg2n = sersic_lgamma(2 * g->n);
	g->finf = src->aux[AUX_FINF];
	g->pt = src->aux[AUX_PT];
	g->qt = src->aux[AUX_QT];
	g->flux = fabs(src->flux);
	g->rt = fmin(g->rho_t * g->re, SERSIC_RT_MAX);
	g->rtb = fmin(g->rho_t * g->minor, g->rt);
	/* u = c dx + s dy, v = -s dx + c dy, rho^2 = u^2 / a^2 + v^2 / b^2
	 * with a, b the semi-axes (a 1/a^2 below 1e-308 is 0: flat) */
	double ia2 = 1.0 / (g->re * g->re), ib2 = 1.0 / (g->minor * g->minor);
	g->ia2 = ia2;
	g->ib2 = ib2;
	g->qa = g->ct * g->ct * ia2 + g->st * g->st * ib2;
	g->qc = g->st * g->st * ia2 + g->ct * g->ct * ib2;
	g->qb = g->ct * g->st * (ia2 - ib2);
}

/*
 * Half-widths (pixels) of the box around the truncation ellipse: an
 * ellipse with semi-axes a, b turned by theta spans
 * sqrt(a^2 cos^2 + b^2 sin^2) along x and sqrt(a^2 sin^2 + b^2 cos^2) along y.
 */
void sersic_halfbox(const struct sersic_gal *g, double *hx, double *hy)
{
	double a = g->rt, b = g->rtb;

	*hx = sqrt(a * a * g->ct * g->ct + b * b * g->st * g->st);
	*hy = sqrt(a * a * g->st * g->st + b * b * g->ct * g->ct);
}

/* ------------------------------------------------------------------ */
/* Exact integral over a rectangle by wedges from the centre.          */

/*
 * Any polygon's integral is the signed sum over its edges of the wedge
 * (centre, edge).  In the circularised (s, t) frame the wedge of an edge at
 * distance d from the centre, seen over angles psi from its foot, reaches
 * rho_e(psi) = d / cos(psi), and its radial integral is closed-form (see
 * the top of this file):
 *
 *   wedge = F_inf / (2 pi) int f(rho_e(psi)) dpsi,  f(rho) = P(2n, b min(rho, rho_t)^(1/n)).
 *
 * Writing f = P_t - g, g(rho) = Q(2n, b rho^(1/n)) - eps (zero beyond rho_t),
 * a rectangle's integral is F_inf / (2 pi) sum_edges (P_t sweep_e - int g),
 * whose P_t sweep terms add to 2 pi P_t = 2 pi flux / F_inf when the
 * centre is inside and to 0 when outside.  Integrating g, which is small
 * far out, instead of f keeps a far cell's small integral from being a
 * difference of large wedges.  An edge on a line through the centre sweeps
 * zero area and is skipped.
 *
 * This is exact for the cusp at the centre (n > 1) and for any r_e, down to
 * a galaxy far smaller than the cell, and for needles (q -> 0): only the
 * smooth one-dimensional g(rho_e(psi)) is integrated numerically, by
 * adaptive 7/15-point Gauss-Kronrod to the relative tolerance tol.
 */
static const double gk_x[8] = {
	0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
	0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
	0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
	0.207784955007898467600689403773245, 0.0 };
static const double gk_wk[8] = {
	0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
	0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
	0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
	0.204432940075298892414161999234649, 0.209482141084727828012999174891714 };
static const double gk_wg[4] = {   /* Gauss 7 weights at gk_x[1], [3], [5], [7] */
	0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
	0.381830050505118944950369775488975, 0.417959183673469387755102040816327 };

static inline double sersic_wedge_g(const struct sersic_gal *g, double d, double psi)
{
	double c = cos(psi);
	if (c <= 0)
		return 0.0;
	double rho = d / c;
	if (rho >= g->rho_t)
		return 0.0;
	double x = g->b * exp(g->inv_n * log(rho));
	return fmax(sersic_gamma_q_lg(2 * g->n, g->lg2n, x) - g->qt, 0.0);
}

static double sersic_gk(const struct sersic_gal *g, double d, double a, double b,
			double tol, int depth)
{
	double m = 0.5 * (a + b), h = 0.5 * (b - a), fc = sersic_wedge_g(g, d, m);
	double k = gk_wk[7] * fc, gs = gk_wg[3] * fc;

	for (int i = 0; i < 7; i++) {
		double f1 = sersic_wedge_g(g, d, m - h * gk_x[i]);
		double f2 = sersic_wedge_g(g, d, m + h * gk_x[i]);
		k += gk_wk[i] * (f1 + f2);
		if (i & 1)
			gs += gk_wg[i / 2] * (f1 + f2);
	}
	k *= h;
	gs *= h;
	if (fabs(k - gs) <= tol || depth >= 40 || h < 1e-15 || !isfinite(k))
		return k;
	return sersic_gk(g, d, a, m, 0.5 * tol, depth + 1)
	       + sersic_gk(g, d, m, b, 0.5 * tol, depth + 1);
}

/*
 * The 3-point Gauss rule and its 7-point Kronrod extension over [a, b]
 * first: where they agree within tol, the Kronrod sum (its own error is far
 * below their difference), for 7 evaluations instead of sersic_gk's 15;
 * else sersic_gk over [a, b].  Worth it where tol is loose (sersic-quick's
 * cells next to the centre of a galaxy below the noise); at 1e-4 of a
 * cell's light the two rarely agree and the 7 are lost.
 */
static const double gk7_x[3] = {
	0.960491268708020283423507092629080, 0.774596669241483377035853079956480,
	0.434243749346802558002071502844628 };
static const double gk7_wk[4] = {
	0.104656226026467265193823857192073, 0.268488089868333440728569280666710,
	0.401397414775962222905051818618432, 0.450916538658474142345110087045571 };

static double sersic_gk7(const struct sersic_gal *g, double d, double a, double b, double tol)
{
	double m = 0.5 * (a + b), h = 0.5 * (b - a), fc = sersic_wedge_g(g, d, m);
	double k = gk7_wk[3] * fc, gs = 8.0 / 9 * fc;

	for (int i = 0; i < 3; i++) {
		double f = sersic_wedge_g(g, d, m - h * gk7_x[i]) + sersic_wedge_g(g, d, m + h * gk7_x[i]);

		k += gk7_wk[i] * f;
		if (i == 1)
			gs += 5.0 / 9 * f;
	}
	k *= h;
	gs *= h;
	if (fabs(k - gs) <= tol && isfinite(k))
		return k;
	return sersic_gk(g, d, a, b, tol, 0);
}

/*
 * Integral of the profile over [x0, x1] x [y0, y1] (offsets from the centre,
 * pixels) by wedges.  tol is the absolute tolerance as a fraction of the
 * galaxy's flux; k7: each edge tries sersic_gk7 first.
 */
static double sersic_rect_polar(const struct sersic_gal *g, double x0, double x1,
				double y0, double y1, double tol, int k7)
{
	double vx[4] = { x0, x1, x1, x0 }, vy[4] = { y0, y0, y1, y1 };
	double s[4], t[4], sum = 0;
	double ire = 1.0 / g->re, iqre = 1.0 / g->minor;

	for (int k = 0; k < 4; k++) {
		double u = g->ct * vx[k] + g->st * vy[k];
		double v = -g->st * vx[k] + g->ct * vy[k];
		s[k] = u * ire;
		t[k] = v * iqre;
	}
	/* The per-edge tolerance on int g, in units of 2 pi / F_inf. */
	double etol = 0.25 * tol * 2 * M_PI * g->pt;
	for (int k = 0; k < 4; k++) {
		int j = (k + 1) & 3;
		double ax = s[k], ay = t[k], bx = s[j], by = t[j];
		double ex = bx - ax, ey = by - ay, len = hypot(ex, ey);
		if (!(len > 0))
			continue;
		double cross = ax * by - ay * bx;       /* twice the signed wedge area */
		double d = fabs(cross) / len;
		double ra = hypot(ax, ay), rb = hypot(bx, by);
		if (d <= 1e-14 * fmax(ra, rb))
			continue;
		double sweep = atan2(cross, ax * bx + ay * by);
		/* Angles from the foot of the perpendicular: psi = atan(along / d). */
		double ux = ex / len, uy = ey / len;
		double pa = atan2(ax * ux + ay * uy, d), pb = atan2(bx * ux + by * uy, d);
		double gi = k7 ? sersic_gk7(g, d, fmin(pa, pb), fmax(pa, pb), etol)
			       : sersic_gk(g, d, fmin(pa, pb), fmax(pa, pb), etol, 0);
		sum += (sweep > 0 ? 1.0 : -1.0) * (g->pt * fabs(sweep) - gi);
	}
	return g->finf / (2 * M_PI) * sum;
}

/*
 * The same integral to a relative tolerance rel of the cell's own light
 * (or an absolute floor atol, a fraction of the flux).  rmin is the cell's
 * sersic_rho_min.  The first pass asks for rel times a bound on the light,
 * I(rho_min) times the area; where the light turns out far below that
 * bound (a needle crossing the cell, a far cell whose wedges nearly
 * cancel) the integral is redone to rel of what the first pass found,
 * at most twice more.  k7: where atol is the looser (a floor set by the
 * noise), the edges try sersic_gk7 first.
 */
double sersic_rect_rel(const struct sersic_gal *g, double x0, double x1, double y0,
		       double y1, double rmin, double rel, double atol, int k7)
{
	double bound = exp(g->lni0 - g->b * pow(rmin, g->inv_n)) * (x1 - x0) * (y1 - y0) / g->flux;
	double t = fmax(rel * fmin(bound, 1.0), atol);
	double v = sersic_rect_polar(g, x0, x1, y0, y1, t, k7 && atol >= rel * fmin(bound, 1.0));

	for (int k = 0; k < 2; k++) {
		double want = fmax(0.5 * rel * fabs(v) / g->flux, atol);
		if (!(want < 0.25 * t))
			break;
		t = want;
		v = sersic_rect_polar(g, x0, x1, y0, y1, t, 0);
	}
	return v;
}

/* ------------------------------------------------------------------ */
/* prepare() and footprint(), shared.                                  */

/* v as the shortest of %.15g, %.16g, %.17g that reads back as v, so a
 * message quotes the value the row holds ("1.0000001", not "1"). */
static const char *sersic_num(char buf[32], double v)
{
	for (int p = 15; p <= 17; p++) {
		snprintf(buf, 32, "%.*g", p, v);
		if (isnan(v) || strtod(buf, NULL) == v)
			break;
	}
	return buf;
}

/*
 * A bound on the light of galaxy g (sersic_unpack) that falls off its SCA,
 * as a fraction of its flux: the light beyond the largest ellipse of its
 * shape that fits inside the SCA's pixels, Q(2n, x) at that ellipse.  An
 * ellipse of radius rho reaches rho sqrt(a^2 cos^2 + b^2 sin^2) along x
 * (sin and cos swapped along y; sersic_halfbox), so the one that touches
 * the nearest edge has rho its distance over that reach; 1 for a centre
 * off the SCA.
 */
static double sersic_off_sca(const struct sersic_gal *g)
{
	double a = g->re, b = g->minor, ct = g->ct, st = g->st;
	double hx = sqrt(ct * ct * a * a + st * st * b * b), hy = sqrt(st * st * a * a + ct * ct * b * b);
	double lo = -0.5, hi = WFS_SCA_SIDE - 0.5;
	double dx = fmin(g->xc - lo, hi - g->xc), dy = fmin(g->yc - lo, hi - g->yc);
	double rho = fmin(dx / hx, dy / hy);

	if (!(rho > 0))
		return 1.0;
	return sersic_gamma_q(2 * g->n, g->b * exp(log(rho) * g->inv_n));
}

/*
 * Where more than SERSIC_OFF_TOL of the flux is both cut and possibly off
 * the SCA (sersic_off_sca), putting all the light cut back would brighten
 * what is drawn (by 25 % for r_e 1e5 pixels at the default
 * sersic-noise-eps): src's finf (and its log intensity) is then such that
 * the truncated profile puts on the SCA's pixels the light the whole one
 * does, each integral exact to SERSIC_OFF_TOL / 100 of the flux, but at
 * most the whole flux (finf at most flux / pt); unchanged when the
 * truncated profile puts none there (nothing of it is drawn), or when
 * nothing was put back (a cut beyond SERSIC_RT_MAX).
 */
void sersic_keep_sca_light(struct wfs_source *src)
{
	double x0 = -0.5 - src->x, x1 = WFS_SCA_SIDE - 0.5 - src->x;
	double y0 = -0.5 - src->y, y1 = WFS_SCA_SIDE - 0.5 - src->y;
	double tol = 0.01 * SERSIC_OFF_TOL, finf = src->aux[AUX_FINF], cut, whole;
	struct sersic_gal g;

	if (!(src->flux > 0) || !(finf > src->flux))
		return;
	sersic_unpack(src, &g);
	if (!(fmin(g.qt, sersic_off_sca(&g)) > SERSIC_OFF_TOL))
		return;
	g.finf = 1.0;
	cut = sersic_rect_polar(&g, x0, x1, y0, y1, tol, 1);
	g.rho_t = g.rho_t2 = INFINITY;
	g.qt = 0.0;
	g.pt = 1.0;
	whole = sersic_rect_polar(&g, x0, x1, y0, y1, tol, 1);
	if (!(cut > 0) || !(whole >= 0))
		return;
	/* at least the flux (the two differ by rounding where the cut holds
	 * the whole SCA), never more than the whole flux: the SCA may see
	 * mostly the wing beyond the cut, not to be pushed into the few
	 * pixels inside */
	src->aux[AUX_FINF] = src->flux * fmin(fmax(whole / cut, 1.0), 1.0 / src->aux[AUX_PT]);
	src->aux[AUX_LNI0] += log(src->aux[AUX_FINF] / finf);
}

/*
 * Validate a row and fill src->aux.  eps is the truncation fraction.  With
 * flux meaning "ie", src->flux is the intensity at r_e and is replaced by
 * the total, q included.
 */
int sersic_prepare_common(const struct wfs_host *host, struct wfs_source *src,
			  double eps, double noise, double noise_eps)
{
	double n = src->param[SERSIC_N], re = src->param[SERSIC_RE];
	double phi = src->param[SERSIC_PHI], q = src->param[SERSIC_RATIO];

	char num[32];

	if (isnan(n))
		return host->error(host->ctx, "column 'n': empty; a Sérsic row needs its index");
	if (n <= 0)
		return host->error(host->ctx, "column 'n': Sérsic index must be > 0, got %s", sersic_num(num, n));
	if (n < SERSIC_N_MIN || n > SERSIC_N_MAX)
		return host->error(host->ctx, "column 'n': Sérsic index %s is outside the supported range %g to %g",
				   sersic_num(num, n), SERSIC_N_MIN, SERSIC_N_MAX);
	if (isnan(re))
		return host->error(host->ctx, "column 're': empty; a Sérsic row needs its half-light radius");
	if (re <= 0 || isinf(re))
		return host->error(host->ctx, "column 're': half-light radius must be > 0 pixels, got %s",
				   sersic_num(num, re));
	if (isnan(q) || q <= 0 || q > 1)
		return host->error(host->ctx, "column 'ratio': axis ratio must be in (0, 1], got %s",
				   sersic_num(num, q));
	if (!isfinite(phi))
		return host->error(host->ctx, "column 'phi': orientation must be a finite angle in degrees, got %s",
				   sersic_num(num, phi));
	if (!isfinite(src->flux) || src->flux < 0)
		return host->error(host->ctx, "column 'flux': a galaxy's flux must be finite and >= 0, got %s",
				   sersic_num(num, src->flux));

	double b = sersic_bn(n), a = 2 * n, ra, rb;
	/* ln of F_inf / I0 = 2 pi n q re^2 Gamma(2n) / b^(2n), in logs so n = 20
	 * (Gamma(40) ~ 1e46), re = 0.01 and re = 1e300 stay in range: first
	 * for the row's own re and q (the total of --sersic-flux ie), then for
	 * the semi-axes the galaxy is drawn with. */
	double lng = log(2 * M_PI * n) + sersic_lgamma(a) - a * log(b);
	sersic_axes(re, q, &ra, &rb);
	double lnk = lng + log(ra) + log(rb);

	/* What the flux column means is a fact of the catalog, in the source;
	 * a host older than that field passed it as the setting sersic-flux. */
	const char *meaning = NULL;
	if (WFS_HAS(host->size, struct wfs_host, source_size) &&
	    WFS_HAS(host->source_size, struct wfs_source, flux_meaning))
		meaning = src->flux_meaning == WFS_FLUX_IE ? "ie" : "total";
	else if (host->setting)
		meaning = host->setting(host->ctx, "sersic-flux");
	if (meaning && !strcmp(meaning, "ie")) {
		/* flux column = I(r_e) = I0 e^-b: total = Ie e^b F_inf / I0. */
		double ie = src->flux;
		src->flux = ie * exp(b + lng + log(q) + 2 * log(re));
		if (!isfinite(src->flux))
			return host->error(host->ctx, "column 'flux': surface brightness %s gives an infinite total",
					   sersic_num(num, ie));
	} else if (meaning && strcmp(meaning, "total")) {
		return host->error(host->ctx, "setting sersic-flux: '%s' is neither 'total' nor 'ie'", meaning);
	}

	/* The cut by the noise (sersic-noise-cut, quick only): where the
	 * untruncated surface brightness falls below noise (counts/s per
	 * pixel), I0 e^(-x) = noise at x = ln I0 - ln noise, the light beyond
	 * is Q(2n, x); the cut is made there when that is more than eps, but
	 * never beyond SERSIC_NOISE_EPS of the light, which the
	 * renormalisation below puts back into the galaxy (so its flux stays
	 * whole and its pixels rise by at most that fraction). */
	if (noise > 0 && src->flux > 0) {
		double x = log(src->flux) - lnk - log(noise);
		double en = x > 0 ? sersic_gamma_q(a, x) : 1.0;
		double cap = SERSIC_NOISE_EPS;

		/* A fainter galaxy may leave out more (sersic-noise-eps): as
		 * much as raises its brightest pixel by at most the noise
		 * level.  No region of one pixel's area holds more light than
		 * the central ellipse of that area, rho <= R with
		 * pi R^2 ra rb = 1, so no pixel more than flux P(2n, b
		 * R^(1/n)); the renormalisation raises a pixel p by
		 * eps / (1 - eps) p, at most noise where eps <= r / (1 + r),
		 * r = noise / (that bound), and a pixel beyond the cut loses
		 * less than noise.  Any pixel then moves by less than noise. */
		if (noise_eps > cap) {
			double r1 = exp(-0.5 * (log(M_PI) + log(ra) + log(rb)));
			double peak = src->flux * sersic_gamma_p_lg(a, sersic_lgamma(a), b * exp(log(r1) / n));
			double r = peak > 0 ? noise / peak : INFINITY;

			cap = fmin(noise_eps, fmax(cap, r / (1 + r)));
		}
		eps = fmax(eps, fmin(en, cap));
	}
	double xt = sersic_trunc_x(n, eps);
	double qt, pt;
	double rho_t = exp(n * log(xt / b));
	/* Never cut inside the central 5 x 5 pixels, whose values the accuracy
	 * targets are about: the cut ellipse's minor semi-axis is at least
	 * SERSIC_RT_MIN pixels (or its major one 10 x that for needles). */
	double rho_floor = fmin(SERSIC_RT_MIN / rb, 10 * SERSIC_RT_MIN / ra);
	if (rho_t < rho_floor)
		rho_t = rho_floor;
	/* A cut beyond SERSIC_RT_MAX pixels is made there instead; the light
	 * beyond is off any SCA, so the profile is not renormalised for it
	 * (for re = 1e300 that light is nearly all of it). */
	int beyond = rho_t * ra > SERSIC_RT_MAX;
	if (beyond)
		rho_t = SERSIC_RT_MAX / ra;
	xt = b * exp(log(rho_t) / n);
	qt = sersic_gamma_q(a, xt);
	pt = 1.0 - qt;
	/* renormalised: the flux inside rho_t is the row's */
	double finf = beyond ? src->flux : src->flux / pt;

	src->aux[AUX_B] = b;
	src->aux[AUX_LNI0] = src->flux > 0 ? log(finf) - lnk : -INFINITY;
	src->aux[AUX_RHO_T] = rho_t;
	src->aux[AUX_FINF] = finf;
	src->aux[AUX_PT] = pt;
	src->aux[AUX_QT] = qt;
	src->aux[AUX_PSFH] = 0;
	src->aux[AUX_PSFALL] = 0;
	return 0;
}

/* The pixels the galaxy touches: the truncation ellipse's box plus the
 * ePSF's half-width drawn, and the pixels its core block (core_k about
 * the centre pixel) reaches through that ePSF (sersic_core_add), which
 * a needle lying across an axis, or a large core, puts beyond the box;
 * clamped so distant or huge galaxies stay in int. */
int sersic_footprint_common(const struct wfs_host *host, const struct wfs_source *src,
			    struct wfs_box *box, int convolve, int core_k)
{
	struct sersic_gal g;
	double hx, hy;
	int hp = 0;

	sersic_unpack(src, &g);
	sersic_halfbox(&g, &hx, &hy);
	if (convolve) {
		struct wfs_epsf e;
		if (sersic_epsf(host, src, &e))
			return -1;
		hp = sersic_psf_drawn(&e, src);
	}
	const double lim = 1e8;
	double x0 = fmax(floor(g.xc - hx + 0.5) - hp, -lim), x1 = fmin(floor(g.xc + hx + 0.5) + hp + 1, lim);
	double y0 = fmax(floor(g.yc - hy + 0.5) - hp, -lim), y1 = fmin(floor(g.yc + hy + 0.5) + hp + 1, lim);
	if (convolve) {
		/* the core's reach: K + hp + 1 about the centre pixel */
		double icx = floor(g.xc + 0.5), icy = floor(g.yc + 0.5), k = core_k + hp + 1;

		x0 = fmax(fmin(x0, icx - k), -lim);
		x1 = fmin(fmax(x1, icx + k + 1), lim);
		y0 = fmax(fmin(y0, icy - k), -lim);
		y1 = fmin(fmax(y1, icy + k + 1), lim);
	}
	/* A central surface brightness below the least double (e^-745 per
	 * pixel; r_e = 1e300, or no flux) puts nothing in any pixel. */
	if (!(x0 < x1) || !(y0 < y1) || !(g.lni0 > -745))
		x0 = x1 = y0 = y1 = 0;  /* far out of range: an empty box */
	box->x0 = (int)x0;
	box->x1 = (int)x1;
	box->y0 = (int)y0;
	box->y1 = (int)y1;
	return 0;
}

/* The reach (model.h) of a galaxy: the extent about its centre of the box
 * footprint() gives it at the origin of the SCA src names, plus 2 pixels
 * for the rounding of the box's edges.  prepare() is run on a copy, so src
 * keeps its aux. */
int sersic_reach_common(const struct wfs_host *host, const struct wfs_source *src,
			double eps, int convolve, int core_k, double *pixels)
{
	struct wfs_source at = *src;
	struct wfs_box box;

	at.x = at.y = 0;
	if (sersic_prepare_common(host, &at, eps, 0, 0) < 0 ||
	    sersic_footprint_common(host, &at, &box, convolve, core_k) < 0)
		return -1;
	*pixels = fmax(fmax(-box.x0, box.x1), fmax(-box.y0, box.y1)) + 2;
	return 0;
}

/* Parse a number setting; fallback when unset; -1 with an error when bad. */
int sersic_setting_num(const struct wfs_host *host, const char *key, double lo,
		       double hi, double fallback, double *out)
{
	const char *s = host->setting ? host->setting(host->ctx, key) : NULL;
	char *end;

	*out = fallback;
	if (!s)
		return 0;
	double v = strtod(s, &end);
	if (end == s || *end || !(v >= lo && v <= hi))
		return host->error(host->ctx, "setting %s: '%s' is not a number from %g to %g", key, s, lo, hi);
	*out = v;
	return 0;
}

/* sersic-core: the core half-width K, 0 to 16 pixels. */
int sersic_setting_core(const struct wfs_host *host, int *out)
{
	double v;

	if (sersic_setting_num(host, "sersic-core", 0, 16, SERSIC_CORE, &v))
		return -1;
	*out = (int)v;
	if (*out != v)
		return host->error(host->ctx, "setting sersic-core: %g is not a whole number of pixels", v);
	return 0;
}

/* sersic-convolve: yes (default) or no. */
int sersic_setting_convolve(const struct wfs_host *host, int *out)
{
	const char *s = host->setting ? host->setting(host->ctx, "sersic-convolve") : NULL;

	*out = 1;
	if (!s || !strcmp(s, "yes") || !strcmp(s, "1"))
		return 0;
	if (!strcmp(s, "no") || !strcmp(s, "0")) {
		*out = 0;
		return 0;
	}
	return host->error(host->ctx, "setting sersic-convolve: '%s' is neither 'yes' nor 'no'", s);
}
