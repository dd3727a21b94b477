/*
 * readnoise.h - the correlated part of an H4RG's read noise and the
 * reference-pixel correction that removes most of it.
 *
 * Each read of each of the 33 readout channels (32 of 128 columns, and
 * amp33) adds to its pixels: a 1/f ("pink") series in time shared by all
 * channels, a pink series of its own, an offset per read (the pedestal)
 * and an offset per read for its odd columns against its even ones
 * (alternating-column noise).  The pink series are continuous over the
 * whole exposure at the time resolution of a row (read_time / 4096 s), a
 * pixel taking the value at its place in its row's readout (linear between
 * a row's start and the next, 128 columns then RN_OVERHEAD idle pixel
 * times).  Each series is the inverse FFT of Gaussian coefficients keyed
 * by (seed, filter, SCA, series, frequency), so every pixel's noise is the
 * same whichever thread, strip or --rows part asks.  The model follows
 * the structure of Rauscher (2015, PASP 127, 1144, NGHXRG); the per-SCA
 * amplitudes are in data/readnoise.tsv.
 *
 * Each pixel also carries a slow noise of its own (the "slow" part), what
 * a pixel keeps over many reads and the reference pixels cannot see (the
 * low-frequency end of its source follower's 1/f and random-telegraph
 * noise): a Gauss-Markov sequence of stationary rms slow and correlation
 * time slow_tau at knots every RN_KNOT reads (read 0 the reset), linear
 * between them.  Knot j of a pixel is keyed by (seed, filter, SCA, j) and
 * the pixel, so any read of any pixel is the same whoever asks; a pixel
 * costs one normal deviate a knot.
 */
#ifndef WFS_READNOISE_H
#define WFS_READNOISE_H

#include <stdint.h>

#include "ramp.h"

struct err;

#define RN_NCHAN 33             /* 32 channels and amp33 (channel 32) */
#define RN_COLS 128             /* columns of a channel */
#define RN_ROWS 4096            /* rows of the frame, read bottom to top */
#define RN_OVERHEAD 12          /* idle pixel times closing each row */

/* The per-read amplitudes (e-) of one SCA, data/readnoise.tsv. */
struct rnoise_par {
	double cds;             /* the Project's CDS noise the parts give */
	double total;           /* and its total noise of 55 reads */
	double white;           /* per pixel and read, independent */
	double ped;             /* per channel and read */
	double cpink;           /* pink, shared by the channels */
	double upink;           /* pink, each channel its own */
	double acn;             /* odd against even columns, per channel and read */
	double slow;            /* per pixel, slow: stationary rms */
	double slow_tau;        /* its correlation time, s */
};

#define RN_KNOT 8               /* reads between the slow part's knots */
#define RN_MAX_KNOT 48          /* knots of an exposure, reads up to 375 */
#define RN_AMP33_CELL 0x1000000u        /* amp33's pixel (y, x): this + y * 128 + x */

/* The amplitudes of SCA sca (1..18).  0 or -1 with a message. */
int rnoise_par_get(int sca, struct rnoise_par *par, struct err *e);

struct rnoise {
	struct rnoise_par par;
	int nres;
	/* resultant r's mean over its reads of the channel's pink (shared
	 * and own) at the start of frame row y: pink[(r * RN_NCHAN + c) *
	 * (RN_ROWS + 1) + y], y = 4096 the start of the next frame; r = nres
	 * is the reset read (read 0), as off, kc, kj0 and kj1 below */
	float *pink;
	/* the mean of pedestal + alternating-column offset of the even (0) and
	 * odd (1) columns: off[(r * RN_NCHAN + c) * 2 + parity] */
	float *off;
	/* the pink series' model: sigma^2 of each, and the number of samples */
	long nsamp;
	double row_time;
	/* the slow part: knots 0 .. nknot - 1, knot j at read j RN_KNOT, the
	 * step from one to the next Y_j = rho Y_j-1 + s1 z_j (Y_0 = slow z_0);
	 * resultant r's mean of it sum_j kc[r * nknot + j] Y_j over knots
	 * kj0[r] .. kj1[r] */
	int nknot;
	double rho, s1;
	double *kc;
	int kj0[RAMP_MAX_RES + 1], kj1[RAMP_MAX_RES + 1];
	uint64_t seed;
	uint32_t slow_dom;      /* its domain but for the knot (bits 24-31) */
};

