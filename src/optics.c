/*
 * optics.c - the Roman WFI optical model and polychromatic PSFs; see
 * optics.h for the recipe and the conventions.
 */
#include <complex.h>
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <fftw3.h>

#include "data.h"
#include "err.h"
#include "instrument.h"
#include "optics.h"
#include "pupil.h"
#include "throughput.h"
#include "spectrum.h"

#define NFP 5                   /* field points per SCA */
#define MAXWAVE 32              /* table wavelengths (21 in Cycle 9) */
#define ARCSEC (M_PI / (180.0 * 3600.0))

struct optics {
	struct optics_pupil pupil[2][WFS_NSCA];         /* [wide][sca-1] */
	/* Zernikes: [sca-1][fp][wave][j] in nm; field points in the 4096
	 * frame as STPSF places them */
	int nwave;
	double wave[MAXWAVE];
	double zt[WFS_NSCA][NFP][MAXWAVE][OPTICS_NZ];
	double fpx[WFS_NSCA][NFP], fpy[WFS_NSCA][NFP];
	/* effective area, m^2, on a common 5 nm grid per filter */
	int nthr[WFS_NFILTER];
	double *thr_lam[WFS_NFILTER];
	double *thr_area[WFS_NFILTER];  /* [k * WFS_NSCA + sca-1] */
};

/*
 * FFTW's planner is process-global state shared with every other module
 * that plans transforms, so planning is made thread-safe once for the
 * whole process and serialised here as well; executing a plan on new
 * arrays is thread-safe by FFTW's contract.
 */
static pthread_mutex_t plan_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_once_t plan_once = PTHREAD_ONCE_INIT;

static void plan_init(void)
{
	fftw_make_planner_thread_safe();
}

static int mask_index(const char *s)
{
	return !strcmp(s, "wide") ? 1 : !strcmp(s, "skinny") ? 0 : -1;
}

static int load_pupils(struct optics *o, struct err *e)
{
	struct tsv t;
	int cm, cs, ce, cr;

	if (tsv_parse(&t, "pupil_edge.tsv"))
		return err_set(e, EXIT_SYSTEM, "broken build: no pupil_edge.tsv");
	cm = tsv_col(&t, "mask");
	cs = tsv_col(&t, "sca");
	ce = tsv_col(&t, "edge");
	cr = tsv_col(&t, "r0");
	if (cm < 0 || cs < 0 || ce < 0 || cr < 0 || t.ncol < cr + OPTICS_NANG)
		goto bad;
	for (int r = 1; r < t.nrow; r++) {
		int w = mask_index(t.cell[r][cm]), sca = atoi(t.cell[r][cs]);
		if (w < 0 || sca < 1 || sca > WFS_NSCA)
			goto bad;
		struct optics_pupil *p = &o->pupil[w][sca - 1];
		double *rr = !strcmp(t.cell[r][ce], "out") ? p->rout : p->rin;
		long acc = 0;   /* delta-coded radii in 0.1 mm */
		for (int k = 0; k < OPTICS_NANG; k++) {
			acc += atol(t.cell[r][cr + k]);
			rr[k] = acc * 1e-4;
		}
		p->half = OPTICS_HALF;
	}
	tsv_free(&t);
	for (int w = 0; w < 2; w++)
		for (int s = 0; s < WFS_NSCA; s++) {
			struct optics_pupil *p = &o->pupil[w][s];
			p->rmax = 0;
			p->rout_min = INFINITY;
			p->rin_max = 0;
			for (int k = 0; k < OPTICS_NANG; k++) {
				if (p->rout[k] > p->rmax)
					p->rmax = p->rout[k];
				p->rout_min = fmin(p->rout_min, p->rout[k]);
				p->rin_max = fmax(p->rin_max, p->rin[k]);
			}
			if (p->rmax <= 0)
				return err_set(e, EXIT_SYSTEM, "broken build: "
					       "pupil_edge.tsv lacks SCA %d", s + 1);
		}

	if (tsv_parse(&t, "pupil_strut.tsv"))
		return err_set(e, EXIT_SYSTEM, "broken build: no pupil_strut.tsv");
	const char *names[] = { "mask", "sca", "x0", "y0", "phi", "lo_a", "lo_b",
				"hi_a", "hi_b", "smin", "smax" };
	int c[11];
	for (int i = 0; i < 11; i++)
		if ((c[i] = tsv_col(&t, names[i])) < 0)
			goto bad;
	for (int r = 1; r < t.nrow; r++) {
		int w = mask_index(t.cell[r][c[0]]), sca = atoi(t.cell[r][c[1]]);
		if (w < 0 || sca < 1 || sca > WFS_NSCA)
			goto bad;
		struct optics_pupil *p = &o->pupil[w][sca - 1];
		if (p->nstrut == OPTICS_MAXSTRUT)
			goto bad;
		struct optics_strut *s = &p->strut[p->nstrut++];
		double phi = atof(t.cell[r][c[4]]);
		s->x0 = atof(t.cell[r][c[2]]);
		s->y0 = atof(t.cell[r][c[3]]);
		s->c = cos(phi);
		s->sn = sin(phi);
		s->lo_a = atof(t.cell[r][c[5]]);
		s->lo_b = atof(t.cell[r][c[6]]);
		s->hi_a = atof(t.cell[r][c[7]]);
		s->hi_b = atof(t.cell[r][c[8]]);
		s->smin = atof(t.cell[r][c[9]]);
		s->smax = atof(t.cell[r][c[10]]);
	}
	tsv_free(&t);
	return 0;
bad:
	tsv_free(&t);
	return err_set(e, EXIT_SYSTEM, "broken build: malformed pupil table");
}

