/*
 * amp33.h - the 33rd amplifier's reference channel of an SCA at levels 1
 * and 2: 128 columns beside the 4096 of the array, read with it, that see
 * no light.
 *
 * Each of its pixels is what a reference pixel of the array is in ramp.c:
 * the pedestal and the reset noise, through the non-linearity, then the
 * read noise of each read averaged into the resultants, in DN.  Its
 * randomness is keyed by (seed, filter, SCA) and the pixel (y * 128 + x) in
 * a domain of its own, so the array's numbers do not move when it is
 * written, and any strip of rows gives the same values.  With the
 * correlated read noise (readnoise.h) its read noise is that model's: the
 * white part per pixel, and the pink series, pedestal, alternating-column
 * offsets and slow part of channel 32, so that a reference correction
 * from amp33 has the channels' shared noise to measure.
 */
#ifndef WFS_AMP33_H
#define WFS_AMP33_H

#include <stddef.h>
#include <stdint.h>

#include "ramp.h"

#define AMP33_COLS 128

struct rnoise;

/* Scratch doubles amp33_rows needs; set up with ramp_scratch_init. */
#define AMP33_SCRATCH RAMP_SCRATCH(AMP33_COLS)

/* Rows [fy0, fy0 + ny) of 0 .. 4096 of the channel: resultant r of row
 * fy0 + i, column x at out[(r * ny + i) * 128 + x]; rn the exposure's
 * correlated read noise, or NULL (white read noise only). */
void amp33_rows(const struct ramp_pattern *p, const struct ramp_det *d,
		const struct ramp_key *k, const struct rnoise *rn, int fy0, int ny, uint16_t *out,
		double *scratch);

#endif
