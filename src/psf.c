/*
 * psf.c - PSF grids: allocation, the STPSF/WebbPSF gridded FITS format,
 * the ePSF kernels and bilinear interpolation between nodes; see psf.h.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fitsio.h>

#include "err.h"
#include "instrument.h"
#include "psf.h"
#include "tempfile.h"
#include "wfiscene/model.h"

/* STPSF counts detector pixels in the 4096-pixel frame that includes the
 * 4-pixel reference border; ours is the 4088-pixel science frame. */
#define PSF_FRAME_OFFSET 4.0

struct psf_grid *psf_grid_new(int n, int over, int nx, int ny)
{
	struct psf_grid *g;

	if (n < 1 || over < 1 || nx < 1 || ny < 1)
		return NULL;
	if (!(g = calloc(1, sizeof(*g))))
		return NULL;
	g->n = n;
	g->over = over;
	g->nx = nx;
	g->ny = ny;
	g->filter = -1;
	g->pixscale = WFS_PIXSCALE / over;
	g->xs = calloc(nx, sizeof(*g->xs));
	g->ys = calloc(ny, sizeof(*g->ys));
	g->data = calloc((size_t)nx * ny * n * n, sizeof(*g->data));
	if (!g->xs || !g->ys || !g->data) {
		psf_grid_free(g);
		return NULL;
	}
	return g;
}

void psf_grid_free(struct psf_grid *g)
{
	if (!g)
		return;
	free(g->xs);
	free(g->ys);
	free(g->data);
	free(g->jac);
	free(g);
}

/* Parse STPSF's "(y, x)" position string. */
static int parse_yx(const char *s, double *y, double *x)
{
	char *end;

	while (*s == ' ' || *s == '(' || *s == '[')
		s++;
	errno = 0;
	*y = strtod(s, &end);
	if (end == s || errno)
		return -1;
	s = end;
	while (*s == ' ' || *s == ',')
		s++;
	*x = strtod(s, &end);
	if (end == s || errno)
		return -1;
	return 0;
}

/* Insert v into the ascending list a[0..*n) unless a value within half a
 * pixel is there; returns its index. */
static int add_node(double *a, int *n, double v)
{
	int i;

	for (i = 0; i < *n; i++)
		if (fabs(a[i] - v) < 0.5)
			return i;
	for (i = *n; i > 0 && a[i - 1] > v; i--)
		a[i] = a[i - 1];
	a[i] = v;
	(*n)++;
	return i;
}

static int find_node(const double *a, int n, double v)
{
	for (int i = 0; i < n; i++)
		if (fabs(a[i] - v) < 0.5)
			return i;
	return -1;
}

/* "SCA05", "WFI05", "wfi5" -> 5; 0 when not recognised. */
static int parse_detector(const char *s)
{
	while (*s && !(*s >= '0' && *s <= '9'))
		s++;
	int v = atoi(s);
	return v >= 1 && v <= WFS_NSCA ? v : 0;
}

/*
 * The sampling of a file.  PIXELSCL (arcsec per sample) is authoritative
 * when present; STPSF's older grids (such as the STIPS sample) carry
 * OVERSAMP = DET_SAMP = 1 even though they were computed at 0.11"/4, so the
 * field of view over its sample count (FOV / FOVPIXEL) comes next, and the
 * OVERSAMP keyword only last.
 */
static int read_sampling(fitsfile *f, double *pixscale, int *over,
			 const char *path, struct err *e)
{
	double ps = 0, fov;
	int st = 0, fovpix, os;

	if (fits_read_key(f, TDOUBLE, "PIXELSCL", &ps, NULL, &st)) {
		st = 0;
		ps = 0;
		if (!fits_read_key(f, TDOUBLE, "FOV", &fov, NULL, &st) &&
		    !fits_read_key(f, TINT, "FOVPIXEL", &fovpix, NULL, &st) &&
		    fovpix > 0)
			ps = fov / fovpix;
		st = 0;
		if (ps <= 0 && !fits_read_key(f, TINT, "OVERSAMP", &os, NULL, &st)
		    && os > 0)
			ps = WFS_PIXSCALE / os;
		st = 0;
	}
	if (!(ps > 0) || !isfinite(ps))
		return err_set(e, EXIT_INPUT, "%s: no PIXELSCL, FOV/FOVPIXEL or "
			       "OVERSAMP: cannot tell the PSF sampling", path);
	double r = WFS_PIXSCALE / ps;
	*over = (int)lround(r);
	if (*over < 1 || fabs(r - *over) > 0.02 * r)
		return err_set(e, EXIT_INPUT, "%s: sampling %.6g arcsec is not "
			       "an integer fraction of the %.2g arcsec pixel",
			       path, ps, WFS_PIXSCALE);
	*pixscale = ps;
	return 0;
}

