/*
 * floor.c - the render stage of point sources against the memory floor, in
 * one run, so that the ratio is measured under the same load.
 *
 *   floor POINT_SO N [KEY=VALUE ...]
 *
 * Places N faint stars (AB 20-27, the starfield luminosity function) at
 * uniform positions on one 4088 x 4088 SCA, bins them by TILE-pixel tile
 * (256, the engine's default --tile) as the engine does, and times, in thread CPU time (the machine is shared;
 * CPU time moves far less than the wall clock), per star:
 *
 *   stamp      adding one precomputed 44 x 44 float stamp into the double
 *              tiles, clipped to each tile: the floor of issue 8
 *   stamp-float  the same stamp into float tiles (a float image): the
 *              floor of issue 18, which the engine's render stage is
 *              measured against (POINT_SO "-" prints the floors alone)
 *   polyphase  the same with a polyphase bilinear interpolation (4 streams
 *              of one array, weights per star): the floor of an
 *              interpolating renderer
 *   polyphase-float  the same into float tiles
 *   random     the stamp in catalog order into the whole image (no binning)
 *   point ...  point.so's render() through a mock host with a synthetic
 *              3 x 3 ePSF grid (177 samples, 4 per pixel), once per
 *              configuration: the KEY=VALUE settings given, each one a
 *              separate configuration ("-" alone: the defaults)
 *
 * Each line: name, ns per star (the best of 3 rounds), ratio to stamp; for
 * point, also the pixels drawn per star and the error against the exact
 * ePSF over 2000 stars of the same fluxes at random positions: the largest
 * pixel error over the peak, the flux error over the flux (both the worst
 * star), and the largest pixel error in units of the noise per pixel
 * (psf-box-sigma, or 0.1 counts/s: F129's zodiacal background and read
 * noise over 139.8 s), then the main thread's ns per star in prepare()
 * and footprint() (arrays blended and copied, box and flux factor), which
 * the engine runs while the workers render.  grid=5 is the mock host's own
 * setting: a 5 x 5 ePSF grid instead of 3 x 3.  Without --epsf a last line,
 * exact-ePSF-per-star, draws the 2000 stars of the error measurement each
 * from its own exactly computed ePSF (no grid), with Keys' cubic everywhere:
 * the main thread's column is then the cost of computing that ePSF.
 * Built by contrib/bench.sh with cc -O3 -march=native.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "wfiscene/model.h"

#define NPIX 4088
#ifndef TILE
#define TILE 256                /* the engine's default --tile; -DTILE=512 for another */
#endif
#define NT ((NPIX + TILE - 1) / TILE)
#define N 177                   /* ePSF samples per side */
#define OVER 4
#define C ((N - 1) / 2)
#define HALF 22                 /* C / OVER */
#define ROUNDS 3
#define NERR 2000           /* stars in the error measurement */

static float *node[9 + 25];
static const char *epsf_file;   /* --epsf: real nodes, errors against the best evaluation */
static const char *settings;    /* the KEY=VALUE of this configuration */

