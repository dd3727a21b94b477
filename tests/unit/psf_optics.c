/*
 * psf_optics.c - the optics against cases with known answers: aberration-
 * free circular and annular pupils must give the Airy and obscured-Airy
 * patterns (peak, first dark ring, encircled energy) to 1e-3; the Noll
 * Zernikes are the textbook polynomials; the Zernikes interpolated in
 * field and wavelength as data/zernike.tsv and STPSF say; the wavelength
 * weights; the PSF on a skewed pixel grid (the Airy pattern through a
 * Jacobian, the jitter's covariance, the identity Jacobian); a cell's
 * cover with its shortcuts against the plain count.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "optics.h"

#define ARCSEC (M_PI / (180.0 * 3600.0))

/* Amplitude of an annular aperture with obscuration eps at v = pi D theta
 * / lambda, 1 at the centre. */
static double airy_amp(double v, double eps)
{
	if (v < 1e-9)
		return 1;
	double a = 2 * j1(v) / v;
	if (eps > 0)
		a -= eps * eps * 2 * j1(eps * v) / (eps * v);
	return a / (1 - eps * eps);
}

/* First zero of airy_amp, by bisection from its sign change. */
static double first_zero(double eps)
{
	double lo = 2, hi = 2;
	while (airy_amp(hi, eps) > 0)
		hi += 0.05;
	lo = hi - 0.05;
	for (int i = 0; i < 100; i++) {
		double m = 0.5 * (lo + hi);
		if (airy_amp(m, eps) > 0)
			lo = m;
		else
			hi = m;
	}
	return 0.5 * (lo + hi);
}

static void airy_case(double eps)
{
	struct err e = { 0 };
	struct optics_pupil pup;
	const int n = 63, h = 31, zs = 5;
	const double scale = 0.0275, lam = 1.2;        /* arcsec, micron */
	double dth = scale * ARCSEC;
	/* put the first dark ring exactly on sample zs */
	double v0 = first_zero(eps);
	double d = v0 * lam * 1e-6 / (M_PI * zs * dth);
	double wt = 1, *img = malloc(sizeof(double) * n * n);
	double *ref = malloc(sizeof(double) * n * n), sref = 0;

	optics_pupil_annulus(&pup, d / 2, eps * d / 2);
	struct optics_psf_req r = {
		.pupil = &pup, .n = n, .scale = scale, .pupil_n = 512,
		.nwave = 1, .lam = &lam, .wt = &wt, .npos = 1, .threads = 2,
	};
	ok(optics_psf(&r, img, &e) == 0, "eps %.2f: optics_psf: %s", eps, e.msg);
	/* the analytic pattern at the same samples, normalised in the same
	 * box as optics_psf normalises (STPSF's normalize='last') */
	for (int y = 0; y < n; y++)
		for (int x = 0; x < n; x++) {
			double th = hypot(x - h, y - h) * dth;
			double a = airy_amp(M_PI * d * th / (lam * 1e-6), eps);
			ref[y * n + x] = a * a;
			sref += a * a;
		}
	double peak_abs = M_PI * d * d / 4 * (1 - eps * eps) /
			  (lam * lam * 1e-12) * dth * dth;
	double maxd = 0;
	for (int i = 0; i < n * n; i++) {
		ref[i] /= sref;
		maxd = fmax(maxd, fabs(img[i] - ref[i]));
	}
	double pk = img[h * n + h];
	diag("eps %.2f: D = %.4f m, peak %.6f (analytic %.6f), ring %.2e, "
	     "max |diff| %.2e of peak", eps, d, pk, ref[h * n + h],
	     img[h * n + h + zs], maxd / ref[h * n + h]);
	is_near(pk / ref[h * n + h], 1, 1e-3, "eps %.2f: peak to 1e-3", eps);
	/* the box holds sref * peak_abs of the light, so the unnormalised
	 * peak is pk * sref * peak_abs */
	is_rel(pk * (sref * peak_abs), peak_abs, 1e-3,
		"eps %.2f: absolute peak fraction pi D^2 (1-eps^2) dth^2 / 4 "
		"lam^2 to 1e-3", eps);
	ok(img[h * n + h + zs] < 1e-3 * pk && img[(h + zs) * n + h] < 1e-3 * pk,
	   "eps %.2f: first dark ring at %.4f lam/D is dark to 1e-3 of the peak",
	   eps, v0 / M_PI);
	ok(img[h * n + h + zs] < img[h * n + h + zs - 1] &&
	   img[h * n + h + zs] < img[h * n + h + zs + 1],
	   "eps %.2f: and is a minimum", eps);
	for (double rad = 2; rad <= 30; rad *= 2.5) {
		double eo = 0, er = 0;
		for (int y = 0; y < n; y++)
			for (int x = 0; x < n; x++)
				if (hypot(x - h, y - h) <= rad) {
					eo += img[y * n + x];
					er += ref[y * n + x];
				}
		is_near(eo, er, 1e-3, "eps %.2f: encircled energy in %.0f "
			"samples to 1e-3", eps, rad);
	}
	is_near(maxd / ref[h * n + h], 0, 1e-3,
		"eps %.2f: every sample to 1e-3 of the peak", eps);
	free(img);
	free(ref);
}