static int load_zernikes(struct optics *o, struct err *e)
{
	struct tsv t;
	int cs, cf, cx, cy, cw, cz;

	if (tsv_parse(&t, "zernike.tsv"))
		return err_set(e, EXIT_SYSTEM, "broken build: no zernike.tsv");
	cs = tsv_col(&t, "sca");
	cf = tsv_col(&t, "fp");
	cx = tsv_col(&t, "local_x");
	cy = tsv_col(&t, "local_y");
	cw = tsv_col(&t, "wave");
	cz = tsv_col(&t, "Z4");
	if (cs < 0 || cf < 0 || cx < 0 || cy < 0 || cw < 0 || cz < 0 ||
	    t.ncol < cz + OPTICS_NZ)
		goto bad;
	o->nwave = 0;
	for (int r = 1; r < t.nrow; r++) {
		int sca = atoi(t.cell[r][cs]), fp = atoi(t.cell[r][cf]), k;
		double w = atof(t.cell[r][cw]);

		if (sca < 1 || sca > WFS_NSCA || fp < 1 || fp > NFP)
			goto bad;
		for (k = 0; k < o->nwave && fabs(o->wave[k] - w) > 1e-9; k++)
			;
		if (k == o->nwave) {
			/* the table lists wavelengths in ascending order */
			if (k == MAXWAVE || (k && w < o->wave[k - 1]))
				goto bad;
			o->wave[o->nwave++] = w;
		}
		for (int j = 0; j < OPTICS_NZ; j++)
			o->zt[sca - 1][fp - 1][k][j] = atof(t.cell[r][cz + j]);
		/* STPSF's placement of a field point on the 4096 frame */
		o->fpx[sca - 1][fp - 1] = round(2048 - 100 * atof(t.cell[r][cx]));
		o->fpy[sca - 1][fp - 1] = round(2048 + 100 * atof(t.cell[r][cy]));
	}
	tsv_free(&t);
	return o->nwave ? 0 : err_set(e, EXIT_SYSTEM, "broken build: empty zernike.tsv");
bad:
	tsv_free(&t);
	return err_set(e, EXIT_SYSTEM, "broken build: malformed zernike.tsv");
}

static int load_throughput(struct optics *o, struct err *e)
{
	return throughput_read(o->thr_lam, o->thr_area, o->nthr, e);
}

struct optics *optics_new(struct err *e)
{
	struct optics *o = calloc(1, sizeof(*o));

	if (!o) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		return NULL;
	}
	if (load_pupils(o, e) || load_zernikes(o, e) || load_throughput(o, e)) {
		optics_free(o);
		return NULL;
	}
	return o;
}

void optics_free(struct optics *o)
{
	if (!o)
		return;
	for (int f = 0; f < WFS_NFILTER; f++) {
		free(o->thr_lam[f]);
		free(o->thr_area[f]);
	}
	free(o);
}

const struct optics_pupil *optics_pupil(const struct optics *o, int sca,
					int wide)
{
	if (sca < 1 || sca > WFS_NSCA)
		return NULL;
	return &o->pupil[!!wide][sca - 1];
}

/*
 * Field interpolation as STPSF does it (scipy griddata 'linear' over the
 * five field points): the Delaunay triangles of centre + four corners are
 * the four triangles (centre, corner, next corner around the centre), and
 * inside one the values are blended barycentrically.  Outside their hull
 * the point is projected onto the line through its two nearest corners
 * and interpolated there, or takes the nearest corner if the projection
 * falls outside that edge.  The result is a weight per field point.
 */
static void field_weights(const double *fx, const double *fy, double x,
			  double y, double w[NFP])
{
	int ord[4] = { 1, 2, 3, 4 };
	double ang[NFP];

	memset(w, 0, NFP * sizeof(double));
	for (int i = 1; i < NFP; i++)
		ang[i] = atan2(fy[i] - fy[0], fx[i] - fx[0]);
	for (int i = 0; i < 4; i++)     /* corners in angle order */
		for (int j = i + 1; j < 4; j++)
			if (ang[ord[j]] < ang[ord[i]]) {
				int t = ord[i];
				ord[i] = ord[j];
				ord[j] = t;
			}
	for (int t = 0; t < 4; t++) {
		int a = 0, b = ord[t], c = ord[(t + 1) % 4];
		double det = (fx[b] - fx[a]) * (fy[c] - fy[a]) -
			     (fx[c] - fx[a]) * (fy[b] - fy[a]);
		double lb = ((x - fx[a]) * (fy[c] - fy[a]) -
			     (fx[c] - fx[a]) * (y - fy[a])) / det;
		double lc = ((fx[b] - fx[a]) * (y - fy[a]) -
			     (x - fx[a]) * (fy[b] - fy[a])) / det;
		double la = 1 - lb - lc;
		const double eps = -1e-12;
		if (la >= eps && lb >= eps && lc >= eps) {
			w[a] = la;
			w[b] = lb;
			w[c] = lc;
			return;
		}
	}
	/* outside: the two nearest corners */
	int n1 = 1, n2 = 2;
	double d[NFP];
	for (int i = 1; i < NFP; i++)
		d[i] = hypot(x - fx[i], y - fy[i]);
	if (d[n2] < d[n1]) {
		n1 = 2;
		n2 = 1;
	}
	for (int i = 3; i < NFP; i++)
		if (d[i] < d[n1]) {
			n2 = n1;
			n1 = i;
		} else if (d[i] < d[n2]) {
			n2 = i;
		}
	double ex = fx[n2] - fx[n1], ey = fy[n2] - fy[n1];
	double t = ((x - fx[n1]) * ex + (y - fy[n1]) * ey) / (ex * ex + ey * ey);
	if (t < 0 || t > 1) {
		w[n1] = 1;
		return;
	}
	w[n1] = 1 - t;
	w[n2] = t;
}

void optics_zernike(const struct optics *o, int sca, double x, double y,
		    double lam, double z[OPTICS_NZ])
{
	double w[NFP], f;
	int k;

	field_weights(o->fpx[sca - 1], o->fpy[sca - 1], x + 4, y + 4, w);
	/* linear in wavelength, clipped to the table's range */
	if (lam <= o->wave[0]) {
		k = 0;
		f = 0;
	} else if (lam >= o->wave[o->nwave - 1]) {
		k = o->nwave - 2;
		f = 1;
	} else {
		for (k = 0; k < o->nwave - 2 && lam > o->wave[k + 1]; k++)
			;
		f = (lam - o->wave[k]) / (o->wave[k + 1] - o->wave[k]);
	}
	for (int j = 0; j < OPTICS_NZ; j++) {
		double v = 0;
		for (int p = 0; p < NFP; p++)
			v += w[p] * ((1 - f) * o->zt[sca - 1][p][k][j] +
				     f * o->zt[sca - 1][p][k + 1][j]);
		z[j] = v;
	}
}

