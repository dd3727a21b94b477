/*
 * asdf_gwcs.h - the gwcs (detector -> v2v3 -> world) of a level-2 ASDF
 * product's meta.wcs; see asdf_gwcs.c.
 */
#ifndef WFS_ASDF_GWCS_H
#define WFS_ASDF_GWCS_H

struct asdf_tree;
struct fy_node;
struct geom_aperture;

struct gwcs_params {
	const struct geom_aperture *ap;   /* the SCA's SIAF aperture */
	double ra_ref, dec_ref;         /* its reference point on the sky, deg */
	double roll_ref;                /* position angle of +V3 there, deg */
	double va;                      /* velocity aberration's scale (1: none) */
};

/* Put meta.wcs into map meta.  0, or -1 (t->bad set) out of memory. */
int asdf_gwcs(struct asdf_tree *t, struct fy_node *meta, const struct gwcs_params *g);

#endif