/* cfitsio failed on a file that could be read (open_cube checks that
 * first): what it holds is cut short or not FITS, bad input (exit 1) as a
 * catalog's or an --into image's is; out of memory stays a system error. */
static void bad_cube(struct err *e, int st, const char *path)
{
	err_fits(e, st, "%s", path);
	if (st != MEMORY_ALLOCATION && e->code == EXIT_SYSTEM)
		e->code = EXIT_INPUT;
}

/* Open a PSF file and check it is a cube of square, odd-sided planes:
 * its plane side and count.  The file, or NULL with e set. */
static fitsfile *open_cube(const char *path, long *side, int *nplane, struct err *e)
{
	fitsfile *f = NULL;
	int st = 0, naxis = 0;
	long nax[3] = { 0, 0, 1 };

	/* a plain file name that cannot be read: the system's reason, rather
	 * than cfitsio's "could not open the named file" (names with cfitsio's
	 * extended syntax, [filters] or URLs, go to cfitsio as they are) */
	if (!strchr(path, '[') && !strstr(path, "://") && access(path, R_OK) < 0) {
		err_set(e, EXIT_SYSTEM, "%s: %s", path, strerror(errno));
		return NULL;
	}
	if (fits_open_diskfile(&f, path, READONLY, &st)) {
		/* compressed or remote files: cfitsio's general opener */
		st = 0;
		if (fits_open_file(&f, path, READONLY, &st)) {
			bad_cube(e, st, path);
			return NULL;
		}
	}
	if (fits_get_img_dim(f, &naxis, &st) || naxis < 2 || naxis > 3 ||
	    fits_get_img_size(f, naxis, nax, &st)) {
		if (!st)
			err_set(e, EXIT_INPUT, "%s: not a PSF cube (NAXIS = %d)",
				path, naxis);
		else
			bad_cube(e, st, path);
		goto fail;
	}
	if (nax[0] != nax[1] || nax[0] % 2 == 0 || nax[0] < 5) {
		err_set(e, EXIT_INPUT, "%s: PSF planes are %ldx%ld; want square "
			"with an odd side", path, nax[0], nax[1]);
		goto fail;
	}
	*nplane = naxis == 3 ? (int)nax[2] : 1;
	if (*nplane < 1 || *nplane > 10000) {
		err_set(e, EXIT_INPUT, "%s: %d PSF planes", path, *nplane);
		goto fail;
	}
	*side = nax[0];
	return f;
fail:
	st = 0;
	fits_close_file(f, &st);
	return NULL;
}

/* The science-frame position (px, py) of each of nplane planes from its
 * DET_YX keyword, and the grid's distinct x and y (xs, ys, ascending, nxs
 * and nys of them), which must make a full grid.  0 or -1. */
static int read_positions(fitsfile *f, const char *path, int nplane, double *px,
			  double *py, double *xs, int *nxs, double *ys, int *nys,
			  struct err *e)
{
	char str[FLEN_VALUE], key[FLEN_KEYWORD];
	int st;

	for (int k = 0; k < nplane; k++) {
		snprintf(key, sizeof(key), "DET_YX%d", k);
		st = 0;
		if (fits_read_key(f, TSTRING, key, str, NULL, &st)) {
			if (nplane > 1)
				return err_set(e, EXIT_INPUT, "%s: no %s for plane %d",
					       path, key, k);
			/* a lone PSF without a position: the SCA centre */
			py[k] = px[k] = 2044 + PSF_FRAME_OFFSET;
		} else if (parse_yx(str, &py[k], &px[k])) {
			return err_set(e, EXIT_INPUT, "%s: %s: not a '(y, x)' position: "
				       "'%s'", path, key, str);
		}
		px[k] -= PSF_FRAME_OFFSET;
		py[k] -= PSF_FRAME_OFFSET;
		add_node(xs, nxs, px[k]);
		add_node(ys, nys, py[k]);
	}
	if (*nxs * *nys != nplane)
		return err_set(e, EXIT_INPUT, "%s: the %d DET_YX positions do not form "
			       "a grid (%d x positions, %d y positions)", path, nplane,
			       *nxs, *nys);
	return 0;
}

