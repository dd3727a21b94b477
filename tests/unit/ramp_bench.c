/*
 * ramp_bench - CPU seconds of the detector levels on one full SCA (4096^2,
 * MA table 4, one thread) against today's --noise all on the same SCA
 * (4088^2 in 512^2 tiles, exposure of table 4): the ratio the issue bounds
 * at 3 for level 2.  Skipped unless WFS_BENCH is set (by hand:
 * WFS_BENCH=1 build/tests/ramp_bench).  Writing is not timed here.
 */
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "tap.h"
#include "err.h"
#include "instrument.h"
#include "noise.h"
#include "ramp.h"

enum { N = 4096, T = 512 };

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* 0.2 to 20 counts/s across the SCA, as noise_bench; RAMP_FLAT=r: a flat
 * r counts/s; RAMP_SKY=r: r counts/s varying by +-3 % across the SCA, as
 * pixel areas make a sky vary (read once: getenv per pixel would cost more
 * than the noise); RAMP_PNORMAL=m as --set poisson-normal=m */
static double flat = -1, sky = -1;

static double signal(int x, int y)
{
	if (flat >= 0)
		return flat;
	if (sky >= 0)
		return sky * (0.97 + 0.06 * (x + 0.7 * y) / (1.7 * N));
	return 0.2 + 19.8 * (x + y) / (2.0 * N);
}

int main(void)
{
	struct err e = { 0 };
	struct ramp_pattern p;
	struct ramp_det d;
	struct ramp_fit_plan fp;
	struct ramp_key k = { .seed = 1, .filter = 4, .sca = 1 };
	double t_noise, t_l1, t_l2, t0, *rate, *scr, *tile;
	uint16_t *dn;
	volatile double sink = 0;

	if (!getenv("WFS_BENCH"))
		skip_all("WFS_BENCH not set");
	if (getenv("RAMP_FLAT"))
		flat = atof(getenv("RAMP_FLAT"));
	if (getenv("RAMP_SKY"))
		sky = atof(getenv("RAMP_SKY"));
	/* RAMP_PNORMAL=m: --set poisson-normal=m (inf: always exact) */
	if (getenv("RAMP_PNORMAL"))
		k.poisson_normal = atof(getenv("RAMP_PNORMAL"));
	if (ramp_pattern_get(4, &p, &e) || ramp_det_get(1, &d, &e)) {
		printf("Bail out! %s\n", e.msg);
		return 1;
	}
	if (ramp_fit_plan_init(&fp, &p, &d) < 0)
		return 1;
	rate = malloc(N * sizeof(double));
	scr = malloc(RAMP_SCRATCH(N) * sizeof(double));
	ramp_scratch_init(scr);
	dn = malloc((size_t)p.nres * N * sizeof(uint16_t));
	tile = malloc((size_t)T * T * sizeof(double));

	{
		struct noise_opts o;

		noise_opts_default(&o);
		o.stages = NOISE_ALL;
		o.exptime = p.exptime;
		o.filter = 4;
		t0 = now();
		for (int ty = 0; ty < WFS_NPIX; ty += T)
			for (int tx = 0; tx < WFS_NPIX; tx += T) {
				int nx = WFS_NPIX - tx < T ? WFS_NPIX - tx : T;
				int ny = WFS_NPIX - ty < T ? WFS_NPIX - ty : T;

				for (int y = 0; y < ny; y++)
					for (int x = 0; x < nx; x++)
						tile[y * T + x] = signal(tx + x, ty + y);
				noise_tile(&o, 1, tx, ty, nx, ny, tile, T);
				sink += tile[0];
			}
		t_noise = now() - t0;
	}
	t0 = now();
	for (int y = 0; y < N; y++) {
		for (int x = 0; x < N; x++)
			rate[x] = signal(x, y);
		ramp_level1_row(&p, &d, &k, (uint32_t)y * N, N, rate, 1, dn, N, scr);
		sink += dn[0];
	}
	t_l1 = now() - t0;
	t0 = now();
	for (int y = 0; y < N; y++) {
		for (int x = 0; x < N; x++)
			rate[x] = signal(x, y);
		ramp_level1_row(&p, &d, &k, (uint32_t)y * N, N, rate, 1, dn, N, scr);
		for (int x = 0; x < N; x += 256) {
			struct ramp_fit f[256];

			ramp_fit_row(&fp, dn + x, N, 256, f);
			sink += f[0].rate;
		}
	}
	t_l2 = now() - t0;
	diag("one SCA, MA table 4 (%d resultants, %.1f s), one thread, CPU s:", p.nres, p.exptime);
	diag("--noise all %.2f s | level 1 %.2f s (%.2fx) | level 1 + fit %.2f s (%.2fx)",
	     t_noise, t_l1, t_l1 / t_noise, t_l2, t_l2 / t_noise);
	ok(t_l2 > 0 && t_noise > 0, "timed (%.0f)", sink > 0 ? 1.0 : 0.0);
	free(rate);
	free(scr);
	free(dn);
	free(tile);
	ramp_fit_plan_free(&fp);
	return done_testing();
}