/*
 * The PSF seen through a non-square pixel grid (optics.h, jac): an
 * aberration-free annulus seen through A = [[1.02, 0.15], [-0.05, 0.93]]
 * (stretched, skewed and turned far beyond any SIAF Jacobian) must be the
 * Airy pattern at the sky offsets scale A u of its samples, to 1e-3 of the
 * peak; and the jitter, isotropic on the sky, adds the covariance
 * sigma^2 A^-1 A^-T in samples (measured as the difference of the
 * images' second moments, to 2 %).
 */
static void skewed_case(void)
{
	struct err e = { 0 };
	struct optics_pupil pup;
	const int n = 95, h = 47;
	const double scale = 0.0275, lam = 1.2, eps = 0.3;
	const double a[4] = { 1.02, 0.15, -0.05, 0.93 };
	double dth = scale * ARCSEC, wt = 1;
	double d = 3 * first_zero(eps) * lam * 1e-6 / (M_PI * 4 * dth);
	double *img = malloc(sizeof(double) * n * n), *jit = malloc(sizeof(double) * n * n);
	double *ref = malloc(sizeof(double) * n * n), sref = 0, maxd = 0;

	optics_pupil_annulus(&pup, d / 2, eps * d / 2);
	struct optics_psf_req r = {
		.pupil = &pup, .n = n, .scale = scale, .pupil_n = 512,
		.nwave = 1, .lam = &lam, .wt = &wt, .npos = 1, .threads = 2, .jac = a,
	};
	ok(optics_psf(&r, img, &e) == 0, "skewed: optics_psf: %s", e.msg);
	for (int y = 0; y < n; y++)
		for (int x = 0; x < n; x++) {
			double u = x - h, v = y - h;
			double th = hypot(a[0] * u + a[1] * v, a[2] * u + a[3] * v) * dth;
			double amp = airy_amp(M_PI * d * th / (lam * 1e-6), eps);
			ref[y * n + x] = amp * amp;
			sref += amp * amp;
		}
	for (int i = 0; i < n * n; i++)
		maxd = fmax(maxd, fabs(img[i] - ref[i] / sref));
	diag("skewed annulus: max |diff| %.2e of the peak", maxd / (ref[h * n + h] / sref));
	is_near(maxd / (ref[h * n + h] / sref), 0, 1e-3,
		"skewed grid: every sample the Airy pattern at scale A u, to 1e-3 of the peak");

	/* jitter of 2 samples' worth on the sky */
	r.jitter = 2 * scale;
	ok(optics_psf(&r, jit, &e) == 0, "skewed with jitter: %s", e.msg);
	double m0[3] = { 0 }, m1[3] = { 0 };
	for (int y = 0; y < n; y++)
		for (int x = 0; x < n; x++) {
			double u = x - h, v = y - h;
			m0[0] += img[y * n + x] * u * u;
			m0[1] += img[y * n + x] * u * v;
			m0[2] += img[y * n + x] * v * v;
			m1[0] += jit[y * n + x] * u * u;
			m1[1] += jit[y * n + x] * u * v;
			m1[2] += jit[y * n + x] * v * v;
		}
	double det = a[0] * a[3] - a[1] * a[2], s2 = 4;
	double i11 = a[3] / det, i12 = -a[1] / det, i21 = -a[2] / det, i22 = a[0] / det;
	double want[3] = { s2 * (i11 * i11 + i12 * i12), s2 * (i11 * i21 + i12 * i22),
			   s2 * (i21 * i21 + i22 * i22) };
	diag("jitter covariance: %.4f %.4f %.4f, want %.4f %.4f %.4f", m1[0] - m0[0],
	     m1[1] - m0[1], m1[2] - m0[2], want[0], want[1], want[2]);
	for (int k = 0; k < 3; k++)
		is_near(m1[k] - m0[k], want[k], 0.02 * want[0],
			"jitter adds sigma^2 A^-1 A^-T, entry %d", k);
	free(img);
	free(jit);
	free(ref);
}

