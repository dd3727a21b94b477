/*
 * asdf_gwcs.c - the gwcs of a level-2 product's meta.wcs: detector ->
 * v2v3 -> world, in astropy's modeling transforms as gwcs and asdf-astropy
 * read them (transform schemas 1.2-1.3, gwcs 1.0.0 frames and steps).
 *
 * It is geometry.c's SIAF mapping, exactly:
 *
 *   detector -> v2v3: the 0-based pixel shifted to the SIAF's science
 *     offsets (u, v) = (x + 1 - XSciRef, y + 1 - YSciRef); Sci2Idl, the
 *     degree-5 polynomials, to ideal (xi, yi) arcsec (inverse: Idl2Sci);
 *     the ideal axes turned by V3IdlYAngle with VIdlParity into offsets
 *     along +V2 and +V3 in the plane tangent to the V2/V3 sphere at
 *     (V2Ref, V3Ref) (an affine map, degrees); that plane to the sphere
 *     (gnomonic) about (V2Ref, V3Ref) (rotate3d).  The longitude is taken
 *     180 degrees round and back (shift), so that V2 near 0 does not wrap
 *     to 360; v2, v3 in arcsec.
 *   v2v3 -> world: the attitude, a rotation of the sphere: (V2Ref, V3Ref)
 *     to the native pole, then the pole to (ra_ref, dec_ref) with +V3 at
 *     position angle roll_ref there.
 *
 * geometry.c goes from the ideal frame to the sky through the same
 * tangent plane (geom_pix_to_sky), so the two agree to rounding; the FITS
 * TAN-SIP header is a fit to it (t4400 compares all three).
 */
#include <math.h>
#include <stdio.h>

#include "asdf.h"
#include "asdf_gwcs.h"
#include "geometry.h"

#define D2R (M_PI / 180)

static struct fy_node *tr(struct asdf_tree *t, const char *tag)
{
	return asdf_map(t, NULL, NULL, tag);
}

static struct fy_node *shift(struct asdf_tree *t, double v)
{
	struct fy_node *m = tr(t, "!transform/shift-1.2.0");

	asdf_num(t, m, "offset", v);
	return m;
}

static struct fy_node *scale(struct asdf_tree *t, double v)
{
	struct fy_node *m = tr(t, "!transform/scale-1.2.0");

	asdf_num(t, m, "factor", v);
	return m;
}

static struct fy_node *pair(struct asdf_tree *t, const char *tag, struct fy_node *a,
			    struct fy_node *b)
{
	struct fy_node *m = tr(t, tag), *f = asdf_seq(t, m, "forward");

	asdf_seq_add(t, f, a);
	asdf_seq_add(t, f, b);
	return m;
}

/* a | b */
static struct fy_node *compose(struct asdf_tree *t, struct fy_node *a, struct fy_node *b)
{
	return pair(t, "!transform/compose-1.2.0", a, b);
}

/* a & b */
static struct fy_node *concat(struct asdf_tree *t, struct fy_node *a, struct fy_node *b)
{
	return pair(t, "!transform/concatenate-1.2.0", a, b);
}

/* (x, y) -> (x, y, x, y) */
static struct fy_node *dup2(struct asdf_tree *t)
{
	struct fy_node *m = tr(t, "!transform/remap_axes-1.3.0");

	asdf_yaml(t, m, "mapping", "[0, 1, 0, 1]");
	return m;
}

/* A degree-5 SIAF polynomial (c[k], k = i (i + 1) / 2 + j the term
 * x^(i-j) y^j) as astropy's Polynomial2D, whose coefficients[p][q] is the
 * term x^p y^q. */
static struct fy_node *poly(struct asdf_tree *t, const double *c)
{
	struct fy_node *m = tr(t, "!transform/polynomial-1.2.0");
	double a[GEOM_DEG + 1][GEOM_DEG + 1] = { { 0 } };

	for (int i = 1; i <= GEOM_DEG; i++)
		for (int j = 0; j <= i; j++)
			a[i - j][j] = c[i * (i + 1) / 2 + j];
	asdf_put(t, m, "coefficients", asdf_inline(t, &a[0][0], GEOM_DEG + 1, GEOM_DEG + 1));
	asdf_yaml(t, m, "domain", "[[-1, 1], [-1, 1]]");
	asdf_yaml(t, m, "window", "[[-1, 1], [-1, 1]]");
	return m;
}

static struct fy_node *rotate3d(struct asdf_tree *t, const char *dir, double phi, double theta,
				double psi)
{
	struct fy_node *m = tr(t, "!transform/rotate3d-1.3.0");

	asdf_str(t, m, "direction", dir);
	asdf_num(t, m, "phi", phi);
	asdf_num(t, m, "theta", theta);
	asdf_num(t, m, "psi", psi);
	return m;
}

