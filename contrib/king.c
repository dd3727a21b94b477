/*
 * king.c - a crowded globular-cluster star list for wfiscene demos.
 *
 *   king [-n N] [-r RA] [-d DEC] [-c RC] [-t RT] [-f FILTER] [-m DM]
 *        [-A AV] [-a ALPHA] [-M MMIN] [-s SEED] [-z] > cluster.csv
 *
 * Writes CSV "id,ra,dec,mag,type" (degrees, AB magnitudes, type point) to
 * stdout, zstd-compressed with -z.  The defaults are M13 (NGC 6205).
 *
 * Positions follow the projected King (1962) profile,
 *
 *   S(R) = k [ (1 + R^2/rc^2)^(-1/2) - (1 + rt^2/rc^2)^(-1/2) ]^2,  R < rt,
 *
 * whose enclosed number has a closed form (King 1962, eq. 18).  With
 * x = R^2/rc^2, xt = rt^2/rc^2, u = 1 + x, ut = 1 + xt and dA = pi rc^2 dx:
 *
 *   N(x) ∝ ln(u) - 4 (sqrt(u) - 1) / sqrt(ut) + x / ut,
 *
 * so radii are drawn exactly by inverting N(x)/N(xt) = uniform with a
 * safeguarded Newton iteration (dN/dx is the bracket above squared).  The
 * position angle is uniform; R is an angle on the sky, turned into RA/Dec
 * by the inverse gnomonic projection about the centre.
 *
 * Brightnesses: an honest approximation, good for pictures and crowding
 * tests, not for photometric science.
 *  - Initial masses from a Kroupa (2001) broken power law, dN/dm ∝ m^-alpha
 *    with alpha = 1.3 (or -a) below 0.5 Msun and 2.3 above, from MMIN to
 *    100 Msun.  Real clusters have lost many low-mass stars (a flatter
 *    present-day function: try -a 0.5); mass segregation is ignored.
 *  - One old metal-poor population, about 12 Gyr and [Fe/H] = -1.5.  Main-
 *    sequence stars (m <= 0.80 Msun, the turn-off) take log L and Teff from a
 *    hand-made table that follows the shape of published isochrones for
 *    that age and metallicity (turn-off M_V ~ +4, 0.5 Msun at M_V ~ +8.5).
 *  - A star above the turn-off mass left the main sequence a time
 *    t = T (1 - (m/m_TO)^-3.5) ago (main-sequence lifetime ∝ m^-3.5,
 *    T = 12 Gyr).  Its place after the turn-off is read from a table of
 *    log L and Teff against time: subgiant branch, red-giant branch (with
 *    a slow-down at the RGB bump), then 100 Myr on a blue horizontal
 *    branch (M13's: Teff 7600-22000 K, uniform in log Teff), 15 Myr on the
 *    AGB, then a white dwarf cooling as L ∝ t^-1.4 (Mestel).  Drawing the
 *    mass and mapping it through time makes the numbers in each phase
 *    proportional to its lifetime (the fuel-consumption theorem), which is
 *    what sets the luminosity function.  Neutron stars and black holes
 *    (m > 8 Msun) are not luminous and are drawn again.
 *  - Magnitudes: a blackbody of that Teff and L, averaged per photon over
 *    the Roman filter's band (a top-hat between its 50% points), in AB;
 *    then distance modulus (default 14.27, 7.1 kpc) and extinction A_V
 *    (default 0.06) scaled to the filter by Cardelli, Clayton & Mathis
 *    (1989) with R_V = 3.1.  Blackbodies are off by a few tenths of a
 *    magnitude for cool dwarfs and giants (molecular bands), less for hot
 *    stars.
 *
 * Deterministic for a seed: xoshiro256** seeded by splitmix64, and every
 * star takes its random numbers in a fixed order.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <zstd.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)

/* ---- random numbers ---- */

struct rng {
	uint64_t s[4];
};

static uint64_t splitmix64(uint64_t *x)
{
	uint64_t z = (*x += 0x9E3779B97F4A7C15u);
	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
	return z ^ (z >> 31);
}

static void rng_seed(struct rng *r, uint64_t seed)
{
	for (int i = 0; i < 4; i++)
		r->s[i] = splitmix64(&seed);
}

static uint64_t rotl(uint64_t x, int k)
{
	return (x << k) | (x >> (64 - k));
}