/* Read the planes into g, each at its own node (px, py) whatever order the
 * file uses (STPSF writes x-major; photutils-sorted files are y-major);
 * NaNs become 0.  0 or -1. */
static int read_planes(fitsfile *f, const char *path, struct psf_grid *g, int nplane,
		       const double *px, const double *py, struct err *e)
{
	size_t np = (size_t)g->n * g->n;
	int *slot = malloc(nplane * sizeof(*slot));
	unsigned char *seen = calloc(nplane, 1);
	int st = 0, anynul = 0, rc = -1;

	if (!slot || !seen) {
		err_set(e, EXIT_SYSTEM, "%s: out of memory", path);
		goto done;
	}
	for (int k = 0; k < nplane; k++) {
		int ix = find_node(g->xs, g->nx, px[k]);
		int iy = find_node(g->ys, g->ny, py[k]);

		slot[k] = iy * g->nx + ix;
		if (seen[slot[k]]) {
			err_set(e, EXIT_INPUT, "%s: two planes at (y, x) = "
				"(%g, %g)", path, py[k] + PSF_FRAME_OFFSET,
				px[k] + PSF_FRAME_OFFSET);
			goto done;
		}
		seen[slot[k]] = 1;
	}
	/* each plane straight into its node, in the file's order */
	for (int k = 0; k < nplane; k++) {
		float *out = g->data + (size_t)slot[k] * np;

		if (fits_read_img(f, TFLOAT, (LONGLONG)k * (LONGLONG)np + 1, (LONGLONG)np, NULL,
				  out, &anynul, &st)) {
			bad_cube(e, st, path);
			goto done;
		}
		for (size_t i = 0; i < np; i++)
			out[i] = isfinite(out[i]) ? out[i] : 0.0f;
	}
	rc = 0;
done:
	free(slot);
	free(seen);
	return rc;
}

/* The pixel grid (write_pixgrid): PIXGRID = 'SIAF' with every plane's
 * JXX..JYY makes a SIAF grid; another PIXGRID, or a plane without them, a
 * square one; no PIXGRID, PSF_PIX_UNSAID.  Plane k sits at node
 * (px[k], py[k]). */
static void read_pixgrid(fitsfile *f, struct psf_grid *g, int nplane,
			 const double *px, const double *py)
{
	static const char *const jn[4] = { "JXX", "JXY", "JYX", "JYY" };
	char str[FLEN_VALUE], key[FLEN_KEYWORD];
	int st = 0;

	g->pixgrid = PSF_PIX_UNSAID;
	if (fits_read_key(f, TSTRING, "PIXGRID", str, NULL, &st))
		return;
	g->pixgrid = PSF_PIX_SQUARE;
	if (strcasecmp(str, "SIAF") || !(g->jac = malloc(sizeof(double) * 4 * nplane)))
		return;
	for (int k = 0; k < nplane; k++) {
		int slot = find_node(g->ys, g->ny, py[k]) * g->nx +
			   find_node(g->xs, g->nx, px[k]);

		for (int q = 0; q < 4; q++) {
			snprintf(key, sizeof(key), "%s%d", jn[q], k);
			if (fits_read_key(f, TDOUBLE, key, &g->jac[4 * slot + q], NULL,
					  &st)) {
				free(g->jac);
				g->jac = NULL;
				return;
			}
		}
	}
	g->pixgrid = PSF_PIX_SIAF;
}