static struct fy_node *frame2d(struct asdf_tree *t, const char *name, const char *ax,
			       const char *unit)
{
	struct fy_node *f = tr(t, "!<tag:stsci.edu:gwcs/frame2d-1.0.0>");
	char s[96];

	asdf_yaml(t, f, "axes_names", ax);
	asdf_yaml(t, f, "axes_order", "[0, 1]");
	asdf_str(t, f, "name", name);
	snprintf(s, sizeof(s), "[!unit/unit-1.0.0 %s, !unit/unit-1.0.0 %s]", unit, unit);
	asdf_yaml(t, f, "unit", s);
	return f;
}

static void step(struct asdf_tree *t, struct fy_node *steps, struct fy_node *frame,
		 struct fy_node *transform)
{
	struct fy_node *s = tr(t, "!<tag:stsci.edu:gwcs/step-1.0.0>");

	asdf_put(t, s, "frame", frame);
	if (transform)
		asdf_put(t, s, "transform", transform);
	else
		asdf_null(t, s, "transform");
	asdf_seq_add(t, steps, s);
}

int asdf_gwcs(struct asdf_tree *t, struct fy_node *meta, const struct gwcs_params *g)
{
	const struct geom_aperture *ap = g->ap;
	double th = ap->v3idlyangle * D2R, par = ap->parity < 0 ? -1 : 1;
	double v2 = ap->v2ref / 3600, v3 = ap->v3ref / 3600;
	/* ideal (xi, yi) arcsec -> offsets along +V2, +V3 in degrees */
	double mat[4] = { par * cos(th) / 3600, sin(th) / 3600,
			  -par * sin(th) / 3600, cos(th) / 3600 }, zero[2] = { 0, 0 };
	struct fy_node *w, *steps, *dist, *inv, *to_v23, *to_sky, *aff;

	/* the distortion and its inverse (Idl2Sci; astropy inverts the
	 * shift itself) */
	dist = compose(t, dup2(t), concat(t, poly(t, ap->sx), poly(t, ap->sy)));
	inv = compose(t, dup2(t), concat(t, poly(t, ap->ix), poly(t, ap->iy)));
	asdf_put(t, dist, "inverse", inv);
	dist = compose(t, concat(t, shift(t, 1 - ap->xref), shift(t, 1 - ap->yref)), dist);
	aff = tr(t, "!transform/affine-1.3.0");
	asdf_put(t, aff, "matrix", asdf_inline(t, mat, 2, 2));
	asdf_put(t, aff, "translation", asdf_inline(t, zero, 0, 2));
	{
		struct fy_node *tan = tr(t, "!transform/gnomonic-1.2.0");

		asdf_str(t, tan, "direction", "pix2sky");
		to_v23 = compose(t, compose(t, compose(t, dist, aff), tan),
				 compose(t, rotate3d(t, "native2celestial", v2 + 180, v3, 180),
					 concat(t, compose(t, shift(t, -180), scale(t, 3600)),
						scale(t, 3600))));
	}
	to_sky = compose(t, compose(t, concat(t, compose(t, scale(t, 1.0 / 3600), shift(t, 180)),
					      scale(t, 1.0 / 3600)),
				    rotate3d(t, "celestial2native", v2 + 180, v3, 180)),
			 rotate3d(t, "native2celestial", g->ra_ref, g->dec_ref,
				  180 + g->roll_ref));

	w = asdf_map(t, meta, "wcs", "!<tag:stsci.edu:gwcs/wcs-1.0.0>");
	asdf_str(t, w, "name", "");
	steps = asdf_seq(t, w, "steps");
	step(t, steps, frame2d(t, "detector", "[x, y]", "pixel"), to_v23);
	if (g->va != 1) {
		/* romancal's differential velocity aberration: V2/V3 scaled by
		 * va about (V2Ref, V3Ref) */
		struct fy_node *dva = compose(t, concat(t, scale(t, g->va), scale(t, g->va)),
					      concat(t, shift(t, (1 - g->va) * ap->v2ref),
						     shift(t, (1 - g->va) * ap->v3ref)));

		step(t, steps, frame2d(t, "v2v3", "[v2, v3]", "arcsec"), dva);
		step(t, steps, frame2d(t, "v2v3vacorr", "[v2, v3]", "arcsec"), to_sky);
	} else {
		step(t, steps, frame2d(t, "v2v3", "[v2, v3]", "arcsec"), to_sky);
	}
	{
		struct fy_node *f = tr(t, "!<tag:stsci.edu:gwcs/celestial_frame-1.0.0>");

		asdf_yaml(t, f, "axes_names", "[lon, lat]");
		asdf_yaml(t, f, "axes_order", "[0, 1]");
		asdf_yaml(t, f, "axis_physical_types", "[pos.eq.ra, pos.eq.dec]");
		asdf_str(t, f, "name", "world");
		asdf_yaml(t, f, "reference_frame",
			  "!<tag:astropy.org:astropy/coordinates/frames/icrs-1.1.0> "
			  "{frame_attributes: {}}");
		asdf_yaml(t, f, "unit", "[!unit/unit-1.0.0 deg, !unit/unit-1.0.0 deg]");
		step(t, steps, f, NULL);
	}
	return t->bad ? -1 : 0;
}