/*
 * The identity Jacobian must give the square grid's PSF (the SCA 1 pupil,
 * its Zernikes and the jitter), to rounding.
 */
static void identity_case(const struct optics *o)
{
	struct err e = { 0 };
	const int n = 45;
	double lam[2], wt[2], zern[2 * OPTICS_NZ], eye[4] = { 1, 0, 0, 1 };
	double *sq = malloc(sizeof(double) * n * n), *id = malloc(sizeof(double) * n * n);
	double maxd = 0, pk = 0;

	optics_weights(o, F158, 1, 2, lam, wt, &e);
	for (int k = 0; k < 2; k++)
		optics_zernike(o, 1, 100, 3900, lam[k], zern + k * OPTICS_NZ);
	struct optics_psf_req r = {
		.pupil = optics_pupil(o, 1, 0), .flip_y = 1, .n = n, .scale = 0.0275,
		.pupil_n = 128, .nwave = 2, .lam = lam, .wt = wt, .npos = 1,
		.zern = zern, .jitter = 0.012, .threads = 2,
	};
	ok(optics_psf(&r, sq, &e) == 0, "square grid: %s", e.msg);
	r.jac = eye;
	ok(optics_psf(&r, id, &e) == 0, "identity Jacobian: %s", e.msg);
	for (int i = 0; i < n * n; i++) {
		maxd = fmax(maxd, fabs(sq[i] - id[i]));
		pk = fmax(pk, sq[i]);
	}
	is_near(maxd / pk, 0, 1e-9, "the identity Jacobian is the square grid, to 1e-9 "
		"of the peak (%.1e)", maxd / pk);
	free(sq);
	free(id);
}

/*
 * A cell's cover with the shortcuts (the coarse map of the mask, the terms
 * far from a cell left out, the rim's radius bounds) against the plain
 * count of the whole clearance test (optics_pupil_cover_plain, and
 * plain_cover in a request): the same numbers for random cells about the
 * edges of the skinny and the wide pupils (the rims, the obscurations,
 * the struts), and the same bits of PSFs through skewed Jacobians, of
 * both masks, with and without the flip.
 */
static unsigned long long lcg = 88172645463325252ULL;

static double unif(double a, double b)
{
	lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;
	return a + (b - a) * (double)(lcg >> 11) / 9007199254740992.0;
}

