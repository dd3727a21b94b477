/*
 * point.h - what the units of the point model (point.so) share: the
 * polyphase arrays, the zones and geometry of a source's pixels, the
 * arguments of the inner loops, the model's state, and the functions one
 * unit offers the others.  Internal to the plugin (built with hidden
 * visibility: nothing here leaves point.so).
 *
 *   point.c          the model: settings, init/fini, and the five callbacks
 *   point_poly.c     polyphase copies of ePSF nodes and blended cells
 *   point_epsf.c     a source's ePSF box: its plan, flux factor and drawing
 *   point_kernels.c  the inner loops (plain and AVX2, the same bits)
 *   point_halo.c     psf-extent=noise: the halo beyond the box
 *   point_near.c     psf-halo-near: the halo's pixels above the level
 *   point_far.c      psf-diffuse=grid: the light left out, spread per tile
 */
#ifndef WFS_POINT_H
#define WFS_POINT_H

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "wfiscene/model.h"
#include "halo.h"
#include "../src/simd.h"

/* Polyphase copies of the ePSF nodes, found by the node's address (the
 * host's arrays stay put until fini), and of blended cells, found by an odd
 * key (node addresses are even).  Open addressing, never removed; the
 * table's size is set once in init from psf-cell (poly_table_init). */
#define POLY_NODES 4096         /* room kept for node copies besides the cells */
#define POLY_SLOTS_MAX (1u << 19)
/* Arrays per SCA are indexed by its number, 1 to WFS_SCA_COUNT (model.h):
 * SCA_SLOTS of them, the first unused. */
#define SCA_SLOTS (WFS_SCA_COUNT + 1)
/* The extra-bright class's half-width: STIPS's 176-pixel box, the farthest
 * a source of psf-extent=stips reaches. */
#define XBRIGHT_HALF 88
#define MAX_ROW 1024            /* widest window row of the general path */
/* Planes carry PAD zero samples on each side, so that the Keys taps (one
 * sample before, two after) of any pixel inside the box stay inside the
 * plane and read zeros beyond the ePSF, and no pixel needs a range test. */
#define PAD 2

/* Eight floats, loaded and stored unaligned: the row sums below are written
 * with GCC's vector extension so that a 44-pixel row is 6 steps with no
 * alignment prologue or scalar tail (rows are summed to a multiple of 8;
 * the planes carry VSLACK floats so the last step can read on). */
typedef float v8f __attribute__((vector_size(32), aligned(4), may_alias));
#define VSLACK 8

typedef float v4f __attribute__((vector_size(16), aligned(4), may_alias));
typedef double v4d __attribute__((vector_size(32), aligned(8), may_alias));
#define SPLAT4(f) ((v4d){ (f), (f), (f), (f) })
#define TO_V4D(p) __builtin_convertvector(*(const v4f *)(p), v4d)
#define SPLAT(f) ((v8f){ (f), (f), (f), (f), (f), (f), (f), (f) })

struct poly {
	uint64_t key;
	int n, over, centre, m; /* m = samples per phase plane side, padded */
	float *plane;           /* over * over planes of m x m */
	/* per plane, its summed-area table: (m + 1) x (m + 1), entry (r, c)
	 * the sum of the plane's rows < r and columns < c, summed in double
	 * and kept in float (a rectangle's sum to ~1e-8 of the flux) */
	float *sat;
	int nee;                /* centre / over */
	double *ee;             /* ee[h], h = 1..nee: see ee_table() */
	/* a blended cell: the nodes and weights it was blended from, and
	 * (psf-blend=core) the nodes' own polyphase copies */
	const float *cnode[8];  /* 8: two spectral classes' nodes */
	double cweight[8];
	const struct poly *cpoly[8];
	/* a colour cell: its step between the pair's classes (0 to 1), and
	 * the two classes' cells at its centre, ends[0] of class a and
	 * ends[1] of a + 1 (cell_add): psf-blend=core's colour correction */
	double cstep;
	const struct poly *ends[2];
	/* or a class cell (cclass >= 0: the blend of one class, which the
	 * pairs cclass - 1, cclass and cclass, cclass + 1 share at their end
	 * steps): its neighbours' cells at the same position, nbr[0] of class
	 * cclass - 1 and nbr[1] of cclass + 1.  A class cell is published
	 * before its neighbours are found: class_add() stores each from NULL
	 * to the neighbour's one published cell (several threads may store
	 * the same pointer), with release order, before a source in the cell
	 * is prepared; read with acquire order (cell_pair) */
	int cclass;
	const struct poly *nbr[2];
};

