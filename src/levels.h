/*
 * levels.h - writing an SCA at detector level 1 (resultants) or 2 (ramp
 * fits) from its rendered rates, strip by strip.
 *
 * The rendered image of an SCA (counts/s, i.e. e-/s) plus the background
 * is the light; the detector's IPC kernel acts on it once (the ePSF of
 * these levels has no IPC: PSF_EPSF_NOIPC), then ramp.c reads it up the
 * ramp.  Each strip of rows is computed by the pool, row by row, and
 * handed to a writer (product.h), so memory
 * holds one strip of resultants whatever their number, and the bytes do
 * not depend on the threads, the strip height or --rows.
 *
 * Level 1: nres planes of 4096 x rows 16-bit DN (the 4-pixel reference
 * border included; with --rows, the rows of the part, with the bottom or
 * top border rows when the part reaches it).  Level 2: the rate (counts/s,
 * the dark current subtracted), its error, DQ (romancal's bits) and the
 * Poisson and read-noise variances ((counts/s)^2), 4088 x rows.
 */
#ifndef WFS_LEVELS_H
#define WFS_LEVELS_H

#include "ramp.h"

struct err;
struct geom_sca;
struct level_strip;
struct pool;

enum level { LEVEL_SCENE = 0, LEVEL_1 = 1, LEVEL_2 = 2 };

/* Parse a --level value: "scene", "1" or "2" (also "l1", "l2"). */
int level_parse(const char *s, int *level, struct err *e);

struct level_sca {
	int level;              /* LEVEL_1 or LEVEL_2 */
	const struct ramp_pattern *pat;
	const struct ramp_det *det;     /* this SCA's constants */
	struct ramp_key key;    /* seed, filter, SCA */
	int ylo, yhi;           /* science rows [ylo, yhi) of 0 .. 4088 */
	int strip;              /* rows per strip, > 0 */
	double background;      /* counts/s/pixel added to the rendered light */
	/* With geo set (the SIAF geometry), the sky's part of it per nominal
	 * 0.11" pixel, which each pixel gets times its own area
	 * (geom_area_row), as the scene level does (detector.c); the rest of
	 * background (the thermal glow) is added as is. */
	const struct geom_sca *geo;
	double bkg_sky;
	/* The rendered rate of science row y (0 .. 4087) into out[0 .. 4087];
	 * called on the calling thread only.  0 or -1 (message in e). */
	int (*rate_row)(void *arg, int y, double *out, struct err *e);
	void *arg;
	/* Where the computed strips go (product.h), in order of rows, on
	 * the calling thread: 0 or -1 (message in e).  With keep_l1, level 2
	 * hands over the resultants too. */
	int (*put)(void *arg, const struct level_strip *s, struct err *e);
	void *put_arg;
	int keep_l1;
	int ramp_stats;         /* level 2: chisq and dumo too (ramp_stats.h) */
	struct pool *pool;
	/* The run's persistence state (NULL: none), begun for the exposure:
	 * the afterglow of its pixels goes into the ramp read by read, the
	 * SCA's light (with the dark current) times the exposure time is
	 * the exposure's stimulus, and level 2 flags DQ PERSISTENCE where the
	 * afterglow's charge reaches the state's flag times the read noise. */
	struct persist *persist;
	/* The correlated read noise (readnoise.h, --detector correlated):
	 * the white part of the read noise becomes the SCA's white amplitude
	 * in data/readnoise.tsv, the rest is drawn per channel, its
	 * reference pixels sample it, and level 2 corrects the resultants
	 * with them before the fit. */
	int correlated;
	/* out: CPU-independent wall seconds spent, for --report */
	double t_ramp, t_write;
};

/* Compute the SCA strip by strip, each handed to L->put.  0 or -1 with a
 * message. */
int level_write_sca(struct level_sca *L, struct err *e);

#endif
