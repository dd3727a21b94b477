/*
 * noise.h - backgrounds, noise and detector residuals, applied tile by tile
 * after the last catalog chunk.  Every random number comes from a
 * counter-based generator keyed by (seed, filter, SCA, stage) and counted by
 * absolute pixel, so an image is bit-identical for any thread count, tile
 * size or tile order, and for runs split by SCA.  (The dark residual field
 * is keyed without the filter: it is the detector's, the same in every
 * filter.)  The model, its defaults and their sources: noise.c and the
 * NOISE section of wfiscene(1).
 */
#ifndef WFS_NOISE_H
#define WFS_NOISE_H

#include <stddef.h>
#include <stdint.h>

struct err;

enum noise_stage {
	NOISE_POISSON = 1 << 0,
	NOISE_READ = 1 << 1,
	NOISE_DARK = 1 << 2,
	NOISE_FLAT = 1 << 3,
	NOISE_COSMIC = 1 << 4,
	NOISE_ALL = 0x1f,
};

struct noise_opts {
	unsigned stages;        /* enum noise_stage bits */
	double background;      /* counts/s/pixel added first; 0 for none */
	double exptime;         /* seconds, > 0 */
	double readnoise;       /* e- per read, default 12 */
	double dark_current;    /* e-/s/pixel mean of the dark stage, with shot
	                           noise; default NOISE_DARK_CURRENT */
	double cosmic_rate;     /* hits/cm^2/s per population, default 5 */
	double cosmic_residual; /* fraction of each hit kept, default 0.01 */
	uint64_t seed;
	int filter;             /* enum wfs_filter: part of the key */
	int counts;             /* 1: leave the image in counts, else counts/s */
	/* Appended fields; 0 selects the default (NOISE_DARK_RESIDUAL,
	 * NOISE_FLAT_RESIDUAL): leave a stage out to drop its field. */
	double dark_residual;   /* sigma of the fixed dark residual field, e-/s */
	double flat_residual;   /* sigma of the fixed flat residual field */
	/* The mean in counts from which the Poisson stage draws the
	 * skew-corrected normal instead of the exact count (rng.h,
	 * rng_poisson_normal); 0 selects NOISE_POISSON_NORMAL (--set
	 * poisson-normal=N). */
	double poisson_normal;
};

/* Defaults, as STIPS or the Roman WFI ground tests give them (see noise.c
 * and wfiscene(1)). */
#define NOISE_READNOISE 12.0        /* e-, STIPS WFI.generateReadnoise */
#define NOISE_DARK_CURRENT 0.028    /* e-/s, WFI mean, all 18 SCAs at 89.5 K */
#define NOISE_DARK_RESIDUAL 0.0037  /* e-/s, sigma of STIPS' mock dark (#198) */
#define NOISE_FLAT_RESIDUAL 0.00068 /* sigma of STIPS' mock flat (#142) */
#define NOISE_COSMIC_RATE 5.0       /* hits/cm^2/s per population */
#define NOISE_COSMIC_RESIDUAL 0.01  /* fraction of each hit left */
#define NOISE_POISSON_NORMAL 1000.0 /* counts: exact Poisson below */

/* Set every field to its default: no stages, no background, exptime 1 s,
 * counts/s output, seed 0. */
void noise_opts_default(struct noise_opts *o);

/* Check the option values (exptime > 0, finite background, non-negative
 * rates and sigmas).  Returns 0 or -1 with a message naming the option. */
int noise_check(const struct noise_opts *o, struct err *e);

/* Parse a --noise value ("all", "none", "poisson,readnoise"), setting
 * *stages.  Returns 0 or -1 with a message. */
int noise_parse(const char *s, unsigned *stages, struct err *e);

/*
 * Apply background, exposure time, the selected stages and the unit
 * conversion to the tile of SCA sca whose pixel (x0, y0) is pix[0]; pixel
 * (x, y) is pix[(y - y0) * stride + (x - x0)], in counts/s on entry.  The
 * result depends only on the options, sca and absolute pixel coordinates.
 * Thread-safe.  Returns 0 or -1.
 */
int noise_tile(const struct noise_opts *o, int sca, int x0, int y0, int nx,
	       int ny, double *pix, ptrdiff_t stride);

#endif