/* A colour cell's step g (0 to 1) between the classes a, a + 1 of a
 * source's pair, and the two classes' cells at the cell's centre into
 * end[]; 0, or -1 when one is not set. */
static inline int cell_pair(const struct poly *cell, int a, double *g, const struct poly *end[2])
{
	if (cell->cclass < 0) {
		*g = cell->cstep;
		end[0] = cell->ends[0];
		end[1] = cell->ends[1];
	} else if (a == cell->cclass) {
		*g = 0;
		end[0] = cell;
		end[1] = __atomic_load_n(&cell->nbr[1], __ATOMIC_ACQUIRE);
	} else {
		*g = 1;
		end[0] = __atomic_load_n(&cell->nbr[0], __ATOMIC_ACQUIRE);
		end[1] = cell;
	}
	return end[0] && end[1] ? 0 : -1;
}

/* Pixels [x0, x1) x [y0, y1), 0-based; empty when x0 >= x1 or y0 >= y1. */
struct zone {
	long x0, x1, y0, y1;
};

/* Where a source's pixels read an array (every array of a size class has
 * the same layout).  Tap a (sample offsets -1, 0, 1, 2 from the sample
 * below the pixel's) of pixel i is sample o (i + mx[a]) + rx[a]: plane
 * column i + mx[a] + PAD of x phase rx[a]; likewise in y. */
struct geom {
	int o;
	long mx[4], rx[4], my[4], ry[4];
	double bx[2], by[2];    /* bilinear weights of taps 1 and 2 */
	double kx[4], ky[4];    /* Keys' weights of taps 0..3 */
	int an, bn;             /* the nearest sample's taps (1 or 2) */
	/* tap (a, b) of pixel (i, j): plane + tx[a] + ty[b] + j m + i, and
	 * its summed-area table: sat + sx[a] + sy[b] + j (m + 1) + i */
	ptrdiff_t tx[4], ty[4], sx[4], sy[4];
	ptrdiff_t m;
};

/* How one source is drawn: the arrays it reads with their weights times the
 * flux, psf-blend=core's correction arrays, and its zones. */
struct draw {
	int nn, ncor, keys;
	int cell;               /* one blended cell (psf-blend=cell or core) */
	const struct poly *pl[8];       /* 8: two spectral classes' nodes */
	double wn[8];
	const struct poly *cp[8];
	double cw[8];
	/* a colour source's core, the blend (1 - f) A + f B of its pair's
	 * class cells A, B at its cell's centre (which equals the cell plus
	 * (f - g) (B - A)): kb the one nearer the cell's step, weight kbw,
	 * and dk the other, weight dkw; drawn with the cell's taps (Keys'
	 * cubic) where the core is cubic, else dk as one more bilinear
	 * correction (render_one); dk NULL: none (kb is then the cell) */
	const struct poly *kb, *dk;
	double kbw, dkw;
	struct geom g;
	struct zone box;        /* every pixel it lights */
	struct zone core;       /* Keys' cubic (or psf-blend=core's bilinear
				 * correction, and a colour source's other
				 * class cell on the Keys taps), not scaled
				 * by f */
	struct zone wing;       /* bilinear; beyond it the nearest sample */
};