/* What the header says of the grid: detector, filter, kind, pixel grid. */
static void read_labels(fitsfile *f, struct psf_grid *g, int nplane,
			const double *px, const double *py)
{
	char str[FLEN_VALUE];
	int st = 0;

	if (!fits_read_key(f, TSTRING, "DETECTOR", str, NULL, &st))
		g->sca = parse_detector(str);
	st = 0;
	if (!fits_read_key(f, TSTRING, "FILTER", str, NULL, &st))
		g->filter = filter_lookup(str);
	st = 0;
	g->kind = PSF_OPTICAL;
	if (!fits_read_key(f, TSTRING, "WFSKIND", str, NULL, &st) &&
	    !strcasecmp(str, "EPSF"))
		g->kind = PSF_EPSF;
	else if (!st && !strcasecmp(str, "EPSFNOIPC"))
		g->kind = PSF_EPSF_NOIPC;
	read_pixgrid(f, g, nplane, px, py);
}

struct psf_grid *psf_grid_read(const char *path, struct err *e)
{
	fitsfile *f;
	struct psf_grid *g = NULL;
	double *px = NULL, *py = NULL, *xs = NULL, *ys = NULL;
	int st = 0, nplane = 0, nxs = 0, nys = 0, over = 0;
	long side = 0;
	double pixscale = 0;

	if (!(f = open_cube(path, &side, &nplane, e)))
		return NULL;
	if (read_sampling(f, &pixscale, &over, path, e))
		goto fail;
	px = malloc(nplane * sizeof(*px));
	py = malloc(nplane * sizeof(*py));
	xs = malloc(nplane * sizeof(*xs));
	ys = malloc(nplane * sizeof(*ys));
	if (!px || !py || !xs || !ys) {
		err_set(e, EXIT_SYSTEM, "%s: out of memory", path);
		goto fail;
	}
	if (read_positions(f, path, nplane, px, py, xs, &nxs, ys, &nys, e))
		goto fail;
	if (!(g = psf_grid_new((int)side, over, nxs, nys))) {
		err_set(e, EXIT_SYSTEM, "%s: out of memory", path);
		goto fail;
	}
	memcpy(g->xs, xs, nxs * sizeof(*xs));
	memcpy(g->ys, ys, nys * sizeof(*ys));
	g->pixscale = pixscale;
	if (read_planes(f, path, g, nplane, px, py, e))
		goto fail;
	read_labels(f, g, nplane, px, py);
	snprintf(g->origin, sizeof(g->origin), "%s", path);
	fits_close_file(f, &st);
	free(px);
	free(py);
	free(xs);
	free(ys);
	return g;
fail:
	st = 0;
	fits_close_file(f, &st);
	psf_grid_free(g);
	free(px);
	free(py);
	free(xs);
	free(ys);
	return NULL;
}

static const char *filter_name(int filter)
{
	const struct filter_info *fi;

	if (filter < 0 || filter >= WFS_NFILTER)
		return "UNKNOWN";
	if (!(fi = filter_get(filter)) || !fi->name) {
		instrument_init(NULL);  /* the tables are constants: cannot fail */
		fi = filter_get(filter);
	}
	if (!fi || !fi->name)
		return "UNKNOWN";
	return fi->name;
}

/* The pixel grid the samples are on (psf.h): PIXGRID, and for the SIAF's
 * per plane k its node's Jacobian JXXk JXYk JYXk JYYk and the scales
 * along the pixel axes, SCLXk SCLYk (up to 9999 planes). */
static void write_pixgrid(fitsfile *f, const struct psf_grid *g, int *st)
{
	int nplane = g->nx * g->ny;
	static const char *const jn[4] = { "JXX", "JXY", "JYX", "JYY" };
	static const char *const jc[4] = {
		"[arcsec/px] d x_idl / d x at this node",
		"[arcsec/px] d x_idl / d y at this node",
		"[arcsec/px] d y_idl / d x at this node",
		"[arcsec/px] d y_idl / d y at this node" };

	if (!g->jac || nplane > 9999) {
		fits_write_key_str(f, "PIXGRID", "SQUARE", "samples: 1/OVERSAMP of a "
				   "square 0.11\" pixel (stips)", st);
		return;
	}
	fits_write_key_str(f, "PIXGRID", "SIAF", "samples: 1/OVERSAMP of the SCA's "
			   "own pixel (SIAF)", st);
	fits_write_comment(f, "The PSF is sampled on the detector's local pixel grid at "
			   "each node: sample (i, j) looks at the SIAF ideal-frame offset "
			   "J (i, j) / OVERSAMP, J = (JXX JXY; JYX JYY) of its plane.", st);
	for (int k = 0; k < nplane; k++) {
		int ix = k / g->ny, iy = k % g->ny;
		const double *j = g->jac + 4 * (size_t)(iy * g->nx + ix);
		char key[FLEN_KEYWORD];

		for (int q = 0; q < 4; q++) {
			snprintf(key, sizeof(key), "%s%d", jn[q], k);
			fits_write_key_dbl(f, key, j[q], 12, jc[q], st);
		}
		snprintf(key, sizeof(key), "SCLX%d", k);
		fits_write_key_dbl(f, key, hypot(j[0], j[2]), 8,
				   "[arcsec] on the sky of one pixel step along x", st);
		snprintf(key, sizeof(key), "SCLY%d", k);
		fits_write_key_dbl(f, key, hypot(j[1], j[3]), 8,
				   "[arcsec] on the sky of one pixel step along y", st);
	}
}