/* The correlated noise of one exposure (pattern p) of the SCA of key k,
 * its series long enough for reads up to nlast (0: p's last read; a larger
 * value lets two patterns of one exposure share the series, as tests do).
 * Costs 34 real FFTs of (nlast + 2) x 4096 points.  0 or -1 (memory,
 * message in e).  Free with rnoise_free(). */
int rnoise_init(struct rnoise *R, const struct ramp_pattern *p, const struct rnoise_par *par,
		const struct ramp_key *k, int nlast, struct err *e);
void rnoise_free(struct rnoise *R);

/* The readout position (0 .. 127) of column x (0 .. 127) of channel c:
 * even channels read their columns upwards, odd ones downwards. */
static inline int rnoise_pos(int c, int x)
{
	return c & 1 ? RN_COLS - 1 - x : x;
}

/*
 * Add to dst[0 .. n) the correlated noise (e-) of resultant r at frame
 * row y (0 .. 4095) of channel c (0 .. 32; 32 is amp33) for its columns
 * x0 .. x0 + n - 1 (0 .. 127 within the channel).  Any column range, any
 * order of calls: the numbers are fixed by rnoise_init.
 */
void rnoise_add(const struct rnoise *R, int r, int c, int y, int x0, int n, float *dst);

/* The same for frame columns fx0 .. fx0 + n - 1 (0 .. 4095) of frame row y,
 * across channels. */
void rnoise_add_frame(const struct rnoise *R, int r, int y, int fx0, int n, float *dst);

/*
 * Add the slow part (e-) of pixels cell0 .. cell0 + n - 1 (frame pixel y *
 * 4096 + x; amp33's RN_AMP33_CELL + y * 128 + x) to their resultants r0 ..
 * r1 - 1: resultant r of pixel i at dst[(r - r0) * plane + i].
 */
void rnoise_slow_add(const struct rnoise *R, uint32_t cell0, int n, int r0, int r1, float *dst,
		     size_t plane);

/* Add the correlated noise, the slow part included, to reference pixels
 * already in DN (frame row y, frame columns fx0 .. fx0 + n - 1, resultant
 * r at out[r * plane + i]), rounding to DN and clipping to 16 bits, with
 * gain e-/DN. */
void rnoise_add_dn(const struct rnoise *R, double gain, int y, int fx0, int n, uint16_t *out,
		   size_t plane);

/* The same for the reset read (read 0, the reference read of a level-1
 * file), row y, frame columns fx0 .. fx0 + n - 1 at out[i]. */
void rnoise_add_read0_dn(const struct rnoise *R, double gain, int y, int fx0, int n, uint16_t *out);

/* The same for amp33's 128 columns of frame row y (channel 32, columns in
 * readout order), resultant r at out[r * plane + x]. */
void rnoise_add_amp33_dn(const struct rnoise *R, double gain, int y, uint16_t *out, size_t plane);

/*
 * The reference correction of level 2, from the reference pixels of the
 * whole frame (which it draws itself with ramp_level1_row and
 * rnoise_add_frame, so that every strip and --rows part sees the same):
 * per resultant, channel and column parity the mean of the 4 top and 4
 * bottom reference rows; per resultant and row the mean of the 4 left and
 * 4 right reference columns (after that), smoothed over 2 RN_SIDE_HALF + 1
 * rows.  In DN.
 */
#define RN_SIDE_HALF 32
struct rnoise_ref {
	int nres;
	double *tb;             /* [r][32][2] */
	double *side;           /* [r][4096] */
};

int rnoise_ref_init(struct rnoise_ref *C, const struct rnoise *R, const struct ramp_pattern *p,
		    const struct ramp_det *d, const struct ramp_key *k, struct err *e);
void rnoise_ref_free(struct rnoise_ref *C);

/* Subtract the correction from science row y's resultants (frame row y,
 * frame columns 4 .. 4091 at dn[r * plane + fx - 4]), rounding to DN. */
void rnoise_ref_apply(const struct rnoise_ref *C, int y, uint16_t *dn, size_t plane, int nres);

#endif
