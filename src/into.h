/*
 * into.h - injection: sources added to an existing image (--into) instead
 * of an empty one.
 *
 * The image's HDUs stand for the requested SCAs: the one whose EXTNAME is
 * WFInn for SCA nn (wfiscene's own images), or the HDU named in
 * "IMAGE[N]" / "IMAGE[EXTNAME]" for the one SCA of the scene, or the file's
 * only image for the one SCA.  Each HDU's own WCS (wcslib, with SIP and
 * other distortions) places the sources on its pixels: it replaces that
 * SCA's geometry in the engine.  The engine draws the added light (and its
 * noise, when asked) as usual; the output is then the image itself, every
 * HDU and header kept, with that light added to the mapped HDUs' pixels.
 */
#ifndef WFS_INTO_H
#define WFS_INTO_H

#include <stddef.h>

struct err;
struct scene_opts;
struct sky;
struct into;
struct pool;

/* Open spec ("IMAGE.fits" or "IMAGE.fits[N]") for the SCAs in mask (bit
 * s-1 for SCA s) and read each mapped HDU's size, WCS, FILTER and BUNIT
 * (the HDU's own, else the primary header's).  An HDU whose EXTNAME or
 * DETECTOR is WFInn stands for SCA nn only: mapped to another SCA (as the
 * file's only image, or named in spec) it is refused, as an ASDF image of
 * another SCA is.  A FITS file cut short (wherever it ends), or with
 * bytes after its last HDU that are no HDU, is refused first, as
 * "IMAGE: truncated FITS file: ..." or "IMAGE: damaged FITS file: ...".
 * NULL with a message naming the file and HDU at fault (exit 1 for what
 * the file holds). */
struct into *into_open(const char *spec, unsigned mask, struct err *e);

/* The pointing to simulate: the primary header's RA_TARG, DEC_TARG,
 * PA_APER and POINTREF (a wfiscene image), else the centre of the first
 * mapped HDU and the position angle of its +y axis there. */
void into_pointing(const struct into *in, double *ra, double *dec, double *pa,
		   int *boresight);

/* Give the mapped SCAs of sky the images' WCSs and centres.  The light is
 * drawn in o's filter and unit: an image whose FILTER (ASDF:
 * meta.instrument.optical_element) names another of wfiscene's filters,
 * or whose BUNIT is the other of 'counts/s' and 'counts', is refused
 * here, before anything is drawn or written (an image without them, or
 * with values wfiscene does not write, is taken as it is).  Refuses an
 * image larger than an SCA or reaching farther from its centre than an
 * SCA's window.  Returns 0 or -1 (exit 1 for the image). */
int into_apply(const struct into *in, struct sky *sky, const struct scene_opts *o,
	       struct err *e);

/* The engine's scene of SCA sca (HDU WFInn of the FITS file at path):
 * its first nx x ny pixels into out, and where asked the number of
 * sources it drew (NSOURCES) and its filter (FILTER); what --into adds to
 * a FITS or an ASDF image.  0 or -1. */
int into_scene(const char *path, int sca, long nx, long ny, double *out, long *nsrc,
	       char *filter, size_t nfilter, struct err *e);

/* The scene's catalogs (NULL-terminated), for an ASDF image's history. */
void into_catalogs(struct into *in, char *const *catalogs);

/* Refuse an output path that names the --into image itself (the same
 * file, by device and inode; a symbolic link as -o is replaced, not
 * followed): the scene would be written over it before it is read.
 * Returns 0 or -1 (exit 1). */
int into_check_output(const struct into *in, const char *path, struct err *e);

/* Replace the engine's image at path (one HDU WFInn per SCA) by a copy of
 * the --into image with those HDUs' pixels added to the mapped HDUs'.
 * Written beside path and renamed over it; an ASDF image's blocks stored
 * as asdf_compression says (asdf.h), compressed on pool's threads.
 * Returns 0 or -1. */
int into_compose(const struct into *in, const char *path, int asdf_compression,
		 struct pool *pool, struct err *e);

void into_free(struct into *in);

#endif