static void cover_case(const struct optics *o)
{
	for (int w = 0; w < 2; w++) {
		const struct optics_pupil *p = optics_pupil(o, w ? 7 : 1, w);
		long partial = 0, differ = 0, n = 0;

		for (int i = 0; i < 300000; i++, n++) {
			double x, y, d = unif(0.001, 0.02), a, b;
			int kind = i % 3;

			if (kind == 0) {                /* anywhere */
				x = unif(-1.25, 1.25);
				y = unif(-1.25, 1.25);
			} else if (kind == 1) {         /* about the rim or the obscuration */
				int k = (int)unif(0, OPTICS_NANG);
				double th = -M_PI + 2 * M_PI * (k + unif(0, 1)) / OPTICS_NANG;
				double r = (unif(0, 1) < 0.5 ? p->rout[k] : p->rin[k]) + unif(-0.03, 0.03);

				x = r * cos(th);
				y = r * sin(th);
			} else {                        /* about a strut's edges */
				const struct optics_strut *s = &p->strut[(int)unif(0, p->nstrut)];
				double t = unif(s->smin - 0.02, s->smax + 0.02), v = unif(-0.06, 0.06);

				x = s->x0 + t * s->c - v * s->sn;
				y = s->y0 + t * s->sn + v * s->c;
			}
			a = optics_pupil_cover_plain(p, x, y, d);
			b = optics_pupil_cover(p, x, y, d);
			partial += a > 0 && a < 1;
			differ += a != b;
		}
		diag("%s pupil: %ld cells, %ld partly clear, %ld differ", w ? "wide" : "skinny", n,
		     partial, differ);
		ok(differ == 0 && partial > 30000, "%s pupil: every cell's cover the plain count's",
		   w ? "wide" : "skinny");
	}

	for (int c = 0; c < 2; c++) {
		struct err e = { 0 };
		const int n = 45, sca = c ? 7 : 1;
		double lam[3], wt[3], zern[2 * 3 * OPTICS_NZ];
		/* a mild skew and the SIAF's flip; a strong one without it */
		double jac[2][8] = { { 1.02, 0.15, -0.05, 0.93, 0.97, -0.08, 0.11, 1.05 },
				     { 1.6, 0.7, -0.5, 0.8, 0.6, -0.4, 0.3, 1.9 } };
		double *plain = malloc(sizeof(double) * 2 * n * n);
		double *fast = malloc(sizeof(double) * 2 * n * n);

		optics_weights(o, c ? F213 : F129, sca, 3, lam, wt, &e);
		for (int pos = 0; pos < 2; pos++)
			for (int k = 0; k < 3; k++)
				optics_zernike(o, sca, pos ? 3900 : 100, 2000, lam[k],
					       zern + (pos * 3 + k) * OPTICS_NZ);
		struct optics_psf_req r = {
			.pupil = optics_pupil(o, sca, c), .flip_y = !c, .n = n, .scale = 0.0275,
			.pupil_n = 256, .nwave = 3, .lam = lam, .wt = wt, .npos = 2,
			.zern = zern, .threads = 2, .jac = jac[c], .plain_cover = 1,
		};
		ok(optics_psf(&r, plain, &e) == 0, "%s mask, skewed PSF, plain cover: %s",
		   c ? "wide" : "skinny", e.msg);
		r.plain_cover = 0;
		ok(optics_psf(&r, fast, &e) == 0, "%s mask, with the shortcuts: %s",
		   c ? "wide" : "skinny", e.msg);
		ok(memcmp(plain, fast, sizeof(double) * 2 * n * n) == 0,
		   "%s mask: the skewed PSFs of two positions the same bits either way",
		   c ? "wide" : "skinny");
		free(plain);
		free(fast);
	}
}

/*
 * The Zernike interpolation against data/zernike.tsv itself (read here
 * with plain stdio, run from the top of the tree as make check runs it):
 * at a field point and a table wavelength optics_zernike() is the table
 * row; halfway between two table wavelengths the mean of the two rows;
 * halfway from the centre field point to a corner the mean of the two;
 * at the centroid of the centre and two neighbouring corners the mean of
 * the three; beyond the table's wavelengths its last row.
 */
#define ZMAXW 64
struct ztab {
	double lx[6], ly[6];            /* per field point 1..5, mm */
	double wave[ZMAXW];
	int nwave;
	double z[6][ZMAXW][OPTICS_NZ];
};

static int read_ztab(int sca, struct ztab *t)
{
	FILE *f = fopen("data/zernike.tsv", "r");
	char line[4096];

	memset(t, 0, sizeof(*t));
	if (!f)
		return -1;
	while (fgets(line, sizeof(line), f)) {
		int s, fp, n = 0;
		double lx, ly, w, v[OPTICS_NZ];
		char *p = line;

		if (sscanf(p, "%d %d %lf %lf %lf%n", &s, &fp, &lx, &ly, &w, &n) != 5 ||
		    s != sca || fp < 1 || fp > 5)
			continue;
		p += n;
		for (int j = 0; j < OPTICS_NZ; j++) {
			v[j] = strtod(p, &p);
		}
		int k;
		for (k = 0; k < t->nwave && t->wave[k] != w; k++)
			;
		if (k == t->nwave) {
			if (t->nwave == ZMAXW)
				break;
			t->wave[t->nwave++] = w;
		}
		t->lx[fp] = lx;
		t->ly[fp] = ly;
		memcpy(t->z[fp][k], v, sizeof(v));
	}
	fclose(f);
	return t->nwave >= 2 ? 0 : -1;
}

