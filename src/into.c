/*
 * into.c - injection into an existing image (--into); see into.h.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <sys/stat.h>

#include <fitsio.h>
#include <wcslib/wcs.h>
#include <wcslib/wcshdr.h>

#include "err.h"
#include "instrument.h"
#include "into.h"
#include "into_asdf.h"
#include "scene.h"
#include "sky.h"
#include "tempfile.h"

struct into_hdu {
	int sca;                /* 1..18 */
	int hdu;                /* cfitsio HDU number, 1 = primary */
	long nx, ny;
	struct wcsprm wcs;      /* the image's celestial WCS, set */
	double ra, dec, pa;     /* centre and position angle of +y there */
	char filter[FLEN_VALUE];/* FILTER, its own or the primary's; "" none */
	char bunit[FLEN_VALUE]; /* BUNIT, the same way */
};

struct into {
	char *path;             /* the file, without an [HDU] suffix */
	char *spec;             /* as given, for messages */
	struct into_hdu h[WFS_NSCA];
	int nh;
	int has_pointing;       /* the primary header gave one */
	struct into_asdf *asdf; /* a Roman level-2 ASDF file (into_asdf.h) */
	double ra, dec, pa;
	int boresight;
	char filter0[FLEN_VALUE];       /* the primary header's FILTER and */
	char bunit0[FLEN_VALUE];        /* BUNIT, for HDUs without their own */
};

/* The SCA of an HDU name or DETECTOR value "WFInn" (1 to 18), else 0. */
static int wfi_number(const char *name)
{
	int s;

	if (strlen(name) != 5 || strncasecmp(name, "WFI", 3) ||
	    !isdigit((unsigned char)name[3]) || !isdigit((unsigned char)name[4]))
		return 0;
	s = atoi(name + 3);
	return s >= 1 && s <= WFS_NSCA ? s : 0;
}

/* String keyword key of the current HDU into v ("" when it has none). */
static void read_str(fitsfile *f, const char *key, char *v)
{
	int status = 0;

	if (fits_read_key(f, TSTRING, key, v, NULL, &status)) {
		v[0] = '\0';
		fits_clear_errmsg();
	}
}

/* Split "file[hdu]" into the file and the HDU text (NULL when none). */
static int split_spec(struct into *in, const char *spec, char **hdu, struct err *e)
{
	size_t n = strlen(spec);
	const char *lb = strrchr(spec, '[');

	*hdu = NULL;
	if (n > 2 && spec[n - 1] == ']' && lb && lb > spec) {
		in->path = strndup(spec, (size_t)(lb - spec));
		*hdu = strndup(lb + 1, (size_t)(spec + n - 1 - lb - 1));
		if (!in->path || !*hdu)
			return err_set(e, EXIT_SYSTEM, "out of memory");
		return 0;
	}
	if (!(in->path = strdup(spec)))
		return err_set(e, EXIT_SYSTEM, "out of memory");
	return 0;
}

/* Centre and +y position angle of a set-up WCS for an nx x ny image. */
static int centre_of(struct into_hdu *h, const char *where, struct err *e)
{
	double pix[2][2] = { { (h->nx + 1) / 2.0, (h->ny + 1) / 2.0 } }, img[2][2], world[2][2];
	double phi[2], theta[2], dx, dy, step;
	int stat[2], status;

	if ((status = wcsp2s(&h->wcs, 1, 2, pix[0], img[0], phi, theta, world[0], stat)) ||
	    stat[0])
		return err_set(e, EXIT_INPUT, "%s: the image's centre has no sky position (wcslib: %s)",
			       where, status ? wcs_errmsg[status] : "bad pixel");
	h->ra = world[0][h->wcs.lng];
	h->dec = world[0][h->wcs.lat];
	/* a step toward the pole, whose direction gives north's */
	step = h->dec > 89 ? -1e-4 : 1e-4;
	world[1][h->wcs.lng] = h->ra;
	world[1][h->wcs.lat] = h->dec + step;
	if ((status = wcss2p(&h->wcs, 1, 2, world[1], phi, theta, img[1], pix[1], stat)) ||
	    stat[0])
		return err_set(e, EXIT_INPUT, "%s: no position angle at the image's centre", where);
	dx = (pix[1][0] - pix[0][0]) * (step > 0 ? 1 : -1);
	dy = (pix[1][1] - pix[0][1]) * (step > 0 ? 1 : -1);
	h->pa = atan2(dx, dy) * (180.0 / M_PI);
	return 0;
}