enum { INTERP_BILINEAR, INTERP_CORE, INTERP_BICUBIC };
enum { EXTENT_NOISE, EXTENT_STIPS };
enum { HALO_FAR_SPIKES, HALO_FAR_DISC };
/* aux[0] holds the box's half-width plus HALO_PACK times the halo's radius
 * (both whole numbers of pixels) */
#define HALO_PACK 65536.0
enum { BLEND_SOURCE, BLEND_CELL, BLEND_CORE };
enum { DIFFUSE_GRID, DIFFUSE_NONE };
/* psf-halo-near=F: within the halo's array, the pixels a source draws are
 * those whose value at any phase reaches F times its drawing level,
 * rounded down to FAR_STEPS steps per octave (level step k:
 * 2^(k / FAR_STEPS)) */
#define FAR_STEPS 4
#define SET_STRIPES 16          /* struct point: set_lock */
#define NEAR_SEG 8              /* offsets of a row segment of the step map */
#define NEAR_CHUNK 16           /* offsets of a chunk (struct near: cs) */

/* The halo's array, pixel by pixel (point_near.c, near_setup): for every
 * pixel offset (dx, dy) from the pixel nearest a source within the
 * array's disc, its step st[(dy + rc) side + dx + rc], floor(FAR_STEPS
 * log2 vmax) of its largest value at any phase (INT16_MIN beyond the
 * disc); smax[(dy + rc) nseg + s] the largest step of row segment s,
 * offsets dx + rc in [s NEAR_SEG, (s + 1) NEAR_SEG).  For k from kmin to
 * kmax, the row's runs of consecutive segments whose largest step reaches
 * k are rs[2 t] .. rs[2 t + 1] (first and last segment) for t from
 * ri[(k - kmin) side + dy + rc] up to the next entry of ri.  Where the
 * AVX-512 loop runs (else ci and cs are NULL), the same runs as chunks
 * of NEAR_CHUNK offsets that do not overlap: chunk c starts
 * at offset cs[c] - rc and covers the next NEAR_CHUNK, for c from
 * ci[(k - kmin) side + dy + rc] up to the next entry of ci; every offset
 * of the runs lies in one of them (an offset a chunk adds outside the
 * runs has a step below k).  ry[2 (k - kmin)] and ry[2 (k - kmin) + 1]:
 * the first and last row (dy + rc) with a run at k, or side and -1.
 * under[k - kmin] is the light (phase 0) of the
 * offsets within the disc and outside the box of half-width hb whose step
 * is below k: what a source of level step k leaves to the diffuse grid
 * there.  pl holds the array's samples by phase: plane r (of h->over)
 * row w column m is sample (w, over m + r), each plane n rows of nh, so
 * that a pixel's samples of one sample row lie in two planes at the same
 * column and a row of pixels reads each plane contiguously. */
struct near {
	int16_t *st, *smax, *rs, *cs;
	int32_t *ri, *ci;
	int16_t *ry;            /* per level: its first and last row with a run */
	int rc, side, nseg, hb;
	int kmin, kmax;
	double *under;          /* steps kmin to kmax + 1 */
	float *pl;
	long nh;
};

/* A halo and what is derived from it (point_halo.c): one per SCA of the
 * scene's default spectrum (cls -1), and for sources with a spectrum one
 * per SCA, spectral class cls and step (of psf-halo-colour-steps) of the
 * blend of the halos of cls and cls + 1, each made on first use under the
 * lock and flagged ready with release order.  cfac and chalf per size
 * class: the core's scale and the box's half-width (core_scale). */
struct hslot {
	struct halo h;
	float *arr;             /* the blended array (NULL: the host's) */
	_Atomic int ready;
	struct near near;       /* psf-halo-near=level */
	_Atomic int near_ready;
	double cfac[3];
	int chalf[3];
	_Atomic int cfac_ready[3];
	int cls, step;
};