/* Effective area of filter f on SCA sca at lam (micron), linear. */
static double area_at(const struct optics *o, int f, int sca, double lam)
{
	const double *l = o->thr_lam[f];
	int n = o->nthr[f];

	if (n < 2 || lam <= l[0] || lam >= l[n - 1])
		return 0;
	int k = (int)((lam - l[0]) / (l[1] - l[0]));   /* uniform 5 nm grid */
	if (k > n - 2)
		k = n - 2;
	double t = (lam - l[k]) / (l[k + 1] - l[k]);
	return (1 - t) * o->thr_area[f][k * WFS_NSCA + sca - 1] +
	       t * o->thr_area[f][(k + 1) * WFS_NSCA + sca - 1];
}

/* Photons per unit wavelength from a blackbody at temperature T, up to a
 * constant: B_lambda / (h c / lambda) ~ lambda^-4 / (exp(c2 / lambda T) - 1)
 * with c2 = h c / k = 14387.77 micron K. */
static double bb_photons(double lam, double temp)
{
	return pow(lam, -4) / expm1(14387.77 / (lam * temp));
}

int optics_weights(const struct optics *o, int filter, int sca, int nwave,
		   double *lam, double *w, struct err *e)
{
	return optics_weights_spec(o, filter, sca, nwave, NULL, lam, w, e);
}

int optics_weights_spec(const struct optics *o, int filter, int sca, int nwave,
			const struct spectrum *spec, double *lam, double *w, struct err *e)
{
	if (filter < 0 || filter >= WFS_NFILTER || sca < 1 || sca > WFS_NSCA ||
	    o->nthr[filter] < 2 || nwave < 1)
		return err_set(e, EXIT_INPUT, "no throughput for filter %d SCA %d",
			       filter, sca);
	const double *l = o->thr_lam[filter];
	int n = o->nthr[filter];
	double peak = 0, lo = l[0], hi = l[n - 1];

	for (int k = 0; k < n; k++)
		peak = fmax(peak, o->thr_area[filter][k * WFS_NSCA + sca - 1]);
	/* the band: first and last crossing of 10% of the peak */
	for (int k = 1; k < n; k++) {
		double a = o->thr_area[filter][(k - 1) * WFS_NSCA + sca - 1];
		double b = o->thr_area[filter][k * WFS_NSCA + sca - 1];
		if (a < 0.1 * peak && b >= 0.1 * peak) {
			lo = l[k - 1] + (0.1 * peak - a) / (b - a) * (l[k] - l[k - 1]);
			break;
		}
	}
	for (int k = n - 1; k > 0; k--) {
		double a = o->thr_area[filter][(k - 1) * WFS_NSCA + sca - 1];
		double b = o->thr_area[filter][k * WFS_NSCA + sca - 1];
		if (b < 0.1 * peak && a >= 0.1 * peak) {
			hi = l[k - 1] + (a - 0.1 * peak) / (a - b) * (l[k] - l[k - 1]);
			break;
		}
	}
	double total = 0;
	for (int b = 0; b < nwave; b++) {
		double a0 = lo + (hi - lo) * b / nwave, a1 = lo + (hi - lo) * (b + 1) / nwave;
		double s = 0, sl = 0;
		int m = 200;    /* midpoint rule, sub-nm steps */
		for (int i = 0; i < m; i++) {
			double x = a0 + (a1 - a0) * (i + 0.5) / m;
			/* photons per unit wavelength: f_nu / (h lam) */
			double v = area_at(o, filter, sca, x) *
				   (spec ? spec_fnu(spec, x, 1.0) / x :
				    bb_photons(x, OPTICS_BB_TEMP));
			s += v;
			sl += v * x;
		}
		w[b] = s;
		lam[b] = s > 0 ? sl / s : 0.5 * (a0 + a1);
		total += s;
	}
	if (!(total > 0))
		return err_set(e, EXIT_SYSTEM, "filter %d SCA %d: zero throughput",
			       filter, sca);
	for (int b = 0; b < nwave; b++)
		w[b] /= total;
	return 0;
}

double optics_lam_max(const struct optics *o, int filter)
{
	if (filter < 0 || filter >= WFS_NFILTER || o->nthr[filter] < 1)
		return 2.5;
	return o->thr_lam[filter][o->nthr[filter] - 1];
}

/* Noll's n and m of Z4..Z22 (Noll 1976: m > 0 takes cos |m| theta, even j;
 * m < 0 sin |m| theta, odd j), constants so that zernike_eval()'s loops
 * unroll into straight code */
static const signed char zern_n[OPTICS_NZ] = { 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 4, 5, 5, 5, 5,
					       5, 5, 6 };
static const signed char zern_m[OPTICS_NZ] = { 0, -2, 2, -1, 1, -3, 3, 0, 2, -2, 4, -4, 1, -1,
					       3, -3, 5, -5, 0 };

/*
 * Z4..Z22 at one point, unit RMS over the unit disk (Noll 1976):
 * Z = sqrt(n+1) R_n^0(rho) for m = 0, else sqrt(2(n+1)) R_n^|m|(rho) times
 * cos |m| theta (even j) or sin |m| theta (odd j), with
 * R_n^m(rho) = sum_k (-1)^k (n-k)! / (k! ((n+m)/2-k)! ((n-m)/2-k)!) rho^(n-2k).
 * The coefficients are fixed integers, so they are tabulated once per
 * call by zernike_table() and the powers and multiple angles come from
 * products rather than pow/cos/sin.
 */
struct zterm {
	double c[4];            /* c[k] multiplies rho^(n-2k), norm included */
};

static void zernike_table(struct zterm zt[OPTICS_NZ])
{
	static const double fact[] = { 1, 1, 2, 6, 24, 120, 720 };

	for (int q = 0; q < OPTICS_NZ; q++) {
		int n = zern_n[q], m = zern_m[q], am = abs(m);
		double norm = m == 0 ? sqrt(n + 1.0) : sqrt(2.0 * (n + 1));

		for (int k = 0; k < (n - am) / 2 + 1; k++)
			zt[q].c[k] = norm * (k % 2 ? -1 : 1) * fact[n - k] /
				     (fact[k] * fact[(n + am) / 2 - k] * fact[(n - am) / 2 - k]);
	}
}