/* Read HDU hdu's size and celestial WCS into h. */
static int read_hdu(struct into *in, fitsfile *f, int hdu, int sca,
		    struct err *e)
{
	struct into_hdu *h = &in->h[in->nh];
	char where[4200], *hdr = NULL;
	int status = 0, naxis = 0, nkeys = 0, nreject = 0, nwcs = 0, type, rc = -1;
	long nax[2] = { 0, 0 };
	struct wcsprm *w = NULL;

	snprintf(where, sizeof(where), "%s[%d]", in->path, hdu - 1);
	if (fits_movabs_hdu(f, hdu, &type, &status) ||
	    fits_get_img_dim(f, &naxis, &status))
		return err_fits(e, status, "%s", where);
	if (type != IMAGE_HDU || naxis != 2)
		return err_set(e, EXIT_INPUT, "%s: not a two-dimensional image", where);
	if (fits_get_img_size(f, 2, nax, &status))
		return err_fits(e, status, "%s", where);
	/* The PSF, zeropoint and pixel response are the SCA's the HDU stands
	 * for: an HDU that names another SCA (EXTNAME or DETECTOR WFInn) is
	 * not drawn with --sca's, as an ASDF image of another SCA is not */
	for (int k = 0; k < 2; k++) {
		static const char *const key[2] = { "EXTNAME", "DETECTOR" };
		char v[FLEN_VALUE];
		int s;

		read_str(f, key[k], v);
		if ((s = wfi_number(v)) && s != sca)
			return err_set(e, EXIT_INPUT, "%s holds WFI%02d: give --sca %d (and that "
				       "SCA only)", where, s, s);
	}
	read_str(f, "FILTER", h->filter);
	read_str(f, "BUNIT", h->bunit);
	if (!h->filter[0])
		snprintf(h->filter, sizeof(h->filter), "%s", in->filter0);
	if (!h->bunit[0])
		snprintf(h->bunit, sizeof(h->bunit), "%s", in->bunit0);
	if (nax[0] > WFS_NPIX || nax[1] > WFS_NPIX)
		return err_set(e, EXIT_INPUT, "%s: %ld x %ld pixels, larger than an SCA (%d x %d)",
			       where, nax[0], nax[1], WFS_NPIX, WFS_NPIX);
	if (fits_hdr2str(f, 1, NULL, 0, &hdr, &nkeys, &status))
		return err_fits(e, status, "%s: header", where);
	if ((status = wcspih(hdr, nkeys, WCSHDR_all, 0, &nreject, &nwcs, &w)) || !nwcs) {
		err_set(e, EXIT_INPUT, "%s: no WCS in the header%s%s", where,
			status ? ": wcslib: " : "", status ? wcs_errmsg[status] : "");
		goto out;
	}
	h->wcs.flag = -1;
	if ((status = wcssub(1, &w[0], NULL, NULL, &h->wcs)) || (status = wcsset(&h->wcs))) {
		err_set(e, EXIT_INPUT, "%s: WCS: wcslib: %s", where, wcs_errmsg[status]);
		goto out;
	}
	h->sca = sca;
	h->hdu = hdu;
	h->nx = nax[0];
	h->ny = nax[1];
	in->nh++;
	if (h->wcs.lng < 0 || h->wcs.lat < 0) {
		err_set(e, EXIT_INPUT, "%s: the WCS is not celestial (CTYPE '%s', '%s')", where,
			h->wcs.ctype[0], h->wcs.ctype[1]);
		goto out;
	}
	rc = centre_of(h, where, e);
out:
	if (w)
		wcsvfree(&nwcs, &w);
	free(hdr);
	return rc;
}