/* xoshiro256** (Blackman & Vigna 2018). */
static uint64_t rng_next(struct rng *r)
{
	uint64_t *s = r->s, out = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;

	s[2] ^= s[0];
	s[3] ^= s[1];
	s[1] ^= s[2];
	s[0] ^= s[3];
	s[2] ^= t;
	s[3] = rotl(s[3], 45);
	return out;
}

/* Uniform in [0, 1) with 53 random bits. */
static double rng_uniform(struct rng *r)
{
	return (double)(rng_next(r) >> 11) * 0x1.0p-53;
}

/* ---- the King profile ---- */

struct king {
	double xt, ut, ntot;    /* (rt/rc)^2, 1 + xt, N(xt) */
};

static double king_n(const struct king *k, double x)
{
	double u = 1 + x;
	return log(u) - 4 * (sqrt(u) - 1) / sqrt(k->ut) + x / k->ut;
}

static double king_dn(const struct king *k, double x)
{
	double d = 1 / sqrt(1 + x) - 1 / sqrt(k->ut);
	return d * d;
}

/* x = (R/rc)^2 with N(x) = p N(xt): Newton steps kept inside a bisection
 * bracket, since dN/dx falls to 0 at the tidal radius. */
static double king_invert(const struct king *k, double p)
{
	double target = p * k->ntot, lo = 0, hi = k->xt, x = p * k->xt;

	for (int i = 0; i < 200; i++) {
		double f = king_n(k, x) - target, d = king_dn(k, x), nx;
		if (f > 0)
			hi = x;
		else
			lo = x;
		nx = d > 0 ? x - f / d : 0.5 * (lo + hi);
		if (!(nx > lo && nx < hi))
			nx = 0.5 * (lo + hi);
		if (fabs(nx - x) <= 1e-15 * (1 + x))
			return nx;
		x = nx;
	}
	return x;
}

/* ---- the stellar population ---- */

/* Main sequence, 12 Gyr, [Fe/H] = -1.5: initial mass (Msun), log L/Lsun,
 * Teff (K).  The last row is the turn-off. */
static const double ms_table[][3] = {
	{ 0.10, -3.00, 3350 }, { 0.12, -2.80, 3450 }, { 0.15, -2.55, 3580 },
	{ 0.20, -2.25, 3700 }, { 0.25, -2.02, 3800 }, { 0.30, -1.85, 3900 },
	{ 0.35, -1.70, 4000 }, { 0.40, -1.56, 4120 }, { 0.45, -1.42, 4260 },
	{ 0.50, -1.27, 4420 }, { 0.55, -1.12, 4600 }, { 0.60, -0.95, 4800 },
	{ 0.65, -0.76, 5020 }, { 0.70, -0.55, 5280 }, { 0.74, -0.35, 5560 },
	{ 0.77, -0.15, 5900 }, { 0.79, 0.10, 6250 }, { 0.80, 0.30, 6450 },
};
#define MS_ROWS (sizeof(ms_table) / sizeof(ms_table[0]))
#define M_TO 0.80
#define AGE_MYR 12000.0

/* After the turn-off: Myr since the turn-off, log L, Teff.  Subgiant
 * branch to the base of the RGB at 850 Myr, the RGB (slowing at the bump
 * near log L 1.55) to the tip at 1327 Myr. */
static const double post_table[][3] = {
	{ 0, 0.30, 6450 }, { 250, 0.40, 6350 }, { 500, 0.45, 6000 },
	{ 700, 0.50, 5500 }, { 850, 0.55, 5200 }, { 1100, 1.00, 4950 },
	{ 1230, 1.45, 4750 }, { 1250, 1.55, 4700 }, { 1270, 1.60, 4680 },
	{ 1300, 2.00, 4480 }, { 1318, 2.50, 4250 }, { 1325, 3.00, 4000 },
	{ 1327, 3.30, 3850 },
};
#define POST_ROWS (sizeof(post_table) / sizeof(post_table[0]))
#define T_TIP 1327.0
#define T_HB (T_TIP + 100.0)    /* end of the horizontal branch */
#define T_AGB (T_HB + 15.0)     /* end of the AGB: a white dwarf after */

/* Linear interpolation in a table's column 0 (ascending). */
static void table_at(const double (*t)[3], size_t n, double v, double *logl,
		     double *teff)
{
	size_t i = 1;

	if (v <= t[0][0]) {
		*logl = t[0][1];
		*teff = t[0][2];
		return;
	}
	while (i < n - 1 && t[i][0] < v)
		i++;
	if (v >= t[n - 1][0]) {
		*logl = t[n - 1][1];
		*teff = t[n - 1][2];
		return;
	}
	{
		double f = (v - t[i - 1][0]) / (t[i][0] - t[i - 1][0]);
		*logl = t[i - 1][1] + f * (t[i][1] - t[i - 1][1]);
		*teff = t[i - 1][2] + f * (t[i][2] - t[i - 1][2]);
	}
}