static void zernike_eval(const struct zterm zt[OPTICS_NZ], double x, double y,
			 double out[OPTICS_NZ])
{
	double rp[7], cm[6], sm[6];
	double r = hypot(x, y);
	double c1 = r > 0 ? x / r : 1, s1 = r > 0 ? y / r : 0;

	rp[0] = 1;
	for (int i = 1; i < 7; i++)
		rp[i] = rp[i - 1] * r;
	cm[0] = 1;
	sm[0] = 0;
	for (int i = 1; i < 6; i++) {   /* angle addition: (m+1) theta */
		cm[i] = cm[i - 1] * c1 - sm[i - 1] * s1;
		sm[i] = sm[i - 1] * c1 + cm[i - 1] * s1;
	}
#pragma GCC unroll 19
	for (int q = 0; q < OPTICS_NZ; q++) {
		const struct zterm *z = &zt[q];
		int n = zern_n[q], m = zern_m[q], am = m < 0 ? -m : m;
		double v = 0;
#pragma GCC unroll 4
		for (int k = 0; k < (n - am) / 2 + 1; k++)
			v += z->c[k] * rp[n - 2 * k];
		out[q] = m == 0 ? v : v * (m > 0 ? cm[am] : sm[am]);
	}
}

void optics_zernike_basis(double x, double y, double z[OPTICS_NZ])
{
	struct zterm zt[OPTICS_NZ];

	zernike_table(zt);
	zernike_eval(zt, x, y, z);
}

/* The smallest size >= n of the form 2^a 3^b 5^c, which FFTW does fastest. */
static int good_size(int n)
{
	for (int m = n;; m++) {
		int r = m;
		while (r % 2 == 0)
			r /= 2;
		while (r % 3 == 0)
			r /= 3;
		while (r % 5 == 0)
			r /= 5;
		if (r == 1)
			return m;
	}
}

/* hypot(x, y) <= OPTICS_ZRADIUS, r2 = x x + y y: from r2 but within
 * 1e-12 of the radius, where the two roundings could part (hypot is
 * within an ulp, r2 within three) */
static inline int in_zradius(double x, double y, double r2)
{
	const double lo = OPTICS_ZRADIUS * OPTICS_ZRADIUS * (1 - 1e-12);
	const double hi = OPTICS_ZRADIUS * OPTICS_ZRADIUS * (1 + 1e-12);

	if (r2 < lo)
		return 1;
	if (r2 > hi)
		return 0;
	return hypot(x, y) <= OPTICS_ZRADIUS;
}

/* a e^(i th): cexp's own numbers (its exp(0) is 1, its cos and sin
 * sincos's), without its cases for an infinite or huge argument */
static inline fftw_complex field(double a, double th)
{
	double sn, cs;

	if (fabs(th) > DBL_MIN) {
		__builtin_sincos(th, &sn, &cs);
	} else {
		sn = th;
		cs = 1;
	}
	return a * cs + I * (a * sn);
}

/* Columns or rows moved at a time between the transforms' arrays. */
#define OPTICS_BLOCK 16

/* One wavelength's pupil, shared by all positions: the lit samples, their
 * amplitude and the Zernike basis there. */
struct mono_pupil {
	int nlit;               /* (its side: the wavelength's p) */
	int *idx;               /* row * p + col of each lit sample */
	double *amp;
	double *basis;          /* [j * nlit + i] */
};

/* One wavelength of the request: its weight, its index k, its pupil
 * raster's step dx (m) and side p, and the plans for that size. */
struct wave {
	double lam, wt, dx;
	int k, p;
	fftw_plan rows, cols;
};

struct job {
	const struct optics_psf_req *r;
	int nfft, h;
	struct wave *wv;        /* r->nwave of them */
	const struct wave *cur; /* the one being done (the shared pupil's) */
	double *acc;            /* npos x n x n, the weighted sum */
	double *sinc;           /* sinc(pi (k - h) / nfft) of output sample k */
	struct pupil_coarse co; /* the mask's clear and dark cells (skewed pupils) */
	/* acc of position pos takes wavelength turn[pos] next (in order of
	 * wavelength whatever thread computes it, so the same sums) */
	int *turn;
	pthread_mutex_t turn_lock;
	pthread_cond_t turn_cond;
	struct mono_pupil mp;
	int pmax, nth;
	fftw_complex **b1, **b2;
	double **tmp;
	struct zterm zt[OPTICS_NZ];
	atomic_int next;
	int ntask;
	void (*fn)(struct job *, int task, int tid);
};

static void *worker(void *arg)
{
	void **a = arg;
	struct job *j = a[0];
	int tid = (int)(intptr_t)a[1];
	int t;

	while ((t = atomic_fetch_add(&j->next, 1)) < j->ntask)
		j->fn(j, t, tid);
	return NULL;
}

/* Run fn for tasks 0..ntask-1 on nthreads threads (the caller is one). */
static void par_for(struct job *j, int nthreads, int ntask,
		    void (*fn)(struct job *, int, int))
{
	pthread_t th[64];
	void *args[64][2];
	int started = 0;

	atomic_store(&j->next, 0);
	j->ntask = ntask;
	j->fn = fn;
	if (nthreads > ntask)
		nthreads = ntask;
	for (int t = 1; t < nthreads && t < 64; t++) {
		args[t][0] = j;
		args[t][1] = (void *)(intptr_t)t;
		if (pthread_create(&th[t], NULL, worker, args[t]))
			break;
		started = t;
	}
	args[0][0] = j;
	args[0][1] = (void *)(intptr_t)0;
	worker(args[0]);
	for (int t = 1; t <= started; t++)
		pthread_join(th[t], NULL);
}

/* Rasterise rows of the shared pupil for wavelength j->cur: task = row. */
static void pupil_row(struct job *j, int row, int tid)
{
	const struct optics_psf_req *r = j->r;
	int p = j->cur->p;
	double dx = j->cur->dx;
	double y = (row - (p - 1) / 2.0) * dx;
	double *out = j->tmp[tid];      /* amp, then basis per column */

	for (int c = 0; c < p; c++) {
		double x = (c - (p - 1) / 2.0) * dx;
		/* STPSF flips the wavefront in y after the mask: the Zernike
		 * plane at (x, y) sees the mask at (x, -y). */
		out[c] = (r->plain_cover ? optics_pupil_cover_plain : optics_pupil_cover)(
			r->pupil, x, r->flip_y ? -y : y, dx);
	}
	/* stored by row into the shared amplitude image */
	memcpy(j->mp.amp + (size_t)row * p, out, p * sizeof(double));
}

