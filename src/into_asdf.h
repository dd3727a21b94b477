/*
 * into_asdf.h - injection into a Roman level-2 ASDF file (--into
 * IMAGE.asdf, a RAD wfi_image).
 *
 * The file is checked first: ASDF Standard 1.6.0 or later, a `roman` node
 * tagged wfi_image (a level-1 file or another model is refused), every
 * block's header sound and within the file, data, var_poisson and err of
 * 4088 x 4088 in blocks.  Its SCA (meta.instrument.detector) is the
 * scene's one SCA; its gwcs (meta.wcs) places the sources where it can
 * be evaluated (gwcs_eval.h); otherwise, with a warning naming the
 * transform, meta.wcsinfo (ra_ref, dec_ref, v2_ref, v3_ref, roll_ref)
 * gives the attitude and wfiscene's SIAF places the sources through it.  The engine draws the light as a scene (counts/s); the result
 * is the image with that light added to data in DN/s (over the gain of
 * data/detector.tsv), its Poisson variance R / (gain T) (T the exposure's
 * effective_exposure_time) added to var_poisson and err, every other
 * array, block and the tree as they were; a block that had an MD5 gets
 * its new one.
 */
#ifndef WFS_INTO_ASDF_H
#define WFS_INTO_ASDF_H

struct err;
struct into_asdf;
struct pool;
struct sky;

/* The file begins "#ASDF", or its name ends in ".asdf". */
int into_is_asdf(const char *path);

/* Open and check path for the SCAs of mask (which must be the file's
 * one).  NULL with a message naming the file and what is wrong. */
struct into_asdf *into_asdf_open(const char *path, unsigned mask, struct err *e);

/* The pointing (WFI01's centre and the position angle of its +y) that
 * puts the file's SCA where its wcsinfo says. */
void into_asdf_pointing(const struct into_asdf *ia, double *ra, double *dec, double *pa);

int into_asdf_sca(const struct into_asdf *ia);

/* The scene's catalogs (NULL-terminated), named in the history entry. */
void into_asdf_catalogs(struct into_asdf *ia, char *const *catalogs);

/* Point the SCA of sky (laid out by into_asdf_pointing) by the file:
 * through meta.wcs where it is evaluated (gwcs_eval.h), else by the SIAF
 * chain of meta.wcsinfo with meta.velocity_aberration.scale_factor
 * applied about the reference point, as romancal's assign_wcs does.  0 or
 * -1. */
int into_asdf_apply(const struct into_asdf *ia, struct sky *sky, struct err *e);

/* Replace the engine's scene at path (FITS, HDU WFInn in counts/s) by the
 * image with that light added, its blocks stored as compression says
 * (asdf.h's enum; ASDF_KEEP: each as the image had it), compressed on
 * pool's threads (may be NULL).  0 or -1. */
int into_asdf_compose(struct into_asdf *ia, const char *path, int compression,
		      struct pool *pool, struct err *e);

void into_asdf_free(struct into_asdf *ia);

/* The image's meta.instrument.optical_element, NULL without one. */
const char *into_asdf_filter(const struct into_asdf *ia);

#endif
