/*
 * spectrum.h - a source's spectrum and what it changes: its counts through
 * an SCA's throughput (the colour term) and its effective wavelength,
 * which picks its PSF among the spectral classes (psf.h).
 *
 * A catalog row gives its spectrum as a blackbody temperature (teff), a
 * power-law slope beta (f_nu ~ nu^beta) or an AB colour between two
 * filters, from which beta follows (wfiscene-catalog(5)).  A row without
 * one keeps the spectrum wfiscene always assumed: counts of a flat f_nu
 * (the AB zeropoints), the PSF of a 5700 K blackbody.
 *
 * Integrals run over the 5 nm samples of data/throughput.tsv (the
 * effective area per SCA), as sums of A(lam) S(lam) / lam: the photons a
 * flux density f_nu = S brings per unit wavelength are f_nu / (h lam).
 */
#ifndef WFS_SPECTRUM_H
#define WFS_SPECTRUM_H

struct err;

enum spec_kind { SPEC_DEFAULT = 0, SPEC_BLACKBODY = 1, SPEC_POWER = 2 };

#define SPEC_TEFF_MIN 1000.0    /* K, the range a teff cell may hold */
#define SPEC_TEFF_MAX 100000.0
#define SPEC_BETA_MAX 20.0     /* |beta| a beta cell, or the slope a colour
				 * gives, may hold: 20 spans 10^11 in f_nu
				 * across the bluest to the reddest filter */

struct spectrum {
	int kind;               /* enum spec_kind */
	double value;           /* teff (K) or beta */
};

/* f_nu of s at lam relative to its value at lam_ref (micron); 1 for
 * SPEC_DEFAULT (a flat f_nu). */
double spec_fnu(const struct spectrum *s, double lam, double lam_ref);

/*
 * The colour tables of one filter, for all SCAs, made when first asked for
 * (each SCA under its own once-lock, so any thread may ask):
 *
 *   colour_factor   counts of s over those of a flat f_nu with the same
 *                   f_nu at the filter's pivot wavelength (filters.tsv):
 *                   sum A S / lam over sum A / lam, S = f_nu(lam) /
 *                   f_nu(pivot).  Exactly 1 for beta = 0.
 *   colour_lam_eff  the photon-weighted mean wavelength through the SCA,
 *                   sum A S  over sum A S / lam, micron.
 *
 * Tables, so that a row costs a few multiplications: beta on [-8, 8] in
 * steps of 1/64, a blackbody on 1000 K / T in [0.01, 1] in steps of
 * 1/1024, each of ln(factor) and lam_eff interpolated by cubic Hermite
 * (Catmull-Rom) splines: within 1e-7 of the sums themselves (measured by
 * tests/unit/spectrum.c).  A beta outside the table is summed directly.
 */
struct colour;

struct colour *colour_new(int filter, struct err *e);
void colour_free(struct colour *c);
double colour_factor(struct colour *c, int sca, const struct spectrum *s);
double colour_lam_eff(struct colour *c, int sca, const struct spectrum *s);
/* Both of s in one look-up, the same numbers as the two calls. */
void colour_both(struct colour *c, int sca, const struct spectrum *s, double *factor,
		 double *lam_eff);

/* The same as sums over the throughput, without tables: the reference the
 * tables are measured against. */
void colour_exact(const struct colour *c, int sca, const struct spectrum *s,
		  double *factor, double *lam_eff);

#endif