/* The primary header's pointing (a wfiscene image), if it has one, and
 * its FILTER and BUNIT. */
static void read_pointing(struct into *in, fitsfile *f)
{
	int status = 0, type;
	char ref[FLEN_VALUE] = "";

	if (fits_movabs_hdu(f, 1, &type, &status)) {
		fits_clear_errmsg();
		return;
	}
	read_str(f, "FILTER", in->filter0);
	read_str(f, "BUNIT", in->bunit0);
	if (fits_read_key(f, TDOUBLE, "RA_TARG", &in->ra, NULL, &status) ||
	    fits_read_key(f, TDOUBLE, "DEC_TARG", &in->dec, NULL, &status) ||
	    fits_read_key(f, TDOUBLE, "PA_APER", &in->pa, NULL, &status)) {
		fits_clear_errmsg();
		return;
	}
	if (fits_read_key(f, TSTRING, "POINTREF", ref, NULL, &status))
		fits_clear_errmsg();
	in->boresight = !strcasecmp(ref, "BORESIGHT");
	in->has_pointing = 1;
}

/* cfitsio's failure on the target: exit 1 when the file could be read
 * (what it holds is at fault), else cfitsio's own status.  -1. */
static int unreadable(const struct into *in, int status, struct err *e)
{
	err_fits(e, status, "--into %s", in->path);
	if (e->code != EXIT_OK && access(in->path, R_OK) == 0)
		e->code = EXIT_INPUT;
	return -1;
}

/*
 * A target cut short (a copy or a download that stopped) is bad input
 * (exit 1), said so before anything is drawn or written, as a catalog's
 * is (table_fits.c), naming the target and where it ends: not a read
 * error from the copy at the end (into_compose) naming the output, nor
 * "no image HDU" for an HDU whose header was cut.  open_failed covers a
 * cut inside the primary header (or no file at all), check_whole the
 * rest.
 *
 * cfitsio could not open the file.  One that begins as FITS does and
 * ends inside its primary header is cut short; a plain file that does
 * not begin so is no FITS file (a compressed one, which cfitsio opens
 * itself, is left to its message).  Exit 1 for what the file holds, 2
 * for one that cannot be read.
 */
static int open_failed(struct into *in, int status, struct err *e)
{
	static const char simple[] = "SIMPLE  =";
	char head[sizeof(simple) - 1];
	struct stat st;
	size_t n = 0;
	FILE *fp;
	int known = stat(in->path, &st) == 0;

	if (known && S_ISDIR(st.st_mode))
		return err_set(e, EXIT_INPUT, "%s: a directory, not a FITS file", in->path);
	if (known && S_ISREG(st.st_mode) && (fp = fopen(in->path, "rb"))) {
		n = fread(head, 1, sizeof(head), fp);
		fclose(fp);
		if (st.st_size == 0)
			return err_set(e, EXIT_INPUT, "%s: truncated FITS file: it is empty "
				       "(0 bytes)", in->path);
		if (n > 0 && !memcmp(head, simple, n) &&
		    (status == END_OF_FILE || status == READ_ERROR))
			return err_set(e, EXIT_INPUT, "%s: truncated FITS file: it ends inside "
				       "its primary header (%lld bytes)", in->path,
				       (long long)st.st_size);
		/* gzip, compress, pack; zip; bzip2 */
		if (n > 0 && memcmp(head, simple, n) && (unsigned char)head[0] != 0x1f &&
		    !(n >= 2 && !memcmp(head, "PK", 2)) && !(n >= 3 && !memcmp(head, "BZh", 3)))
			return err_set(e, EXIT_INPUT, "%s: not a FITS file: it does not begin "
				       "with 'SIMPLE  ='", in->path);
	}
	return unreadable(in, status, e);
}

