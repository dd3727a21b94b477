/*
 * ramp_pois.h - the Poisson counts of a row of pixels for the ramp
 * (ramp_pois.c): internal to ramp.c.
 */
#ifndef WFS_RAMP_POIS_H
#define WFS_RAMP_POIS_H

#include <stdint.h>

struct rng;

#define POIS_TAB 128            /* F(k) for k < 128: 1 - F < 1e-30 at 32 */
#define POIS_GUIDE 1024
#define POIS_PAST 0x80          /* guide flag: u may pass the guide's k */

struct pois_tab {
	double mu;              /* the mean tabulated, or -1 */
	double cdf[POIS_TAB];
	unsigned char guide[POIS_GUIDE + 8];  /* 8 more: read 8 bytes at a time */
};

/* out[i] = a Poisson count of mean mu[i], i < n, from draw 0 of the cells
 * cell0 + i of g (out may be mu); from a mean of normal_above the normal
 * form.  Thread-safe (the tables are built once, by the first call). */
void ramp_pois_row(const struct rng *g, uint32_t cell0, int n, const double *mu,
		   double *out, double normal_above);

#endif
