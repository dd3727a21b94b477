/*
 * preview.c - wfiscene preview: look at a simulated exposure as a PNG.
 *
 *   wfiscene preview IN.fits [-o OUT.png] [--sca N|all] [--width PX]
 *                    [--stretch asinh|linear] [--scale Q] [--min V] [--max V]
 *   wfiscene preview --rgb R.fits G.fits B.fits -o OUT.png [...]
 *
 * Two ways to draw a file:
 *
 *   detector  one image HDU (--sca N picks EXTNAME WFInn; a file with a
 *             single image needs no --sca) in its own pixel frame, FITS
 *             row 1 at the bottom as ds9 shows it, averaged down to --width.
 *   sky       every image HDU placed by its own WCS on one tangent plane
 *             about the mean pointing, north up and east left, so the 18
 *             SCAs appear as the focal plane projects onto the sky.  Gaps
 *             between detectors are transparent.
 *
 * Memory stays bounded by the output, not the input: a detector is read in
 * row blocks and averaged into one row of accumulators at a time, and in sky
 * mode each SCA is first averaged to about the canvas pixel size and then
 * sampled (nearest neighbour, canvas pixel -> sky -> SCA pixel through the
 * SCA's WCS), so an 18 x 4088^2 file needs a few tens of megabytes.
 *
 * Levels come from the averaged picture itself (what you see is what is
 * stretched): the median is the sky, 1.4826 x the median absolute deviation
 * its noise, and a high percentile (99.5 %, or higher when most pixels are
 * empty sky, as in a noiseless sparse field; never below sky + 30 noise)
 * the white point.  The colour
 * composite follows Lupton et al. (2004, PASP 116, 133): the bands are put
 * in one flux unit by their PHOTZPAB when they have it (see "Colour
 * balance"), each is sky subtracted and scaled to the common white point
 * (else each to its own), and the asinh stretch is applied
 * to the mean intensity I with every band multiplied by f(I)/I, so colours
 * of bright, saturated-looking stars are kept instead of bleaching to white.
 */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fitsio.h>
#include <png.h>
#include <wcshdr.h>
#include <wcs.h>

#include "commands.h"
#include "err.h"
#include "options.h"
#include "names.h"
#include "tempfile.h"

#ifndef WFS_VERSION
#define WFS_VERSION "unknown"
#endif

#define PREVIEW_WIDTH 1024          /* default output width, pixels */
#define PREVIEW_MAX_SIDE 8192       /* largest PNG side we agree to make */
#define PREVIEW_BLOCK_BYTES (4 << 20) /* FITS rows read per call, bytes */
#define PREVIEW_SAMPLE (1 << 20)    /* pixels sampled for the levels */
#define PREVIEW_Q 8.0               /* asinh softening, Lupton's Q */
#define PREVIEW_NPOINT 9            /* outline points per SCA (see below) */
#define PREVIEW_MAX_HDU 4096

enum preview_stretch { PREVIEW_ASINH, PREVIEW_LINEAR };

struct preview_opts {
	const char *in[3];
	int nin;                    /* 1, or 3 with --rgb */
	const char *out;
	char out_default[PATH_MAX];     /* IN with .png, or -o expanded */
	int sca;                    /* 0 unset, -1 all, else EXTNAME WFInn */
	int width;
	int stretch;
	double q;
	double vmin, vmax;
	int have_min, have_max;
	int verbose;
};

/* One picture being built: nx x ny floats, row 0 at the top of the PNG,
 * NaN where there is no data (gaps between SCAs, blank pixels). */
struct preview_plane {
	int nx, ny;
	float *pix;
	long src_nx, src_ny;        /* the detector drawn, in detector mode */
};

/* The sky canvas: a gnomonic (TAN) projection about (ra0, dec0) in
 * standard coordinates xi (east) and eta (north), radians.  Canvas pixel
 * (cx, cy) has its centre at xi = xi_max - (cx + 0.5) step,
 * eta = eta_max - (cy + 0.5) step: east left, north up. */
struct preview_sky {
	double ra0, dec0, sin_d0, cos_d0;
	double xi_max, eta_max, step;
	int nx, ny;
};

/* Levels of one band, in the image's units (counts/s). */
struct preview_levels {
	double sky, sigma, white;
	double lo, hi;              /* what the stretch maps to 0 and 1 */
};

static int preview_parse_double(const char *opt, const char *s, double *out,
				 struct err *e)
{
	char *end;

	errno = 0;
	*out = strtod(s, &end);
	if (end == s || *end || errno || !isfinite(*out))
		return err_set(e, EXIT_INPUT, "%s: not a number: '%s'", opt, s);
	return 0;
}

static int preview_parse_int(const char *opt, const char *s, long lo, long hi,
			     int *out, struct err *e)
{
	char *end;
	long v;

	errno = 0;
	v = strtol(s, &end, 10);
	if (end == s || *end || errno)
		return err_set(e, EXIT_INPUT, "%s: not an integer: '%s'", opt, s);
	if (v < lo || v > hi)
		return err_set(e, EXIT_INPUT, "%s: %ld is outside %ld..%ld", opt,
			       v, lo, hi);
	*out = (int)v;
	return 0;
}

/* "all", "5", "05", "WFI05", "wfi5", "SCA05". */
static int preview_parse_sca(const char *s, int *out, struct err *e)
{
	const char *num = s;

	if (!strcasecmp(s, "all")) {
		*out = -1;
		return 0;
	}
	if (!strncasecmp(s, "wfi", 3) || !strncasecmp(s, "sca", 3))
		num = s + 3;
	if (!*num || preview_parse_int("--sca", num, 1, 18, out, e) < 0) {
		err_clear(e);
		return err_set(e, EXIT_INPUT,
			       "--sca: expected a detector 1..18 (or WFInn) or 'all': '%s'", s);
	}
	return 0;
}

/* IN.fits -> IN.png next to it; compressed and alternative suffixes too. */
static int preview_default_output(struct preview_opts *o, struct err *e)
{
	static const char *const suffix[] = {
		".fits.fz", ".fits.gz", ".fit.gz", ".fits", ".fit", ".fts", ".fz",
	};
	const char *in = o->in[0];
	size_t n = strlen(in), k;

	if (!strcmp(in, "-") || strchr(in, '['))
		return err_set(e, EXIT_INPUT, "'%s': name the PNG with -o", in);
	for (k = 0; k < sizeof(suffix) / sizeof(suffix[0]); k++) {
		size_t m = strlen(suffix[k]);
		if (n > m && !strcasecmp(in + n - m, suffix[k])) {
			n -= m;
			break;
		}
	}
	if (n + 5 > sizeof(o->out_default))
		return err_set(e, EXIT_INPUT, "'%s': name too long", in);
	memcpy(o->out_default, in, n);
	memcpy(o->out_default + n, ".png", 5);
	o->out = o->out_default;
	return 0;
}

#define STR_(x) #x
#define STR(x) STR_(x)
#define OFF(f) offsetof(struct preview_opts, f)

static opt_set_fn set_sca, set_width, set_stretch, set_scale, set_level, set_rgb;

