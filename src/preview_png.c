/*
 * preview_png.c - the picture of `wfiscene preview` made visible: levels
 * from the averaged image (sky, noise, white point), the colour balance of
 * a three-band composite by PHOTZPAB, the asinh or linear stretch (Lupton et
 * al. 2004 for colour), and the PNG written atomically (see preview.c for
 * the method, preview.h for the API).
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <fitsio.h>
#include <png.h>

#include "err.h"
#include "preview.h"
#include "tempfile.h"

#ifndef WFS_VERSION
#define WFS_VERSION "unknown"
#endif

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

int preview_levels(const struct preview_plane *pl, const char *what,
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
int preview_balance(const struct preview_opts *o, double *scale,
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
void preview_common_levels(struct preview_levels *lv,
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
int preview_png_save(struct preview_png *p, const struct preview_opts *o,
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

