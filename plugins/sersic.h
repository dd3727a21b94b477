/*
 * sersic.h - what sersic_quick.c and sersic_precise.c share: the profile
 * of one galaxy (struct sersic_gal) and the small functions of it their
 * inner loops call (static inline here), and the two compiled units both
 * plugins link in: sersic_core.c (b_n, normalisation, truncation, exact
 * pixel integrals, prepare() and footprint(), settings) and
 * sersic_render.c (rendering through the ePSF).  The plugins differ only
 * in how they integrate a cell (struct sersic_method).  Only
 * <wfiscene/model.h> and libc/libm.
 *
 * The profile.  With (u, v) the offsets from the centre along the major and
 * minor axes (pixels), q = b/a and r_e the half-light radius along the major
 * axis,
 *
 *     rho^2 = (u^2 + v^2 / q^2) / r_e^2,     I = I0 exp(-b_n rho^(1/n)).
 *
 * Orientation (STIPS, reference §4.3): phi = 0 puts the major axis along +y
 * and phi turns it toward -x, so the major axis points at theta = phi + 90°
 * from +x toward +y: u = dx cos(theta) + dy sin(theta),
 * v = -dx sin(theta) + dy cos(theta).
 *
 * Flux inside the ellipse rho < R.  In the circularised coordinates
 * (s, t) = (u, v/q) / r_e an area element is q r_e^2 ds dt, and with
 * w = b rho^(1/n), i.e. rho = (w/b)^n, d rho = n w^(n-1) / b^n dw,
 *
 *     F(<R) = q r_e^2 I0 2 pi int_0^R e^(-b rho^(1/n)) rho d rho
 *           = 2 pi n q r_e^2 I0 b^(-2n) gamma(2n, b R^(1/n)),
 *
 * so the total is F_inf = 2 pi n q r_e^2 I0 Gamma(2n) / b^(2n) (the axis
 * ratio included; STIPS's precise total leaves it out, its issue #183), and
 * the fraction inside R is the regularised P(2n, b R^(1/n)).  r_e is the
 * half-light radius exactly when P(2n, b_n) = 1/2, which fixes b_n.
 * STIPS's "Ie" is the intensity at rho = 1: I0 = Ie e^(b_n).
 *
 * Truncation.  The profile is cut at rho_t where the flux beyond is a
 * stated fraction eps: Q(2n, x_t) = eps with x_t = b rho_t^(1/n), so
 * rho_t = (x_t / b)^n.  The cut profile is renormalised (I0 scaled by
 * 1 / (1 - eps)) so the rendered galaxy still carries its whole flux.
 * For n = 4 and eps = 1e-4, rho_t is about 60 r_e; for n = 10 it is about
 * 1200 r_e, which is why a footprint can cover a whole SCA.  For small
 * galaxies rho_t is raised so the cut lies at least 5 pixels out (then
 * eps is smaller than asked), so the central pixels are never cut.
 */
#ifndef WFS_SERSIC_H
#define WFS_SERSIC_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wfiscene/model.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* The catalog columns of both plugins, in this order in src->param. */
enum { SERSIC_N, SERSIC_RE, SERSIC_PHI, SERSIC_RATIO, SERSIC_NCOL };

/* Their names and fallbacks (sersic_core.c), and what they are to the host
 * (model.h, enum wfs_column_role): the shape it writes in romanisim's
 * convention and reshapes to the SIAF. */
extern const struct wfs_column sersic_columns[SERSIC_NCOL];
extern const int sersic_roles[SERSIC_NCOL];

/* Supported index range.  Below 0.05 the profile is a flat-topped box whose
 * edge sharpens as rho^(1/n); above 20 the truncation radius passes 1e6 r_e. */
#define SERSIC_N_MIN 0.05
#define SERSIC_N_MAX 20.0
/* Truncation radii are clamped here (pixels); far beyond any SCA. */
#define SERSIC_RT_MAX 1e7
/* ... and never below this along the minor axis, pixels (see prepare). */
#define SERSIC_RT_MIN 5.0
/* The most light the cut by the noise may leave out (sersic-noise-cut),
 * whatever the galaxy's brightness; sersic-noise-eps may raise it for
 * faint galaxies. */
#define SERSIC_NOISE_EPS 1e-2
/* Where more than this fraction of a galaxy's light may be cut and fall off
 * its SCA, the light kept on the SCA is set by integrals over its pixels
 * (prepare), not by renormalising to the whole flux. */