/* STPSF's pixel of a field point, in wfiscene's 0-based science frame
 * (the 4096 frame less 4): round(2048 - 100 local_x), round(2048 + 100
 * local_y) (roman-data.md 4). */
static double fp_x(const struct ztab *t, int fp) { return round(2048 - 100 * t->lx[fp]) - 4; }
static double fp_y(const struct ztab *t, int fp) { return round(2048 + 100 * t->ly[fp]) - 4; }

static double zdiff(const double *a, const double *b)
{
	double m = 0;

	for (int j = 0; j < OPTICS_NZ; j++)
		m = fmax(m, fabs(a[j] - b[j]));
	return m;
}

static void zernike_interp(const struct optics *o, int sca)
{
	static struct ztab t;
	double z[OPTICS_NZ], want[OPTICS_NZ], worst = 0;

	int rc = read_ztab(sca, &t);

	if (!ok(rc == 0, "SCA %d: data/zernike.tsv read (%d wavelengths)", sca,
		t.nwave))
		return;
	/* the wavelengths in increasing order (the table's order) */
	for (int k = 1; k < t.nwave; k++)
		if (!(t.wave[k] > t.wave[k - 1]))
			return (void)ok(0, "table wavelengths increase");
	for (int fp = 1; fp <= 5; fp++)
		for (int k = 0; k < t.nwave; k++) {
			optics_zernike(o, sca, fp_x(&t, fp), fp_y(&t, fp), t.wave[k], z);
			worst = fmax(worst, zdiff(z, t.z[fp][k]));
		}
	ok(worst < 1e-9, "SCA %d: at each field point and table wavelength, the "
	   "table's row (worst %.1e nm)", sca, worst);

	worst = 0;
	for (int fp = 1; fp <= 5; fp++)
		for (int k = 0; k + 1 < t.nwave; k++) {
			optics_zernike(o, sca, fp_x(&t, fp), fp_y(&t, fp),
				       0.5 * (t.wave[k] + t.wave[k + 1]), z);
			for (int j = 0; j < OPTICS_NZ; j++)
				want[j] = 0.5 * (t.z[fp][k][j] + t.z[fp][k + 1][j]);
			worst = fmax(worst, zdiff(z, want));
		}
	ok(worst < 1e-9, "SCA %d: linear in wavelength (worst %.1e nm)", sca, worst);

	worst = 0;
	for (int c = 2; c <= 5; c++)
		for (int k = 0; k < t.nwave; k += 3) {
			optics_zernike(o, sca, 0.5 * (fp_x(&t, 1) + fp_x(&t, c)),
				       0.5 * (fp_y(&t, 1) + fp_y(&t, c)), t.wave[k], z);
			for (int j = 0; j < OPTICS_NZ; j++)
				want[j] = 0.5 * (t.z[1][k][j] + t.z[c][k][j]);
			worst = fmax(worst, zdiff(z, want));
		}
	ok(worst < 1e-9, "SCA %d: halfway from the centre to each corner, the mean "
	   "(worst %.1e nm)", sca, worst);

	/* neighbouring corners: consecutive in angle about the centre */
	int ord[4] = { 2, 3, 4, 5 };
	double ang[6];
	for (int c = 2; c <= 5; c++)
		ang[c] = atan2(fp_y(&t, c) - fp_y(&t, 1), fp_x(&t, c) - fp_x(&t, 1));
	for (int i = 0; i < 4; i++)
		for (int j = i + 1; j < 4; j++)
			if (ang[ord[j]] < ang[ord[i]]) {
				int tmp = ord[i];
				ord[i] = ord[j];
				ord[j] = tmp;
			}
	worst = 0;
	for (int i = 0; i < 4; i++) {
		int b = ord[i], c = ord[(i + 1) % 4], k = t.nwave / 2;

		optics_zernike(o, sca, (fp_x(&t, 1) + fp_x(&t, b) + fp_x(&t, c)) / 3,
			       (fp_y(&t, 1) + fp_y(&t, b) + fp_y(&t, c)) / 3, t.wave[k], z);
		for (int j = 0; j < OPTICS_NZ; j++)
			want[j] = (t.z[1][k][j] + t.z[b][k][j] + t.z[c][k][j]) / 3;
		worst = fmax(worst, zdiff(z, want));
	}
	ok(worst < 1e-9, "SCA %d: at the centroid of the centre and two "
	   "neighbouring corners, the mean of the three (worst %.1e nm)", sca, worst);

	optics_zernike(o, sca, fp_x(&t, 3), fp_y(&t, 3), t.wave[t.nwave - 1] + 0.5, z);
	ok(zdiff(z, t.z[3][t.nwave - 1]) < 1e-9, "SCA %d: beyond the table's "
	   "wavelengths, its last row", sca);
}

