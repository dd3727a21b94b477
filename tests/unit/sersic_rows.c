/*
 * sersic_rows - sersic-quick's fast rows (quick_stamp_setup and
 * quick_wing_row) against its pixel-by-pixel wing (quick_wing): every
 * pixel of 121 rows of 121 for 650 galaxies (n from 0.3 to 20, r_e from
 * 1e-3 to 100 pixels, axis ratios down to 1e-3, every sersic-taylor from
 * 0.25 to 4) gets the same integral to 1e-11 (the rows' exp and log are
 * vmath.h's, the pixel's libm's), the same gradient and the same smooth
 * part; and sersic_rect_rel's 7-point first pass (sersic-centre-cut) taken
 * where the noise floor is the looser tolerance, and only there.  The
 * plugin's sources are compiled in, so their static functions are
 * reachable.
 */
#include "tap.h"
#include "../../plugins/sersic_quick.c"
#include "../../plugins/sersic_core.c"
#include "../../plugins/sersic_render.c"

static double uniform(unsigned long long *s)
{
	*s = *s * 6364136223846793005ull + 1442695040888963407ull;
	return (double)(*s >> 11) * 0x1p-53;
}

/* a galaxy as sersic_unpack would set it up, flux 1, centre in [0, 1)^2 */
static void galaxy(struct sersic_gal *g, double n, double re, double q, double th,
		   unsigned long long *s)
{
	double xt = sersic_trunc_x(n, 1e-3);

	memset(g, 0, sizeof(*g));
	g->n = n;
	g->inv_n = 1 / n;
	g->b = sersic_bn(n);
	sersic_axes(re, q, &g->re, &g->minor);
	g->ct = cos(th);
	g->st = sin(th);
	g->rho_t = fmin(fmax(exp(n * log(xt / g->b)), 5.0 / g->minor), 60 / g->re);
	g->rho_t2 = g->rho_t * g->rho_t;
	g->xt = xt;
	g->ia2 = 1 / (g->re * g->re);
	g->ib2 = 1 / (g->minor * g->minor);
	g->qa = g->ct * g->ct * g->ia2 + g->st * g->st * g->ib2;
	g->qc = g->st * g->st * g->ia2 + g->ct * g->ct * g->ib2;
	g->qb = g->ct * g->st * (g->ia2 - g->ib2);
	g->flux = g->finf = g->pt = 1;
	g->lg2n = sersic_lgamma(2 * n);
	g->xc = uniform(s);
	g->yc = uniform(s);
}

int main(void)
{
	static const double ns[] = { 0.3, 0.5, 0.51, 0.7, 0.9, 0.999, 1, 1.001, 1.5, 2, 4, 8, 20 };
	static const double taylors[] = { 0.25, 0.5, 1, 2, 4 };
	enum { H = 60, W = 2 * H + 1 };
	unsigned long long s = 7;
	long pixels = 0, differ = 0, smooth = 0, grads = 0, with_rows = 0, n_lt1 = 0;
	double worst = 0;

	for (int it = 0; it < 650; it++) {
		struct quick p;
		struct sersic_gal g;
		double re = exp(log(1e-3) + uniform(&s) * log(1e5));
		double q = it % 7 == 0 ? 1e-3 : it % 7 == 1 ? 1 : 0.05 + 0.95 * uniform(&s);

		memset(&p, 0, sizeof(p));
		p.taylor = taylors[it % 5];
		for (int k = 0; k < QUICK_GAUSS; k++)
			p.gauss_t[k] = gauss_tmax(k + 1);
		galaxy(&g, ns[(it / 5) % 13], re, q, M_PI * uniform(&s), &s);
		quick_stamp_setup(&g, &p);
		if (g.method_lo2 < INFINITY) {
			with_rows++;
			n_lt1 += g.n < 1;
		}
		for (int y = -H; y <= H; y++) {
			double img[W], gx[W], gy[W], lp[W];
			int any = 0, rough = 0, pany = 0, prough = 0;

			quick_wing_row(&g, &p, y, -H, H, img, gx, gy, lp, &any, &rough);
			for (int x = -H; x <= H; x++) {
				double v, px, py;
				int k = x + H;
				int sm = quick_wing(&g, &p, x - 0.5 - g.xc, x + 0.5 - g.xc, y - 0.5 - g.yc,
						    y + 0.5 - g.yc, &v, &px, &py);
				double d = fabs(img[k] - v) / fmax(fabs(v), 1e-300);

				pixels++;
				differ += !(d <= 1e-11 || fabs(img[k] - v) <= 1e-300);
				worst = d > worst && d < 1 ? d : worst;
				smooth += (lp[k] != 0) != (sm && v != 0);
				grads += !(fabs(gx[k] - px) <= 1e-11 * fabs(px) + 1e-300 &&
					   fabs(gy[k] - py) <= 1e-11 * fabs(py) + 1e-300);
				pany |= v != 0;
				prough |= (sm ? v : 0) != v;
			}
			smooth += any != pany || rough != prough;
		}
	}
	ok(with_rows > 200 && n_lt1 > 50,
	   "fast rows set up for %ld of 650 galaxies (%ld of them n < 1)", with_rows, n_lt1);
	ok(differ == 0, "%ld of %ld pixels: the row's integral within 1e-11 of the pixel's (worst %.2g)",
	   pixels - differ, pixels, worst);
	ok(grads == 0, "gradients the same to 1e-11 (%ld differ)", grads);
	ok(smooth == 0, "the smooth part and the any/rough flags the same (%ld differ)", smooth);

	/* sersic-centre-cut's wedges (sersic_rect_rel with k7): where the
	 * absolute floor is the looser, the 7-point pair is taken (another
	 * value than the 15-point rule's, within the floor); where it is not,
	 * the 15-point rule alone (the same bytes). */
	long loose = 0, took7 = 0, beyond = 0, tight_same = 0, tight = 0;
	for (int it = 0; it < 200; it++) {
		struct sersic_gal g;
		double re = exp(log(1e-3) + uniform(&s) * log(1e4));

		galaxy(&g, ns[it % 13], re, 0.05 + 0.95 * uniform(&s), M_PI * uniform(&s), &s);
		for (int c = 0; c < 9; c++) {
			double h = 0.25, x0 = (c % 3 - 1.5) * h, y0 = (c / 3 - 1.5) * h;
			double rmin = sersic_rho_min(&g, x0, x0 + h, y0, y0 + h);
			double bound = exp(g.lni0 - g.b * pow(rmin, g.inv_n)) * h * h / g.flux;

			if (!(rmin < g.rho_t))
				continue;
			for (int k = 0; k < 2; k++) {
				double atol = k ? 1e-3 : 1e-12;
				double v7 = sersic_rect_rel(&g, x0, x0 + h, y0, y0 + h, rmin, 1e-4, atol, 1);
				double v15 = sersic_rect_rel(&g, x0, x0 + h, y0, y0 + h, rmin, 1e-4, atol, 0);

				if (atol >= 1e-4 * fmin(bound, 1.0)) {
					loose++;
					took7 += v7 != v15;
					beyond += !(fabs(v7 - v15) <= 2 * atol * g.flux);
				} else {
					tight++;
					tight_same += v7 == v15;
				}
			}
		}
	}
	ok(loose > 100 && took7 > loose / 4 && beyond == 0,
	   "loose floor: the 7-point pair taken in %ld of %ld cells, %ld beyond twice the floor",
	   took7, loose, beyond);
	ok(tight > 100 && tight_same == tight, "tight: the 15-point rule alone in %ld of %ld cells",
	   tight_same, tight);
	return done_testing();
}
