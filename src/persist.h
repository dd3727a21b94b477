/*
 * persist.h - persistence: the charge an H4RG's pixels trap where earlier
 * exposures of a series brought much light, released as an extra current
 * (an afterglow) in the exposures that follow.
 *
 * The state of a run is, per SCA, a list of the pixels that hold trapped
 * charge, in pixel order: each with the amplitude of its stimulus (the
 * fermi model's response to the fluence it reached, relative to the
 * response to the stimulus the Project's decay curves were measured
 * with) and the time that stimulus ended.  The exposures of a run are
 * taken in order (their dates must not go back); each exposure's detector
 * stage reads the state as it was when the exposure began (the afterglow
 * of every pixel, a pure function of the state and the exposure's times)
 * and adds its own stimulus, pixel row by pixel row in order, to a second
 * list that persist_end() merges into the state.  The state can be carried
 * from one run to the next through a file (persist_load, persist_save).
 *
 * The model, its constants and their sources: persist.c, data/
 * persistence.tsv and the PERSISTENCE section of wfiscene(1).
 */
#ifndef WFS_PERSIST_H
#define WFS_PERSIST_H

#include <stddef.h>
#include <stdint.h>

#include "instrument.h"

struct err;
struct exposure;

/* romancal's DQ bit for a pixel affected by persistence (2^5). */
#define PERSIST_DQ (1u << 5)

/* The decay of one SCA's persistence current after a stimulus of the
 * reference fluence: a e^(-b t) + d e^(-e t) + c e-/s at t seconds after
 * its end, nothing beyond tmax (the end of the measurements). */
struct persist_curve {
	double a, b, c, d, e;
	double tmax;
};

/* The pixels of one SCA holding trapped charge: science pixel y * 4088 + x
 * (ascending), the stimulus's amplitude and the time its exposure ended
 * (s on the run's clock, see persist_begin). */
struct persist_list {
	size_t n, cap;
	uint32_t *pix;
	float *scale;
	double *tend;
};

struct persist {
	unsigned sca_mask;      /* the SCAs the state is of */
	int ylo, yhi;           /* the science rows [ylo, yhi) of the run;
	                           at levels 1 and 2 it holds the row either
	                           side too (IPC brings their charge in) */
	struct persist_list now[WFS_NSCA], next[WFS_NSCA];
	struct persist_curve curve[WFS_NSCA];
	/* per SCA the least fluence (e-) whose current 30 s after its
	 * exposure reaches the floor: below it persist_add() keeps nothing */
	double x_keep[WFS_NSCA];
	/* the fermi model: x0, dx, alpha, half well (e-); its response to the
	 * reference fluence */
	double x0, dx, alpha, half_well, ref_response;
	/* --set persistence-floor (e-/s: a pixel is kept while its current
	 * 30 s after the latest exposure's end reaches it),
	 * persistence-flag (DQ where the afterglow's charge over the exposure
	 * reaches this fraction of the read noise of a read),
	 * persistence-gap (s between exposures without dates) */
	double floor, flag, gap;
	/* the exposure begun: its reset and its last read, s (an MJD times
	 * 86400, or the default cadence's clock); the end of the one before */
	double t0, t1, last_end;
	int have_last;
	int exposures;          /* taken so far, across runs */
};

/* A state for the SCAs of sca_mask and science rows [ylo, yhi), empty,
 * its knobs from settings ("key=value", NULL-ended, the last one given
 * winning).  NULL with a message. */
struct persist *persist_new(unsigned sca_mask, int ylo, int yhi,
			    const char *const *settings, struct err *e);
void persist_free(struct persist *p);

/* Take up the state in path, written by persist_save() of an earlier run;
 * a path that does not exist leaves the state empty.  The file must be of
 * the same SCAs and rows: otherwise -1 with a message naming path and what
 * differs (exit 1), as for a file that is not a state (exit 1) or cannot
 * be read (exit 2). */
int persist_load(struct persist *p, const char *path, struct err *e);

/* Write the state to path (through a temporary renamed over it when
 * complete).  0 or -1 with a message. */
int persist_save(const struct persist *p, const char *path, struct err *e);

/* The decay curve of SCA sca (1..18) from data/persistence.tsv. */
int persist_curve_get(int sca, struct persist_curve *c, struct err *e);

/* The charge (e-) a pixel of stimulus amplitude scale releases between t0
 * and t1 seconds after the end of its stimulus (0 <= t0 <= t1). */
double persist_charge(const struct persist_curve *c, double scale, double t0, double t1);

/* The amplitude of the afterglow after fluence x (e-), relative to the
 * reference stimulus's. */
double persist_scale(const struct persist *p, double x);

/* Begin the exposure named name (for messages) of date mjd (NaN: none)
 * whose reset and last read are exptime apart.  With a date it begins
 * then; without, p->gap seconds after the previous one ended (at 0 for the
 * first).  An exposure that begins before the previous one ended is
 * refused (exit 1). */
int persist_begin(struct persist *p, const char *name, double mjd, double exptime,
		  struct err *e);

/* Refuse, before anything is drawn, exposures x[0 .. n) (each lasting
 * exptime) whose dates would make persist_begin() fail; the state is left
 * as it was.  0 or -1 with persist_begin()'s message. */
int persist_check_dates(struct persist *p, const struct exposure *x, int n, double exptime,
			struct err *e);

/* The entries of science row y of SCA sca in the state: indices
 * [*first, *first + return value) of p->now[sca - 1]. */
size_t persist_row(const struct persist *p, int sca, int y, size_t *first);

/* Add the stimulus of science row y of SCA sca, pixels x0 .. x0 + n - 1
 * with fluence[0 .. n) (e-) in the exposure begun.  Rows must come in
 * ascending order per SCA.  0 or -1 out of memory. */
int persist_add(struct persist *p, int sca, int y, int x0, int n, const double *fluence);

/* End the exposure begun: each SCA's pixels become those of its state and
 * of the exposure's stimulus, a pixel in both keeping the one whose current
 * is the larger 30 s after the exposure's end, and a pixel whose current
 * there is below p->floor (or whose stimulus is older than the curve's
 * tmax) dropped.  0 or -1 out of memory. */
int persist_end(struct persist *p, struct err *e);

#endif