static void basis_task(struct job *j, int blk, int tid)
{
	int i0 = blk * 4096, i1 = i0 + 4096;
	int p = j->cur->p;
	double dx = j->cur->dx;

	if (i1 > j->mp.nlit)
		i1 = j->mp.nlit;
	for (int i = i0; i < i1; i++) {
		int row = j->mp.idx[i] / p, col = j->mp.idx[i] % p;
		double x = (col - (p - 1) / 2.0) * dx, y = (row - (p - 1) / 2.0) * dx;
		double zv[OPTICS_NZ];
		/* poppy's ZernikeWFE is zero beyond its radius */
		if (in_zradius(x, y, x * x + y * y))
			zernike_eval(j->zt, x / OPTICS_ZRADIUS,
				     y / OPTICS_ZRADIUS, zv);
		else
			memset(zv, 0, sizeof(zv));
		for (int z = 0; z < OPTICS_NZ; z++)
			j->mp.basis[(size_t)z * j->mp.nlit + i] = zv[z];
	}
}

/* The pupil of position pos at wavelength w seen through its Jacobian
 * (optics.h): sample s of the transform's grid holds the pupil and
 * the Zernike phase at r = B s, B = A^-T, into b1 (p rows of nfft). */
static void skewed_pupil(struct job *j, const struct wave *w, int pos, fftw_complex *b1,
			 double *zb)
{
	const struct optics_psf_req *r = j->r;
	const double *a = r->jac + 4 * (size_t)pos;
	int p = w->p, nfft = j->nfft;
	double dx = w->dx;
	double det = a[0] * a[3] - a[1] * a[2];
	double b[4] = { a[3] / det, -a[2] / det, -a[1] / det, a[0] / det };
	const double *z = r->zern ? r->zern + ((size_t)pos * r->nwave + w->k) *
			  OPTICS_NZ : NULL;
	double k2pi = 2 * M_PI / (w->lam * 1000);      /* rad per nm */
	/* cells wholly beyond the rim or inside the obscuration are dark:
	 * the radius alone tells, without the cover's angle and struts */
	double reach = 0.5 * dx * fmax(hypot(b[0] + b[1], b[2] + b[3]),
				       hypot(b[0] - b[1], b[2] - b[3]));
	double rin = INFINITY;
	for (int k = 0; k < OPTICS_NANG; k++)
		rin = fmin(rin, r->pupil->rin[k]);
	double out2 = pow(r->pupil->rmax + 1.01 * reach, 2);
	double in2 = rin > 1.01 * reach ? pow(rin - 1.01 * reach, 2) : -1;

	/* a row's lit samples first (column, amplitude, Zernike basis or
	 * none), then their phases four at a time (each sum in the order of
	 * its terms, the four chains side by side), then their fields */
	double *la = zb + (size_t)p * OPTICS_NZ;
	int *lc = (int *)(la + p);

	for (int row = 0; row < p; row++) {
		double sy = (row - (p - 1) / 2.0) * dx;
		int nl = 0;

		for (int col = 0; col < p; col++) {
			double sx = (col - (p - 1) / 2.0) * dx;
			double x = b[0] * sx + b[1] * sy, y = b[2] * sx + b[3] * sy;
			double r2 = x * x + y * y;

			if (r2 > out2 || r2 < in2)
				continue;
			int cl = pupil_coarse_at(&j->co, x, r->flip_y ? -y : y);
			double am = cl == PUPIL_CLEAR ? 1 : cl == PUPIL_DARK ? 0 :
				    pupil_cover_affine(r->pupil, x, y, b, dx, r->flip_y, reach,
						       r->plain_cover);

			if (am <= 0)
				continue;
			/* poppy's ZernikeWFE is zero beyond its radius */
			if (z && in_zradius(x, y, r2))
				zernike_eval(j->zt, x / OPTICS_ZRADIUS, y / OPTICS_ZRADIUS,
					     zb + (size_t)nl * OPTICS_NZ);
			else
				zb[(size_t)nl * OPTICS_NZ] = NAN;       /* no phase */
			lc[nl] = col;
			la[nl++] = am;
		}
		for (int i = 0; i < nl; i += 4) {
			const double *v0 = zb + (size_t)i * OPTICS_NZ;
			double ph[4] = { 0, 0, 0, 0 };
			int m = nl - i < 4 ? nl - i : 4;

			if (m == 4 && !isnan(v0[0]) && !isnan(v0[OPTICS_NZ]) &&
			    !isnan(v0[2 * OPTICS_NZ]) && !isnan(v0[3 * OPTICS_NZ])) {
				for (int q = 0; q < OPTICS_NZ; q++) {
					ph[0] += z[q] * v0[q];
					ph[1] += z[q] * v0[OPTICS_NZ + q];
					ph[2] += z[q] * v0[2 * OPTICS_NZ + q];
					ph[3] += z[q] * v0[3 * OPTICS_NZ + q];
				}
			} else {
				for (int t = 0; t < m; t++)
					if (!isnan(v0[t * OPTICS_NZ]))
						for (int q = 0; q < OPTICS_NZ; q++)
							ph[t] += z[q] * v0[t * OPTICS_NZ + q];
			}
			for (int t = 0; t < m; t++)
				b1[(size_t)row * nfft + lc[i + t]] = field(la[i + t], k2pi * ph[t]);
		}
	}
}

/* One position at wavelength w: field, two pruned FFT passes, intensity
 * normalised in the box, added with the wavelength's weight after the
 * wavelengths before it.  It has no way to fail: a return before its
 * turn is passed on would leave the next wavelength's thread waiting. */
