/*
 * preview.c - wfiscene preview: look at a simulated exposure as a PNG.
 * This file is the command; preview_fits.c reads and places the images,
 * preview_png.c sets the levels and writes the PNG (see preview.h).
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
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <fitsio.h>

#include "commands.h"
#include "err.h"
#include "names.h"
#include "options.h"
#include "preview.h"


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