/* One array, the whole window, straight into the tile: for each row j and
 * pixel i < nx,
 *
 *   pix[j stride + i] += wn sn[j m + i]
 *
 * but on the wing rows jw <= j < jw + nw, over wa <= i < wb,
 *
 *   w0 s0[j m + i] + w1 s1[..] + w2 s2[..] + w3 s3[..]
 *
 * (the last three products fused: fmaf)
 * and on the core rows jc <= j < jc + nc, over ka <= i < kb, kv[] replaces
 * the sum; in float.  Two builds with the same operations per pixel in the
 * same order, so the same bits: 8 pixels at a time with AVX2 (reading on
 * into the planes' slack and into kv's margins, the lanes outside a run
 * masked), and one by one.  The float sums are converted and added in
 * registers. */
#define KV_ROWS 48              /* core rows and columns the fast path takes: */
#define KV_COLS 48              /* the 44-pixel box, so psf-interp=bicubic too */
#define KV_PITCH (KV_COLS + 16) /* a core row of kv: 8 floats margin, then column ka */

struct rows_args {
	const float *s[4];      /* the bilinear streams at the window's first pixel */
	const float *sn;        /* the nearest sample's stream */
	ptrdiff_t m;            /* floats from one plane row to the next */
	float w[4], wn;         /* their weights: flux f bilinear weight; flux f */
	int jw, nw, wa, wb;     /* the wing square, window coordinates */
	int jc, nc, ka, kb;     /* the core, window coordinates */
	const float *kv;        /* pixel i of row jc + c: kv[c KV_PITCH + 8 + i - ka] */
};

/* The core: for rows c < nc and pixels i < nk (8 at a time; kv gets a
 * multiple of 8), each lane
 *
 *   v = sum over b of ky[b] (kx[0] t[b][0] + kx[1] t[b][1] + ...)   Keys
 *   v = bw[0] t[1][1] + bw[1] t[1][2] + bw[2] t[2][1] + bw[3] t[2][2] bilinear
 *   kv = v + sum over k of cw[k] ct[k]         psf-blend=core's correction
 *
 * With dbase (a colour source's other class cell, Keys only) each tap of
 * its nearer class's cell is t[b][a] + ds d[b][a] (fmaf) before Keys'
 * weights, ds the other class's weight over the nearer's.
 *
 * every product but the first of a sum fused (fmaf), in this order, so
 * that the vector builds and the plain one give the same bits; and K, the sum
 * of kv over the core, in double (lanes l and l + 4 to accumulator l). */
struct core_args {
	/* tap (a, b) of core row c, pixel i: base + ty[b] + tx[a] + c m + i;
	 * the correction's array k, bilinear tap (a, b): cbase[k] + ty[b + 1]
	 * + tx[a + 1] + c m + i */
	const float *base, *cbase[8], *dbase;
	ptrdiff_t tx[4], ty[4], m;
	int ncor, keys, nc, nk;
	float kx[4], ky[4], bw[4], cw[32], ds;
};

/* What one thread's prepare() calls counted, psf-extent=noise: the flux
 * of the sources prepared and the part left beyond their drawn radii, the
 * sources drawn with a halo and all of them.  Summed at fini (in the order
 * the threads first prepared, so the sums' last bits may vary; they are
 * only logged). */
struct far_dep {
	int k;                  /* psf-halo-near=level: the level step of light
				 * left out of the halo's array (r = 0), else
				 * INT_MIN */
	short sca;
	short slot;             /* the halo whose shape it is spread in: -1
				 * the default spectrum's, else the colour
				 * halo's index (hslot_at: below classes x
				 * 64 steps, far below 2^15); shorts keep a
				 * deposit at 40 bytes, as before slots */
	double r, x, y, light;
};

#define FAR_RING 16