/* "HDU k 'EXTNAME'" (k 0-based, as in IMAGE[N]) of the current HDU. */
static void hdu_label(fitsfile *f, int hdu, char *buf, size_t size)
{
	char name[FLEN_VALUE];

	read_str(f, "EXTNAME", name);
	if (name[0])
		snprintf(buf, size, "HDU %d '%s'", hdu - 1, name);
	else
		snprintf(buf, size, "HDU %d", hdu - 1);
}

/*
 * The file opened: cfitsio counts an HDU once its header is whole, so a
 * cut lies in the data (or the padding) of the last HDU it counts, or
 * after it, in the next HDU's header.  The length is cfitsio's own
 * (logfilesize of fitsio.h's FITSfile: the file's size when it was
 * opened, or the decompressed size of a compressed one, which cfitsio
 * reads into memory).  0, or -1 (exit 1).
 */
static int check_whole(struct into *in, fitsfile *f, int nhdu, struct err *e)
{
	LONGLONG head, data, end, size = f->Fptr->logfilesize, extra;
	long long naxis = 0, bitpix = 0, w = 0, h = 0;
	char label[FLEN_VALUE + 16], tail[8], where[64];
	int status = 0, type;

	if (fits_movabs_hdu(f, nhdu, &type, &status) ||
	    fits_get_hduaddrll(f, &head, &data, &end, &status))
		return err_fits(e, status, "%s[%d]", in->path, nhdu - 1);
	hdu_label(f, nhdu, label, sizeof(label));
	if (end > size) {
		/* the row it ends in, for a two-dimensional image or table */
		fits_read_key(f, TLONGLONG, "NAXIS", &naxis, NULL, &status);
		fits_read_key(f, TLONGLONG, "BITPIX", &bitpix, NULL, &status);
		fits_read_key(f, TLONGLONG, "NAXIS1", &w, NULL, &status);
		fits_read_key(f, TLONGLONG, "NAXIS2", &h, NULL, &status);
		fits_clear_errmsg();
		w *= llabs(bitpix) / 8;
		if (size <= data)
			snprintf(where, sizeof(where), "before its data");
		else if (status || naxis != 2 || w <= 0 || h <= 0)
			snprintf(where, sizeof(where), "in its data");
		else if ((size - data) / w < h)
			snprintf(where, sizeof(where), "in row %lld of %lld",
				 (long long)((size - data) / w + 1), h);
		else
			snprintf(where, sizeof(where), "after its %lld rows", h);
		return err_set(e, EXIT_INPUT, "%s: truncated FITS file: %s needs %lld bytes, "
			       "the file has %lld: it ends %s", in->path, label, (long long)end,
			       (long long)size, where);
	}
	if ((extra = size - end) == 0)
		return 0;
	/*
	 * Bytes after the last HDU.  into_compose's copy (fits_copy_file)
	 * reads on from there as cfitsio's own count of HDUs did: it stops
	 * cleanly at a 2880-byte block beginning with a zero or a newline
	 * (or at one such byte alone, an editor's end-of-file mark), and
	 * fails on anything else.  The first bytes say which: cfitsio's
	 * buffer holds them even when the block is short; should it not,
	 * they are damage all the same.
	 */
	if (fits_read_ext(f, end - data, extra < 8 ? extra : 8, tail, &status)) {
		fits_clear_errmsg();
		memset(tail, 0x7f, sizeof(tail));
	}
	if (!memcmp(tail, "XTENSION", extra < 8 ? (size_t)extra : 8))
		return err_set(e, EXIT_INPUT, "%s: truncated FITS file: the header of HDU %d "
			       "ends at byte %lld, incomplete", in->path, nhdu, (long long)size);
	if ((extra == 1 && (tail[0] == 0 || tail[0] == '\n' || tail[0] == ' ')) ||
	    (extra >= 2880 && (tail[0] == 0 || tail[0] == '\n')))
		return 0;
	return err_set(e, EXIT_INPUT, "%s: damaged FITS file: the %lld byte%s after its last "
		       "HDU (%s, from byte %lld) %s not an HDU", in->path, (long long)extra,
		       extra == 1 ? "" : "s", label, (long long)end, extra == 1 ? "is" : "are");
}