#define SERSIC_OFF_TOL 2e-4      /* above sersic-precise's default cut, 1e-4 */

/* Where prepare() leaves its results in src->aux. */
enum {
	AUX_B,          /* b_n */
	AUX_LNI0,       /* ln I0, counts/s per pixel^2 at the centre (renormalised) */
	AUX_RHO_T,      /* truncation radius in units of r_e */
	AUX_PSFALL,     /* the whole ePSF's light at whole-pixel offsets, when cut (AUX_PSFH) */
	AUX_FINF,       /* flux of the untruncated profile with this I0 */
	AUX_PT,         /* 1 - eps: fraction of F_inf inside rho_t */
	AUX_QT,         /* eps = Q(2n, x_t) */
	AUX_PSFH,       /* the ePSF's half-width drawn, whole pixels (sersic-psf-cut); 0: all of it */
	/* x_t = b rho_t^(1/n) is not kept: sersic_unpack forms it again,
	 * with the same operations as prepare(), so the same bits. */
};

/* ------------------------------------------------------------------ */
/* One galaxy, unpacked for integration.                               */

struct sersic_gal {
	double xc, yc;          /* centre, pixels */
	double n, inv_n, b;
	double re, minor;       /* semi-axes r_e and q r_e as drawn (sersic_axes) */
	double ct, st;          /* cos and sin of theta = phi + 90° */
	double lni0;            /* ln I0 */
	double rho_t, rho_t2;   /* truncation radius (units of r_e) and square */
	double xt;              /* b rho_t^(1/n) */
	double finf, pt, qt;    /* F_inf, 1 - eps, eps */
	double flux;            /* the row's flux, the scale of absolute tolerances */
	double rt, rtb;         /* truncation semi-axes, pixels */
	double lg2n;            /* ln Gamma(2n), for the wedges' Q(2n, x) */
	/* rho^2 = u^2 ia2 + v^2 ib2 (below); and as a quadratic form in
	 * (dx, dy), A dx^2 + 2 B dx dy + C dy^2, only for its ratios */
	double ia2, ib2;
	double qa, qb, qc;
	/* for a method's own use, set by its stamp_setup (struct sersic_method) */
	double method_lo2, method_hi2;
};

/* A helper here that the compiler should keep as one function of each
 * unit, not copy into its callers: sersic_rho_min, inlined into the cell
 * loops of sersic-quick, made it run 9% more instructions (callgrind, 500
 * galaxies); `unused' for the units that do not call it. */
#if defined(__GNUC__)
#define SERSIC_OUT_OF_LINE __attribute__((noinline, unused))
#else
#define SERSIC_OUT_OF_LINE
#endif

/* rho^2 at offset (dx, dy), through u and v: for a needle the quadratic
 * form's terms are each 1/(q r_e)^2 times larger than their sum along the
 * major axis, and would cancel to noise; v carries only its own rounding. */
static inline double sersic_rho2(const struct sersic_gal *g, double dx, double dy)
{
	double u = g->ct * dx + g->st * dy, v = g->ct * dy - g->st * dx;

	return u * u * g->ia2 + v * v * g->ib2;
}

/* Surface brightness (counts/s per pixel^2) at offset (dx, dy) from the
 * centre; zero beyond the truncation ellipse.  rho^(1/n) is computed as
 * exp(log(rho^2) / 2n), one log and two exps. */
static inline double sersic_sb(const struct sersic_gal *g, double dx, double dy)
{
	double r2 = sersic_rho2(g, dx, dy);

	if (r2 >= g->rho_t2)
		return 0.0;
	if (r2 <= 0)
		return exp(g->lni0);
	return exp(g->lni0 - g->b * exp(0.5 * g->inv_n * log(r2)));
}

/* The gradient of the surface brightness at (dx, dy): with
 * rho^2 = u^2 ia2 + v^2 ib2, grad rho^2 = 2 (u ia2 grad u + v ib2 grad v),
 * grad u = (c, s), grad v = (-s, c), and
 * d I / d rho^2 = -I b rho^(1/n) / (2 n rho^2). */
static inline void sersic_grad(const struct sersic_gal *g, double dx, double dy,
			       double *gx, double *gy)
{
	double u = g->ct * dx + g->st * dy, v = g->ct * dy - g->st * dx;
	double r2 = u * u * g->ia2 + v * v * g->ib2;

	*gx = *gy = 0;
	if (r2 >= g->rho_t2 || r2 <= 0)
		return;
	double p = g->b * exp(0.5 * g->inv_n * log(r2));
	double d = -exp(g->lni0 - p) * p * g->inv_n / r2;      /* 2 dI/drho^2 */
	double pu = u * g->ia2, pv = v * g->ib2;
	*gx = d * (pu * g->ct - pv * g->st);
	*gy = d * (pu * g->st + pv * g->ct);
}