static void one_position(struct job *j, const struct wave *w, int pos, int tid)
{
	const struct optics_psf_req *r = j->r;
	int n = r->n, h = j->h, nfft = j->nfft, p = w->p;
	fftw_complex *b1 = j->b1[tid], *b2 = j->b2[tid];
	const double *z = r->zern ? r->zern + ((size_t)pos * r->nwave + w->k) *
			  OPTICS_NZ : NULL;
	double k2pi = 2 * M_PI / (w->lam * 1000);      /* rad per nm */

	memset(b1, 0, (size_t)p * nfft * sizeof(fftw_complex));
	if (r->jac) {
		skewed_pupil(j, w, pos, b1, j->tmp[tid]);
	} else for (int i = 0; i < j->mp.nlit; i++) {
		double ph = 0;
		if (z)
			for (int q = 0; q < OPTICS_NZ; q++)
				ph += z[q] * j->mp.basis[(size_t)q * j->mp.nlit + i];
		int row = j->mp.idx[i] / p, col = j->mp.idx[i] % p;
		double a = j->mp.amp[j->mp.idx[i]];
		b1[(size_t)row * nfft + col] = field(a, k2pi * ph);
	}
	fftw_execute_dft(w->rows, b1, b1);
	/* gather the n wanted frequencies of every row into columns (the
	 * columns' rows from p on zero), OPTICS_BLOCK columns at a time so
	 * that both sides are read and written a cache line at a time */
	for (int c0 = 0; c0 < n; c0 += OPTICS_BLOCK) {
		int c1 = c0 + OPTICS_BLOCK < n ? c0 + OPTICS_BLOCK : n;

		for (int row = 0; row < p; row++) {
			const fftw_complex *in = b1 + (size_t)row * nfft;

			for (int c = c0; c < c1; c++)
				b2[(size_t)c * nfft + row] = in[c < h ? c - h + nfft : c - h];
		}
		for (int c = c0; c < c1; c++)
			memset(b2 + (size_t)c * nfft + p, 0, (size_t)(nfft - p) * sizeof(fftw_complex));
	}
	fftw_execute_dft(w->cols, b2, b2);
	/* The pupil's samples are the clear fraction of their cells, i.e. the
	 * pupil convolved with the cell, whose transform multiplies the field
	 * by sinc(pi u / nfft) sinc(pi v / nfft) at output sample (u, v) for
	 * every wavelength alike: divided out here, or the far wing is dimmed
	 * by up to sinc^2(pi / 4) = 0.81 at the edge of a field of nfft / 2
	 * samples (a 7% error at 230 pixels of a 256-pixel halo against a
	 * larger computation before; BENCHMARKS.md "Halo"). */
	/* (a block of OPTICS_BLOCK rows at a time, read along the columns;
	 * then summed in row order) */
	double *img = j->tmp[tid], sum = 0;
	for (int y0 = 0; y0 < n; y0 += OPTICS_BLOCK) {
		int y1 = y0 + OPTICS_BLOCK < n ? y0 + OPTICS_BLOCK : n;

		for (int c = 0; c < n; c++) {
			const fftw_complex *col = b2 + (size_t)c * nfft;
			double sx = j->sinc[c];

			for (int yy = y0; yy < y1; yy++) {
				fftw_complex v = col[yy < h ? yy - h + nfft : yy - h];
				double sy = j->sinc[yy];

				img[(size_t)yy * n + c] = (creal(v) * creal(v) + cimag(v) * cimag(v)) /
							  (sx * sx * sy * sy);
			}
		}
	}
	for (size_t i = 0; i < (size_t)n * n; i++)
		sum += img[i];
	double *acc = j->acc + (size_t)pos * n * n, s = sum > 0 ? w->wt / sum : 0;

	/* added when the wavelengths before are, then the next one's turn */
	pthread_mutex_lock(&j->turn_lock);
	while (j->turn[pos] != w->k)
		pthread_cond_wait(&j->turn_cond, &j->turn_lock);
	pthread_mutex_unlock(&j->turn_lock);
	for (int i = 0; i < n * n; i++)
		acc[i] += s * img[i];
	pthread_mutex_lock(&j->turn_lock);
	j->turn[pos]++;
	pthread_cond_broadcast(&j->turn_cond);
	pthread_mutex_unlock(&j->turn_lock);
}

/* The shared pupil's wavelength at one position (task = position). */
static void position_task(struct job *j, int pos, int tid)
{
	one_position(j, j->cur, pos, tid);
}

/* A skewed pupil's wavelength and position: task = k npos + pos, so that
 * the threads take the wavelengths in order and, with few positions, two
 * wavelengths of one position at once. */
static void wave_task(struct job *j, int task, int tid)
{
	one_position(j, &j->wv[task / j->r->npos], task % j->r->npos, tid);
}

/* Gaussian jitter on an n x n image through its DFT: multiply by the
 * Gaussian's transfer function exp(-2 pi^2 sigma^2 f^2) (f in cycles per
 * sample).  This is the exact convolution for a band-limited image,
 * which a 4x-sampled PSF nearly is; a sampled kernel would not be at
 * sigma ~ 0.4 samples.  Normalised to sum 1 afterwards.  With cov =
 * { cxx, cxy, cyy } (samples^2) the Gaussian of that covariance instead:
 * exp(-2 pi^2 f^T C f). */
static int jitter(double *img, int n, double sigma, const double *cov,
		  struct err *e)
{
	int nc = n / 2 + 1;
	fftw_complex *spec = fftw_malloc(sizeof(fftw_complex) * n * nc);
	double *buf = fftw_malloc(sizeof(double) * n * n);
	fftw_plan fw, bw;

	if (!spec || !buf) {
		fftw_free(spec);
		fftw_free(buf);
		return err_set(e, EXIT_SYSTEM, "out of memory");
	}
	pthread_mutex_lock(&plan_lock);
	fw = fftw_plan_dft_r2c_2d(n, n, buf, spec, FFTW_ESTIMATE);
	bw = fftw_plan_dft_c2r_2d(n, n, spec, buf, FFTW_ESTIMATE);
	pthread_mutex_unlock(&plan_lock);
	memcpy(buf, img, sizeof(double) * n * n);
	fftw_execute(fw);
	for (int y = 0; y < n; y++) {
		double fy = (y <= n / 2 ? y : y - n) / (double)n;
		for (int x = 0; x < nc; x++) {
			double fx = x / (double)n;
			if (cov)
				spec[y * nc + x] *= exp(-2 * M_PI * M_PI *
							(cov[0] * fx * fx + 2 * cov[1] * fx * fy +
							 cov[2] * fy * fy));
			else
				spec[y * nc + x] *= exp(-2 * M_PI * M_PI * sigma * sigma *
							(fx * fx + fy * fy));
		}
	}
	fftw_execute(bw);
	double sum = 0;
	for (int i = 0; i < n * n; i++)
		sum += buf[i];
	for (int i = 0; i < n * n; i++)
		img[i] = buf[i] / sum;
	pthread_mutex_lock(&plan_lock);
	fftw_destroy_plan(fw);
	fftw_destroy_plan(bw);
	pthread_mutex_unlock(&plan_lock);
	fftw_free(spec);
	fftw_free(buf);
	return 0;
}

/* The largest singular value of the positions' Jacobians (at least 1):
 * how much wider than the pupil its raster must be in the transform's
 * frame.  -1 for a singular or extreme Jacobian. */
