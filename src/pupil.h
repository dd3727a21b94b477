/*
 * pupil.h - a pupil mask's clear fraction for optics.c's rasters (pupil.c).
 */
#ifndef WFS_PUPIL_H
#define WFS_PUPIL_H

#include <stddef.h>

#include "optics.h"

/* The clear fraction of the parallelogram cell b (d, 0), b (0, d) about
 * (x, y) of the Zernike plane, b = { b11, b12, b21, b22 }, the mask seen at
 * (x, -y) when flip: optics_pupil_cover() for a pupil sampled through the
 * linear map b (8 x 8 sub-samples across the cell's edges); reach, half
 * the cell's longer diagonal, 0.5 d max(|b (1, 1)|, |b (1, -1)|).  plain:
 * each sub-sample by the whole clearance test (for tests; the same
 * numbers). */
double pupil_cover_affine(const struct optics_pupil *p, double x, double y, const double b[4],
			  double d, int flip, double reach, int plain);

/*
 * A coarse map of the mask, so that most samples of a skewed pupil need no
 * clearance test at all: cells of side cs over [org, org + g cs)^2 in the
 * mask's frame, each clear when every sample in it has a clearance above
 * 1.01 reach, for the largest reach of the build, so that
 * pupil_cover_affine() gives 1 there without looking further; dark when
 * each has one below -1.01 reach (it gives 0); else unknown.  From each
 * term of the clearance at the cell's centre, within its slope times the
 * cell's half diagonal (pupil.c), whatever the slopes.
 */
#define PUPIL_UNKNOWN 0
#define PUPIL_CLEAR 1
#define PUPIL_DARK 2
#define PUPIL_COARSE_SIDE 256

struct pupil_coarse {
	int g;
	double org, cs, inv;
	unsigned char *cl;      /* g x g, row y; NULL: no map */
};

/* The map for cells of at most that reach: 0, or -1 when out of memory. */
int pupil_coarse_make(struct pupil_coarse *co, const struct optics_pupil *p, double reach);
void pupil_coarse_free(struct pupil_coarse *co);

/* The class of the coarse cell holding (x, y) of the mask's frame. */
static inline int pupil_coarse_at(const struct pupil_coarse *co, double x, double y)
{
	double u = (x - co->org) * co->inv, v = (y - co->org) * co->inv;

	if (!co->cl || !(u >= 0 && v >= 0 && u < co->g && v < co->g))
		return PUPIL_UNKNOWN;
	return co->cl[(size_t)(int)v * co->g + (int)u];
}

#endif
