/*
 * ramp.h - the detector read up the ramp: level-1 resultants of a pixel row
 * from its expected rate, and the level-2 ramp fit of a pixel's resultants.
 *
 * Pure functions of their arguments: no engine, no files.  The randomness
 * is Philox keyed by (seed, domain, absolute pixel), the domain naming the
 * filter, the SCA and the purpose (see ramp.c), so a row gives the same
 * resultants whatever the strip, thread or split run that asks for it.
 *
 * Units: charge in electrons (e-), rates in e-/s (wfiscene's counts/s),
 * resultants in DN (16-bit, gain e-/DN).  The model and every constant:
 * ramp.c (level 1), ramp_fit.c (level 2), data/detector.tsv and the LEVELS
 * section of wfiscene(1).
 */
#ifndef WFS_RAMP_H
#define WFS_RAMP_H

#include <stddef.h>
#include <stdint.h>

struct err;

#define RAMP_MAX_RES 32         /* resultants of a read pattern */

/* DQ bits as romancal defines them. */
enum ramp_dq {
	RAMP_DO_NOT_USE = 1,
	RAMP_SATURATED = 2,
	RAMP_JUMP_DET = 4,
	RAMP_NONLINEAR = 1 << 16,
	RAMP_NO_LIN_CORR = 1 << 20,
};

/* A MultiAccum table: resultant i is the mean of reads first[i] ..
 * last[i] (1-based; read k ends k read times after the reset). */
struct ramp_pattern {
	int table;              /* MA table number */
	int nres;
	int first[RAMP_MAX_RES], last[RAMP_MAX_RES];
	double read_time;       /* s */
	/* derived by ramp_pattern_finish(): */
	int nread[RAMP_MAX_RES];
	double tbar[RAMP_MAX_RES];  /* mean time of the reads, s */
	double tau[RAMP_MAX_RES];   /* Poisson variance time: Var = rate tau */
	double exptime;         /* last read x read time */
};

/* The detector constants of one SCA (data/detector.tsv). */
struct ramp_det {
	double read_time;       /* s */
	double gain;            /* e-/DN */
	double saturation;      /* DN, measured signal with the pedestal */
	double beta;            /* measured = true + beta true^2, 1/e- */
	double pedestal;        /* e- */
	double reset_noise;     /* e- */
	double read_noise;      /* e- per read */
	double dark;            /* e-/s */
	double cosmic_rate;     /* hits/cm^2/s per population */
	double cosmic_e[2];     /* e- per hit of the two populations */
	double pixel_area;      /* cm^2 */
	double jump_threshold;  /* sigma */
	double nonlinear_flag;  /* DQ NONLINEAR beyond this correction, true /
	                           measured - 1 */
	double ipc[3][3];       /* [dy + 1][dx + 1], sum 1 */
	/* derived by ramp_det_finish(): */
	double sat_e;           /* saturation in measured e- */
	double sat_true;        /* true charge (pedestal included) at sat_e */
};

/* The read pattern of MA table `table` from data/ma_tables.tsv.  Returns 0,
 * or -1 with a message listing the tables there are. */
int ramp_pattern_get(int table, struct ramp_pattern *p, struct err *e);

/* Fill the derived fields of p from first/last/read_time (for patterns
 * built by hand, e.g. in tests).  Returns 0 or -1 when p is not a valid
 * pattern (ascending, non-overlapping runs of reads). */
int ramp_pattern_finish(struct ramp_pattern *p);

/* The constants of SCA sca (1..18) from data/detector.tsv.  0 or -1. */
int ramp_det_get(int sca, struct ramp_det *d, struct err *e);

/* Fill the derived fields of d.  0, or -1 when a constant is out of range. */
int ramp_det_finish(struct ramp_det *d);

/* The classical non-linearity of the measured signal and its inverse (e-,
 * pedestal included); ramp_nl() saturates at d->sat_e. */
double ramp_nl(const struct ramp_det *d, double s);
double ramp_nl_inverse(const struct ramp_det *d, double m);

/* Keys of the level-1 randomness: seed and the (filter, SCA) domain. */
struct ramp_key {
	uint64_t seed;
	int filter, sca;
	double split_exact_max; /* arrivals in a group up to which they are
	                           placed among its reads one by one; above,
	                           the Irwin-Hall normal (ramp.c); default 4 */
	double poisson_normal;  /* mean from which a group's count is the
	                           skew-corrected normal (rng_poisson_normal);
	                           0: RAMP_POISSON_NORMAL */
};

#define RAMP_POISSON_NORMAL 1000.0  /* e-, --set poisson-normal */

/*
 * Level 1 of the n pixels cell0 .. cell0 + n - 1 (cell = absolute pixel
 * y * 4096 + x of the 4096^2 array, reference border included) given their
 * expected rates rate[0..n) in e-/s of light (source and sky; the dark
 * current d->dark is added here).  light = 0 marks reference pixels:
 * pedestal, reset and read noise only.  Resultant r of pixel i goes to
 * out[r * plane + i].  No IPC: see ramp_level1_charge().  scratch:
 * RAMP_SCRATCH(n) doubles.  Thread-safe.
 */
#define RAMP_SCRATCH(n) ((size_t)(n) * 8 + 512)
/* Kept for the callers: the scratch needs no set-up (the Poisson tables,
 * once kept there, are the process's: ramp_pois.c). */