int psf_grid_write(const char *path, const struct psf_grid *g,
		   const char *const *extra_cards, struct err *e)
{
	char key[FLEN_KEYWORD], val[FLEN_VALUE], *tmp;
	size_t tn = TEMPFILE_SIZE(path);
	fitsfile *f = NULL;
	int st = 0, fd, nplane = g->nx * g->ny;
	size_t np = (size_t)g->n * g->n;
	long nax[3] = { g->n, g->n, nplane };
	struct stat sb;

	/* Renaming over a device, FIFO or socket (/dev/null, /dev/stdout)
	 * would replace the node itself; a directory is a mistake. */
	if (stat(path, &sb) == 0 && !S_ISREG(sb.st_mode))
		return err_set(e, EXIT_INPUT, "%s: not a regular file; the grid "
			       "is written under a temporary name and renamed "
			       "over it", path);
	if (!(tmp = malloc(tn)))
		return err_sys(e, "%s", path);
	/* The shared temporary: mode 0666 less the umask, as any new file
	 * gets (a cache shared on a cluster is read by other users), and
	 * registered, so that a fatal signal removes it.  It proved the name
	 * free and the directory writable; cfitsio creates the file itself
	 * (fits_create_diskfile takes the name literally: no "[ext]" or "!"
	 * parsing of user paths) with the same mode. */
	if ((fd = tempfile_beside(path, tmp, tn, e)) < 0) {
		free(tmp);
		return -1;
	}
	close(fd);
	unlink(tmp);
	if (fits_create_diskfile(&f, tmp, &st)) {
		f = NULL;
		goto fitsfail;
	}
	if (fits_create_img(f, FLOAT_IMG, 3, nax, &st))
		goto fitsfail;

	fits_write_key_str(f, "INSTRUME", "WFI", "Instrument name", &st);
	snprintf(val, sizeof(val), "SCA%02d", g->sca);
	fits_write_key_str(f, "DETECTOR", val, "Detector name", &st);
	fits_write_key_str(f, "FILTER", filter_name(g->filter), "Filter name",
			   &st);
	fits_write_key_lng(f, "OVERSAMP", g->over,
			   "Samples per detector pixel", &st);
	fits_write_key_lng(f, "DET_SAMP", g->over,
			   "Samples per detector pixel", &st);
	fits_write_key_dbl(f, "PIXELSCL", g->pixscale, 10,
			   "[arcsec] Scale of one PSF sample", &st);
	fits_write_key_lng(f, "FOVPIXEL", g->n, "Samples per side", &st);
	fits_write_key_dbl(f, "FOV", g->pixscale * g->n, 10,
			   "[arcsec] Field of view of a plane", &st);
	/* STPSF's order: x-major, plane k at node (ix, iy) = (k / ny, k % ny),
	 * its position in the 4096-pixel frame as "(y, x)". */
	for (int k = 0; k < nplane; k++) {
		int ix = k / g->ny, iy = k % g->ny;
		char com[FLEN_COMMENT];

		snprintf(key, sizeof(key), "DET_YX%d", k);
		snprintf(val, sizeof(val), "(%.1f, %.1f)",
			 g->ys[iy] + PSF_FRAME_OFFSET,
			 g->xs[ix] + PSF_FRAME_OFFSET);
		snprintf(com, sizeof(com), "The #%d PSF's (y,x) detector pixel "
			 "position", k);
		fits_write_key_str(f, key, val, com, &st);
	}
	fits_write_key_lng(f, "NUM_PSFS", nplane,
			   "The total number of fiducial PSFs", &st);
	fits_write_key_str(f, "WFSKIND", g->kind == PSF_EPSF ? "EPSF" :
			   g->kind == PSF_EPSF_NOIPC ? "EPSFNOIPC" : "PSF",
			   g->kind == PSF_EPSF ? "ePSF: pixel and IPC kernels "
			   "applied" : g->kind == PSF_EPSF_NOIPC ? "ePSF: pixel "
			   "kernel applied, no IPC" : "optical PSF", &st);
	fits_write_key_str(f, "ORIGIN", "wfiscene", NULL, &st);
	write_pixgrid(f, g, &st);
	for (const char *const *c = extra_cards; c && *c; c++)
		fits_write_record(f, *c, &st);
	if (st)
		goto fitsfail;
	for (int k = 0; k < nplane && !st; k++) {
		int ix = k / g->ny, iy = k % g->ny;
		LONGLONG first = (LONGLONG)k * np + 1;

		fits_write_img(f, TFLOAT, first, (LONGLONG)np,
			       g->data + (size_t)(iy * g->nx + ix) * np, &st);
	}
	if (st || fits_write_chksum(f, &st))
		goto fitsfail;
	/* cfitsio releases the file even when closing fails */
	if (fits_close_file(f, &st)) {
		f = NULL;
		goto fitsfail;
	}
	f = NULL;
	/* Make the bytes durable before the name appears. */
	if ((fd = open(tmp, O_RDONLY | O_CLOEXEC)) >= 0) {
		fsync(fd);
		close(fd);
	}
	st = tempfile_commit(tmp, path, e);
	free(tmp);
	return st;
fitsfail:
	err_fits(e, st, "%s", path);
	if (f) {
		st = 0;
		fits_close_file(f, &st);
		fits_clear_errmsg();
	}
	tempfile_discard(tmp);
	free(tmp);
	return -1;
}