struct tally {
	double requested, left;
	double spread;          /* of left, what went to the diffuse grid */
	long long nhalo, npoint;
	/* psf-diffuse=grid: per SCA, the thread's grid of light left out,
	 * in two integer counters per cell (point_far.c); NULL until used */
	int64_t *cnt[SCA_SLOTS];
	/* the last FAR_RING deposits into them, held back with their cells
	 * fetched ahead (far_deposit): the grid is too large for the cache,
	 * and a deposit waited for its cells */
	struct far_pend {
		int sca;
		uint32_t c0;    /* cells c0, c0 + 1, c0 + n, c0 + n + 1 */
		double v[4];
	} ring[FAR_RING];
	unsigned long long nring;       /* deposits ever held */
	/* and the light beyond the radii of sources with a halo, each
	 * spread with the wing beyond its own radius (far_deposit) */
	struct far_dep *dep;
	size_t ndep, capdep;
	pthread_t thread;
	struct tally *next;
};

struct point {
	const struct wfs_host *host;
	int interp;             /* psf-interp */
	double core;            /* half-width of the cubic core, pixels */
	double wing;            /* half-width of the bilinear square, pixels */
	int adaptive;           /* psf-box=adaptive */
	double box_noise;       /* psf-box-noise: fraction of the box's noise */
	double sigma;           /* noise per pixel, counts/s (psf-box-sigma) */
	int blend;              /* psf-blend */
	int cell;               /* psf-cell: side of a blended cell, pixels */
	int colour_steps;       /* psf-colour-steps: a colour source's cell blends
				 * its two classes rounded to 1/colour_steps */
	int colour_cells;       /* blended cells kept per position for colour
				 * sources (0: they are blended per source) */
	int nclasses;           /* the host's spectral classes, two families of
				 * nclasses / 2 (setting spectral-classes) */
	int extent;             /* psf-extent: EXTENT_NOISE or EXTENT_STIPS */
	double extent_noise;    /* psf-extent-noise: fraction of sigma */
	double extent_max;      /* psf-extent-max: largest radius, pixels */
	double extent_min;      /* psf-extent-min: smallest box half-width, pixels
				 * (negative: the class's box) */
	double extent_cut;      /* psf-extent-cut: fraction of sigma (0: off) */
	double halo_power;      /* psf-halo-power: the tail's power */
	double halo_taper;      /* psf-halo-taper: pixels */
	int halo_far;           /* psf-halo-far: HALO_FAR_SPIKES or HALO_FAR_DISC */
	double halo_near;       /* psf-halo-near: of the drawing level (0: off) */
	int diffuse;            /* psf-diffuse: DIFFUSE_GRID or DIFFUSE_NONE */
	int far_cell;           /* psf-diffuse-cell: side of a cell, pixels */
	double diffuse_floor;   /* psf-diffuse-floor: of the drawing level */
	long far_org;           /* the diffuse grid's first pixel (far_geometry) */
	int far_n;              /* its cells along each axis */
	double *far[SCA_SLOTS]; /* per SCA, gathered: light per pixel at the
				 * cells' centres (far_gather) */
	/* prepare() runs on several threads (WFS_PARALLEL_PREPARE): what it
	 * sets up on first use (the halos, the cores' scales, the polyphase
	 * copies) is made under lock and then flagged ready with release
	 * order; its counters are per thread (struct tally) */
	pthread_mutex_t lock;
	struct hslot hs[SCA_SLOTS]; /* per SCA, the default spectrum's halo */
	pthread_mutex_t hs_lock[SCA_SLOTS]; /* each taken to set up hs[] (so that
					     * two SCAs are set up at once) */
	/* the halo arrays' shape's geometry (halo.h), made once under
	 * geom_lock for every halo set up after (point_halo.c, geom_of) */
	struct halo_geom geom;
	_Atomic int geom_ready;
	pthread_mutex_t geom_lock;
	/* taken to set up a colour halo or a halo's near lists, one of them
	 * by the object's address (set_lock_of), so that two threads set up
	 * two halos at once */
	pthread_mutex_t set_lock[SET_STRIPES];
	/* per SCA and size class, the flux at or below which prepare() (k =
	 * 0) and reach() (k = 1) need not plan a source (faint_flux,
	 * point_halo.c), once faint_known is set (release order, under lock) */
	double faint_at[2][SCA_SLOTS][3];
	_Atomic char faint_known[2][SCA_SLOTS][3];
	/* psf-halo-colour-steps (0: every source has the default's halo),
	 * and the colour halos: chs[(sca nclasses + cls) halo_steps + step],
	 * NULL until made (point_halo.c) */
	int halo_steps;
	_Atomic(struct hslot *) *chs;
	unsigned long serial;   /* this state's number among all made */
	struct tally *tallies;  /* one per thread that prepared */
	void (*sum_rows)(double *, ptrdiff_t, int, int, const struct rows_args *);
	double (*core_rows)(const struct core_args *, float *);
	struct poly *slot;      /* nslots of them, a power of two */
	_Atomic uint64_t *keys; /* slot[i]'s key once published (point_poly.c) */
	size_t nslots;
	long cell_hi;           /* the cells kept per SCA and class along each
				 * axis, -1 .. cell_hi (cell_in_range) */
};