/* Without an HDU in --into: the HDU named WFInn for each SCA of mask;
 * else the file's only image, for a scene of one SCA.  0, or -1 with e
 * set. */
static int read_by_name(struct into *in, fitsfile *f, int nhdu, unsigned mask, int nscas,
			const char *spec, struct err *e)
{
	int found[WFS_NSCA + 1] = { 0 }, images = 0, last = 0, status = 0;

	for (int k = 1; k <= nhdu; k++) {
		char name[FLEN_VALUE] = "";
		int type, naxis = 0, s;

		if (fits_movabs_hdu(f, k, &type, &status)) {
			err_fits(e, status, "--into %s", in->path);
			return -1;
		}
		if (type != IMAGE_HDU)
			continue;
		fits_get_img_dim(f, &naxis, &status);
		if (naxis == 2)
			images++, last = k;
		if (fits_read_key(f, TSTRING, "EXTNAME", name, NULL, &status)) {
			status = 0;
			fits_clear_errmsg();
			continue;
		}
		if ((s = wfi_number(name)) && !found[s])
			found[s] = k;
	}
	for (int s = 1; s <= WFS_NSCA; s++) {
		if (!(mask & (1u << (s - 1))))
			continue;
		if (found[s]) {
			if (read_hdu(in, f, found[s], s, e) < 0)
				return -1;
		} else if (nscas == 1 && images == 1) {
			if (read_hdu(in, f, last, s, e) < 0)
				return -1;
		} else {
			err_set(e, EXIT_INPUT, "--into %s: no image HDU 'WFI%02d' for SCA %d "
				"(name one HDU with %s[N] for a scene of one SCA)",
				spec, s, s, in->path);
			return -1;
		}
	}
	return 0;
}

struct into *into_open(const char *spec, unsigned mask, struct err *e)
{
	struct into *in = calloc(1, sizeof(*in));
	fitsfile *f = NULL;
	char *hdu = NULL;
	int status = 0, nhdu = 0, nscas = 0, one = 0;

	if (!in || !(in->spec = strdup(spec))) {
		err_set(e, EXIT_SYSTEM, "out of memory");
		goto fail;
	}
	for (int s = 1; s <= WFS_NSCA; s++)
		if (mask & (1u << (s - 1))) {
			nscas++;
			one = s;
		}
	if (split_spec(in, spec, &hdu, e) < 0)
		goto fail;
	if (!hdu && into_is_asdf(in->path)) {
		/* the SCAs keep the SIAF geometry, pointed by the file's meta */
		if (!(in->asdf = into_asdf_open(in->path, mask, e)))
			goto fail;
		into_asdf_pointing(in->asdf, &in->ra, &in->dec, &in->pa);
		in->boresight = 0;
		in->has_pointing = 1;
		return in;
	}
	if (fits_open_diskfile(&f, in->path, READONLY, &status)) {
		open_failed(in, status, e);
		goto fail;
	}
	if (fits_get_num_hdus(f, &nhdu, &status)) {
		unreadable(in, status, e);
		goto fail;
	}
	if (check_whole(in, f, nhdu, e) < 0)
		goto fail;
	read_pointing(in, f);
	if (hdu) {
		/* IMAGE[N] (0 the primary) or IMAGE[EXTNAME]: the scene's one SCA */
		char *end;
		long n = strtol(hdu, &end, 10);
		int type;

		if (nscas != 1) {
			err_set(e, EXIT_INPUT, "--into %s: one HDU stands for one SCA; the scene has %d",
				spec, nscas);
			goto fail;
		}
		if (*end || end == hdu) {
			if (fits_movnam_hdu(f, IMAGE_HDU, hdu, 0, &status)) {
				err_set(e, EXIT_INPUT, "--into %s: no image HDU named '%s'", spec, hdu);
				fits_clear_errmsg();
				goto fail;
			}
			fits_get_hdu_num(f, &type);
			n = type - 1;
		}
		if (n < 0 || n >= nhdu) {
			err_set(e, EXIT_INPUT, "--into %s: HDU %ld: the file has HDUs 0 to %d",
				spec, n, nhdu - 1);
			goto fail;
		}
		if (read_hdu(in, f, (int)n + 1, one, e) < 0)
			goto fail;
	} else if (read_by_name(in, f, nhdu, mask, nscas, spec, e) < 0) {
		goto fail;
	}
	fits_close_file(f, &status);
	free(hdu);
	if (!in->has_pointing) {
		in->ra = in->h[0].ra;
		in->dec = in->h[0].dec;
		in->pa = in->h[0].pa;
		in->boresight = 0;
	}
	return in;
fail:
	if (f) {
		status = 0;
		fits_close_file(f, &status);
	}
	free(hdu);
	into_free(in);
	return NULL;
}