/* Kroupa (2001) initial masses: slope alpha_lo below 0.5 Msun, 2.3 above,
 * continuous at 0.5; each piece sampled by its inverse CDF. */
struct imf {
	double mmin, alo, w_lo; /* w_lo: share of stars below 0.5 Msun */
};

static double powlaw_integral(double a, double m0, double m1)
{
	if (fabs(a - 1) < 1e-12)
		return log(m1 / m0);
	return (pow(m1, 1 - a) - pow(m0, 1 - a)) / (1 - a);
}

static double powlaw_draw(double a, double m0, double m1, double u)
{
	if (fabs(a - 1) < 1e-12)
		return m0 * pow(m1 / m0, u);
	return pow(pow(m0, 1 - a) + u * (pow(m1, 1 - a) - pow(m0, 1 - a)),
		   1 / (1 - a));
}

static void imf_init(struct imf *f, double mmin, double alo)
{
	/* dN/dm = m^-alo below 0.5 and 0.5^(2.3-alo) m^-2.3 above. */
	double lo = powlaw_integral(alo, mmin, 0.5);
	double hi = pow(0.5, 2.3 - alo) * powlaw_integral(2.3, 0.5, 100);

	f->mmin = mmin;
	f->alo = alo;
	f->w_lo = lo / (lo + hi);
}

static double imf_draw(const struct imf *f, struct rng *r)
{
	double u = rng_uniform(r), v = rng_uniform(r);

	return u < f->w_lo ? powlaw_draw(f->alo, f->mmin, 0.5, v)
			   : powlaw_draw(2.3, 0.5, 100, v);
}

/* log L and Teff of a star of initial mass m at 12 Gyr; 0 when it is a
 * neutron star or black hole (dark).  hb is a uniform number used for the
 * horizontal-branch temperature. */
static int star_state(double m, double hb, double *logl, double *teff)
{
	double tms, t, period, tau;

	if (m <= M_TO) {
		table_at(ms_table, MS_ROWS, m, logl, teff);
		return 1;
	}
	if (m > 8)
		return 0;
	/* Main-sequence lifetime scales as m^-3.5, and so, here, does the
	 * whole post-main-sequence sequence: a star is in the phase at
	 * fraction (T - tms)/period of it. */
	tms = AGE_MYR * pow(m / M_TO, -3.5);
	t = AGE_MYR - tms;
	period = T_AGB * tms / AGE_MYR;
	if (t < period) {
		double s = t * AGE_MYR / tms;   /* time in turn-off units */
		if (s <= T_TIP) {
			table_at(post_table, POST_ROWS, s, logl, teff);
		} else if (s <= T_HB) {
			/* Blue HB: zero-age HB luminosity falls with Teff;
			 * stars brighten by ~0.15 dex as they evolve. */
			double lt = log10(7600) + hb * (log10(22000) - log10(7600));
			*teff = pow(10, lt);
			*logl = 1.65 - 1.1 * (lt - 3.9) + 0.15 * (s - T_TIP) / 100;
		} else {
			double f = (s - T_HB) / (T_AGB - T_HB);
			*logl = 1.8 + 1.3 * f;
			*teff = 4800 - 900 * f;
		}
		return 1;
	}
	/* White dwarf, radius 0.0125 Rsun, Mestel cooling. */
	tau = t - period;
	if (tau < 0.01)
		tau = 0.01;
	*logl = 1.1 - 1.4 * log10(tau);
	if (*logl > 2.5)
		*logl = 2.5;
	*teff = 5772 * pow(pow(10, *logl) / (0.0125 * 0.0125), 0.25);
	return 1;
}

/* ---- photometry ---- */

struct band {
	const char *name;
	double lo, hi;          /* 50% points, micron */
};

static const struct band bands[] = {
	{ "F062", 0.48, 0.76 }, { "F087", 0.76, 0.977 },
	{ "F106", 0.927, 1.192 }, { "F129", 1.131, 1.454 },
	{ "F158", 1.380, 1.774 }, { "F184", 1.683, 2.000 },
	{ "F213", 1.95, 2.30 }, { "F146", 0.927, 2.000 },
};
#define NBANDS (sizeof(bands) / sizeof(bands[0]))

