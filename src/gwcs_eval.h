/*
 * gwcs_eval.h - evaluating the gwcs of a Roman level-2 ASDF file (its
 * meta.wcs): the astropy modeling transforms of its steps, as the ASDF
 * transform schemas serialize them, from detector pixels to the sky and
 * back.
 *
 * Evaluated (ASDF transform schemas 1.x, gwcs 1.x): compose, concatenate,
 * add, subtract, multiply, divide (of two transforms), remap_axes,
 * identity, shift, scale, multiplyscale, polynomial (1D and 2D,
 * domain and window), affine, rotate2d, rotate3d (native2celestial,
 * celestial2native, Euler axes), rotate_sequence_3d (cartesian and
 * spherical), gnomonic (pix2sky, sky2pix), constant, and gwcs's
 * spherical_cartesian; numbers plain or as unit/quantity values (their
 * units taken as the transform's), arrays inline or in the file's blocks.
 * A transform's own `inverse` is used where it has one; astropy's
 * analytic inverses elsewhere (compose and concatenate of invertible
 * parts, mappings that keep every input, the rotations, projections,
 * shifts, scales, affine maps).  Where some part has none (a polynomial
 * without an inverse), sky -> pixel is Newton's method on the forward
 * transform.
 */
#ifndef WFS_GWCS_EVAL_H
#define WFS_GWCS_EVAL_H

#include <stddef.h>

struct asdf_in;
struct fy_node;
struct gwcs;

/*
 * The gwcs at node w (tagged gwcs/wcs-1.x): the transforms of its steps
 * composed, from its first frame to its last.  NULL, with why (a sentence
 * naming the unsupported transform, or what is wrong, and where in the
 * tree) when it cannot be evaluated here; *fatal set when the reason is
 * the file itself (a block that cannot be read), not a missing transform.
 */
struct gwcs *gwcs_load(struct asdf_in *a, struct fy_node *w, char *why, size_t nwhy,
		       int *fatal);
void gwcs_free(struct gwcs *g);

/* 0-based pixel (x, y) to the sky (degrees, ra in [0, 360)).  0, or -1
 * where the transform gives no finite answer. */
int gwcs_pix_to_sky(const struct gwcs *g, double x, double y, double *ra, double *dec);

/* The sky (degrees) to a 0-based pixel: through the inverse transform
 * where there is one, else Newton's method on the forward one from
 * (x0, y0).  0, or -1 (no answer: NaN out). */
int gwcs_sky_to_pix(const struct gwcs *g, double ra, double dec, double x0, double y0,
		    double *x, double *y);

/* 1 when sky -> pixel goes through an inverse transform, 0 by Newton. */
int gwcs_has_inverse(const struct gwcs *g);

#endif