int main(void)
{
	struct err e = { 0 };
	double z[OPTICS_NZ];

	/* textbook Noll polynomials at rho = 0.7, theta = 0.3 */
	double rho = 0.7, th = 0.3, x = rho * cos(th), y = rho * sin(th);
	optics_zernike_basis(x, y, z);
	is_near(z[0], sqrt(3) * (2 * rho * rho - 1), 1e-12, "Z4 defocus");
	is_near(z[1], sqrt(6) * rho * rho * sin(2 * th), 1e-12, "Z5");
	is_near(z[2], sqrt(6) * rho * rho * cos(2 * th), 1e-12, "Z6");
	is_near(z[3], sqrt(8) * (3 * pow(rho, 3) - 2 * rho) * sin(th), 1e-12, "Z7");
	is_near(z[4], sqrt(8) * (3 * pow(rho, 3) - 2 * rho) * cos(th), 1e-12, "Z8");
	is_near(z[7], sqrt(5) * (6 * pow(rho, 4) - 6 * rho * rho + 1), 1e-12,
		"Z11 spherical");
	is_near(z[13], sqrt(12) * (10 * pow(rho, 5) - 12 * pow(rho, 3) +
		3 * rho) * sin(th), 1e-12, "Z17");
	is_near(z[18], sqrt(7) * (20 * pow(rho, 6) - 30 * pow(rho, 4) +
		12 * rho * rho - 1), 1e-12, "Z22");

	airy_case(0);
	airy_case(0.3);
	skewed_case();

	if (instrument_init(&e) < 0)
		return printf("# %s\n", e.msg), 1;
	struct optics *o = optics_new(&e);
	ok(o != NULL, "optics tables load: %s", e.msg);
	if (!o)
		return done_testing();
	double lam[8], w[8], s = 0, zz[OPTICS_NZ];
	ok(optics_weights(o, F129, 1, 8, lam, w, &e) == 0, "weights");
	for (int k = 0; k < 8; k++)
		s += w[k];
	is_near(s, 1, 1e-12, "weights sum to 1");
	ok(lam[0] > 1.12 && lam[7] < 1.47 && lam[0] < lam[7],
	   "F129 wavelengths in the band: %.4f .. %.4f", lam[0], lam[7]);
	/* Table row: SCA 1, field point 1, 1.293 micron: Z4 = -0.0149871 waves
	 * (roman-data.md 1.2), at its own STPSF position (2042, 2079) - 4 */
	optics_zernike(o, 1, 2042 - 4, 2079 - 4, 1.293, zz);
	is_near(zz[0], -0.0149871 * 1293, 0.01, "Z4 at SCA01 field point 1, "
		"1.293 micron, in nm");
	const struct optics_pupil *p = optics_pupil(o, 1, 0);
	ok(p && p->nstrut >= 6 && p->rmax > 1.1 && p->rmax < 1.22,
	   "SCA01 skinny pupil: %d struts, rim %.3f m", p ? p->nstrut : 0,
	   p ? p->rmax : 0);
	zernike_interp(o, 1);
	zernike_interp(o, 11);
	identity_case(o);
	cover_case(o);
	ok(optics_pupil_cover(p, 0, 0, 0.005) == 0 &&
	   optics_pupil_cover(p, 0, 0.8, 0.005) == 1,
	   "centre obscured, mid-pupil between struts clear");
	optics_free(o);
	return done_testing();
}