static int host_error(void *ctx, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	fputs("floor: point: ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	return -1;
}

static void host_log(void *ctx, int level, const char *fmt, ...)
{
}

/* settings is "k1=v1,k2=v2" */
static const char *host_setting(void *ctx, const char *key)
{
	static char val[256];
	size_t n = strlen(key);

	for (const char *s = settings; s && *s;) {
		const char *end = strchr(s, ',');
		size_t len = end ? (size_t)(end - s) : strlen(s);

		if (len > n && !strncmp(s, key, n) && s[n] == '=') {
			snprintf(val, sizeof(val), "%.*s", (int)(len - n - 1), s + n + 1);
			return val;
		}
		s += len + (end ? 1 : 0);
	}
	/* The synthetic ePSF has no far wing to draw to the noise, so this
	 * host keeps STIPS's boxes unless a setting says otherwise (the
	 * engine's defaults are measured in the engine, make bench-render). */
	if (!strcmp(key, "psf-extent"))
		return "stips";
	return NULL;
}

/* The synthetic PSF: a core Gaussian whose width changes over the SCA
 * (0.42 to 0.55 pixels: Roman's core is undersampled like this) and a
 * 15 % halo of 2.5 pixels; the ePSF sample at offset (dx, dy) pixels of a
 * source at (X, Y) is its integral over the pixel, a product of erf
 * differences: the exact reference every evaluation is measured against. */
static double pix_int(double d, double s)
{
	return 0.5 * (erf((d + 0.5) / (s * M_SQRT2)) - erf((d - 0.5) / (s * M_SQRT2)));
}

static double epsf_exact(double dx, double dy, double X, double Y)
{
	double sc = 0.42 + 0.08 * X / 4088 + 0.05 * Y / 4088, sw = 2.5;

	return 0.85 * pix_int(dx, sc) * pix_int(dy, sc) + 0.15 * pix_int(dx, sw) * pix_int(dy, sw);
}

static const char *host_setting(void *ctx, const char *key);

/* The 3 x 3 grid at STIPS' node positions (or 5 x 5 with the mock's own
 * setting grid=5), bilinear in position. */
static const float *exact_node;        /* the "exact" line: one node for every position */

static int host_epsf(void *ctx, int sca, double x, double y, int cls, struct wfs_epsf *e)
{
	const char *gs = host_setting(ctx, "grid");

	if (exact_node) {
		*e = (struct wfs_epsf){ N, OVER, C, { exact_node, exact_node, exact_node, exact_node },
					{ 1, 0, 0, 0 } };
		return 0;
	}
	int g = gs && *gs == '5' ? 5 : 3, base = g == 5 ? 9 : 0;
	double step = 4095.0 / (g - 1), u = (x + 4) / step, v = (y + 4) / step;
	int ix = (int)floor(u), iy = (int)floor(v);

	ix = ix < 0 ? 0 : ix > g - 2 ? g - 2 : ix;
	iy = iy < 0 ? 0 : iy > g - 2 ? g - 2 : iy;
	u -= ix;
	v -= iy;
	u = u < 0 ? 0 : u > 1 ? 1 : u;
	v = v < 0 ? 0 : v > 1 ? 1 : v;
	e->n = N;
	e->over = OVER;
	e->centre = C;
	e->node[0] = node[base + iy * g + ix];
	e->node[1] = node[base + iy * g + ix + 1];
	e->node[2] = node[base + (iy + 1) * g + ix];
	e->node[3] = node[base + (iy + 1) * g + ix + 1];
	e->weight[0] = (1 - u) * (1 - v);
	e->weight[1] = u * (1 - v);
	e->weight[2] = (1 - u) * v;
	e->weight[3] = u * v;
	return 0;
}

/* --epsf FILE: a 3 x 3 grid of 177-sample ePSFs as `wfiscene psf` writes it
 * (one primary HDU, a float cube, DET_YXk node positions) in place of the
 * synthetic one.  A minimal reader: this harness links no FITS library.
 * The nodes are put in the mock's 3 x 3 order by their DET_YX positions.
 * Returns 0 or -1. */
static int read_grid(const char *path)
{
	FILE *f = fopen(path, "rb");
	char card[81] = { 0 };
	long nax[4] = { 0 }, hdr = 0, bitpix = 0;
	double yx[9][2];
	int have = 0, done = 0;

	if (!f)
		return -1;
	while (!done && fread(card, 1, 80, f) == 80) {
		hdr += 80;
		if (!strncmp(card, "END     ", 8))
			done = 1;
		else if (!strncmp(card, "BITPIX  =", 9))
			bitpix = atol(card + 10);
		else if (!strncmp(card, "NAXIS", 5) && card[5] >= '1' && card[5] <= '3' && card[8] == '=')
			nax[card[5] - '0'] = atol(card + 10);
		else if (!strncmp(card, "DET_YX", 6) && card[6] >= '0' && card[6] <= '8') {
			const char *q = strchr(card, '(');

			if (q && sscanf(q, "(%lf ,%lf", &yx[card[6] - '0'][0], &yx[card[6] - '0'][1]) == 2)
				have |= 1 << (card[6] - '0');
		}
	}
	if (!done || bitpix != -32 || nax[1] != N || nax[2] != N || nax[3] != 9 || have != 511 ||
	    fseek(f, (hdr + 2879) / 2880 * 2880, SEEK_SET)) {
		fclose(f);
		return -1;
	}
	for (int k = 0; k < 9; k++) {
		/* the node's place in the mock's grid: columns by x, rows by y */
		int ix = yx[k][1] < 1000 ? 0 : yx[k][1] < 3000 ? 1 : 2;
		int iy = yx[k][0] < 1000 ? 0 : yx[k][0] < 3000 ? 1 : 2;
		float *a = node[iy * 3 + ix];

		if (fread(a, sizeof(float), N * N, f) != N * N) {
			fclose(f);
			return -1;
		}
		for (int i = 0; i < N * N; i++) {
			uint32_t u;

			memcpy(&u, &a[i], 4);
			u = __builtin_bswap32(u);
			memcpy(&a[i], &u, 4);
		}
	}
	fclose(f);
	return 0;
}

static void *host_scratch(void *thread, size_t bytes)
{
	return NULL;
}

struct star {
	double x, y, flux;
	int tile;
};

static double cpu_now(void)
{
	struct timespec t;

	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
	return t.tv_sec + 1e-9 * t.tv_nsec;
}

static uint64_t rng = 0x853c49e6748fea9bULL;

static double uniform(void)
{
	uint64_t z = (rng += 0x9e3779b97f4a7c15ULL);

	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
	return ((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

static int by_tile(const void *a, const void *b)
{
	const struct star *p = a, *q = b;

	return (p->tile > q->tile) - (p->tile < q->tile);
}

/* The windows of a star's 44-pixel box in the tiles it touches. */
#define FOR_WINDOWS(s, ...) do { \
	int bx0 = (int)floor((s)->x - HALF) + 1, bx1 = (int)ceil((s)->x + HALF); \
	int by0 = (int)floor((s)->y - HALF) + 1, by1 = (int)ceil((s)->y + HALF); \
	bx0 = bx0 < 0 ? 0 : bx0; by0 = by0 < 0 ? 0 : by0; \
	bx1 = bx1 > NPIX ? NPIX : bx1; by1 = by1 > NPIX ? NPIX : by1; \
	for (int ty = by0 / TILE; ty <= (by1 - 1) / TILE; ty++) \
		for (int tx = bx0 / TILE; tx <= (bx1 - 1) / TILE; tx++) { \
			int x0 = bx0 > tx * TILE ? bx0 : tx * TILE; \
			int y0 = by0 > ty * TILE ? by0 : ty * TILE; \
			int x1 = bx1 < (tx + 1) * TILE ? bx1 : (tx + 1) * TILE; \
			int y1 = by1 < (ty + 1) * TILE ? by1 : (ty + 1) * TILE; \
			double *tile = img + (size_t)(ty * NT + tx) * TILE * TILE; \
			__VA_ARGS__ \
		} \
} while (0)

/* ROUNDS timings of the polyphase loop over the n stars st into the tiles of
 * base (img, or imgf laid out as it), whose elements are of type T; the
 * fastest in best.  poly holds OVER x OVER phases of 48 x 48. */
#define POLYPHASE_ROUNDS(T, base) do { \
	best = 1e30; \
	for (int r = 0; r < ROUNDS; r++) { \
		double t = cpu_now(); \
		for (long i = 0; i < n; i++) { \
			const struct star *s = &st[i]; \
			double tx0 = -OVER * s->x, ty0 = -OVER * s->y; \
			int bx = (int)floor(tx0), by = (int)floor(ty0); \
			double fx = tx0 - bx, fy = ty0 - by; \
			long sx = C + bx, sy = C + by; \
			int mx0 = (int)(sx >= 0 ? sx / OVER : -((-sx + OVER - 1) / OVER)); \
			int my0 = (int)(sy >= 0 ? sy / OVER : -((-sy + OVER - 1) / OVER)); \
			int rx0 = (int)(sx - OVER * mx0), ry0 = (int)(sy - OVER * my0); \
			int rx1 = (rx0 + 1) % OVER, ry1 = (ry0 + 1) % OVER; \
			int mx1 = mx0 + (rx0 + 1) / OVER, my1 = my0 + (ry0 + 1) / OVER; \
			float w0 = (float)(s->flux * (1 - fy) * (1 - fx)); \
			float w1 = (float)(s->flux * (1 - fy) * fx); \
			float w2 = (float)(s->flux * fy * (1 - fx)), w3 = (float)(s->flux * fy * fx); \
			FOR_WINDOWS(s, { \
				T *tb = (base) + (tile - img); \
				for (int y = y0; y < y1; y++) { \
					T *restrict row = tb + (size_t)(y - ty * TILE) * TILE - tx * TILE; \
					const float *restrict s0 = poly + ((ry0 * OVER + rx0) * 48 + y + my0 + 1) * 48 + mx0 + 1; \
					const float *restrict s1 = poly + ((ry0 * OVER + rx1) * 48 + y + my0 + 1) * 48 + mx1 + 1; \
					const float *restrict s2 = poly + ((ry1 * OVER + rx0) * 48 + y + my1 + 1) * 48 + mx0 + 1; \
					const float *restrict s3 = poly + ((ry1 * OVER + rx1) * 48 + y + my1 + 1) * 48 + mx1 + 1; \
					for (int x = x0; x < x1; x++) \
						row[x] += w0 * s0[x] + w1 * s1[x] + w2 * s2[x] + w3 * s3[x]; \
				} \
			}); \
		} \
		t = cpu_now() - t; \
		best = t < best ? t : best; \
	} \
} while (0)

/* Draw source q alone into a zeroed buffer of w x w pixels whose pixel 0
 * is the first of its box (returned in b), as the host would: prepare(),
 * footprint(), render().  Returns 0 or -1. */
static int draw_alone(const struct wfs_model *md, void *state, struct wfs_source *q,
		      double *buf, int w, struct wfs_box *b)
{
	struct wfs_window win;

	if ((md->prepare && md->prepare(state, q) < 0) || md->footprint(state, q, b) < 0)
		return -1;
	memset(buf, 0, sizeof(double) * w * w);
	win = (struct wfs_window){ buf, w, b->x0, b->y0, b->x1 - b->x0, b->y1 - b->y0 };
	return md->render(state, NULL, NULL, q, &win);
}

int main(int argc, char **argv)
{
	static float stamp[2 * HALF * 2 * HALF];
	float *poly;
	double *img;
	float *imgf;
	struct star *st, *rs;
	long n;
	void *so;
	const struct wfs_model *(*entry)(uint32_t);
	const struct wfs_model *md;
	struct wfs_host host = { WFS_ABI_VERSION, sizeof(struct wfs_host), NULL,
				 host_error, host_log, host_setting, host_epsf,
				 host_scratch, NULL };
	double best;
	double stamp_ns = 0;
	volatile double sink = 0;

	if (argc >= 5 && !strcmp(argv[1], "--epsf")) {
		epsf_file = argv[2];
		argv += 2;
		argc -= 2;
	}
	if (argc < 3) {
		fprintf(stderr, "usage: floor [--epsf GRID.fits] POINT_SO N [KEY=VALUE[,KEY=VALUE] ...]\n");
		return 1;
	}
	n = atol(argv[2]);
	/* the synthetic ePSF nodes of a 3 x 3 and a 5 x 5 grid */
	for (int k = 0; k < 9 + 25; k++) {
		int g = k < 9 ? 3 : 5, kk = k < 9 ? k : k - 9;
		double X = -4 + 4095.0 * (kk % g) / (g - 1), Y = -4 + 4095.0 * (kk / g) / (g - 1);

		if (!(node[k] = malloc(sizeof(float) * N * N)))
			return 2;
		for (int y = 0; y < N; y++)
			for (int x = 0; x < N; x++)
				node[k][y * N + x] = (float)epsf_exact((x - C) / (double)OVER,
								      (y - C) / (double)OVER, X, Y);
	}
	if (epsf_file && read_grid(epsf_file) < 0) {
		fprintf(stderr, "floor: %s: not a 3 x 3 grid of %d-sample ePSFs\n", epsf_file, N);
		return 1;
	}
	for (int j = 0; j < 2 * HALF; j++)
		for (int i = 0; i < 2 * HALF; i++)
			stamp[j * 2 * HALF + i] = node[4][(C - OVER * HALF + OVER * j) * N +
							  C - OVER * HALF + OVER * i];
	/* one polyphase array, 16 planes of 46 x 46 (padded) */
	poly = calloc((size_t)OVER * OVER * 48 * 48, sizeof(float));
	for (int r = 0; r < OVER; r++)
		for (int s = 0; s < OVER; s++)
			for (int y = r, a = 1; y < N; y += OVER, a++)
				for (int x = s, b = 1; x < N; x += OVER, b++)
					poly[((r * OVER + s) * 48 + a) * 48 + b] = node[4][y * N + x];
	img = calloc((size_t)NT * NT * TILE * TILE, sizeof(double));
	imgf = calloc((size_t)NT * NT * TILE * TILE, sizeof(float));
	st = malloc(sizeof(*st) * n);
	rs = malloc(sizeof(*rs) * n);
	if (!poly || !img || !imgf || !st || !rs)
		return 2;
	for (long i = 0; i < n; i++) {
		double u = uniform(), a = pow(10, 0.3 * 20), b = pow(10, 0.3 * 27);
		double mag = log10(a + u * (b - a)) / 0.3;

		st[i].x = uniform() * NPIX - 0.5;
		st[i].y = uniform() * NPIX - 0.5;
		st[i].flux = pow(10, -0.4 * (mag - 26.4));
		st[i].tile = (int)((st[i].y + 0.5) / TILE) * NT + (int)((st[i].x + 0.5) / TILE);
	}
	memcpy(rs, st, sizeof(*st) * n);
	qsort(st, n, sizeof(*st), by_tile);

	printf("# %ld stars on one SCA, %d-pixel tiles, thread CPU ns per star, best of %d\n",
	       n, TILE, ROUNDS);
	/* the floor: a stamp binned by tile */
	best = 1e30;
	for (int r = 0; r < ROUNDS; r++) {
		double t = cpu_now();

		for (long i = 0; i < n; i++) {
			const struct star *s = &st[i];
			int ox = (int)floor(s->x - HALF) + 1, oy = (int)floor(s->y - HALF) + 1;
			float f = (float)s->flux;

			FOR_WINDOWS(s, {
				for (int y = y0; y < y1; y++) {
					double *restrict row = tile + (size_t)(y - ty * TILE) * TILE - tx * TILE;
					const float *restrict sp = stamp + (y - oy) * 2 * HALF - ox;

					for (int x = x0; x < x1; x++)
						row[x] += f * sp[x];
				}
			});
		}
		t = cpu_now() - t;
		best = t < best ? t : best;
	}
	stamp_ns = best / n * 1e9;
	printf("stamp %.1f 1.00\n", stamp_ns);
	/* the same into float tiles */
	best = 1e30;
	for (int r = 0; r < ROUNDS; r++) {
		double t = cpu_now();

		for (long i = 0; i < n; i++) {
			const struct star *s = &st[i];
			int ox = (int)floor(s->x - HALF) + 1, oy = (int)floor(s->y - HALF) + 1;
			float f = (float)s->flux;

			FOR_WINDOWS(s, {
				float *ftile = imgf + (tile - img);

				for (int y = y0; y < y1; y++) {
					float *restrict row = ftile + (size_t)(y - ty * TILE) * TILE - tx * TILE;
					const float *restrict sp = stamp + (y - oy) * 2 * HALF - ox;

					for (int x = x0; x < x1; x++)
						row[x] += f * sp[x];
				}
			});
		}
		t = cpu_now() - t;
		best = t < best ? t : best;
	}
	printf("stamp-float %.1f %.2f\n", best / n * 1e9, best / n * 1e9 / stamp_ns);
	if (!strcmp(argv[1], "-")) {
		for (size_t i = 0; i < (size_t)NT * NT * TILE * TILE; i += 4096)
			sink += img[i] + imgf[i];
		return sink == 12345.678;
	}
	/* polyphase bilinear from one array: weights per star, 4 streams; into
	 * the double tiles, then into float ones (the floor of an interpolating
	 * renderer that accumulates in float) */
	POLYPHASE_ROUNDS(double, img);
	printf("polyphase %.1f %.2f\n", best / n * 1e9, best / n * 1e9 / stamp_ns);
	POLYPHASE_ROUNDS(float, imgf);
	printf("polyphase-float %.1f %.2f\n", best / n * 1e9, best / n * 1e9 / stamp_ns);
	/* the stamp in catalog order */
	best = 1e30;
	for (int r = 0; r < ROUNDS; r++) {
		double t = cpu_now();

		for (long i = 0; i < n; i++) {
			const struct star *s = &rs[i];
			int ox = (int)floor(s->x - HALF) + 1, oy = (int)floor(s->y - HALF) + 1;
			float f = (float)s->flux;

			FOR_WINDOWS(s, {
				for (int y = y0; y < y1; y++) {
					double *restrict row = tile + (size_t)(y - ty * TILE) * TILE - tx * TILE;
					const float *restrict sp = stamp + (y - oy) * 2 * HALF - ox;

					for (int x = x0; x < x1; x++)
						row[x] += f * sp[x];
				}
			});
		}
		t = cpu_now() - t;
		best = t < best ? t : best;
	}
	printf("random %.1f %.2f\n", best / n * 1e9, best / n * 1e9 / stamp_ns);

	/* point.so's render, binned the same way, one line per configuration */
	if (!(so = dlopen(argv[1], RTLD_NOW)) ||
	    !(entry = (const struct wfs_model *(*)(uint32_t))dlsym(so, WFS_MODEL_ENTRY)) ||
	    !(md = entry(WFS_ABI_VERSION))) {
		fprintf(stderr, "floor: %s: %s\n", argv[1], dlerror());
		return 2;
	}
	for (int c = 3; c < argc; c++) {
		void *state;
		struct wfs_source *src = calloc(n, sizeof(*src));
		struct wfs_box *box = calloc(n, sizeof(*box));
		double pix = 0, prep;

		settings = strcmp(argv[c], "-") ? argv[c] : NULL;
		if (!src || !box || md->init(&host, &state) < 0)
			return 3;
		/* prepare() and footprint(), as the host's main thread calls
		 * them: timed apart from render() */
		prep = cpu_now();
		for (long i = 0; i < n; i++) {
			src[i] = (struct wfs_source){ .x = st[i].x, .y = st[i].y, .flux = st[i].flux,
						      .sca = 1, .psf_class = 0, .id = i };
			if ((md->prepare && md->prepare(state, &src[i]) < 0) ||
			    md->footprint(state, &src[i], &box[i]) < 0)
				return 3;
			pix += (double)(box[i].x1 - box[i].x0) * (box[i].y1 - box[i].y0);
		}
		prep = cpu_now() - prep;
		best = 1e30;
		for (int r = 0; r < ROUNDS; r++) {
			double t = cpu_now();

			for (long i = 0; i < n; i++) {
				const struct wfs_box *b = &box[i];
				int bx0 = b->x0 < 0 ? 0 : b->x0, by0 = b->y0 < 0 ? 0 : b->y0;
				int bx1 = b->x1 > NPIX ? NPIX : b->x1, by1 = b->y1 > NPIX ? NPIX : b->y1;

				for (int ty = by0 / TILE; ty <= (by1 - 1) / TILE; ty++)
					for (int tx = bx0 / TILE; tx <= (bx1 - 1) / TILE; tx++) {
						struct wfs_window w;
						double *tile = img + (size_t)(ty * NT + tx) * TILE * TILE;

						w.x0 = bx0 > tx * TILE ? bx0 : tx * TILE;
						w.y0 = by0 > ty * TILE ? by0 : ty * TILE;
						w.nx = (bx1 < (tx + 1) * TILE ? bx1 : (tx + 1) * TILE) - w.x0;
						w.ny = (by1 < (ty + 1) * TILE ? by1 : (ty + 1) * TILE) - w.y0;
						w.stride = TILE;
						w.pix = tile + (size_t)(w.y0 - ty * TILE) * TILE + (w.x0 - tx * TILE);
						if (md->render(state, NULL, NULL, &src[i], &w) < 0)
							return 3;
					}
			}
			t = cpu_now() - t;
			best = t < best ? t : best;
		}
		/* error against the exact ePSF: stars of the same fluxes
		 * at random positions, each drawn alone into a zeroed box */
		double emax = 0, eflux = 0, esig = 0;
		const char *sg = host_setting(NULL, "psf-box-sigma");
		double sigma = sg ? atof(sg) : 0.1;

		/* with --epsf, the reference is the plugin's best evaluation:
		 * blended at the source, Keys' cubic everywhere */
		const char *mine = settings;
		void *rstate = NULL;

		settings = "psf-blend=source,psf-interp=bicubic";
		if (epsf_file && md->init(&host, &rstate) < 0)
			return 3;
		settings = mine;
		rng = 0x2545f4914f6cdd1dULL;    /* the same stars for every configuration */
		for (long i = 0; i < NERR && i < n; i++) {
			enum { W = 2 * HALF + 2 };
			static double buf[W * W], rbuf[W * W];
			struct wfs_source q = src[i], rq;
			struct wfs_box b, rb;
			double peak = 0, dmax = 0, dsum = 0;

			q.x = 40 + uniform() * (NPIX - 80);
			q.y = 40 + uniform() * (NPIX - 80);
			rq = q;
			if (draw_alone(md, state, &q, buf, W, &b) < 0)
				return 3;
			if (rstate) {
				settings = "psf-blend=source,psf-interp=bicubic";
				if (draw_alone(md, rstate, &rq, rbuf, W, &rb) < 0)
					return 3;
				settings = mine;
			}
			for (int y = (int)floor(q.y - HALF) + 1; y < (int)ceil(q.y + HALF); y++)
				for (int x = (int)floor(q.x - HALF) + 1; x < (int)ceil(q.x + HALF); x++) {
					double ref = rstate ? rbuf[(y - rb.y0) * W + (x - rb.x0)] :
						q.flux * epsf_exact(x - q.x, y - q.y, q.x, q.y), got = 0;

					if (x >= b.x0 && x < b.x1 && y >= b.y0 && y < b.y1)
						got = buf[(y - b.y0) * W + (x - b.x0)];
					peak = fmax(peak, ref);
					dmax = fmax(dmax, fabs(got - ref));
					dsum += got - ref;
				}
			emax = fmax(emax, dmax / peak);
			eflux = fmax(eflux, fabs(dsum) / q.flux);
			esig = fmax(esig, dmax / sigma);
		}
		printf("point:%s %.1f %.2f %.0f %.2e %.2e %.2e %.1f\n", settings ? settings : "defaults",
		       best / n * 1e9, best / n * 1e9 / stamp_ns, pix / n, emax, eflux, esig,
		       prep / n * 1e9);
		md->fini(state);
		if (rstate)
			md->fini(rstate);
		free(src);
		free(box);
	}
	/* The ePSF computed exactly at each star (no grid to interpolate in
	 * position; Keys' cubic everywhere on the pixels), for the synthetic
	 * PSF: the cost is computing the node, per star, and the error what
	 * the on-pixel interpolation alone leaves. */
	if (!epsf_file) {
		double tnode = 0, tdraw = 0, emax = 0, eflux = 0, esig = 0;
		float *ex = malloc(sizeof(float) * N * N);
		int ne = NERR < n ? NERR : (int)n;

		settings = "psf-blend=source,psf-interp=bicubic";
		rng = 0x2545f4914f6cdd1dULL;    /* the stars of the error lines */
		for (int i = 0; ex && i < ne; i++) {
			enum { W = 2 * HALF + 2 };
			static double buf[W * W];
			struct wfs_source q = { .flux = st[i].flux, .sca = 1 };
			struct wfs_box b;
			void *state;
			double t = cpu_now(), peak = 0, dmax = 0, dsum = 0;

			q.x = 40 + uniform() * (NPIX - 80);
			q.y = 40 + uniform() * (NPIX - 80);
			for (int y = 0; y < N; y++)
				for (int x = 0; x < N; x++)
					ex[y * N + x] = (float)epsf_exact((x - C) / (double)OVER,
									  (y - C) / (double)OVER, q.x, q.y);
			tnode += cpu_now() - t;
			exact_node = ex;
			if (md->init(&host, &state) < 0)
				return 3;
			t = cpu_now();
			if (draw_alone(md, state, &q, buf, W, &b) < 0)
				return 3;
			tdraw += cpu_now() - t;
			md->fini(state);
			exact_node = NULL;
			for (int y = b.y0; y < b.y1; y++)
				for (int x = b.x0; x < b.x1; x++) {
					double ref = q.flux * epsf_exact(x - q.x, y - q.y, q.x, q.y);
					double got = buf[(y - b.y0) * W + (x - b.x0)];

					peak = fmax(peak, ref);
					dmax = fmax(dmax, fabs(got - ref));
					dsum += got - ref;
				}
			emax = fmax(emax, dmax / peak);
			eflux = fmax(eflux, fabs(dsum) / q.flux);
			esig = fmax(esig, dmax / 0.1);
		}
		/* render: the draw less the polyphase copy a fresh state makes
		 * is not separable here, so the line gives the copy and draw
		 * together as render, and the node as the main thread's */
		printf("point:exact-ePSF-per-star %.1f %.2f %d %.2e %.2e %.2e %.1f\n", tdraw / ne * 1e9,
		       tdraw / ne * 1e9 / stamp_ns, (2 * HALF) * (2 * HALF), emax, eflux, esig,
		       tnode / ne * 1e9);
		free(ex);
	}
	for (size_t i = 0; i < (size_t)NT * NT * TILE * TILE; i += 4096)
		sink += img[i];
	return sink == 12345.678;
}