static double pupil_stretch(const struct optics_psf_req *r, struct err *e)
{
	double stretch = 1;

	for (int pos = 0; r->jac && pos < r->npos; pos++) {
		const double *a = r->jac + 4 * (size_t)pos;
		double det = a[0] * a[3] - a[1] * a[2];
		double t = a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3];
		if (!(fabs(det) > 1e-3 && t < 16))
			return err_set(e, EXIT_INPUT, "optics_psf: singular or "
				       "extreme Jacobian at position %d", pos);
		double smax = sqrt(0.5 * (t + sqrt(fmax(t * t - 4 * det * det, 0))));
		stretch = fmax(stretch, smax * 1.0001);
	}
	return stretch;
}

/* The jitter's covariance in samples at position pos, sigma^2 A^-1 A^-T,
 * into cov (returned); NULL for the square grid (isotropic). */
static const double *jitter_cov(const struct optics_psf_req *r, int pos, double cov[3])
{
	if (!r->jac)
		return NULL;
	const double *a = r->jac + 4 * (size_t)pos;
	double det = a[0] * a[3] - a[1] * a[2], k = r->jitter / r->scale;
	double m11 = a[3] / det, m12 = -a[1] / det, m21 = -a[2] / det, m22 = a[0] / det;

	cov[0] = k * k * (m11 * m11 + m12 * m12);
	cov[1] = k * k * (m11 * m21 + m12 * m22);
	cov[2] = k * k * (m21 * m21 + m22 * m22);
	return cov;
}

/* The transform's size *nfft, the pupil raster's largest side *pmax (at
 * the shortest wavelength) and the Jacobians' stretch for request r: what
 * optics_psf() and optics_psf_fits() share.  -1 with e set on a bad
 * request. */
static int psf_sizes(const struct optics_psf_req *r, int *nfft, int *pmax,
		     double *stretch, struct err *e)
{
	int pupil_n = r->pupil_n > 0 ? r->pupil_n : 256;
	double lmax = 0, lmin = 1e9, dth = r->scale * ARCSEC;

	if (r->n < 3 || r->n % 2 == 0 || r->nwave < 1 || r->npos < 1)
		return err_set(e, EXIT_INPUT, "optics_psf: bad request");
	for (int k = 0; k < r->nwave; k++) {
		lmax = fmax(lmax, r->lam[k]);
		lmin = fmin(lmin, r->lam[k]);
	}
	/* FFT size: the pupil array (2 half, or the rim for an unclipped
	 * pupil) gets >= pupil_n samples at the longest wavelength, and the
	 * field of view is >= 2 n samples, so the periodic copies of the PSF
	 * that an FFT implies sit at least n samples beyond the box. */
	double span = fmin(2 * r->pupil->half, 2 * r->pupil->rmax);
	int need = (int)ceil(pupil_n * lmax * 1e-6 / (span * dth));
	*nfft = good_size(need > 2 * r->n ? need : 2 * r->n);
	/* pupil samples per side at the shortest wavelength; a Jacobian
	 * stretches the pupil's extent in the transform's frame by up to the
	 * largest singular value of A.  As nfft * dth / lambda is the
	 * transform's period in the pupil plane, pmax / nfft is about
	 * stretch D dth / lambda_min whatever nfft: the pupil fits only when
	 * the samples are finer than lambda_min / (stretch D). */
	if ((*stretch = pupil_stretch(r, e)) < 0)
		return -1;
	*pmax = (int)ceil(*stretch * 2 * fmin(r->pupil->rmax, r->pupil->half * M_SQRT2) /
			  (lmin * 1e-6 / (*nfft * dth))) + 2;
	return 0;
}

int optics_psf_fits(const struct optics_psf_req *r, struct err *e)
{
	int nfft, pmax;
	double stretch;

	if (psf_sizes(r, &nfft, &pmax, &stretch, e))
		return -1;
	return pmax <= nfft;
}

/* The job's buffers for nth threads (j->r, nfft, pmax and h set), and the
 * sinc table: 0, or -1 with e set (job_free() frees what was made). */
static int job_alloc(struct job *j, int nth, struct err *e)
{
	const struct optics_psf_req *r = j->r;
	/* tmp: the image, a row of the pupil, or a skewed row's lit samples
	 * (skewed_pupil: OPTICS_NZ + 2 doubles each, at most) */
	size_t tmpn = (size_t)r->n * r->n, rown = (size_t)j->pmax * (OPTICS_NZ + 2);

	tmpn = tmpn > rown ? tmpn : rown;
	pthread_mutex_init(&j->turn_lock, NULL);
	pthread_cond_init(&j->turn_cond, NULL);
	j->nth = nth;
	j->acc = calloc((size_t)r->npos * r->n * r->n, sizeof(double));
	j->sinc = malloc((size_t)r->n * sizeof(double));
	j->wv = calloc(r->nwave, sizeof(*j->wv));
	j->turn = calloc(r->npos, sizeof(*j->turn));
	j->b1 = calloc(nth, sizeof(*j->b1));
	j->b2 = calloc(nth, sizeof(*j->b2));
	j->tmp = calloc(nth, sizeof(*j->tmp));
	j->mp.amp = malloc((size_t)j->pmax * j->pmax * sizeof(double));
	j->mp.idx = malloc((size_t)j->pmax * j->pmax * sizeof(int));
	j->mp.basis = malloc((size_t)j->pmax * j->pmax * OPTICS_NZ * sizeof(double));
	if (!j->acc || !j->sinc || !j->wv || !j->turn || !j->b1 || !j->b2 || !j->tmp ||
	    !j->mp.amp || !j->mp.idx || !j->mp.basis)
		return err_set(e, EXIT_SYSTEM, "out of memory");
	for (int t = 0; t < nth; t++) {
		j->b1[t] = fftw_malloc(sizeof(fftw_complex) * j->pmax * j->nfft);
		j->b2[t] = fftw_malloc(sizeof(fftw_complex) * r->n * j->nfft);
		j->tmp[t] = malloc(sizeof(double) * tmpn);
		if (!j->b1[t] || !j->b2[t] || !j->tmp[t])
			return err_set(e, EXIT_SYSTEM, "out of memory");
	}
	for (int k = 0; k < r->n; k++) {
		double a = M_PI * (k - j->h) / j->nfft;

		j->sinc[k] = k == j->h ? 1 : sin(a) / a;
	}
	return 0;
}