/* The source's spectral class (model.h, wfs_source.colour), or -1 for
 * the scene's default spectrum (and hosts without classes). */
static inline double point_colour(const struct point *p, const struct wfs_source *src)
{
	if (!WFS_HAS(p->host->size, struct wfs_host, epsf_colour) || !p->host->epsf_colour ||
	    !WFS_HAS(p->host->source_size, struct wfs_source, colour))
		return -1;
	return src->colour;
}

/* A colour source's pair of classes a, a + 1 of one family and its
 * fraction f of the way from a to a + 1 (a source on the last class of a
 * family is f = 1 of the pair before it).  Needs p->nclasses. */
static inline void point_pair(const struct point *p, double c, int *a, double *f)
{
	int n = p->nclasses / 2;

	*a = (int)c;
	*f = c - *a;
	if (n > 1 && *a % n == n - 1) {
		--*a;
		*f += 1;
	}
}

/* floor(x) and ceil(x) for |x| < 2^62, without a library call (the
 * plugin's baseline build has no rounding instruction) */
static inline long lfloor(double x)
{
	long i = (long)x;

	return i - (x < i);
}

static inline long lceil(double x)
{
	long i = (long)x;

	return i + (x > i);
}

/* The pixels within h of (x, y) along both axes: |i - x| < h, |j - y| < h. */
static inline struct zone square(double x, double y, double h)
{
	return (struct zone){ lfloor(x - h) + 1, lceil(x + h), lfloor(y - h) + 1, lceil(y + h) };
}

static inline struct zone meet(struct zone a, struct zone b)
{
	a.x0 = a.x0 > b.x0 ? a.x0 : b.x0;
	a.x1 = a.x1 < b.x1 ? a.x1 : b.x1;
	a.y0 = a.y0 > b.y0 ? a.y0 : b.y0;
	a.y1 = a.y1 < b.y1 ? a.y1 : b.y1;
	return a;
}

static inline int zone_empty(struct zone z)
{
	return z.x0 >= z.x1 || z.y0 >= z.y1;
}

/* The source's halo radius (0: none) and its box's half-width from aux[0]
 * (negative when the halo is its spectrum's, point_halo.c). */
static inline double halo_radius_of(const struct wfs_source *src)
{
	return floor(fabs(src->aux[0]) / HALO_PACK);
}

static inline double box_half_of(const struct wfs_source *src)
{
	return fabs(src->aux[0]) - HALO_PACK * halo_radius_of(src);
}

/* psf-halo-far=spikes: beyond the radius where the halo away from its
 * spikes sinks below the level, only the spikes' strips are drawn */