void into_pointing(const struct into *in, double *ra, double *dec, double *pa,
		   int *boresight)
{
	*ra = in->ra;
	*dec = in->dec;
	*pa = in->pa;
	*boresight = in->boresight;
}

void into_catalogs(struct into *in, char *const *catalogs)
{
	if (in->asdf)
		into_asdf_catalogs(in->asdf, catalogs);
}

/*
 * The light is drawn in the run's filter and unit and added as it is: an
 * image of another filter (its FILTER, or an ASDF image's
 * meta.instrument.optical_element, naming another of wfiscene's filters)
 * or another of wfiscene's units (BUNIT 'counts/s' or 'counts') is
 * refused.  An image without them, or with a filter or unit wfiscene does
 * not write, is taken as it is.
 */
static int check_light(const struct into *in, const struct scene_opts *o, struct err *e)
{
	const char *want_filter = filter_get(o->filter)->name;
	const char *want_unit = o->bunit_counts ? "counts" : "counts/s";

	if (in->asdf) {
		const char *f = into_asdf_filter(in->asdf);

		if (f && filter_lookup(f) >= 0 && filter_lookup(f) != o->filter)
			return err_set(e, EXIT_INPUT, "%s is in %s (meta.instrument.optical_element): "
				       "give --filter %s, not %s", in->path, f, f, want_filter);
		return 0;
	}
	for (int k = 0; k < in->nh; k++) {
		const struct into_hdu *h = &in->h[k];

		if (filter_lookup(h->filter) >= 0 && filter_lookup(h->filter) != o->filter)
			return err_set(e, EXIT_INPUT, "%s[%d] is in %s (FILTER): give --filter %s, "
				       "not %s", in->path, h->hdu - 1, h->filter, h->filter,
				       want_filter);
		if ((!strcasecmp(h->bunit, "counts/s") || !strcasecmp(h->bunit, "counts")) &&
		    strcasecmp(h->bunit, want_unit))
			return err_set(e, EXIT_INPUT, "%s[%d] is in %s (BUNIT): give --bunit %s, "
				       "not %s", in->path, h->hdu - 1, h->bunit, h->bunit, want_unit);
	}
	return 0;
}