/*
 * The local length scale (pixels) over which ln I changes by one, at
 * elliptical radius rho, taken along the minor axis (the short way):
 * with s1 = |d lnI / d rho| = (b/n) rho^(1/n - 1) and
 * s2 = |d2 lnI / d rho^2| = (b/n) |1/n - 1| rho^(1/n - 2),
 * ell = q r_e / sqrt(s1^2 + s2).  It sets the sub-sampling of quick and
 * the 2-point shortcut of precise: midpoint error ~ h^2 / (24 ell^2).
 */
static inline double sersic_scale(const struct sersic_gal *g, double rho)
{
	rho = fmax(rho, 1e-12);
	double p = exp((g->inv_n - 1.0) * log(rho));
	double s1 = g->b * g->inv_n * p;
	double s2 = g->b * g->inv_n * fabs(g->inv_n - 1.0) * p / rho;
	return g->minor / sqrt(s1 * s1 + s2 + 1e-300);
}

static inline double sersic_clamp(double v, double lo, double hi)
{
	return v < lo ? lo : v > hi ? hi : v;
}

/* Whether the cell [x0, x1] x [y0, y1] (offsets from the centre) lies
 * within h of the centre, where the cusp of n > 1 sits. */
static inline int sersic_near_centre(double x0, double x1, double y0, double y1, double h)
{
	return x0 - h <= 0 && x1 + h >= 0 && y0 - h <= 0 && y1 + h >= 0;
}

/*
 * The smallest elliptical radius (units of r_e) of any point of the box
 * [x0, x1] x [y0, y1] (offsets from the centre): zero if the box holds the
 * centre.  Else rho^2, convex with its least value at the centre, is least
 * on an edge that faces the centre (x = x0 when x0 > 0, and so on; one or
 * two of them).  Along x = x0, rho^2 = A x0^2 + 2 B x0 y + C y^2 is least
 * at y = -B x0 / C, clamped to [y0, y1]; likewise for the others.  Exact,
 * so a cell beside a needle (q -> 0) is seen to be dark however close it
 * is in pixels.
 */
SERSIC_OUT_OF_LINE static double sersic_rho_min(const struct sersic_gal *g, double x0, double x1,
						double y0, double y1)
{
	double m = INFINITY;

	if (x0 > 0 || x1 < 0) {
		double x = x0 > 0 ? x0 : x1;
		double y = g->qc > 0 ? sersic_clamp(-g->qb * x / g->qc, y0, y1) : y0;
		m = sersic_rho2(g, x, y);
	}
	if (y0 > 0 || y1 < 0) {
		double y = y0 > 0 ? y0 : y1;
		double x = g->qa > 0 ? sersic_clamp(-g->qb * y / g->qa, x0, x1) : x0;
		double r = sersic_rho2(g, x, y);
		m = r < m ? r : m;
	}
	return m < INFINITY ? sqrt(m > 0 ? m : 0.0) : 0.0;
}

/* The largest rho^2 over the box: rho^2 is convex, so at a corner. */
static inline double sersic_rho2_max(const struct sersic_gal *g, double x0, double x1,
			      double y0, double y1)
{
	double m = 0;

	for (int k = 0; k < 4; k++) {
		double dx = k & 1 ? x1 : x0, dy = k & 2 ? y1 : y0, r = sersic_rho2(g, dx, dy);

		m = r > m ? r : m;      /* fmax's value (a NaN keeps m), without its call */
	}
	return m;
}

/* The midpoint rule on an n x n grid over the box. */
static inline double sersic_midpoint(const struct sersic_gal *g, double x0, double x1,
				     double y0, double y1, int n)
{
	double sx = (x1 - x0) / n, sy = (y1 - y0) / n, s = 0;

	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++)
			s += sersic_sb(g, x0 + (i + 0.5) * sx, y0 + (j + 0.5) * sy);
	return s * sx * sy;
}

/* The profile's length scale over a cell: for n >= 1 the profile is
 * steepest at the cell's nearest point, for n < 1 at its farthest. */