static void job_free(struct job *j)
{
	const struct optics_psf_req *r = j->r;

	for (int t = 0; t < j->nth; t++) {
		if (j->b1)
			fftw_free(j->b1[t]);
		if (j->b2)
			fftw_free(j->b2[t]);
		if (j->tmp)
			free(j->tmp[t]);
	}
	for (int k = 0; j->wv && k < r->nwave; k++) {
		pthread_mutex_lock(&plan_lock);
		if (j->wv[k].rows)
			fftw_destroy_plan(j->wv[k].rows);
		if (j->wv[k].cols)
			fftw_destroy_plan(j->wv[k].cols);
		pthread_mutex_unlock(&plan_lock);
	}
	free(j->b1);
	free(j->b2);
	free(j->tmp);
	free(j->acc);
	free(j->sinc);
	free(j->wv);
	free(j->turn);
	pthread_mutex_destroy(&j->turn_lock);
	pthread_cond_destroy(&j->turn_cond);
	pupil_coarse_free(&j->co);
	free(j->mp.amp);
	free(j->mp.idx);
	free(j->mp.basis);
}

/* The coarse map of a skewed request's mask (pupil.h), for the largest
 * reach of any position's cells at the longest wavelength. */
static int job_coarse(struct job *j, double dth, struct err *e)
{
	const struct optics_psf_req *r = j->r;
	double rmax = 0, lmax = 0;

	for (int k = 0; k < r->nwave; k++)
		lmax = fmax(lmax, r->lam[k]);
	for (int pos = 0; pos < r->npos; pos++) {
		const double *a = r->jac + 4 * (size_t)pos;
		double det = a[0] * a[3] - a[1] * a[2];
		double b[4] = { a[3] / det, -a[2] / det, -a[1] / det, a[0] / det };

		rmax = fmax(rmax, 0.5 * (lmax * 1e-6 / (j->nfft * dth)) *
				  fmax(hypot(b[0] + b[1], b[2] + b[3]), hypot(b[0] - b[1], b[2] - b[3])));
	}
	if (pupil_coarse_make(&j->co, r->pupil, rmax * (1 + 1e-6)) < 0)
		return err_set(e, EXIT_SYSTEM, "out of memory");
	return 0;
}

/* Each wavelength's raster step and side and its plans: p rows, then n
 * columns, each a length-nfft transform of a contiguous line (the side
 * from the step as psf_sizes() sizes the rasters, whose rounding
 * may differ in the last bit). */
static int job_waves(struct job *j, double dth, double stretch, struct err *e)
{
	const struct optics_psf_req *r = j->r;

	for (int k = 0; k < r->nwave; k++) {
		struct wave *w = &j->wv[k];
		double dx = r->lam[k] * 1e-6 / (j->nfft * dth);
		int p = (int)ceil(stretch * 2 * fmin(r->pupil->rmax, r->pupil->half * M_SQRT2) /
				  dx) + 2;

		w->lam = r->lam[k];
		w->wt = r->wt[k];
		w->dx = w->lam * 1e-6 / (j->nfft * r->scale * ARCSEC);
		w->k = k;
		w->p = p > j->pmax ? j->pmax : p;
		pthread_mutex_lock(&plan_lock);
		w->rows = fftw_plan_many_dft(1, &j->nfft, w->p, j->b1[0], NULL, 1, j->nfft,
					     j->b1[0], NULL, 1, j->nfft, FFTW_BACKWARD,
					     FFTW_ESTIMATE);
		w->cols = fftw_plan_many_dft(1, &j->nfft, r->n, j->b2[0], NULL, 1, j->nfft,
					     j->b2[0], NULL, 1, j->nfft, FFTW_BACKWARD,
					     FFTW_ESTIMATE);
		pthread_mutex_unlock(&plan_lock);
		if (!w->rows || !w->cols)
			return err_set(e, EXIT_SYSTEM, "FFTW could not plan a %d-point transform",
				       j->nfft);
	}
	return 0;
}

int optics_psf(const struct optics_psf_req *r, double *out, struct err *e)
{
	struct job j;
	int nth = r->threads > 0 ? r->threads : (int)sysconf(_SC_NPROCESSORS_ONLN);
	int rc = -1;
	double dth = r->scale * ARCSEC, stretch;

	if (nth < 1)
		nth = 1;
	if (nth > 64)
		nth = 64;
	memset(&j, 0, sizeof(j));
	if (psf_sizes(r, &j.nfft, &j.pmax, &stretch, e))
		return -1;
	j.r = r;
	j.h = (r->n - 1) / 2;
	zernike_table(j.zt);
	if (j.pmax > j.nfft)
		return err_set(e, EXIT_INPUT, "optics_psf: samples of %g arcsec are "
			       "coarser than the shortest wavelength's lambda / D: "
			       "the pupil does not fit the FFT (%d > %d)", r->scale,
			       j.pmax, j.nfft);
	pthread_once(&plan_once, plan_init);
	if (job_alloc(&j, nth, e) < 0 ||
	    (r->jac && !r->plain_cover && job_coarse(&j, dth, e) < 0) ||
	    job_waves(&j, dth, stretch, e) < 0)
		goto done;
	if (r->jac) {
		/* each position makes its own pupil: every wavelength and
		 * position a task (a lone halo's wavelengths two at a time) */
		par_for(&j, nth, r->nwave * r->npos, wave_task);
	} else {
		/* the shared pupil of each wavelength, then its positions */
		for (int k = 0; k < r->nwave; k++) {
			int p = j.wv[k].p;

			j.cur = &j.wv[k];
			j.mp.nlit = 0;
			par_for(&j, nth, p, pupil_row);
			for (int i = 0; i < p * p; i++)
				if (j.mp.amp[i] > 0)
					j.mp.idx[j.mp.nlit++] = i;
			if (r->zern)
				par_for(&j, nth, (j.mp.nlit + 4095) / 4096, basis_task);
			par_for(&j, nth, r->npos, position_task);
		}
	}
	for (int pos = 0; pos < r->npos; pos++) {
		double *img = j.acc + (size_t)pos * r->n * r->n, cov[3];

		if (r->jitter > 0 && jitter(img, r->n, r->jitter / r->scale,
					    jitter_cov(r, pos, cov), e))
			goto done;
		memcpy(out + (size_t)pos * r->n * r->n, img,
		       sizeof(double) * r->n * r->n);
	}
	rc = 0;
done:
	job_free(&j);
	return rc;
}