int into_apply(const struct into *in, struct sky *sky, const struct scene_opts *o,
	       struct err *e)
{
	if (check_light(in, o, e) < 0)
		return -1;
	if (in->asdf)
		return into_asdf_apply(in->asdf, sky, e);
	for (int k = 0; k < in->nh; k++) {
		const struct into_hdu *h = &in->h[k];
		struct sky_sca *ss = &sky->sca[h->sca - 1];
		double cx, cy, far = 0;
		/* corners and edge midpoints, 1-based pixels */
		double px[8] = { 0.5, h->nx + 0.5, 0.5, h->nx + 0.5, 0.5, h->nx + 0.5,
				 (h->nx + 1) / 2.0, (h->nx + 1) / 2.0 };
		double py[8] = { 0.5, 0.5, h->ny + 0.5, h->ny + 0.5, (h->ny + 1) / 2.0,
				 (h->ny + 1) / 2.0, 0.5, h->ny + 0.5 };
		int status;

		/* The SCA takes the image's own WCS, through wcslib (the geometry
		 * kind that maps by a wcsprm, whatever the image's projection) */
		geom_sca_free(&ss->geo);
		ss->geo.kind = GEOM_STIPS;
		ss->geo.wcs.flag = -1;
		ss->geo.have_wcs = 1;
		if ((status = wcssub(1, &h->wcs, NULL, NULL, &ss->geo.wcs)) ||
		    (status = wcsset(&ss->geo.wcs)))
			return err_set(e, EXIT_SYSTEM, "--into %s: wcslib: %s", in->spec,
				       wcs_errmsg[status]);
		ss->ra = h->ra;
		ss->dec = h->dec;
		ss->pa = h->pa;
		sky_to_focal(sky, 1, &h->ra, &h->dec, INFINITY, &cx, &cy);
		if (!isfinite(cx) || !isfinite(cy))
			return err_set(e, EXIT_INPUT, "--into %s[%d]: the image is far from the "
				       "pointing", in->path, h->hdu - 1);
		ss->fx = cx;
		ss->fy = cy;
		/* The engine culls rows outside a square of an SCA's size about
		 * the centre in the focal plane: the image must fit in it. */
		for (int c = 0; c < 8; c++) {
			double pix[2] = { px[c], py[c] }, img[2], world[2], phi, theta, fx, fy;
			int stat;

			if (wcsp2s(&ss->geo.wcs, 1, 2, pix, img, &phi, &theta, world, &stat) || stat)
				return err_set(e, EXIT_INPUT, "--into %s[%d]: a corner of the image "
					       "has no sky position", in->path, h->hdu - 1);
			sky_to_focal(sky, 1, &world[ss->geo.wcs.lng], &world[ss->geo.wcs.lat], INFINITY,
				     &fx, &fy);
			far = fmax(far, fmax(fabs(fx - cx), fabs(fy - cy)));
		}
		/* An SCA of the SIAF geometry reaches up to ~231": allow 10 % over
		 * the 0.11" square, and cull with the image's own extent. */
		if (!(far <= SKY_SCA_HALF * 1.1))
			return err_set(e, EXIT_INPUT, "--into %s[%d]: the image reaches %.1f arcsec "
				       "from its centre along the detector axes, more than an SCA's "
				       "%.1f", in->path, h->hdu - 1, far, SKY_SCA_HALF * 1.1);
		ss->half = fmax(SKY_SCA_HALF, far + 1.0);
	}
	return 0;
}

/* Checksums are brought up to date where the image had them. */
static int had_checksum(fitsfile *f)
{
	char v[FLEN_VALUE];
	int status = 0;

	if (fits_read_key(f, TSTRING, "CHECKSUM", v, NULL, &status)) {
		fits_clear_errmsg();
		return 0;
	}
	return 1;
}

int into_check_output(const struct into *in, const char *path, struct err *e)
{
	struct stat a, b;

	/* lstat: an output that is a symbolic link is replaced itself (the
	 * output is renamed over its name), not the file it points to */
	if (stat(in->path, &a) == 0 && lstat(path, &b) == 0 && a.st_dev == b.st_dev &&
	    a.st_ino == b.st_ino)
		return err_set(e, EXIT_INPUT, "--into %s and -o %s are the same file: the "
			       "scene would replace the image before it is read; write "
			       "the result to another name", in->spec, path);
	return 0;
}

