/*
 * persist_glow - the afterglow of persistence through the ramp: many
 * pixels of no light but an afterglow (ramp_level1_charge_glow) against
 * the charge the decay curve releases by each read (persist_charge), and
 * persist_charge against a sum over small steps of the curve.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tap.h"
#include "err.h"
#include "persist.h"
#include "ramp.h"

enum { ROW = 4088, ROWS = 20 };

int main(void)
{
	struct err e = { 0 };
	struct ramp_pattern p;
	struct ramp_det d;
	struct persist_curve c;
	struct ramp_key k = { .seed = 7, .filter = 3, .sca = 1 };
	double *scr = malloc(RAMP_SCRATCH(ROW) * sizeof(double)), *r = calloc(ROW, sizeof(double));
	double *ch, sum[RAMP_MAX_RES] = { 0 }, lag = 60;
	float *own, *scale = malloc(ROW * sizeof(float));
	double *tend = malloc(ROW * sizeof(double));
	uint32_t *pix = malloc(ROW * sizeof(uint32_t));

	if (ramp_pattern_get(4, &p, &e) < 0 || ramp_det_get(1, &d, &e) < 0 ||
	    persist_curve_get(1, &c, &e) < 0)
		return 1;
	/* the curve's integral against the sum of its current over 1 ms steps */
	{
		double s = 0;

		for (double t = 60; t < 200; t += 1e-3) {
			double u = t + 5e-4;

			s += 1e-3 * (c.a * exp(-c.b * u) + c.d * exp(-c.e * u) + c.c);
		}
		is_rel(persist_charge(&c, 1, 60, 200), s, 1e-6,
			     "the charge released 60 to 200 s after is the curve's integral");
		ok(persist_charge(&c, 1, 1800, 2000) == 0, "nothing beyond the last time measured");
		is_rel(persist_charge(&c, 2, 60, 200), 2 * persist_charge(&c, 1, 60, 200), 1e-12, "scaled by the amplitude");
	}
	ch = malloc((size_t)p.nres * ROW * sizeof(double));
	own = malloc((size_t)p.nres * ROW * sizeof(float));
	memset(d.ipc, 0, sizeof(d.ipc));
	d.ipc[1][1] = 1;
	d.dark = 0;
	d.cosmic_rate = 0;
	ramp_scratch_init(scr);
	for (int y = 0; y < ROWS; y++) {
		struct ramp_glow g = { .n = ROW / 2, .pix = pix, .base = (uint32_t)y * ROW,
				       .scale = scale, .tend = tend, .t0 = 1000 + lag, .curve = &c };

		/* every other pixel glows */
		for (int i = 0; i < ROW / 2; i++) {
			pix[i] = (uint32_t)y * ROW + 2 * i;
			scale[i] = 1;
			tend[i] = 1000;
		}
		ramp_level1_charge_glow(&p, &d, &k, (uint32_t)y * 4096, ROW, r, &g, ch, own, ROW, scr);
		for (int q = 0; q < p.nres; q++)
			for (int i = 0; i < ROW; i += 2)
				sum[q] += ch[(size_t)q * ROW + i] - ch[(size_t)q * ROW + i + 1];
	}
	for (int q = 0; q < p.nres; q++) {
		double want = 0, got = sum[q] / (ROWS * ROW / 2.0);

		for (int j = p.first[q]; j <= p.last[q]; j++)
			want += persist_charge(&c, 1, lag, lag + j * p.read_time);
		want /= p.nread[q];
		diag("resultant %d: %.3f e- (curve %.3f)", q, got, want);
		/* the Poisson scatter of the mean over 40,880 pixels, ~0.005
		 * of the charge at 2 e-, less after */
		is_rel(got, want, 0.02 + 0.5 / sqrt(ROWS * ROW / 2.0 * want),
			     "resultant %d: the afterglow's mean charge follows the curve", q);
	}
	free(scr);
	free(r);
	free(ch);
	free(own);
	free(scale);
	free(tend);
	free(pix);
	return done_testing();
}
