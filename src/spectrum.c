/* spectrum.c - spectra, the colour term and effective wavelengths; see spectrum.h. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "err.h"
#include "instrument.h"
#include "optics.h"
#include "throughput.h"
#include "spectrum.h"

/* c2 = h c / k in micron K */
#define C2 14387.77

double spec_fnu(const struct spectrum *s, double lam, double lam_ref)
{
	switch (s->kind) {
	case SPEC_POWER:
		/* f_nu ~ nu^beta ~ lam^-beta */
		return pow(lam / lam_ref, -s->value);
	case SPEC_BLACKBODY:
		/* B_nu ~ nu^3 / (exp(h nu / k T) - 1) */
		return pow(lam_ref / lam, 3) * expm1(C2 / (lam_ref * s->value)) /
		       expm1(C2 / (lam * s->value));
	default:
		return 1;
	}
}

#define BETA_LO (-8.0)
#define BETA_HI 8.0
#define BETA_STEP (1.0 / 64)
#define NBETA 1025              /* (BETA_HI - BETA_LO) / BETA_STEP + 1 */
#define U_LO 0.01               /* 1000 K / T */
#define U_HI 1.0
#define U_STEP (1.0 / 1024)
#define NU 1016                 /* (U_HI - U_LO) / U_STEP + 2, rounded down */

struct sca_tables {
	pthread_mutex_t lock;
	int done;               /* read with acquire, set with release */
	double lnf_beta[NBETA], lam_beta[NBETA];
	double lnf_bb[NU], lam_bb[NU];
};

struct colour {
	int filter;
	double pivot;
	int n;                  /* throughput samples */
	double *lam;            /* micron */
	double *area;           /* [k * WFS_NSCA + sca - 1], m^2 */
	struct sca_tables t[WFS_NSCA];
};

void colour_exact(const struct colour *c, int sca, const struct spectrum *s,
		  double *factor, double *lam_eff)
{
	double sa = 0, sas = 0, sasl = 0;

	for (int k = 0; k < c->n; k++) {
		double a = c->area[k * WFS_NSCA + sca - 1], l = c->lam[k];
		double v = s->kind == SPEC_DEFAULT ? 1 : spec_fnu(s, l, c->pivot);

		sa += a / l;
		sas += a * v / l;
		sasl += a * v;
	}
	*factor = sas / sa;
	*lam_eff = sasl / sas;
}

/*
 * SCA sca's tables: the sums of colour_exact() for every table node, the
 * nodes in the inner loop so that each sample's f_nu follows from the
 * previous node's by one multiplication (beta and 1000 K / T step
 * uniformly, so f_nu and exp(h nu / k T) are geometric in them), restarted
 * from pow() and exp() every RESTART nodes: the rounding so gathered stays
 * below 1e-13 of the sums, and the fill costs some 10 million instructions
 * an SCA instead of 120 million with a pow() or two expm1() per term.
 * Samples of zero area are skipped (they add nothing).
 */
#define RESTART 64

static void tables_fill(struct colour *c, int sca)
{
	struct sca_tables *t = &c->t[sca - 1];
	double sa = 0, p = c->pivot;
	double sb[NBETA] = { 0 }, sbl[NBETA] = { 0 }, st[NU] = { 0 }, stl[NU] = { 0 };
	double gp[NU];          /* expm1(h nu_pivot / k T) of each node */

	for (int i = 0; i < NU; i++)
		gp[i] = expm1(C2 * (U_LO + i * U_STEP) / (1000 * p));
	for (int k = 0; k < c->n; k++) {
		double a = c->area[k * WFS_NSCA + sca - 1], l = c->lam[k];
		double r = pow(l / p, -BETA_STEP), x = C2 / (1000 * l), q = exp(x * U_STEP);
		double p3 = pow(p / l, 3), v = 0, e = 0;

		sa += a / l;
		if (a == 0)
			continue;
		for (int i = 0; i < NBETA; i++) {
			v = i % RESTART ? v * r : pow(l / p, -(BETA_LO + i * BETA_STEP));
			sb[i] += a * v / l;
			sbl[i] += a * v;
		}
		for (int i = 0; i < NU; i++) {
			e = i % RESTART ? e * q : exp(x * (U_LO + i * U_STEP));
			v = p3 * gp[i] / (e - 1);
			st[i] += a * v / l;
			stl[i] += a * v;
		}
	}
	for (int i = 0; i < NBETA; i++) {
		t->lam_beta[i] = sbl[i] / sb[i];
		t->lnf_beta[i] = log(sb[i] / sa);
	}
	for (int i = 0; i < NU; i++) {
		t->lam_bb[i] = stl[i] / st[i];
		t->lnf_bb[i] = log(st[i] / sa);
	}
}

struct colour *colour_new(int filter, struct err *e)
{
	struct colour *c;
	double *lam[WFS_NFILTER], *area[WFS_NFILTER];
	int n[WFS_NFILTER];