/*
 * EPSF4 is the detector pixel seen on the 4x grid: a box 4 samples wide
 * centred on a sample reaches 2 samples either side, and integrating it by
 * the trapezoid rule on the sample lattice weights those samples 1/2, 1, 1,
 * 1, 1/2 along each axis.  The 5x5 kernel is the outer product of that row
 * (corners 1/4, other outer-ring entries 1/2, inner 3x3 1, sum 16), so the
 * convolution is done as two 1-D passes.  Any even sampling s works the
 * same way (s + 1 taps, 1/2 at the ends; the halo's s = 2 is 1/2, 1, 1/2;
 * the kernel sums to s^2, the samples a pixel holds).  One pass over n samples of each line: element i of a line is at
 * line * stride_line + i * stride_i.
 */
static void epsf_pass(const float *in, float *out, int n, int s, int stride_line,
		      int stride_i)
{
	int h = s / 2;

	for (int line = 0; line < n; line++)
		for (int i = 0; i < n; i++) {
			double sum = 0;

			for (int k = -h; k <= h; k++) {
				int j = i - k;
				if (j >= 0 && j < n)
					sum += (k == -h || k == h ? 0.5 : 1) *
					       in[line * stride_line + j * stride_i];
			}
			out[line * stride_line + i * stride_i] = (float)sum;
		}
}

/* STIPS's IPC kernel in percent: rows are y offsets -1, 0, +1 of the pixel
 * that receives charge, columns x offsets -1, 0, +1.  Sum 99.46. */
static const double psf_ipc[3][3] = {
	{ 0.21, 1.62, 0.20 },
	{ 1.88, 91.59, 1.87 },
	{ 0.21, 1.66, 0.22 },
};

int psf_make_epsf(struct psf_grid *g, struct err *e)
{
	return psf_make_epsf_kind(g, PSF_EPSF, e);
}