/* A_lambda / A_V from Cardelli, Clayton & Mathis (1989), R_V = 3.1. */
static double ccm(double lambda_um)
{
	double x = 1 / lambda_um, a, b, rv = 3.1;

	if (x < 1.1) {
		a = 0.574 * pow(x, 1.61);
		b = -0.527 * pow(x, 1.61);
	} else {
		double y = x - 1.82;
		a = 1 + y * (0.17699 + y * (-0.50447 + y * (-0.02427 + y * (0.72085
			+ y * (0.01979 + y * (-0.77530 + y * 0.32999))))));
		b = y * (1.41338 + y * (2.28305 + y * (1.07233 + y * (-5.38434
			+ y * (-0.62251 + y * (5.30260 - y * 2.09002))))));
	}
	return a + b / rv;
}

/*
 * Absolute AB magnitude of a blackbody with L = 1 Lsun and temperature
 * teff in band b.  The photon-weighted mean flux density over a top-hat in
 * wavelength is <f_nu> = ∫ f_nu dλ/λ / ∫ dλ/λ, and at 10 pc
 * f_nu = F_bol pi B_nu(T) / (sigma T^4).  A star's magnitude is this minus
 * 2.5 log L.
 */
static double bb_abmag(const struct band *b, double teff)
{
	const double h = 6.62607015e-34, c = 2.99792458e8, k = 1.380649e-23;
	const double sigma = 5.670374419e-8, lsun = 3.828e26, pc = 3.0856775814913673e16;
	const int n = 256;
	double l0 = log(b->lo * 1e-6), l1 = log(b->hi * 1e-6), sum = 0;
	double fbol = lsun / (4 * M_PI * (10 * pc) * (10 * pc));

	for (int i = 0; i < n; i++) {
		double lam = exp(l0 + (i + 0.5) * (l1 - l0) / n), nu = c / lam;
		double bnu = 2 * h * nu * nu * nu / (c * c) / expm1(h * nu / (k * teff));
		sum += bnu;
	}
	sum /= n;       /* uniform in ln λ: the dλ/λ weighting */
	return -2.5 * log10(fbol * M_PI * sum / (sigma * pow(teff, 4)) / 3631e-26);
}

/* The bolometric-to-band term on a grid in log Teff, for speed. */
#define BC_LO 3.3
#define BC_HI 5.3
#define BC_N 2001
struct phot {
	double bc[BC_N];
	double offset;          /* distance modulus + extinction */
};

static void phot_init(struct phot *p, const struct band *b, double dm, double av)
{
	for (int i = 0; i < BC_N; i++)
		p->bc[i] = bb_abmag(b, pow(10, BC_LO + i * (BC_HI - BC_LO) / (BC_N - 1)));
	p->offset = dm + av * ccm(0.5 * (b->lo + b->hi));
}

static double phot_mag(const struct phot *p, double logl, double teff)
{
	double t = (log10(teff) - BC_LO) / (BC_HI - BC_LO) * (BC_N - 1), f;
	int i;

	if (t < 0)
		t = 0;
	if (t > BC_N - 1.000001)
		t = BC_N - 1.000001;
	i = (int)t;
	f = t - i;
	return p->bc[i] + f * (p->bc[i + 1] - p->bc[i]) - 2.5 * logl + p->offset;
}

/* ---- output: stdout, plain or zstd ---- */

struct out {
	ZSTD_CCtx *z;
	char *zbuf;
	size_t zcap;
	char buf[1 << 16];
	size_t len;
};

static int out_write(const void *p, size_t n)
{
	if (fwrite(p, 1, n, stdout) == n)
		return 0;
	fprintf(stderr, "king: writing <stdout>: %s\n", strerror(errno));
	return -1;
}

static int out_flush(struct out *o, ZSTD_EndDirective end)
{
	ZSTD_inBuffer in = { o->buf, o->len, 0 };

	if (!o->z) {
		if (o->len && out_write(o->buf, o->len))
			return -1;
		o->len = 0;
		return 0;
	}
	for (;;) {
		ZSTD_outBuffer zo = { o->zbuf, o->zcap, 0 };
		size_t left = ZSTD_compressStream2(o->z, &zo, &in, end);
		if (ZSTD_isError(left)) {
			fprintf(stderr, "king: zstd: %s\n", ZSTD_getErrorName(left));
			return -1;
		}
		if (zo.pos && out_write(o->zbuf, zo.pos))
			return -1;
		/* continue: until the input is taken; end: until flushed */
		if (end == ZSTD_e_end ? left == 0 : in.pos == in.size)
			break;
	}
	o->len = 0;
	return 0;
}