static const struct opt preview_options[] = {
	{ OPT("output", 'o', "FILE", "IN with .png", "PNG to write ('-' for stdout)",
	  opt_string, OFF(out)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("sca", 0, "N|all", "the only image, else all", "one detector (EXTNAME WFInn) "
	  "in its pixel frame, or all image HDUs placed by their WCS, north up, east "
	  "left", set_sca, OFF(sca)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("width", 0, "PX", STR(PREVIEW_WIDTH), "output width, at most the detector "
	  "width for one SCA, at most " STR(PREVIEW_MAX_SIDE), set_width, OFF(width)),
	  .lo = 16, .hi = PREVIEW_MAX_SIDE, .flags = OPT_SHOW_DEFAULT },
	{ OPT("stretch", 0, "S", "asinh", "asinh or linear", set_stretch, OFF(stretch)) },
	{ OPT("scale", 0, "Q", STR(PREVIEW_Q), "asinh softening Q (larger shows fainter "
	  "light)", set_scale, OFF(q)) },
	{ OPT("min", 0, "V", "sky - noise", "level mapped to black, in image units",
	  set_level, OFF(vmin)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("max", 0, "V", "the 99.5th percentile but at least sky + 30 noise",
	  "level mapped to white, in image units", set_level, OFF(vmax)),
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("rgb", 0, "R G B", NULL, "colour composite of three filters (Lupton et al. "
	  "2004)", set_rgb, OFF(in)), .nargs = 3 },
	{ OPT("verbose", 'v', NULL, NULL, "print the levels used", opt_count, OFF(verbose)) },
	{ OPT("help", 'h', NULL, NULL, "this text", opt_show_help, 0) },
	OPT_END
};

static const struct opt_cmd preview_cmd_line = {
	.prog = "wfiscene: preview",
	.usage =
"usage: wfiscene preview IN.fits [-o OUT.png] [--sca N|all] [--width PX]\n"
"                        [--stretch asinh|linear] [--scale Q] [--min V] [--max V] [-v]\n"
"       wfiscene preview --rgb R.fits G.fits B.fits -o OUT.png [options]\n"
"\n",
	.opts = preview_options,
};

static int set_sca(const struct opt_arg *a, struct err *e)
{
	return preview_parse_sca(a->value, a->field, e);
}

static int set_width(const struct opt_arg *a, struct err *e)
{
	return preview_parse_int("--width", a->value, (long)a->opt->lo, (long)a->opt->hi,
				 a->field, e);
}

static int set_stretch(const struct opt_arg *a, struct err *e)
{
	if (!strcmp(a->value, "asinh"))
		*(int *)a->field = PREVIEW_ASINH;
	else if (!strcmp(a->value, "linear"))
		*(int *)a->field = PREVIEW_LINEAR;
	else
		return err_set(e, EXIT_INPUT, "--stretch: expected asinh or linear: '%s'",
			       a->value);
	return 0;
}

static int set_scale(const struct opt_arg *a, struct err *e)
{
	double *q = a->field;

	if (preview_parse_double("--scale", a->value, q, e) < 0)
		return -1;
	if (!(*q > 0) || *q > 1e6)
		return err_set(e, EXIT_INPUT, "--scale: Q must be above 0 (and sane): '%s'",
			       a->value);
	return 0;
}

/* --min and --max: the level, and that it was given. */
static int set_level(const struct opt_arg *a, struct err *e)
{
	struct preview_opts *o = a->base;
	int is_min = a->field == &o->vmin;

	if (preview_parse_double(is_min ? "--min" : "--max", a->value, a->field, e) < 0)
		return -1;
	*(is_min ? &o->have_min : &o->have_max) = 1;
	return 0;
}

static int set_rgb(const struct opt_arg *a, struct err *e)
{
	struct preview_opts *o = a->base;

	if (a->nvalues < 3)
		return err_set(e, EXIT_INPUT, "--rgb needs three FITS files: red, green, blue");
	for (int k = 0; k < 3; k++)
		o->in[k] = a->values[k];
	o->nin = 3;
	return 0;
}

/* Returns 0, 1 for --help (done), or -1 with an error (and the usage
 * already printed after an error of the command line itself). */
static int preview_parse(int argc, char **argv, struct preview_opts *o,
			 struct err *e)
{
	int first;

	memset(o, 0, sizeof(*o));
	first = opt_parse(&preview_cmd_line, argc, argv, o, e);
	if (first == OPT_PARSE_DONE)
		return 1;
	if (first == OPT_PARSE_USAGE) {
		opt_fail(&preview_cmd_line, first, e);
		return -2;
	}
	if (first < 0)
		return -1;
	if (first < argc && o->nin == 3)
		return err_set(e, EXIT_INPUT, "--rgb takes the three files itself; '%s' is "
			       "extra", argv[first]);
	if (first + 1 < argc)
		return err_set(e, EXIT_INPUT, "one input file only: '%s'", argv[first + 1]);
	if (first < argc)
		o->in[o->nin++] = argv[first];
	if (!o->nin)
		return err_set(e, EXIT_INPUT, "no input FITS file (see --help)");
	if (o->have_min && o->have_max && !(o->vmax > o->vmin))
		return err_set(e, EXIT_INPUT, "--max %g must be above --min %g",
			       o->vmax, o->vmin);
	if (!o->out) {
		if (o->nin == 3)
			return err_set(e, EXIT_INPUT, "--rgb needs -o OUT.png");
		if (preview_default_output(o, e) < 0)
			return -1;
	} else {
		/* one file: '%%' is its only escape (names.h) */
		if (name_check("-o", o->out, 0, 0, e) < 0 ||
		    name_expand(o->out_default, sizeof(o->out_default), "-o", o->out, 0, NULL,
				e) < 0)
			return -1;
		o->out = o->out_default;
	}
	if (!strcmp(o->out, "-") && isatty(STDOUT_FILENO))
		return err_set(e, EXIT_INPUT, "refusing to write a PNG to a terminal");
	return 0;
}

/* FITS input ----------------------------------------------------------- */

static int preview_open(const char *path, fitsfile **f, struct err *e)
{
	struct stat st;
	int status = 0;

	*f = NULL;
	if (fits_open_file(f, path, READONLY, &status) == 0)
		return 0;
	/* cfitsio says "could not open the named file" for both a missing
	 * file and one it cannot parse; tell people which. */
	if (strcmp(path, "-") && !strchr(path, '[') && stat(path, &st) < 0) {
		fits_clear_errmsg();
		return err_sys(e, "%s", path);
	}
	err_fits(e, status, "%s: cannot read it as FITS", path);
	e->code = EXIT_INPUT;
	return -1;
}

static void preview_close(fitsfile *f)
{
	int status = 0;

	if (f)
		fits_close_file(f, &status);
}

/* Image HDUs (2-D, non-empty; tile-compressed ones count) of an open file,
 * as 1-based HDU numbers.  Returns how many, or -1. */
static int preview_images(fitsfile *f, const char *path, int *hdu, int max,
			  struct err *e)
{
	int nhdu = 0, k, n = 0, status = 0;

	if (fits_get_num_hdus(f, &nhdu, &status))
		return err_fits(e, status, "%s", path);
	for (k = 1; k <= nhdu && n < max; k++) {
		int type, naxis;
		long naxes[2];

		if (fits_movabs_hdu(f, k, &type, &status) ||
		    fits_get_img_dim(f, &naxis, &status))
			return err_fits(e, status, "%s: HDU %d", path, k);
		if (type != IMAGE_HDU || naxis != 2)
			continue;
		if (fits_get_img_size(f, 2, naxes, &status))
			return err_fits(e, status, "%s: HDU %d", path, k);
		if (naxes[0] > 0 && naxes[1] > 0)
			hdu[n++] = k;
	}
	return n;
}

/* Move to HDU k and name it for messages: "in.fits[WFI03]" or "in.fits[2]". */
static int preview_goto(fitsfile *f, const char *path, int k, char *where,
			size_t wsize, long *nx, long *ny, struct err *e)
{
	char extname[FLEN_VALUE] = "";
	long naxes[2];
	int type, status = 0;

	if (fits_movabs_hdu(f, k, &type, &status) ||
	    fits_get_img_size(f, 2, naxes, &status))
		return err_fits(e, status, "%s: HDU %d", path, k);
	if (fits_read_key(f, TSTRING, "EXTNAME", extname, NULL, &status)) {
		status = 0;
		fits_clear_errmsg();
	}
	if (extname[0])
		snprintf(where, wsize, "%s[%s]", path, extname);
	else
		snprintf(where, wsize, "%s[%d]", path, k - 1);
	*nx = naxes[0];
	*ny = naxes[1];
	return 0;
}

/* The image HDU whose EXTNAME is WFInn (or SCAnn) for detector sca. */
static int preview_find_sca(fitsfile *f, const char *path, const int *hdu,
			    int n, int sca, struct err *e)
{
	char want[2][16], extname[FLEN_VALUE];
	int k, status;

	snprintf(want[0], sizeof(want[0]), "WFI%02d", sca);
	snprintf(want[1], sizeof(want[1]), "SCA%02d", sca);
	for (k = 0; k < n; k++) {
		status = 0;
		extname[0] = 0;
		if (fits_movabs_hdu(f, hdu[k], NULL, &status) ||
		    fits_read_key(f, TSTRING, "EXTNAME", extname, NULL, &status)) {
			fits_clear_errmsg();
			continue;
		}
		if (!strcasecmp(extname, want[0]) || !strcasecmp(extname, want[1]))
			return hdu[k];
	}
	return err_set(e, EXIT_INPUT, "%s: no image HDU with EXTNAME '%s'", path,
		       want[0]);
}

/*
 * Average the current image HDU (nx x ny) onto an ox x oy grid (ox <= nx,
 * oy <= ny): input pixel (i, j) goes to output (i ox / nx, j oy / ny), so
 * every output pixel is the mean of a box of nx/ox by ny/oy inputs (the
 * boxes differ by at most one pixel).  Output row 0 is FITS row 1.  Rows
 * are read in blocks and only one output row is accumulated at a time.
 * NaN (and BLANK) pixels are left out of the means; a box with none is NaN.
 */
static int preview_bin(fitsfile *f, const char *where, long nx, long ny,
		       int ox, int oy, float *out, struct err *e)
{
	long rows = PREVIEW_BLOCK_BYTES / (nx * (long)sizeof(float));
	float nanval = NAN, *buf = NULL;
	double *sum = NULL;
	int *cnt = NULL, *col = NULL, v = 0, status = 0, rc = -1;
	long i, j, j0;

	if (rows < 1)
		rows = 1;
	if (rows > ny)
		rows = ny;
	buf = malloc((size_t)rows * nx * sizeof(*buf));
	sum = calloc(ox, sizeof(*sum));
	cnt = calloc(ox, sizeof(*cnt));
	col = malloc(nx * sizeof(*col));
	if (!buf || !sum || !cnt || !col) {
		err_sys(e, "%s: %ld x %ld image", where, nx, ny);
		goto done;
	}
	for (i = 0; i < nx; i++)
		col[i] = (int)(i * (long long)ox / nx);
	for (j0 = 0; j0 < ny; j0 += rows) {
		long n = j0 + rows <= ny ? rows : ny - j0;
		long first[2] = { 1, j0 + 1 };
		int anynul;

		if (fits_read_pix(f, TFLOAT, first, (LONGLONG)n * nx, &nanval, buf,
				  &anynul, &status)) {
			err_fits(e, status, "%s: reading rows %ld-%ld", where,
				 j0 + 1, j0 + n);
			goto done;
		}
		for (j = j0; j < j0 + n; j++) {
			const float *row = buf + (j - j0) * nx;
			int vj = (int)(j * (long long)oy / ny);

			if (vj != v) {
				for (i = 0; i < ox; i++) {
					out[(size_t)v * ox + i] = cnt[i] ? (float)(sum[i] / cnt[i]) : NAN;
					sum[i] = 0;
					cnt[i] = 0;
				}
				v = vj;
			}
			for (i = 0; i < nx; i++)
				if (isfinite(row[i])) {
					sum[col[i]] += row[i];
					cnt[col[i]]++;
				}
		}
	}
	for (i = 0; i < ox; i++)
		out[(size_t)v * ox + i] = cnt[i] ? (float)(sum[i] / cnt[i]) : NAN;
	rc = 0;
done:
	free(buf);
	free(sum);
	free(cnt);
	free(col);
	return rc;
}

/* The celestial WCS of the current HDU, set up, or NULL with an error.
 * Free with preview_wcs_free(). */
static struct wcsprm *preview_wcs(fitsfile *f, const char *where, int *nwcs,
				  struct err *e)
{
	struct wcsprm *wcs = NULL;
	char *hdr = NULL;
	int nkeys = 0, nreject = 0, status = 0, k;

	*nwcs = 0;
	if (fits_convert_hdr2str(f, 0, NULL, 0, &hdr, &nkeys, &status)) {
		err_fits(e, status, "%s: header", where);
		return NULL;
	}
	status = wcspih(hdr, nkeys, WCSHDR_all, 0, &nreject, nwcs, &wcs);
	fits_free_memory(hdr, &k);
	if (status || *nwcs < 1) {
		if (wcs)
			wcsvfree(nwcs, &wcs);
		err_set(e, EXIT_INPUT, "%s: no WCS in the header%s", where,
			status ? " (wcslib could not parse it)" : "");
		return NULL;
	}
	/* wcs[0] is the primary description (alternate ' '). */
	if (wcsset(wcs) || wcs->lng < 0 || wcs->lat < 0 || wcs->naxis != 2) {
		err_set(e, EXIT_INPUT, "%s: no usable celestial WCS (RA/Dec on both axes)",
			where);
		wcsvfree(nwcs, &wcs);
		return NULL;
	}
	return wcs;
}

static void preview_wcs_free(struct wcsprm *wcs, int nwcs)
{
	if (wcs)
		wcsvfree(&nwcs, &wcs);
}

/* Pixel (1-based FITS coordinates) to RA, Dec in degrees. */
static int preview_pix2sky(struct wcsprm *wcs, double px, double py,
			   double *ra, double *dec)
{
	double pix[2] = { px, py }, img[2], phi, theta, world[2];
	int stat;

	if (wcsp2s(wcs, 1, 2, pix, img, &phi, &theta, world, &stat))
		return -1;
	*ra = world[wcs->lng];
	*dec = world[wcs->lat];
	return 0;
}

static void preview_unit(double ra_deg, double dec_deg, double u[3])
{
	double a = ra_deg * M_PI / 180, d = dec_deg * M_PI / 180;

	u[0] = cos(d) * cos(a);
	u[1] = cos(d) * sin(a);
	u[2] = sin(d);
}

/* Gnomonic projection about (ra0, dec0); -1 when the point is on the far
 * hemisphere (never for one exposure). */
static int preview_project(const struct preview_sky *s, double ra_deg,
			   double dec_deg, double *xi, double *eta)
{
	double a = ra_deg * M_PI / 180 - s->ra0, d = dec_deg * M_PI / 180;
	double cosc = s->sin_d0 * sin(d) + s->cos_d0 * cos(d) * cos(a);

	if (cosc < 0.1)
		return -1;
	*xi = cos(d) * sin(a) / cosc;
	*eta = (s->cos_d0 * sin(d) - s->sin_d0 * cos(d) * cos(a)) / cosc;
	return 0;
}

static void preview_deproject(const struct preview_sky *s, double xi,
			      double eta, double *ra_deg, double *dec_deg)
{
	/* The point is along (xi, eta, 1) in the frame whose z axis is the
	 * tangent point; rotate that back to equatorial axes. */
	double x = -eta * s->sin_d0 + s->cos_d0, y = xi;
	double z = eta * s->cos_d0 + s->sin_d0;
	double a = atan2(y, x) + s->ra0;

	*dec_deg = atan2(z, hypot(x, y)) * 180 / M_PI;
	a = fmod(a * 180 / M_PI, 360);
	*ra_deg = a < 0 ? a + 360 : a;
}

/* One HDU's outline on the sky: corners, edge midpoints, centre. */
struct preview_outline {
	double ra[PREVIEW_NPOINT], dec[PREVIEW_NPOINT];
};

static int preview_outline(struct wcsprm *wcs, long nx, long ny,
			   struct preview_outline *o)
{
	static const double fx[PREVIEW_NPOINT] = { 0, 1, 1, 0, 0.5, 1, 0.5, 0, 0.5 };
	static const double fy[PREVIEW_NPOINT] = { 0, 0, 1, 1, 0, 0.5, 1, 0.5, 0.5 };
	int k;

	for (k = 0; k < PREVIEW_NPOINT; k++)
		if (preview_pix2sky(wcs, 0.5 + fx[k] * nx, 0.5 + fy[k] * ny,
				    &o->ra[k], &o->dec[k]))
			return -1;
	return 0;
}

/* Image HDUs a file contributes in sky mode: all of them, or --sca's. */
static int preview_sky_hdus(fitsfile *f, const char *path, int *hdu,
			    struct err *e)
{
	int n = preview_images(f, path, hdu, PREVIEW_MAX_HDU, e);

	if (n == 0)
		return err_set(e, EXIT_INPUT, "%s: no 2-D image in the file", path);
	return n;
}

/*
 * Lay out the canvas: the tangent point is the mean direction of all SCA
 * centres of all inputs, and the canvas spans every SCA outline plus a 2 %
 * margin, width pixels wide.
 */
static int preview_sky_layout(const struct preview_opts *o, int width,
			      struct preview_sky *s, struct err *e)
{
	struct preview_outline *all = NULL, *grow;
	double u[3], sum[3] = { 0, 0, 0 }, norm;
	double xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
	int *hdu = NULL, nall = 0, c, k, p, rc = -1;
	char where[PATH_MAX + 80];

	hdu = malloc(PREVIEW_MAX_HDU * sizeof(*hdu));
	if (!hdu)
		return err_sys(e, "preview");
	for (c = 0; c < o->nin; c++) {
		fitsfile *f;
		int n;

		if (preview_open(o->in[c], &f, e) < 0)
			goto done;
		n = preview_sky_hdus(f, o->in[c], hdu, e);
		for (k = 0; k < n; k++) {
			struct wcsprm *wcs;
			long nx, ny;
			int nwcs;

			if (preview_goto(f, o->in[c], hdu[k], where, sizeof(where),
					 &nx, &ny, e) < 0 ||
			    !(wcs = preview_wcs(f, where, &nwcs, e))) {
				n = -1;
				break;
			}
			if (!(grow = realloc(all, (nall + 1) * sizeof(*all)))) {
				preview_wcs_free(wcs, nwcs);
				err_sys(e, "preview");
				n = -1;
				break;
			}
			all = grow;
			if (preview_outline(wcs, nx, ny, &all[nall]) < 0) {
				preview_wcs_free(wcs, nwcs);
				err_set(e, EXIT_INPUT, "%s: the WCS cannot place the detector corners", where);
				n = -1;
				break;
			}
			preview_wcs_free(wcs, nwcs);
			preview_unit(all[nall].ra[8], all[nall].dec[8], u);
			for (p = 0; p < 3; p++)
				sum[p] += u[p];
			nall++;
		}
		preview_close(f);
		if (n < 0)
			goto done;
	}
	norm = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
	if (!(norm > 0)) {
		err_set(e, EXIT_INPUT, "%s: the detectors have no common centre", o->in[0]);
		goto done;
	}
	s->ra0 = atan2(sum[1], sum[0]);
	s->dec0 = asin(sum[2] / norm);
	s->sin_d0 = sin(s->dec0);
	s->cos_d0 = cos(s->dec0);
	for (k = 0; k < nall; k++)
		for (p = 0; p < PREVIEW_NPOINT; p++) {
			double xi, eta;

			/* 0.1 in cos(c) is 84 degrees from the centre: not one
			 * exposure, and TAN would blow up. */
			if (preview_project(s, all[k].ra[p], all[k].dec[p], &xi, &eta) < 0 ||
			    fabs(xi) > 0.6 || fabs(eta) > 0.6) {
				err_set(e, EXIT_INPUT,
					"%s: the images spread over more than ~30 degrees of sky; "
					"view one with --sca N", o->in[0]);
				goto done;
			}
			xmin = fmin(xmin, xi);
			xmax = fmax(xmax, xi);
			ymin = fmin(ymin, eta);
			ymax = fmax(ymax, eta);
		}
	{
		double span = fmax(xmax - xmin, ymax - ymin), margin = 0.02 * span;

		if (!(span > 0)) {
			err_set(e, EXIT_INPUT, "%s: the WCS gives the image no extent", o->in[0]);
			goto done;
		}
		xmin -= margin;
		xmax += margin;
		ymin -= margin;
		ymax += margin;
		s->xi_max = xmax;
		s->eta_max = ymax;
		s->nx = width;
		s->step = (xmax - xmin) / width;
		s->ny = (int)ceil((ymax - ymin) / s->step);
		if (s->ny < 1)
			s->ny = 1;
		if (s->ny > PREVIEW_MAX_SIDE) {
			/* A tall layout: keep the height within bounds instead. */
			s->ny = PREVIEW_MAX_SIDE;
			s->step = (ymax - ymin) / s->ny;
			s->nx = (int)ceil((xmax - xmin) / s->step);
			if (s->nx < 1)
				s->nx = 1;
		}
	}
	rc = 0;
done:
	free(all);
	free(hdu);
	return rc;
}

/* Angle between two sky positions, radians. */
static double preview_sep(double ra1, double dec1, double ra2, double dec2)
{
	double u[3], v[3], c[3];

	preview_unit(ra1, dec1, u);
	preview_unit(ra2, dec2, v);
	c[0] = u[1] * v[2] - u[2] * v[1];
	c[1] = u[2] * v[0] - u[0] * v[2];
	c[2] = u[0] * v[1] - u[1] * v[0];
	return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
		     u[0] * v[0] + u[1] * v[1] + u[2] * v[2]);
}

/*
 * Draw the current HDU onto the canvas.  It is first averaged in boxes of
 * b x b pixels, b the canvas pixel size over the detector pixel size
 * (rounded down), so each canvas sample stands for the light of its whole
 * canvas pixel rather than one detector pixel (which would drop most stars
 * at 1/25 scale).  Then each canvas pixel inside the detector's outline is
 * mapped canvas -> (xi, eta) -> (RA, Dec) -> detector pixel through the
 * detector's own WCS and takes that box's value: nearest neighbour, which is
 * exact for any rotation between the detector and the canvas.
 */
static int preview_sky_draw(fitsfile *f, const char *where, long nx, long ny,
			    const struct preview_sky *s, struct preview_plane *pl,
			    struct err *e)
{
	struct preview_outline ol;
	struct wcsprm *wcs;
	double ra1, dec1, ra2, dec2, pixscale, xmin = HUGE_VAL, xmax = -HUGE_VAL;
	double ymin = HUGE_VAL, ymax = -HUGE_VAL;
	double *world = NULL, *img = NULL, *pix = NULL, *phi = NULL, *theta = NULL;
	float *bin = NULL;
	int *stat = NULL, nwcs, cx0, cx1, cy0, cy1, cx, cy, bx, by, b, k, rc = -1;

	if (!(wcs = preview_wcs(f, where, &nwcs, e)))
		return -1;
	if (preview_outline(wcs, nx, ny, &ol) < 0 ||
	    preview_pix2sky(wcs, nx / 2.0 + 1, ny / 2.0, &ra1, &dec1) < 0 ||
	    preview_pix2sky(wcs, nx / 2.0, ny / 2.0 + 1, &ra2, &dec2) < 0) {
		err_set(e, EXIT_INPUT, "%s: the WCS cannot place the detector", where);
		goto done;
	}
	pixscale = 0.5 * (preview_sep(ol.ra[8], ol.dec[8], ra1, dec1) +
			  preview_sep(ol.ra[8], ol.dec[8], ra2, dec2));
	b = pixscale > 0 ? (int)floor(s->step / pixscale) : 1;
	if (b < 1)
		b = 1;
	bx = (int)(nx / b > 0 ? nx / b : 1);
	by = (int)(ny / b > 0 ? ny / b : 1);
	bin = malloc((size_t)bx * by * sizeof(*bin));
	if (!bin) {
		err_sys(e, "%s", where);
		goto done;
	}
	if (preview_bin(f, where, nx, ny, bx, by, bin, e) < 0)
		goto done;

	for (k = 0; k < PREVIEW_NPOINT; k++) {
		double xi, eta;

		if (preview_project(s, ol.ra[k], ol.dec[k], &xi, &eta) < 0) {
			err_set(e, EXIT_INPUT, "%s: far from the other images", where);
			goto done;
		}
		xmin = fmin(xmin, (s->xi_max - xi) / s->step);
		xmax = fmax(xmax, (s->xi_max - xi) / s->step);
		ymin = fmin(ymin, (s->eta_max - eta) / s->step);
		ymax = fmax(ymax, (s->eta_max - eta) / s->step);
	}
	/* One pixel of slack: the outline is sampled at 9 points only. */
	cx0 = (int)fmax(0, floor(xmin) - 1);
	cx1 = (int)fmin(s->nx - 1, ceil(xmax) + 1);
	cy0 = (int)fmax(0, floor(ymin) - 1);
	cy1 = (int)fmin(s->ny - 1, ceil(ymax) + 1);
	if (cx1 < cx0 || cy1 < cy0) {
		rc = 0;
		goto done;
	}
	world = malloc(2 * (size_t)(cx1 - cx0 + 1) * sizeof(*world));
	img = malloc(2 * (size_t)(cx1 - cx0 + 1) * sizeof(*img));
	pix = malloc(2 * (size_t)(cx1 - cx0 + 1) * sizeof(*pix));
	phi = malloc((size_t)(cx1 - cx0 + 1) * sizeof(*phi));
	theta = malloc((size_t)(cx1 - cx0 + 1) * sizeof(*theta));
	stat = malloc((size_t)(cx1 - cx0 + 1) * sizeof(*stat));
	if (!world || !img || !pix || !phi || !theta || !stat) {
		err_sys(e, "%s", where);
		goto done;
	}
	for (cy = cy0; cy <= cy1; cy++) {
		int n = cx1 - cx0 + 1;
		double eta = s->eta_max - (cy + 0.5) * s->step;

		for (cx = cx0; cx <= cx1; cx++) {
			double ra, dec;

			preview_deproject(s, s->xi_max - (cx + 0.5) * s->step, eta,
					  &ra, &dec);
			world[2 * (cx - cx0) + wcs->lng] = ra;
			world[2 * (cx - cx0) + wcs->lat] = dec;
		}
		/* WCSERR_BAD_WORLD (some points invalid) still converts the
		 * rest; the per-point stat says which. */
		k = wcss2p(wcs, n, 2, world, phi, theta, img, pix, stat);
		if (k && k != WCSERR_BAD_WORLD) {
			err_set(e, EXIT_INPUT, "%s: wcslib cannot map the sky to pixels (status %d)",
				where, k);
			goto done;
		}
		for (cx = cx0; cx <= cx1; cx++) {
			int q = cx - cx0;
			double i = floor(pix[2 * q] - 0.5), j = floor(pix[2 * q + 1] - 0.5);
			float val;

			if (stat[q] || !(i >= 0 && i < nx && j >= 0 && j < ny))
				continue;
			val = bin[(size_t)((long long)j * by / ny) * bx +
				  (size_t)((long long)i * bx / nx)];
			if (isfinite(val))
				pl->pix[(size_t)cy * pl->nx + cx] = val;
		}
	}
	rc = 0;
done:
	free(world);
	free(img);
	free(pix);
	free(phi);
	free(theta);
	free(stat);
	free(bin);
	preview_wcs_free(wcs, nwcs);
	return rc;
}

/* Levels ----------------------------------------------------------------- */

static int preview_cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;

	return (x > y) - (x < y);
}

/* The q-quantile of a sorted array (0 <= q <= 1), by linear interpolation. */
static double preview_quantile(const float *v, size_t n, double q)
{
	double r = q * (n - 1);
	size_t k = (size_t)r;

	if (k + 1 >= n)
		return v[n - 1];
	return v[k] + (r - k) * (v[k + 1] - v[k]);
}

static int preview_levels(const struct preview_plane *pl, const char *what,
			  const struct preview_opts *o,
			  struct preview_levels *lv, struct err *e)
{
	static const double tops[] = { 0.995, 0.999, 0.9999, 1.0 };
	size_t total = (size_t)pl->nx * pl->ny, stride, n = 0, k;
	float *v;

	stride = total / PREVIEW_SAMPLE + 1;
	v = malloc((total / stride + 1) * sizeof(*v));
	if (!v)
		return err_sys(e, "%s: levels", what);
	for (k = 0; k < total; k += stride)
		if (isfinite(pl->pix[k]))
			v[n++] = pl->pix[k];
	if (n == 0) {
		/* A sparse sample of a mostly empty mosaic can miss every SCA;
		 * fall back to every pixel before giving up. */
		free(v);
		v = malloc(PREVIEW_SAMPLE * sizeof(*v));
		if (!v)
			return err_sys(e, "%s: levels", what);
		for (k = 0; k < total && n < PREVIEW_SAMPLE; k++)
			if (isfinite(pl->pix[k]))
				v[n++] = pl->pix[k];
	}
	if (n == 0) {
		free(v);
		return err_set(e, EXIT_INPUT, "%s: no finite pixels to show", what);
	}
	qsort(v, n, sizeof(*v), preview_cmp_float);
	lv->sky = preview_quantile(v, n, 0.5);
	/* The white point: the first of these quantiles that rises above the
	 * sky.  In a noiseless sparse field 99.5 % of pixels may be exactly the
	 * sky, and the stars are all in the last half percent. */
	for (k = 0; k < sizeof(tops) / sizeof(tops[0]); k++) {
		lv->white = preview_quantile(v, n, tops[k]);
		if (lv->white > lv->sky)
			break;
	}
	for (k = 0; k < n; k++)
		v[k] = fabsf(v[k] - (float)lv->sky);
	qsort(v, n, sizeof(*v), preview_cmp_float);
	lv->sigma = 1.4826 * preview_quantile(v, n, 0.5);
	free(v);
	/* In a sparse field the 99.5th percentile is itself noise, and
	 * stretching noise to white hides the stars in snow.  30 sigma keeps
	 * the sky a faint texture (about 0.1 of full scale under asinh, Q 8). */
	if (lv->white < lv->sky + 30 * lv->sigma)
		lv->white = lv->sky + 30 * lv->sigma;

	/* Single band: a noise below the sky is black so the sky shows as a
	 * faint texture and the detector outlines stay visible.  Colour: the
	 * sky itself is black, as Lupton et al. subtract it. */
	lv->lo = o->have_min ? o->vmin : lv->sky - (o->nin == 1 ? lv->sigma : 0);
	lv->hi = o->have_max ? o->vmax : lv->white;
	if (!(lv->hi > lv->lo)) {
		if (o->have_min && o->have_max)
			return err_set(e, EXIT_INPUT, "--max must be above --min");
		/* A flat image: any positive range shows it as flat. */
		if (o->have_max)
			lv->lo = lv->hi - 1;
		else
			lv->hi = lv->lo + (fabs(lv->lo) > 0 ? fabs(lv->lo) : 1);
	}
	if (o->verbose)
		fprintf(stderr, "wfiscene: %s: sky %g, noise %g, white %g; black at %g, white at %g\n",
			what, lv->sky, lv->sigma, lv->white, lv->lo, lv->hi);
	return 0;
}

/*
 * Colour balance.  A composite of three filters is only neutral for a
 * source of flat spectrum if the bands are in the same units, and counts/s
 * are not: a star of one AB magnitude gives different counts through
 * different filters.  When every image of the three files carries its AB
 * zeropoint (PHOTZPAB, the AB magnitude of 1 count/s, which wfiscene writes
 * per SCA), each band is multiplied by 10^(-0.4 (zp - 25)), zp the mean
 * PHOTZPAB of its images: the pixels become fluxes per pixel in units
 * where AB magnitude 25 gives 1 (f_nu in units of 0.3631 uJy), and the
 * three bands share one black-to-white range, so a star of flat f_nu is
 * white and a red one red.  One factor per band, not per SCA: wfiscene's
 * background is a count rate, the same on every SCA, and the SCAs' own
 * zeropoints (a few hundredths of a magnitude apart) would tint the sky of
 * one SCA against the next.
 */
#define PREVIEW_ZP_UNIT 25.0

/* The factor for each band in scale[3] and 1, if every image HDU of the
 * three inputs has a finite PHOTZPAB; else 0.  -1 with an error if a file
 * cannot be read. */
static int preview_balance(const struct preview_opts *o, double *scale,
			   struct err *e)
{
	int *hdu, c, k, n, ok = o->nin == 3;

	if (!ok)
		return 0;
	if (!(hdu = malloc(PREVIEW_MAX_HDU * sizeof(*hdu))))
		return err_sys(e, "preview");
	for (c = 0; c < o->nin && ok; c++) {
		double zp, sum = 0;
		fitsfile *f;

		if (preview_open(o->in[c], &f, e) < 0 ||
		    (n = preview_images(f, o->in[c], hdu, PREVIEW_MAX_HDU, e)) < 0) {
			preview_close(f);
			free(hdu);
			return -1;
		}
		for (k = 0; k < n && ok; k++) {
			int status = 0;

			if (fits_movabs_hdu(f, hdu[k], NULL, &status) ||
			    fits_read_key(f, TDOUBLE, "PHOTZPAB", &zp, NULL, &status) ||
			    !isfinite(zp))
				ok = 0;
			sum += zp;
		}
		fits_clear_errmsg();
		preview_close(f);
		if (ok && n > 0)
			scale[c] = pow(10, -0.4 * (sum / n - PREVIEW_ZP_UNIT));
		else
			ok = 0;
	}
	free(hdu);
	return ok;
}

/* Balanced bands: black at each band's own sky, white one common range
 * above it, the widest of the three bands' own (so no band's noise or
 * crowding is stretched more than it would be alone). */
static void preview_common_levels(struct preview_levels *lv,
				  const struct preview_opts *o)
{
	double range = 0;
	int c;

	for (c = 0; c < 3; c++)
		range = fmax(range, lv[c].white - lv[c].sky);
	for (c = 0; c < 3; c++) {
		if (!o->have_min)
			lv[c].lo = lv[c].sky;
		if (!o->have_max)
			lv[c].hi = lv[c].lo + range;
		if (!(lv[c].hi > lv[c].lo))
			lv[c].hi = lv[c].lo + 1;
		if (o->verbose)
			fprintf(stderr, "wfiscene: %s: balanced by PHOTZPAB: black at %g, "
				"white at %g\n", o->in[c], lv[c].lo, lv[c].hi);
	}
}

/* PNG output ------------------------------------------------------------- */

struct preview_png {
	const struct preview_plane *pl; /* 1 or 3 */
	const struct preview_levels *lv;
	int nband;
	int alpha;                  /* write transparency for NaN (sky mode) */
	int balanced;               /* bands scaled by PHOTZPAB to one unit */
	int stretch;
	double q;
	char msg[256];              /* libpng's error, if any */
};

static double preview_asinh(double t, double q)
{
	return asinh(q * t) / asinh(q);
}

/* One PNG row from the planes. */
static void preview_row(const struct preview_png *p, int y, png_byte *row)
{
	int nx = p->pl[0].nx, x, c, ch = p->nband + p->alpha;

	for (x = 0; x < nx; x++) {
		double t[3], big;
		int valid = 1;

		for (c = 0; c < p->nband; c++) {
			float v = p->pl[c].pix[(size_t)y * nx + x];

			if (!isfinite(v))
				valid = 0;
			t[c] = (v - p->lv[c].lo) / (p->lv[c].hi - p->lv[c].lo);
		}
		if (!valid) {
			for (c = 0; c < ch; c++)
				row[x * ch + c] = 0;
			continue;
		}
		if (p->nband == 1) {
			t[0] = p->stretch == PREVIEW_ASINH ? preview_asinh(t[0], p->q) : t[0];
		} else {
			/* Lupton et al. 2004: stretch the mean intensity I and
			 * scale the bands alike by f(I)/I, then bring the largest
			 * band back to 1 if it overshoots, which keeps the hue. */
			double in = (t[0] + t[1] + t[2]) / 3, g;

			if (in <= 0) {
				g = 0;
			} else if (p->stretch == PREVIEW_ASINH) {
				g = in * p->q < 1e-6 ? p->q / asinh(p->q)
						     : preview_asinh(in, p->q) / in;
			} else {
				g = 1;
			}
			big = 0;
			for (c = 0; c < 3; c++) {
				t[c] = t[c] * g;
				big = fmax(big, t[c]);
			}
			if (big > 1)
				for (c = 0; c < 3; c++)
					t[c] /= big;
		}
		for (c = 0; c < p->nband; c++) {
			double u = t[c] < 0 ? 0 : t[c] > 1 ? 1 : t[c];
			row[x * ch + c] = (png_byte)lrint(255 * u);
		}
		if (p->alpha)
			row[x * ch + p->nband] = 255;
	}
}

static void preview_png_error(png_structp png, png_const_charp msg)
{
	struct preview_png *p = png_get_error_ptr(png);

	snprintf(p->msg, sizeof(p->msg), "%s", msg);
	png_longjmp(png, 1);
}

static void preview_png_warning(png_structp png, png_const_charp msg)
{
	(void)png;
	(void)msg;
}

/*
 * Write the PNG to fp.  libpng reports errors by longjmp to the setjmp
 * below; everything the error path touches is set before setjmp and not
 * changed after, so nothing needs to be volatile.
 */
static int preview_png_write(FILE *fp, struct preview_png *p,
			     const struct preview_opts *o, struct err *e)
{
	png_structp png;
	png_infop info = NULL;
	png_byte *row;
	png_text text[3];
	char comment[384], source[PATH_MAX * 3 + 8];
	int nx = p->pl[0].nx, ny = p->pl[0].ny, y, ch = p->nband + p->alpha;
	int type = p->nband == 1 ? (p->alpha ? PNG_COLOR_TYPE_GRAY_ALPHA : PNG_COLOR_TYPE_GRAY)
				 : (p->alpha ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB);

	row = malloc((size_t)nx * ch);
	if (!row)
		return err_sys(e, "%s", o->out);
	png = png_create_write_struct(PNG_LIBPNG_VER_STRING, p, preview_png_error,
				      preview_png_warning);
	if (png)
		info = png_create_info_struct(png);
	if (!png || !info) {
		png_destroy_write_struct(&png, &info);
		free(row);
		return err_set(e, EXIT_SYSTEM, "%s: out of memory in libpng", o->out);
	}
	if (setjmp(png_jmpbuf(png))) {
		png_destroy_write_struct(&png, &info);
		free(row);
		return err_set(e, EXIT_SYSTEM, "%s: writing PNG: %s", o->out, p->msg);
	}
	png_init_io(png, fp);
	png_set_IHDR(png, info, nx, ny, 8, type, PNG_INTERLACE_NONE,
		     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	snprintf(source, sizeof(source), "%s%s%s%s%s", o->in[0],
		 o->nin == 3 ? " " : "", o->nin == 3 ? o->in[1] : "",
		 o->nin == 3 ? " " : "", o->nin == 3 ? o->in[2] : "");
	if (p->nband == 1)
		snprintf(comment, sizeof(comment), "%s stretch, Q %g; black %g, white %g",
			 p->stretch == PREVIEW_ASINH ? "asinh" : "linear", p->q,
			 p->lv[0].lo, p->lv[0].hi);
	else
		snprintf(comment, sizeof(comment),
			 "Lupton et al. (2004) %s composite, Q %g%s; black %g %g %g, white %g %g %g",
			 p->stretch == PREVIEW_ASINH ? "asinh" : "linear", p->q,
			 p->balanced ? ", bands balanced by PHOTZPAB (1 = AB mag 25)" : "",
			 p->lv[0].lo, p->lv[1].lo, p->lv[2].lo,
			 p->lv[0].hi, p->lv[1].hi, p->lv[2].hi);
	memset(text, 0, sizeof(text));
	text[0].compression = text[1].compression = text[2].compression = PNG_TEXT_COMPRESSION_NONE;
	text[0].key = "Software";
	text[0].text = "wfiscene preview " WFS_VERSION;
	text[1].key = "Source";
	text[1].text = source;
	text[2].key = "Comment";
	text[2].text = comment;
	png_set_text(png, info, text, 3);
	png_write_info(png, info);
	for (y = 0; y < ny; y++) {
		preview_row(p, y, row);
		png_write_row(png, row);
	}
	png_write_end(png, info);
	png_destroy_write_struct(&png, &info);
	free(row);
	return 0;
}

/* Write to a temporary name beside the target and rename when complete
 * (tempfile_open_output), so a failure never leaves a half-written PNG under
 * the requested name; "-", and an existing device or FIFO, in place. */
static int preview_png_save(struct preview_png *p, const struct preview_opts *o,
			    struct err *e)
{
	char tmp[PATH_MAX];
	FILE *fp;
	int fd;

	if (!strcmp(o->out, "-")) {
		if (preview_png_write(stdout, p, o, e) < 0)
			return -1;
		if (fflush(stdout) || ferror(stdout))
			return err_sys(e, "writing PNG to stdout");
		return 0;
	}
	if ((fd = tempfile_open_output(o->out, tmp, sizeof(tmp), e)) < 0)
		return -1;
	if (!(fp = fdopen(fd, "wb"))) {
		err_sys(e, "%s", o->out);
		close(fd);
		goto fail;
	}
	if (preview_png_write(fp, p, o, e) < 0) {
		fclose(fp);
		goto fail;
	}
	if (fflush(fp) || ferror(fp) || (tmp[0] && fsync(fileno(fp)) < 0)) {
		err_sys(e, "%s", o->out);
		fclose(fp);
		goto fail;
	}
	if (fclose(fp)) {
		err_sys(e, "%s", o->out);
		goto fail;
	}
	if (tmp[0] && tempfile_commit(tmp, o->out, e) < 0)
		return -1;
	return 0;
fail:
	tempfile_discard(tmp);
	return -1;
}

/* The whole command ------------------------------------------------------ */

/* Detector mode: the chosen HDU of file c, averaged to width. */
static int preview_detector(const struct preview_opts *o, int c,
			    struct preview_plane *pl, struct err *e)
{
	char where[PATH_MAX + 80];
	fitsfile *f = NULL;
	int *hdu, n, k, rc = -1;
	long nx, ny;

	if (!(hdu = malloc(PREVIEW_MAX_HDU * sizeof(*hdu))))
		return err_sys(e, "preview");
	if (preview_open(o->in[c], &f, e) < 0 ||
	    (n = preview_images(f, o->in[c], hdu, PREVIEW_MAX_HDU, e)) < 0)
		goto done;
	if (n == 0) {
		err_set(e, EXIT_INPUT, "%s: no 2-D image in the file", o->in[c]);
		goto done;
	}
	if (o->sca > 0) {
		if ((k = preview_find_sca(f, o->in[c], hdu, n, o->sca, e)) < 0)
			goto done;
	} else if (n == 1) {
		k = hdu[0];
	} else {
		err_set(e, EXIT_INPUT, "%s: %d images; choose one with --sca N or all with --sca all",
			o->in[c], n);
		goto done;
	}
	if (preview_goto(f, o->in[c], k, where, sizeof(where), &nx, &ny, e) < 0)
		goto done;
	if (nx > INT_MAX / 2 || ny > INT_MAX / 2) {
		err_set(e, EXIT_INPUT, "%s: %ld x %ld is too large", where, nx, ny);
		goto done;
	}
	if (c == 0) {
		int ox = o->width ? o->width : PREVIEW_WIDTH;

		/* Never enlarge; keep the aspect ratio; bound the height. */
		if (ox > nx)
			ox = (int)nx;
		pl->nx = ox;
		pl->ny = (int)fmax(1, floor((double)ny * ox / nx + 0.5));
		if (pl->ny > PREVIEW_MAX_SIDE || pl->ny > ny) {
			pl->ny = (int)(ny < PREVIEW_MAX_SIDE ? ny : PREVIEW_MAX_SIDE);
			pl->nx = (int)fmax(1, fmin(nx, floor((double)nx * pl->ny / ny + 0.5)));
		}
	} else {
		/* The bands of a composite must be pixel for pixel the same
		 * grid; a different size means a different detector. */
		if (nx != pl[-c].src_nx || ny != pl[-c].src_ny) {
			err_set(e, EXIT_INPUT, "%s: %ld x %ld pixels, but %s has %ld x %ld; "
				"use --sca all to align them by WCS", where, nx, ny,
				o->in[0], pl[-c].src_nx, pl[-c].src_ny);
			goto done;
		}
		pl->nx = pl[-c].nx;
		pl->ny = pl[-c].ny;
	}
	pl->src_nx = nx;
	pl->src_ny = ny;
	if (!(pl->pix = malloc((size_t)pl->nx * pl->ny * sizeof(float)))) {
		err_sys(e, "%s", where);
		goto done;
	}
	if (preview_bin(f, where, nx, ny, pl->nx, pl->ny, pl->pix, e) < 0)
		goto done;
	/* FITS row 1 is the bottom of the picture. */
	for (n = 0; n < pl->ny / 2; n++)
		for (k = 0; k < pl->nx; k++) {
			float *a = pl->pix + (size_t)n * pl->nx + k;
			float *b = pl->pix + (size_t)(pl->ny - 1 - n) * pl->nx + k;
			float t = *a;
			*a = *b;
			*b = t;
		}
	rc = 0;
done:
	preview_close(f);
	free(hdu);
	return rc;
}

/* Sky mode: every image HDU of file c drawn on the canvas by its WCS. */
static int preview_sky(const struct preview_opts *o, int c,
		       const struct preview_sky *s, struct preview_plane *pl,
		       struct err *e)
{
	char where[PATH_MAX + 80];
	fitsfile *f = NULL;
	int *hdu, n, k, rc = -1;
	size_t i;

	if (!(hdu = malloc(PREVIEW_MAX_HDU * sizeof(*hdu))))
		return err_sys(e, "preview");
	pl->nx = s->nx;
	pl->ny = s->ny;
	if (!(pl->pix = malloc((size_t)pl->nx * pl->ny * sizeof(float)))) {
		err_sys(e, "%s: %d x %d canvas", o->in[c], pl->nx, pl->ny);
		goto done;
	}
	for (i = 0; i < (size_t)pl->nx * pl->ny; i++)
		pl->pix[i] = NAN;
	if (preview_open(o->in[c], &f, e) < 0 ||
	    (n = preview_sky_hdus(f, o->in[c], hdu, e)) < 0)
		goto done;
	for (k = 0; k < n; k++) {
		long nx, ny;

		if (preview_goto(f, o->in[c], hdu[k], where, sizeof(where), &nx, &ny, e) < 0 ||
		    preview_sky_draw(f, where, nx, ny, s, pl, e) < 0)
			goto done;
		if (o->verbose > 1)
			fprintf(stderr, "wfiscene: %s: drawn\n", where);
	}
	rc = 0;
done:
	preview_close(f);
	free(hdu);
	return rc;
}

static int preview_run(const struct preview_opts *o, struct err *e)
{
	struct preview_plane pl[3];
	struct preview_levels lv[3];
	struct preview_png png;
	struct preview_sky sky;
	double scale[3];
	int sky_mode = o->sca == -1, balance, c, rc = -1;
	size_t i;

	memset(pl, 0, sizeof(pl));
	if (o->sca == 0) {
		/* No --sca: the only image in detector mode, else all of them. */
		int *hdu = malloc(PREVIEW_MAX_HDU * sizeof(*hdu)), n;
		fitsfile *f;

		if (!hdu)
			return err_sys(e, "preview");
		if (preview_open(o->in[0], &f, e) < 0) {
			free(hdu);
			return -1;
		}
		n = preview_images(f, o->in[0], hdu, PREVIEW_MAX_HDU, e);
		preview_close(f);
		free(hdu);
		if (n < 0)
			return -1;
		if (n == 0)
			return err_set(e, EXIT_INPUT, "%s: no 2-D image in the file", o->in[0]);
		sky_mode = n > 1;
	}
	if ((balance = preview_balance(o, scale, e)) < 0)
		return -1;
	if (o->nin == 3 && !balance && o->verbose)
		fprintf(stderr, "wfiscene: not every image has PHOTZPAB: each band is "
			"scaled to its own white point\n");
	if (sky_mode && preview_sky_layout(o, o->width ? o->width : PREVIEW_WIDTH,
					   &sky, e) < 0)
		return -1;
	if (sky_mode && o->verbose)
		fprintf(stderr, "wfiscene: canvas %d x %d, %.4g arcsec per pixel, centre %.6f %+.6f\n",
			sky.nx, sky.ny, sky.step * 180 / M_PI * 3600,
			fmod(sky.ra0 * 180 / M_PI + 360, 360), sky.dec0 * 180 / M_PI);
	for (c = 0; c < o->nin; c++) {
		if (sky_mode ? preview_sky(o, c, &sky, &pl[c], e) < 0
			     : preview_detector(o, c, &pl[c], e) < 0)
			goto done;
		for (i = 0; balance && i < (size_t)pl[c].nx * pl[c].ny; i++)
			pl[c].pix[i] *= scale[c];
		if (preview_levels(&pl[c], o->in[c], o, &lv[c], e) < 0)
			goto done;
	}
	if (balance)
		preview_common_levels(lv, o);
	memset(&png, 0, sizeof(png));
	png.pl = pl;
	png.lv = lv;
	png.nband = o->nin;
	png.alpha = sky_mode;
	png.balanced = balance;
	png.stretch = o->stretch;
	png.q = o->q;
	rc = preview_png_save(&png, o, e);
done:
	for (c = 0; c < 3; c++)
		free(pl[c].pix);
	return rc;
}

int preview_main(int argc, char **argv)
{
	struct preview_opts o;
	struct err e = { EXIT_OK, "" };
	int rc;

	rc = preview_parse(argc, argv, &o, &e);
	if (rc == 1)
		return EXIT_OK;
	if (rc == -2)
		return e.code;
	if (rc == 0)
		rc = preview_run(&o, &e);
	if (rc < 0) {
		fprintf(stderr, "wfiscene: preview: %s\n", e.msg);
		return e.code != EXIT_OK ? e.code : EXIT_SYSTEM;
	}
	return EXIT_OK;
}