#define psf_spikes(p) ((p)->halo_far == HALO_FAR_SPIKES)
/* psf-halo-near=F > 0 (with psf-diffuse=grid): within the halo's array
 * only the pixels at or above F times the level are drawn, the rest
 * spread on the grid */
#define psf_near(p) ((p)->halo_near > 0 && (p)->diffuse == DIFFUSE_GRID)

/* point_kernels.c: set p's inner loops, the AVX2 ones where the processor
 * has AVX2 and FMA and simd_flags() allows them (WFISCENE_NO_SIMD unset or
 * "avx512"; the plain loops give the same bits, the variable is for
 * testing that they do). */
void kernels_choose(struct point *p);

/* point_poly.c */
int poly_table_init(struct point *p);
int cell_in_range(const struct point *p, const struct wfs_source *src);
const struct poly *poly_find(const struct point *p, uint64_t key);
struct poly *poly_add(struct point *p, uint64_t key, const float *node, int n, int over);
uint64_t cell_key(const struct point *p, const struct wfs_source *src);
struct poly *cell_add(struct point *p, const struct wfs_source *src);
void poly_free_all(struct point *p);

/* point_epsf.c: prepare() and render() of a source's ePSF box; a box of
 * half-width at most cap (0: the class's) */
int epsf_prepare(struct point *p, struct wfs_source *src, double cap, int cut, double *drawn);
int epsf_render(struct point *p, const struct wfs_source *src, const struct wfs_window *win);

/* point.c: the calling thread's counters of p (NULL: out of memory) */
struct tally *tally_of(struct point *p);

/* point_halo.c: psf-extent=noise */
int noise_prepare(struct point *p, struct wfs_source *src);
int noise_render(struct point *p, const struct wfs_source *src, const struct wfs_window *win);
int noise_reach(struct point *p, const struct wfs_source *src, double *pixels);
double halo_level(const struct point *p, double flux, int *k);
void hslot_free_all(struct point *p);
/* point.c: the lock of the set-up of obj (struct point: set_lock) */
pthread_mutex_t *set_lock_of(struct point *p, const void *obj);

/* point_near.c: psf-halo-near; near_of() sets up slot s's step map and
 * runs on first use (the box's half-width hb), near_under() is the light
 * (over the flux) a source of level step k leaves to the grid within the
 * array's disc, near_render() draws a source's pixels of level step k or
 * above within radius r, outside its box, into win */
const struct near *near_of(struct point *p, struct hslot *s, int hb);
double near_under(const struct near *n, int k);
void near_free(struct near *n);
void near_render(const struct halo *h, const struct near *n, double flux, double x, double y,
		 double r, int k, struct zone box, const struct wfs_window *win);

/* The colour halo idx of SCA sca once made (NULL before), or with idx -1
 * the SCA's default one. */
static inline const struct hslot *hslot_at(const struct point *p, int sca, int idx)
{
	if (idx < 0)
		return &p->hs[sca];
	return atomic_load_explicit(&p->chs[((size_t)sca * p->nclasses) * p->halo_steps + idx],
				    memory_order_acquire);
}

/* point_far.c: psf-diffuse=grid; far_deposit() adds light (counts/s) left
 * out of src beyond its box (r = 0) or beyond its radius r to its
 * thread's grid, from prepare(), to be spread in the shape of halo slot
 * (hslot_at; r = 0: the default's always); far_radius() rounds a halo's radius up
 * to the radii whose wings the grid spreads */
void far_geometry(struct point *p);
double far_radius(const struct point *p, double r);
int far_deposit(struct point *p, const struct wfs_source *src, double light, double r, int slot);
int far_deposit_near(struct point *p, const struct wfs_source *src, double light, int k, int slot);
int far_gather(void *state, void *thread, int sca);
int far_spread(void *state, void *thread, int sca, const struct wfs_window *win);
void far_free(struct point *p);

#endif
