/*
 * throughput.c - data/throughput.tsv read once for the optical model
 * (optics.c) and the colour tables (spectrum.c), both of which need every
 * filter's effective area per SCA.
 */
#include <stdio.h>
#include <stdlib.h>

#include "data.h"
#include "err.h"
#include "instrument.h"
#include "throughput.h"

/* throughput.tsv's columns filter, wave and sca01..sca18, once for the
 * optical model and the colour tables (spectrum.c). */
int throughput_read(double *lam[], double *area[], int n[], struct err *e)
{
	struct tsv t;
	int cf, cw, cs[WFS_NSCA];
	char name[16];

	for (int f = 0; f < WFS_NFILTER; f++) {
		lam[f] = area[f] = NULL;
		n[f] = 0;
	}
	if (tsv_parse(&t, "throughput.tsv"))
		return err_set(e, EXIT_SYSTEM, "broken build: no throughput.tsv");
	cf = tsv_col(&t, "filter");
	cw = tsv_col(&t, "wave");
	for (int s = 0; s < WFS_NSCA; s++) {
		snprintf(name, sizeof(name), "sca%02d", s + 1);
		if ((cs[s] = tsv_col(&t, name)) < 0)
			cf = -1;
	}
	if (cf < 0 || cw < 0) {
		tsv_free(&t);
		return err_set(e, EXIT_SYSTEM, "broken build: malformed throughput.tsv");
	}
	for (int r = 1; r < t.nrow; r++) {
		int f = filter_lookup(t.cell[r][cf]);
		if (f >= 0)
			n[f]++;
	}
	for (int f = 0; f < WFS_NFILTER; f++) {
		lam[f] = malloc((n[f] + 1) * sizeof(double));
		area[f] = malloc((n[f] + 1) * WFS_NSCA * sizeof(double));
		n[f] = 0;
		if (!lam[f] || !area[f]) {
			tsv_free(&t);
			throughput_free(lam, area);
			return err_set(e, EXIT_SYSTEM, "out of memory");
		}
	}
	for (int r = 1; r < t.nrow; r++) {
		int f = filter_lookup(t.cell[r][cf]);
		if (f < 0)
			continue;
		int k = n[f]++;
		lam[f][k] = atof(t.cell[r][cw]);
		for (int s = 0; s < WFS_NSCA; s++)
			area[f][k * WFS_NSCA + s] = atof(t.cell[r][cs[s]]);
	}
	tsv_free(&t);
	return 0;
}

void throughput_free(double *lam[], double *area[])
{
	for (int f = 0; f < WFS_NFILTER; f++) {
		free(lam[f]);
		free(area[f]);
		lam[f] = area[f] = NULL;
	}
}
