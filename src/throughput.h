/*
 * throughput.h - the effective area of each filter and SCA, from the
 * embedded data/throughput.tsv (derived by contrib/tables/derive_optics.py).
 */
#ifndef WFS_THROUGHPUT_H
#define WFS_THROUGHPUT_H

struct err;

/* The samples of every filter in throughput.tsv (the reader the optical
 * model and the colour tables share): n[f] wavelengths lam[f][k] (micron)
 * and the effective area of SCA s + 1 at each, area[f][k * WFS_NSCA + s]
 * (m^2), in the file's order; malloc'd, freed by throughput_free.
 * Returns 0, or -1 with e set (nothing left allocated). */
int throughput_read(double *lam[], double *area[], int n[], struct err *e);
void throughput_free(double *lam[], double *area[]);

#endif