int into_compose(const struct into *in, const char *path, int asdf_compression,
		 struct pool *pool, struct err *e)
{
	fitsfile *src = NULL, *out = NULL;
	char tmp[4200];
	double *a = NULL, *b = NULL;
	int status = 0, fd, rc = -1;
	struct stat sb;

	if (in->asdf) {
		rc = into_asdf_compose(in->asdf, path, asdf_compression, pool, e);
		/* as below: a failed run leaves nothing under the name */
		if (rc < 0 && stat(path, &sb) == 0 && S_ISREG(sb.st_mode))
			unlink(path);
		return rc;
	}

	/* The registered temporary (tempfile.h) proved the name free; cfitsio
	 * creates the file itself, taking the name literally
	 * (fits_create_diskfile: no "[ext]" or "!" parsing of a user's path). */
	if ((fd = tempfile_beside(path, tmp, sizeof(tmp), e)) < 0)
		goto out;
	close(fd);
	unlink(tmp);
	if (fits_open_diskfile(&src, in->path, READONLY, &status) ||
	    fits_create_diskfile(&out, tmp, &status) ||
	    fits_copy_file(src, out, 1, 1, 1, &status)) {
		err_fits(e, status, "--into %s: %s", in->spec, path);
		goto out;
	}
	for (int k = 0; k < in->nh; k++) {
		const struct into_hdu *h = &in->h[k];
		size_t n = (size_t)h->nx * (size_t)h->ny;
		long fp[2] = { 1, 1 };
		char hist[80];
		int type, any;

		if (!(a = malloc(n * sizeof(double))) || !(b = malloc(n * sizeof(double)))) {
			err_set(e, EXIT_SYSTEM, "out of memory");
			goto out;
		}
		if (into_scene(path, h->sca, h->nx, h->ny, a, NULL, NULL, 0, e) < 0)
			goto out;
		if (fits_movabs_hdu(out, h->hdu, &type, &status) ||
		    fits_read_pix(out, TDOUBLE, fp, (LONGLONG)n, NULL, b, &any, &status)) {
			err_fits(e, status, "--into %s[%d]", in->path, h->hdu - 1);
			goto out;
		}
		for (size_t i = 0; i < n; i++)
			b[i] += a[i];
		snprintf(hist, sizeof(hist), "wfiscene %s: sources added to these pixels "
			 "(SCA %d)", WFS_VERSION, h->sca);
		if (fits_write_pix(out, TDOUBLE, fp, (LONGLONG)n, b, &status) ||
		    fits_write_history(out, hist, &status) ||
		    (had_checksum(out) && fits_write_chksum(out, &status))) {
			err_fits(e, status, "%s: HDU %d", path, h->hdu - 1);
			goto out;
		}
		free(a);
		free(b);
		a = b = NULL;
	}
	fits_close_file(out, &status);
	out = NULL;
	if (status) {
		err_fits(e, status, "%s", tmp);
		goto out;
	}
	if (tempfile_commit(tmp, path, e) < 0)
		goto out;
	rc = 0;
out:
	status = 0;
	if (out)
		fits_close_file(out, &status);
	status = 0;
	if (src)
		fits_close_file(src, &status);
	tempfile_discard(tmp);
	/* The run failed: what lies under path is the scene without the
	 * image it was to be added to, so it goes too (a failed run leaves
	 * nothing under the requested name). */
	if (rc < 0 && stat(path, &sb) == 0 && S_ISREG(sb.st_mode))
		unlink(path);
	free(a);
	free(b);
	return rc;
}

void into_free(struct into *in)
{
	if (!in)
		return;
	for (int k = 0; k < in->nh; k++)
		wcsfree(&in->h[k].wcs);
	into_asdf_free(in->asdf);
	free(in->path);
	free(in->spec);
	free(in);
}
