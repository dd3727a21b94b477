/*
 * preview_fits.c - the images of `wfiscene preview` read from FITS: image
 * HDUs found and named, a detector averaged down to the output size in row
 * blocks, and in sky mode every SCA placed on one tangent-plane canvas
 * through its own WCS (see preview.c for the method, preview.h for the API).
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include <fitsio.h>
#include <wcshdr.h>
#include <wcs.h>

#include "err.h"
#include "preview.h"

int preview_open(const char *path, fitsfile **f, struct err *e)
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

void preview_close(fitsfile *f)
{
	int status = 0;

	if (f)
		fits_close_file(f, &status);
}

/* Image HDUs (2-D, non-empty; tile-compressed ones count) of an open file,
 * as 1-based HDU numbers.  Returns how many, or -1. */
int preview_images(fitsfile *f, const char *path, int *hdu, int max,
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
int preview_goto(fitsfile *f, const char *path, int k, char *where,
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
int preview_find_sca(fitsfile *f, const char *path, const int *hdu,
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
int preview_bin(fitsfile *f, const char *where, long nx, long ny,
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
	int nkeys = 0, nreject = 0, status = 0, k = 0;

	*nwcs = 0;
	if (fits_convert_hdr2str(f, 0, NULL, 0, &hdr, &nkeys, &status)) {
		err_fits(e, status, "%s: header", where);
		return NULL;
	}
	status = wcspih(hdr, nkeys, WCSHDR_all, 0, &nreject, nwcs, &wcs);
	fits_free_memory(hdr, &k);	/* frees only while k holds no error */
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
int preview_sky_hdus(fitsfile *f, const char *path, int *hdu,
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
int preview_sky_layout(const struct preview_opts *o, int width,
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
int preview_sky_draw(fitsfile *f, const char *where, long nx, long ny,
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