static int out_line(struct out *o, const char *s, size_t n)
{
	if (o->len + n > sizeof(o->buf) && out_flush(o, ZSTD_e_continue))
		return -1;
	memcpy(o->buf + o->len, s, n);
	o->len += n;
	return 0;
}

/* ---- command line ---- */

static void usage(FILE *fp)
{
	fprintf(fp,
"usage: king [options] > cluster.csv\n"
"Write a globular-cluster star list (King profile, old metal-poor\n"
"population) as CSV: id,ra,dec,mag,type (degrees, AB magnitudes).\n"
"Defaults are M13.\n"
"\n"
"  -n N       number of stars (100000)\n"
"  -r RA      centre right ascension, degrees (250.4235)\n"
"  -d DEC     centre declination, degrees (36.4613)\n"
"  -c RC      King core radius, arcmin (0.62)\n"
"  -t RT      King tidal radius, arcmin (21.0)\n"
"  -f FILTER  Roman filter: F062 F087 F106 F129 F146 F158 F184 F213 (F129)\n"
"  -m DM      distance modulus, magnitudes (14.27)\n"
"  -A AV      extinction A_V, magnitudes (0.06)\n"
"  -a ALPHA   mass-function slope below 0.5 Msun (1.3, Kroupa)\n"
"  -M MMIN    lowest stellar mass, Msun (0.1)\n"
"  -s SEED    random seed (1); the same seed gives the same list\n"
"  -z         compress the output with zstd\n"
"  -h         this help\n");
}

static int number(const char *opt, const char *s, double lo, double hi,
		  double *out)
{
	char *end;
	double v;

	errno = 0;
	v = strtod(s, &end);
	if (end == s || *end || errno || !isfinite(v) || v < lo || v > hi) {
		fprintf(stderr, "king: -%s: bad value '%s' (want %g to %g)\n",
			opt, s, lo, hi);
		return -1;
	}
	*out = v;
	return 0;
}

/* The options, with M13's defaults (see usage()). */
struct opts {
	double n, ra0, dec0, rc, rt, dm, av, alpha, mmin;
	unsigned long long seed;
	const struct band *band;
	int zstd;
};

/* Parse the command line into o.  Returns 0, 1 after -h (usage written),
 * or -1 after a message on stderr. */
static int parse_options(int argc, char **argv, struct opts *o)
{
	int c;

	while ((c = getopt(argc, argv, "n:r:d:c:t:f:m:A:a:M:s:zh")) != -1) {
		int bad = 0;
		switch (c) {
		case 'n': bad = number("n", optarg, 0, 1e12, &o->n);
			if (!bad && o->n != floor(o->n)) {
				fprintf(stderr, "king: -n: not a whole number: '%s'\n",
					optarg);
				bad = 1;
			}
			break;
		case 'r': bad = number("r", optarg, -360, 720, &o->ra0); break;
		case 'd': bad = number("d", optarg, -90, 90, &o->dec0); break;
		case 'c': bad = number("c", optarg, 1e-6, 1e4, &o->rc); break;
		case 't': bad = number("t", optarg, 1e-6, 1e5, &o->rt); break;
		case 'm': bad = number("m", optarg, -10, 60, &o->dm); break;
		case 'A': bad = number("A", optarg, 0, 50, &o->av); break;
		case 'a': bad = number("a", optarg, -5, 5, &o->alpha); break;
		case 'M': bad = number("M", optarg, 0.08, 0.79, &o->mmin); break;
		case 's': {
			char *end;
			errno = 0;
			o->seed = strtoull(optarg, &end, 0);
			if (end == optarg || *end || errno || *optarg == '-') {
				fprintf(stderr, "king: -s: bad seed '%s' (want an "
					"integer from 0 to 2^64-1)\n", optarg);
				bad = 1;
			}
			break;
		}
		case 'z': o->zstd = 1; break;
		case 'f':
			o->band = NULL;
			for (size_t i = 0; i < NBANDS; i++)
				if (!strcmp(optarg, bands[i].name))
					o->band = &bands[i];
			if (!o->band) {
				fprintf(stderr, "king: -f: unknown filter '%s' (use "
					"F062 F087 F106 F129 F146 F158 F184 F213)\n",
					optarg);
				bad = 1;
			}
			break;
		case 'h': usage(stdout); return 1;
		default: bad = 1; break;
		}
		if (bad) {
			fprintf(stderr, "king: try 'king -h'\n");
			return -1;
		}
	}
	if (optind < argc) {
		fprintf(stderr, "king: unexpected argument '%s'; try 'king -h'\n",
			argv[optind]);
		return -1;
	}
	if (o->rt <= o->rc) {
		fprintf(stderr, "king: the tidal radius (%g') must exceed the "
			"core radius (%g')\n", o->rt, o->rc);
		return -1;
	}
	if (o->rt > 600) {
		fprintf(stderr, "king: tidal radius %g' is beyond 10 degrees\n", o->rt);
		return -1;
	}
	if (o->zstd && isatty(STDOUT_FILENO)) {
		fprintf(stderr, "king: refusing to write compressed data to a "
			"terminal\n");
		return -1;
	}
	return 0;

}