void ramp_scratch_init(double *scratch);
void ramp_level1_row(const struct ramp_pattern *p, const struct ramp_det *d,
		     const struct ramp_key *k, uint32_t cell0, int n,
		     const double *rate, int light, uint16_t *out, size_t plane,
		     double *scratch);

/*
 * The same row of light pixels in two parts, for IPC to act on the
 * collected charge: ch[r * cplane + i] the charge that resultant r of
 * pixel i measures (Poisson arrivals of light and dark, cosmic rays,
 * non-linearity and saturation; e-, its reset level taken out) and
 * own[r * cplane + i] what the pixel adds itself (its reset level through
 * the non-linearity, and the read noise).  The same random numbers as
 * ramp_level1_row(), so a row's charge is the same whichever strip asks.
 */
void ramp_level1_charge(const struct ramp_pattern *p, const struct ramp_det *d,
			const struct ramp_key *k, uint32_t cell0, int n,
			const double *rate, double *ch, float *own, size_t cplane,
			double *scratch);

/*
 * The afterglow of persistence (persist.h) in a row of light pixels: n of
 * them, science pixels pix[0 .. n) ascending (pix - base their offset in
 * the row call), each releasing scale[k] times the SCA's decay curve from
 * tend[k] on; the exposure's reset at t0 (s, the clock of tend).  Each
 * read's share of it is a Poisson count of the charge the curve releases
 * between that read and the one before (the reset for read 1), keyed by
 * (seed, read, pixel), so a pixel's afterglow is the same whoever asks.
 */
struct persist_curve;
struct ramp_glow {
	int n;
	const uint32_t *pix;
	uint32_t base;
	const float *scale;
	const double *tend;
	double t0;
	const struct persist_curve *curve;
};

/* ramp_level1_charge() with the afterglow glow (NULL or n = 0: none). */
void ramp_level1_charge_glow(const struct ramp_pattern *p, const struct ramp_det *d,
			     const struct ramp_key *k, uint32_t cell0, int n,
			     const double *rate, const struct ramp_glow *glow, double *ch,
			     float *own, size_t cplane, double *scratch);

/*
 * The resultants (DN) of a row from ramp_level1_charge()'s parts: the
 * charge of the rows above, at and below (NULL for a row off the array,
 * which brings none; each with its resultants cplane apart) through the
 * 3x3 IPC kernel of d, plus the row's own part; clipped at saturation and
 * to 16 bits.  Resultant r of pixel x goes to out[r * plane + x].
 */
void ramp_level1_finish(const struct ramp_det *d, int nres, int n, const double *above,
			const double *row, const double *below, const float *own,
			size_t cplane, uint16_t *out, size_t plane);

/*
 * The reference read of the n pixels cell0 .. cell0 + n - 1: the read
 * right after the reset, before any light, in DN: the reset level the
 * pixel's resultants start from, through the non-linearity, plus one
 * read's noise (keyed apart from the resultants').  scratch: 2 n doubles.
 * Level 1's optional reference_read of the ASDF product.  Thread-safe.
 */
void ramp_reference_row(const struct ramp_det *d, const struct ramp_key *k, uint32_t cell0,
			int n, uint16_t *out, double *scratch);

/* Weights of the unsegmented full ramp, one set per Casertano power;
 * computed once per pattern and detector, then shared by threads. */
struct ramp_fit_plan {
	struct ramp_pattern p;
	struct ramp_det d;
	double var_read[RAMP_MAX_RES];  /* e^2 per resultant */
	int nres;
	double w[6][RAMP_MAX_RES], vr[6], vp[6];
	double *nlinv;          /* true charge of each DN value, 65536 */
	double jump2;           /* jump_threshold^2 */
	double dtbar[RAMP_MAX_RES], vdiff[RAMP_MAX_RES], cdiff[RAMP_MAX_RES];
	int nl_dn;              /* the first DN whose correction exceeds
	                           d.nonlinear_flag: DQ NONLINEAR */
};

/* 0, or -1 when out of memory.  Free with ramp_fit_plan_free(). */
int ramp_fit_plan_init(struct ramp_fit_plan *fp, const struct ramp_pattern *p,
		       const struct ramp_det *d);
void ramp_fit_plan_free(struct ramp_fit_plan *fp);

/* The level-2 result of a pixel. */
struct ramp_fit {
	double rate;            /* e-/s */
	double var_poisson, var_rnoise;  /* (e-/s)^2 */
	uint32_t dq;
	int njump;              /* jumps found */
	int nuse;               /* resultants used */
};

/*
 * Fit the resultants dn[0 .. nres) (DN, resultant r at dn[r * stride]) of
 * one pixel: saturated resultants (and one partly saturated before them)
 * dropped, non-linearity corrected, jumps found and the ramp split there,
 * each piece fitted with Casertano et al. (2022) optimal weights, the
 * pieces combined.  The rate keeps the dark current in (the caller
 * subtracts it as the pipeline's dark step would).  Thread-safe.
 */
void ramp_fit_pixel(const struct ramp_fit_plan *fp, const uint16_t *dn,
		    size_t stride, struct ramp_fit *out);

/* The fits of the n pixels x = 0 .. n-1 of a row, resultant r of pixel x
 * at dn[r * plane + x], into out[x]: the results of ramp_fit_pixel(),
 * faster for pixels with no saturation, flag or jump.  Thread-safe. */
void ramp_fit_row(const struct ramp_fit_plan *fp, const uint16_t *dn, size_t plane, int n,
		  struct ramp_fit *out);

#endif