	if (instrument_init(e))
		return NULL;
	if (filter < 0 || filter >= WFS_NFILTER)
		return err_set(e, EXIT_INPUT, "unknown filter %d", filter), NULL;
	if (!(c = calloc(1, sizeof(*c))))
		return err_set(e, EXIT_SYSTEM, "out of memory"), NULL;
	c->filter = filter;
	c->pivot = filter_get(filter)->pivot;
	if (throughput_read(lam, area, n, e)) {
		free(c);
		return NULL;
	}
	/* the filter's samples kept, the others' freed */
	c->lam = lam[filter];
	c->area = area[filter];
	c->n = n[filter];
	lam[filter] = area[filter] = NULL;
	throughput_free(lam, area);
	for (int s = 0; s < WFS_NSCA; s++)
		pthread_mutex_init(&c->t[s].lock, NULL);
	if (c->n < 2) {
		colour_free(c);
		return err_set(e, EXIT_SYSTEM, "broken build: no throughput for %s",
			       filter_get(filter)->name), NULL;
	}
	return c;
}

void colour_free(struct colour *c)
{
	if (!c)
		return;
	free(c->lam);
	free(c->area);
	for (int s = 0; s < WFS_NSCA; s++)
		pthread_mutex_destroy(&c->t[s].lock);
	free(c);
}

/* SCA sca's tables filled, by the first thread that wants them. */
static __attribute__((noinline)) void tables_once(struct colour *c, struct sca_tables *t, int sca)
{
	pthread_mutex_lock(&t->lock);
	if (!t->done) {
		tables_fill(c, sca);
		__atomic_store_n(&t->done, 1, __ATOMIC_RELEASE);
	}
	pthread_mutex_unlock(&t->lock);
}

/* SCA sca's tables (a row's look-up: the filled test inline). */
static inline const struct sca_tables *tables(struct colour *c, int sca)
{
	struct sca_tables *t = &c->t[sca - 1];

	if (!__atomic_load_n(&t->done, __ATOMIC_ACQUIRE))
		tables_once(c, t, sca);
	return t;
}

/* Catmull-Rom through tab[] (n uniform nodes) at fractional index u >= 0
 * (so (int) u is its floor). */
static inline double spline(const double *tab, int n, double u)
{
	int i = (int)u;

	if (i < 1)
		i = 1;
	if (i > n - 3)
		i = n - 3;
	double t = u - i, p0 = tab[i - 1], p1 = tab[i], p2 = tab[i + 1], p3 = tab[i + 2];

	return p1 + 0.5 * t * (p2 - p0 + t * (2 * p0 - 5 * p1 + 4 * p2 - p3 +
					      t * (3 * (p1 - p2) + p3 - p0)));
}

/* s's tables on SCA sca, ln factor and lam_eff, of n nodes, and its
 * fractional index u there; 0, or -1 when s is outside the tables. */
static int table_at(struct colour *c, int sca, const struct spectrum *s, const double **lnf,
		    const double **lam, int *n, double *u)
{
	const struct sca_tables *t;

	if (s->kind == SPEC_POWER && s->value >= BETA_LO && s->value <= BETA_HI) {
		t = tables(c, sca);
		*lnf = t->lnf_beta;
		*lam = t->lam_beta;
		*n = NBETA;
		*u = (s->value - BETA_LO) / BETA_STEP;
		return 0;
	}
	if (s->kind == SPEC_BLACKBODY) {
		double v = 1000.0 / s->value;

		if (v >= U_LO && v <= U_HI) {
			t = tables(c, sca);
			*lnf = t->lnf_bb;
			*lam = t->lam_bb;
			*n = NU;
			*u = (v - U_LO) / U_STEP;
			return 0;
		}
	}
	return -1;
}

/* The table value of s: ln factor (which = 0) or lam_eff (1); 0 with *out
 * set, or -1 when s is outside the tables. */
static int table_value(struct colour *c, int sca, const struct spectrum *s, int which,
		       double *out)
{
	const double *lnf, *lam;
	double u;
	int n;

	if (table_at(c, sca, s, &lnf, &lam, &n, &u) < 0)
		return -1;
	*out = spline(which ? lam : lnf, n, u);
	return 0;
}

double colour_factor(struct colour *c, int sca, const struct spectrum *s)
{
	double v, lam;

	if (s->kind == SPEC_DEFAULT || (s->kind == SPEC_POWER && s->value == 0))
		return 1;
	if (!table_value(c, sca, s, 0, &v))
		return exp(v);
	colour_exact(c, sca, s, &v, &lam);
	return v;
}

double colour_lam_eff(struct colour *c, int sca, const struct spectrum *s)
{
	struct spectrum bb = { SPEC_BLACKBODY, OPTICS_BB_TEMP };
	double v, f;

	if (s->kind == SPEC_DEFAULT)
		s = &bb;
	if (!table_value(c, sca, s, 1, &v))
		return v;
	colour_exact(c, sca, s, &f, &v);
	return v;
}

void colour_both(struct colour *c, int sca, const struct spectrum *s, double *factor,
		 double *lam_eff)
{
	const double *lnf, *lam;
	double u;
	int n;

	if (s->kind == SPEC_DEFAULT) {
		*factor = 1;
		*lam_eff = colour_lam_eff(c, sca, s);
		return;
	}
	if (table_at(c, sca, s, &lnf, &lam, &n, &u) < 0) {
		colour_exact(c, sca, s, factor, lam_eff);
	} else {
		*factor = exp(spline(lnf, n, u));
		*lam_eff = spline(lam, n, u);
	}
	if (s->kind == SPEC_POWER && s->value == 0)
		*factor = 1;
}
