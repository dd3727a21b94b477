/*
 * detector.h - the detector stage: what happens to the light the models
 * drew, after rendering and before the image is written.
 *
 * write.c hands each strip of tiles of an SCA to detector_strip_start()
 * once all catalog chunks are drawn.  How far the detector is simulated
 * is the exposure's level; each level is a function of the drawn rates,
 * the options, the SCA and the absolute pixel coordinates only (never of
 * the tile size, tile order or thread count), so runs split by SCA or rows
 * give the same bytes.
 */
#ifndef WFS_DETECTOR_H
#define WFS_DETECTOR_H

#include <stdatomic.h>
#include <stddef.h>

#include "instrument.h"
#include "noise.h"
#include "ramp.h"

struct err;
struct exposure;
struct pool;
struct scene_opts;
struct sky;

enum detector_level {
	/* A rate image (or counts with --bunit counts): background, exposure
	 * time and the --noise stages, tile by tile (noise.c). */
	DETECTOR_SCENE = 0,
	/* The detector read up the ramp (ramp.c, levels.c): the resultants of
	 * the MA table as 16-bit DN (level 1), or their ramp fits (level 2).
	 * The SCA is written by level_write_sca() instead of strip by strip
	 * through detector_strip_start(). */
	DETECTOR_L1 = 1,
	DETECTOR_L2 = 2,
};

struct detector {
	enum detector_level level;
	struct noise_opts noise;        /* DETECTOR_SCENE, but the background: */
	/* Each SCA's background in counts/s per pixel, in two parts: the
	 * sky's light, per nominal 0.11" pixel (the zodiacal light of avg and
	 * sky, all of a number), which a geometry whose pixels differ in area
	 * scales by each pixel's area; and the internal thermal glow, per
	 * detector pixel whatever its area on the sky. */
	double bkg_sky[WFS_NSCA], bkg_pixel[WFS_NSCA];
	int active;                     /* 0: the drawn image is written as is */
	struct ramp_pattern pattern;    /* DETECTOR_L1, DETECTOR_L2 */
	/* The geometry of each SCA (NULL: a flat background, as stips): in
	 * the SIAF geometry each pixel's background is the --background value
	 * times its area over a nominal 0.11" square (DETECTOR_SCENE). */
	const struct sky *sky;
	/* --set poisson-normal=N: the mean (e-, counts) from which a Poisson
	 * count is the skew-corrected normal (rng_poisson_normal), at every
	 * level; 0 for the defaults (NOISE_POISSON_NORMAL, RAMP_POISSON_NORMAL). */
	double poisson_normal;
	/* The run's persistence state (NULL: none), begun for this exposure
	 * by detector_init(): the afterglow of earlier exposures, and this
	 * one's stimulus added to it strip by strip (scene level) or row by
	 * row (levels.c) */
	struct persist *persist;
	double exptime;         /* s: the scene's --exptime or the last read */
	unsigned parts;         /* enum detector_part bits (--detector) */
};

/* The named parts of the detector model that can be turned off
 * (--detector); each in wfiscene(1), DETECTOR MODEL, with its source. */
enum detector_part {
	/* trapped charge from earlier exposures of the series released as
	 * an afterglow (persist.c) */
	DETECTOR_PERSISTENCE = 1 << 0,
	/* the read noise's 1/f, pedestal and alternating-column parts per
	 * readout channel, sampled by the reference pixels and corrected at
	 * level 2 (readnoise.c) */
	DETECTOR_CORRELATED = 1 << 1,
	DETECTOR_ALL = DETECTOR_PERSISTENCE | DETECTOR_CORRELATED,
	/* what levels 1 and 2 have without --detector: the parts whose
	 * calibration holds (wfiscene(1), DETECTOR MODEL): all */
	DETECTOR_DEFAULT = DETECTOR_ALL,
};

/* Parse a --detector value: "all", "none" or a comma-separated list of
 * parts ("persistence", "correlated"), into *parts.  0 or -1 with a message. */
int detector_parse(const char *s, unsigned *parts, struct err *e);

struct level_sca;

/* The background of SCA sca at levels 1 and 2 (the sky's part per pixel
 * area in the SIAF geometry, as a scene's strips have it) and the knobs of
 * the ramp's approximations, into L. */
void detector_level_setup(const struct detector *d, int sca, struct level_sca *L);

/* The detector stage of exposure x of a run with options o.  With a
 * persistence state (x->persist), the exposure is begun in it
 * (persist_begin; the caller ends it with persist_end once written). */
int detector_init(struct detector *d, const struct scene_opts *o, const struct exposure *x,
		  struct err *e);

/*
 * Apply the stage to one strip of an SCA: tiles[0 .. ntx-1], each T x T
 * doubles (row stride T) holding the drawn counts/s of pixels
 * [tx T, tx T + T) x [y0, y0 + ny), clipped to the detector; every tile
 * MUST be allocated.  In two halves, so that the caller can write the
 * strip before while the pool works on this one: detector_strip_start()
 * runs the persistence step (on the calling thread) and starts the tiles
 * on pool, in parallel, which must be idle; detector_strip_wait() waits
 * for them.  Every start that returned 0 needs its wait, also after a
 * failure elsewhere.  Each returns 0, or -1 when a tile (or the
 * persistence step) failed.  With done set, the pool calls it for each
 * tile once the stage is through with it (done_arg, tile tx), also when
 * the stage is the identity (a tile never drawn on is then NULL): the
 * writer's conversion, beside the stage.
 */
struct detector_run {
	const struct detector *d;
	struct pool *pool;
	int sca, y0, ny, T, started;
	double *const *tiles;
	atomic_int failed;
	void (*done)(void *done_arg, size_t tx);
	void *done_arg;
};

int detector_strip_start(struct detector_run *r, const struct detector *d, struct pool *pool,
			 int sca, int y0, int ny, double *const *tiles, int ntx, int T,
			 void (*done)(void *, size_t), void *done_arg);
int detector_strip_wait(struct detector_run *r);

#endif
