/*
 * product.h - an exposure's products and the writers that store them.
 *
 * write.c makes the products of an exposure once: for each SCA, the image
 * after the detector stage (the scene level, strip by strip) or the read
 * ramp and its fit (levels 1 and 2, levels.c), with what is known about
 * them (struct product).  It hands them to a writer, which stores them in
 * one file format: write_fits.c (FITS, the default) or write_asdf.c (the
 * Roman pipeline's ASDF).  A writer sees every array once, in order of
 * rows, and never computes pixels; another format is one more writer.
 */
#ifndef WFS_PRODUCT_H
#define WFS_PRODUCT_H

#include <stdint.h>

struct engine;
struct err;
struct ramp_det;
struct ramp_pattern;
struct rnoise;

/* The output formats (--format; by default from -o's extension). */
enum product_format { FORMAT_FITS = 0, FORMAT_ASDF = 1 };

/* One SCA of an exposure as the writers see it. */
struct product {
	struct engine *g;       /* the exposure's engine: options, sky, date */
	int slot, sca;          /* g->slot[slot] is SCA sca (1..18) */
	int level;              /* enum detector_level */
	int ylo, yhi;           /* science rows [ylo, yhi) of 0 .. 4088 */
	/* levels 1 and 2: the read pattern and the SCA's constants */
	const struct ramp_pattern *pat;
	const struct ramp_det *det;
	int correlated;         /* the correlated read noise (RNCORR) */
};

/*
 * A computed strip of a level-1 or level-2 SCA (levels.c), in order of
 * rows.  l1: frame rows [fy0, fy0 + ny) of the 4096-pixel frame (the
 * reference border included), resultant r of frame row fy0 + i, pixel x
 * at l1[(r * ny + i) * 4096 + x]; at level 2 only when the writer asked
 * for it (writer_ops.l1_at_l2), else NULL.  Level 2: the ramp fit of the
 * science rows [sy0, sy0 + nsy) of 0 .. 4088 among them (nsy may be 0 for
 * a strip of reference rows), each plane [nsy][4088], rates in counts/s.
 */
struct level_strip {
	int fy0, ny;
	const uint16_t *l1;
	int sy0, nsy;
	const float *rate, *err, *var_poisson, *var_rnoise;
	const uint32_t *dq;
	/* with writer_ops.ramp_stats: ramp_stats.h's chisq and dumo (DN/s) */
	const float *chisq, *dumo;
	/* the exposure's correlated read noise (readnoise.h), for amp33; NULL:
	 * white read noise only */
	const struct rnoise *rn;
};

struct writer;

struct writer_ops {
	const char *name;               /* "FITS", "ASDF" */
	/* An SCA per file: -o needs %d when the exposure has several. */
	int one_sca_per_file;
	/* Level 2 also hands the writer the resultants (level_strip.l1), and
	 * chisq and dumo. */
	int l1_at_l2;
	int ramp_stats;
	/* Open path (after names.h's expansion) for the exposure of g: the
	 * file is written beside it and renamed by commit.  NULL on error. */
	struct writer *(*open)(struct engine *g, const char *path, struct err *e);
	/* An SCA: begin, its rows (the scene level: nrows rows of 4088
	 * float32 from the SCA's row ylo on, in order) or its strips (levels
	 * 1 and 2), end.  0 or -1 with a message. */
	int (*sca_begin)(struct writer *w, const struct product *p, struct err *e);
	int (*rows)(struct writer *w, const float *rows, int nrows, struct err *e);
	int (*strip)(struct writer *w, const struct level_strip *s, struct err *e);
	int (*sca_end)(struct writer *w, struct err *e);
	/* Finish the file and rename it to its name; frees w either way. */
	int (*commit)(struct writer *w, struct err *e);
	/* Give up: remove the temporary, free w.  NULL is a no-op. */
	void (*abort)(struct writer *w);
};

struct writer {
	const struct writer_ops *ops;
};

extern const struct writer_ops writer_fits;
extern const struct writer_ops writer_asdf;

/* The format of -o path when --format is not given: ".asdf" is ASDF,
 * anything else FITS. */
int product_format_of(const char *path);

#endif