int main(int argc, char **argv)
{
	struct opts opt = {
		.n = 100000, .ra0 = 250.4235, .dec0 = 36.4613, .rc = 0.62, .rt = 21.0,
		.dm = 14.27, .av = 0.06, .alpha = 1.3, .mmin = 0.1, .seed = 1,
		.band = &bands[3],
	};
	int status = 2, r;
	struct rng rng;
	struct king king;
	struct imf imf;
	static struct phot phot;
	static struct out out;
	double sd0, cd0;
	char line[128];

	if ((r = parse_options(argc, argv, &opt)))
		return r < 0;

	double n = opt.n, ra0 = opt.ra0, dec0 = opt.dec0, rc = opt.rc, rt = opt.rt;
	double dm = opt.dm, av = opt.av, alpha = opt.alpha, mmin = opt.mmin;
	unsigned long long seed = opt.seed;
	const struct band *band = opt.band;
	int zstd = opt.zstd;

	rng_seed(&rng, (uint64_t)seed);
	king.xt = (rt / rc) * (rt / rc);
	king.ut = 1 + king.xt;
	king.ntot = king_n(&king, king.xt);
	imf_init(&imf, mmin, alpha);
	phot_init(&phot, band, dm, av);
	sd0 = sin(dec0 * DEG);
	cd0 = cos(dec0 * DEG);
	ra0 = fmod(ra0, 360);
	if (ra0 < 0)
		ra0 += 360;

	if (zstd) {
		out.z = ZSTD_createCCtx();
		out.zcap = ZSTD_CStreamOutSize();
		out.zbuf = malloc(out.zcap);
		if (!out.z || !out.zbuf) {
			fprintf(stderr, "king: out of memory\n");
			return 2;
		}
	}
	if (out_line(&out, "id,ra,dec,mag,type\n", 19))
		goto fail;
	for (long long id = 1; id <= (long long)n; id++) {
		double p = rng_uniform(&rng), theta = 2 * M_PI * rng_uniform(&rng);
		double hb = rng_uniform(&rng), m, logl, teff;
		double r = rc * sqrt(king_invert(&king, p)) / 60 * DEG;
		double xi = tan(r) * cos(theta), eta = tan(r) * sin(theta);
		double ra, dec, mag;
		int len;

		/* Inverse gnomonic projection; xi points east, eta north. */
		dec = asin((sd0 + eta * cd0) / sqrt(1 + xi * xi + eta * eta));
		ra = ra0 + atan2(xi, cd0 - eta * sd0) / DEG;
		if (ra < 0)
			ra += 360;
		else if (ra >= 360)
			ra -= 360;
		do
			m = imf_draw(&imf, &rng);
		while (!star_state(m, hb, &logl, &teff));
		mag = phot_mag(&phot, logl, teff);
		len = snprintf(line, sizeof(line), "%lld,%.7f,%.7f,%.4f,point\n",
			       id, ra, dec / DEG, mag);
		if (out_line(&out, line, (size_t)len))
			goto fail;
	}
	if (out_flush(&out, zstd ? ZSTD_e_end : ZSTD_e_continue))
		goto fail;
	status = 0;
fail:
	/* A write error may surface only when stdio's buffer is flushed. */
	if (fclose(stdout) && status == 0) {
		fprintf(stderr, "king: writing <stdout>: %s\n", strerror(errno));
		status = 2;
	}
	ZSTD_freeCCtx(out.z);
	free(out.zbuf);
	return status;
}