static inline double sersic_cell_scale(const struct sersic_gal *g, double rmin,
				       double x0, double x1, double y0, double y1)
{
	double l = sersic_scale(g, rmin);

	if (g->n < 1)
		l = fmin(l, sersic_scale(g, fmin(sqrt(sersic_rho2_max(g, x0, x1, y0, y1)), g->rho_t)));
	return l;
}

/* The ePSF a galaxy is convolved with: the blend of its spectrum's two
 * spectral classes (model.h, wfs_source.colour, host->epsf_blend;
 * wfiscene(1) "Spectral classes"), or from an older host the nearest
 * class, else the scene's default spectrum.  Every call for one source
 * gives the same arrays. */
static inline int sersic_epsf(const struct wfs_host *host, const struct wfs_source *src,
			      struct wfs_epsf *e)
{
	int colour = WFS_HAS(host->source_size, struct wfs_source, colour) && src->colour >= 0;

	if (colour && WFS_HAS(host->size, struct wfs_host, epsf_blend) && host->epsf_blend)
		return host->epsf_blend(host->ctx, src->sca, src->x, src->y, src->psf_class,
					src->colour, e);
	if (colour && WFS_HAS(host->size, struct wfs_host, epsf_colour) && host->epsf_colour)
		return host->epsf_colour(host->ctx, src->sca, src->x, src->y, src->psf_class,
					 (int)floor(src->colour + 0.5), e);
	return host->epsf(host->ctx, src->sca, src->x, src->y, src->psf_class, e);
}

/*
 * How a plugin integrates the profile over an axis-aligned cell
 * [x0, x1] x [y0, y1] (offsets from the centre).  h is the cell's nominal
 * size (1 for pixels, 1/over for sub-pixel cells).
 */
typedef double (*sersic_cell_fn)(const struct sersic_gal *g, const void *opt,
				 double x0, double x1, double y0, double y1, double h);

struct sersic_method {
	sersic_cell_fn cell;
	const void *opt;
	int convolve;           /* 0: pixel integrals only (no PSF) */
	double psf_core;        /* radius of the cubic ePSF core, pixels */
	int core_k;             /* half-width of the sub-pixel core, pixels */
	/* Optional: a block of block x block wing pixels
	 * ([x0, x1] x [y0, y1], offsets) at once.  Returns -1 when the block
	 * is dark (no light in any of its pixels), 1 when its light is faint
	 * and smooth enough to be spread over its pixels from its integral *v
	 * and the gradient (*gx, *gy) at its centre, 0 when its pixels must be
	 * taken one by one. */
	int (*block_fn)(const struct sersic_gal *g, const void *opt, double x0, double x1,
			double y0, double y1, double *v, double *gx, double *gy);
	int block;
	/* Optional: the wing pixels xa..xb of row y at once, what
	 * sersic_wing_pixel gives each of them one by one (the integral, the
	 * gradient where the light is smooth over the pixel, the same tests),
	 * pixel xa + k into img[k], gxi[k], gyi[k] and lpi[k] (the smooth
	 * part: img where the light is smooth, else 0), *any and *rough as
	 * sersic_wing_pixel sets them; so that the work of a row can be shared
	 * and run in vector code.  NULL: sersic_wing_pixel. */
	void (*wing_row)(const struct sersic_gal *g, const void *opt, int y, int xa, int xb,
			 double *img, double *gxi, double *gyi, double *lpi, int *any, int *rough);
	/* Optional: called once a stamp, after the galaxy is unpacked. */
	void (*stamp_setup)(struct sersic_gal *g, const void *opt);
	/* The first-moment terms (the gradient planes through the ePSF's
	 * gradient) are left out of a stamp where a bound on what they add
	 * to any pixel is at most this, counts/s (sersic-moment-cut times
	 * the pixel noise; 0: always drawn). */
	double moment_level;
};

/*
 * The core is the (2K+1)^2 block of pixels around the centre drawn on
 * sub-pixel cells; K is the setting sersic-core (default SERSIC_CORE).
 * Outside it the pixel grid with the sharpened ePSF is accurate to second
 * order in the pixel size over the profile's length scale; inside it sits
 * the cusp (n > 1) and any structure finer than a pixel.  Measured against
 * K = 8 (contrib/sersic-bench.py), K = 1 is within 0.3% per pixel for
 * every galaxy of the benchmark grid and costs (4(2K+1)+1)^2 cells times
 * (2K+1+2 h)^2 pixels of direct sums, about 0.3 ms.
 */
