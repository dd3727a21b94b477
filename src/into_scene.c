/*
 * into_scene.c - the engine's scene of one SCA read back from the FITS file
 * the run wrote, for --into to add to an image: into.c's FITS images and
 * into_asdf.c's Roman ASDF images both take it from here.
 */
#include <stdio.h>

#include <fitsio.h>

#include "err.h"
#include "into.h"

int into_scene(const char *path, int sca, long nx, long ny, double *out, long *nsrc,
	       char *filter, size_t nfilter, struct err *e)
{
	fitsfile *f = NULL;
	long fp[2] = { 1, 1 }, lp[2] = { nx, ny }, inc[2] = { 1, 1 }, ns = 0;
	char ext[16], fv[FLEN_VALUE] = "";
	int status = 0, any;

	snprintf(ext, sizeof(ext), "WFI%02d", sca);
	if (fits_open_diskfile(&f, path, READONLY, &status) ||
	    fits_movnam_hdu(f, IMAGE_HDU, ext, 0, &status) ||
	    (nsrc && fits_read_key(f, TLONG, "NSOURCES", &ns, NULL, &status)) ||
	    (filter && fits_read_key(f, TSTRING, "FILTER", fv, NULL, &status)) ||
	    fits_read_subset(f, TDOUBLE, fp, lp, inc, NULL, out, &any, &status)) {
		err_fits(e, status, "%s[%s]", path, ext);
		status = 0;
		if (f)
			fits_close_file(f, &status);
		return -1;
	}
	fits_close_file(f, &status);
	if (nsrc)
		*nsrc = ns;
	if (filter)
		snprintf(filter, nfilter, "%s", fv);
	return 0;
}