int psf_make_epsf_kind(struct psf_grid *g, int kind, struct err *e)
{
	int n = g->n, s = g->over;
	size_t np = (size_t)n * n;
	float *a, *b;

	if (g->kind == kind)
		return 0;
	if (g->kind != PSF_OPTICAL)
		return err_set(e, EXIT_INPUT, "%s: an ePSF grid cannot be made "
			       "into another kind of ePSF", g->origin);
	if (g->over != 4 && !(g->over == 2 && !strcmp(g->origin, "builtin")))
		return err_set(e, EXIT_INPUT, "%s: the ePSF kernel needs 4 "
			       "samples per pixel, not %d", g->origin, g->over);
	if (!(a = malloc(np * sizeof(*a))) || !(b = malloc(np * sizeof(*b)))) {
		free(a);
		return err_set(e, EXIT_SYSTEM, "out of memory");
	}
	for (int k = 0; k < g->nx * g->ny; k++) {
		float *p = g->data + k * np;

		/* rows (along x), then columns (along y) */
		epsf_pass(p, a, n, s, n, 1);
		epsf_pass(a, b, n, s, 1, n);
		if (kind == PSF_EPSF_NOIPC) {
			for (size_t i = 0; i < np; i++)
				p[i] = b[i];
			continue;
		}
		/* IPC at detector-pixel spacing: sample (y, x) receives
		 * ipc[a][b] of the charge of the sample s*a, s*b away on
		 * the other side, i.e. out(y, x) = sum in(y - s a, x - s b)
		 * ipc(a, b); outside the array counts as zero. */
		for (int y = 0; y < n; y++)
			for (int x = 0; x < n; x++) {
				double v = 0;

				for (int dy = -1; dy <= 1; dy++) {
					int yy = y - s * dy;
					if (yy < 0 || yy >= n)
						continue;
					for (int dx = -1; dx <= 1; dx++) {
						int xx = x - s * dx;
						if (xx < 0 || xx >= n)
							continue;
						v += b[yy * n + xx] *
						     psf_ipc[dy + 1][dx + 1];
					}
				}
				p[y * n + x] = (float)(v * 0.01);
			}
	}
	free(a);
	free(b);
	g->kind = kind;
	return 0;
}

/* Interval of the ascending nodes a[0..n) holding v and the weight of the
 * upper end, clamped so positions beyond the outer nodes take the edge. */
static void bracket(const double *a, int n, double v, int *i0, double *t)
{
	int i;

	if (n < 2 || v <= a[0]) {
		*i0 = 0;
		*t = 0;
		return;
	}
	if (v >= a[n - 1]) {
		*i0 = n - 2;
		*t = 1;
		return;
	}
	for (i = 0; i < n - 2 && v > a[i + 1]; i++)
		;
	*i0 = i;
	*t = (v - a[i]) / (a[i + 1] - a[i]);
}

void psf_grid_at(const struct psf_grid *g, double x, double y,
		 struct wfs_epsf *out)
{
	int ix, iy, ix1, iy1;
	double tx, ty;
	size_t np = (size_t)g->n * g->n;

	bracket(g->xs, g->nx, x, &ix, &tx);
	bracket(g->ys, g->ny, y, &iy, &ty);
	ix1 = g->nx > 1 ? ix + 1 : ix;
	iy1 = g->ny > 1 ? iy + 1 : iy;
	out->n = g->n;
	out->over = g->over;
	out->centre = (g->n - 1) / 2;
	out->node[0] = g->data + (size_t)(iy * g->nx + ix) * np;
	out->node[1] = g->data + (size_t)(iy * g->nx + ix1) * np;
	out->node[2] = g->data + (size_t)(iy1 * g->nx + ix) * np;
	out->node[3] = g->data + (size_t)(iy1 * g->nx + ix1) * np;
	out->weight[0] = (1 - tx) * (1 - ty);
	out->weight[1] = tx * (1 - ty);
	out->weight[2] = (1 - tx) * ty;
	out->weight[3] = tx * ty;
}

/* Phases count from the centre sample: (0, 0) sums the samples a whole
 * number of pixels from the centre, as a star centred on a pixel sees. */
double psf_enclosed(const struct psf_grid *g, int k, int px, int py)
{
	int n = g->n, s = g->over, c = (n - 1) / 2;
	const float *p = g->data + (size_t)k * n * n;
	double sum = 0;
	/* first sample on the lattice through centre + phase */
	int x0 = ((c + px) % s + s) % s, y0 = ((c + py) % s + s) % s;

	for (int y = y0; y < n; y += s)
		for (int x = x0; x < n; x += s)
			sum += p[y * n + x];
	return sum;
}