#define SERSIC_CORE 1

/* Pixels whose light varies on a scale below this (pixels) get no
 * second-order correction (see sersic_wings_integrate). */
#define SERSIC_SMOOTH 0.1

/* A wing pixel's integral v and gradient (gx, gy) into the planes at k:
 * the smooth part lpi is v where the light is smooth over the pixel (the
 * second-order terms hold there), else 0 and the pixel is rough. */
static inline void sersic_wing_put(double *img, double *gxi, double *gyi, double *lpi, size_t k,
				   double v, double gx, double gy, int smooth, int *any, int *rough)
{
	img[k] = v;
	gxi[k] = gx;
	gyi[k] = gy;
	lpi[k] = smooth ? v : 0;
	*any |= v != 0;
	*rough |= lpi[k] != v;
}

/* A number as text, for the defaults in a wfs_setting table. */
#define SERSIC_STR_(x) #x
#define SERSIC_STR(x) SERSIC_STR_(x)

/* The ePSF core half-width of the convolution (the point model's psf-core
 * setting, read by the galaxies too, with the same default). */
#define SERSIC_PSF_CORE 4

/* The settings both methods read; each adds its own in front. */
#define SERSIC_SETTINGS \
	{ "psf-core", SERSIC_STR(SERSIC_PSF_CORE), "number from 0 to 1000", \
	  "half-width of the ePSF core drawn with Keys' cubic, pixels" }, \
	{ "sersic-core", SERSIC_STR(SERSIC_CORE), "whole number from 0 to 16", \
	  "half-width of the sub-sampled core, pixels" }, \
	{ "sersic-convolve", "yes", "yes|no", "convolve with the ePSF" }

/* ------------------------------------------------------------------ */
/* sersic_core.c                                                      */

/* Unpack src (prepare()'s aux) into g, for integration. */
void sersic_unpack(const struct wfs_source *src, struct sersic_gal *g);
/* Half-widths (pixels) of the box around the truncation ellipse. */
void sersic_halfbox(const struct sersic_gal *g, double *hx, double *hy);
/* The exact integral over [x0, x1] x [y0, y1] (offsets from the centre)
 * to a relative tolerance rel of the cell's own light, or the floor atol
 * (a fraction of the flux); rmin is the cell's sersic_rho_min; k7: try the
 * 7-point rule first where atol is the looser. */
double sersic_rect_rel(const struct sersic_gal *g, double x0, double x1, double y0,
		       double y1, double rmin, double rel, double atol, int k7);
/* prepare(), footprint() and reach() of both plugins (see sersic_core.c):
 * eps the truncation fraction, noise the pixel noise of the cut,
 * noise_eps the most light that cut may leave out where no pixel moves
 * by more than noise (sersic-noise-eps; at most SERSIC_NOISE_EPS: 0). */
int sersic_prepare_common(const struct wfs_host *host, struct wfs_source *src,
			  double eps, double noise, double noise_eps);

/* After sersic_prepare_common at the row's own position on its SCA (not
 * reach()'s stand-in): where the light cut would partly fall off the SCA,
 * src's scale puts on it the light the whole profile does. */
void sersic_keep_sca_light(struct wfs_source *src);
int sersic_footprint_common(const struct wfs_host *host, const struct wfs_source *src,
			    struct wfs_box *box, int convolve, int core_k);
int sersic_reach_common(const struct wfs_host *host, const struct wfs_source *src,
			double eps, int convolve, int core_k, double *pixels);
/* The settings: a number from lo to hi (fallback when unset), sersic-core,
 * sersic-convolve.  0, or -1 with an error. */
int sersic_setting_num(const struct wfs_host *host, const char *key, double lo,
		       double hi, double fallback, double *out);
int sersic_setting_core(const struct wfs_host *host, int *out);
int sersic_setting_convolve(const struct wfs_host *host, int *out);

/* ------------------------------------------------------------------ */
/* sersic_render.c                                                    */

/* The ePSF's half-width in whole pixels, and the half-width drawn for src
 * (sersic-psf-cut, aux AUX_PSFH). */
int sersic_psf_half(const struct wfs_epsf *e);
int sersic_psf_drawn(const struct wfs_epsf *e, const struct wfs_source *src);
/* Add the galaxy src to window win, its cells integrated by method m. */
int sersic_render_common(const struct wfs_host *host, void *thread,
			 const struct wfs_source *src, const struct wfs_window *win,
			 const struct sersic_method *m);

#endif
