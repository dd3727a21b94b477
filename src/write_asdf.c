/*
 * write_asdf.c - the ASDF writer of an exposure's products (product.h):
 * one file per SCA that the Roman pipeline reads, its tree's `roman` node
 * a RAD datamodel (rad 2.1.0: wfi_science_raw at level 1, wfi_image at
 * level 2), its arrays at their RAD datatypes in binary blocks.
 *
 * Level 1 (wfi_science_raw-2.1.0): data, the resultants in DN with the
 * reference border, uint16 (n_resultants, 4096, 4096); amp33, the 33rd
 * amplifier's channel (amp33.h), uint16 (n_resultants, 4096, 128);
 * reference_read, the read after the reset (ramp_reference_row), uint16
 * (4096, 4096).
 *
 * Level 2 (wfi_image-2.1.0): the ramp fit in DN/s (the FITS product's
 * counts/s over the gain): data float32, dq uint32, err, var_poisson,
 * var_rnoise float16 ((DN/s)^2 for the variances); chisq and dumo float16
 * (ramp_stats.h); amp33 as at level 1; the reference border's
 * resultants as float32 DN (border_ref_pix_left/right (n, 4096, 4),
 * top/bottom (n, 4, 4096)) and their DQ, uint32, zero.
 *
 * The meta blocks and where each value comes from: wfiscene(1), OUTPUT
 * FORMATS.  The gwcs of meta.wcs: asdf_gwcs.c.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "amp33.h"
#include "readnoise.h"
#include "asdf.h"
#include "asdf_gwcs.h"
#include "date.h"
#include "detector.h"
#include "engine.h"
#include "err.h"
#include "exposure.h"
#include "geometry.h"
#include "levels.h"
#include "motion.h"
#include "product.h"
#include "simd.h"

#define FRAME 4096
#define BORDER 4
#define AU_KM 149597870.7
#define C_KMS 299792.458
#define D2R (M_PI / 180)
#define R2D (180 / M_PI)
#define ARCSEC_SR (M_PI / 180 / 3600 * M_PI / 180 / 3600)
#define TAG_RAW "!<asdf://stsci.edu/datamodels/roman/tags/wfi_science_raw-2.1.0>"
#define TAG_IMAGE "!<asdf://stsci.edu/datamodels/roman/tags/wfi_image-2.1.0>"

/* The blocks of the two levels, in the order of their schemas. */
enum { L1_DATA, L1_AMP33, L1_REF, L1_N };
enum {
	L2_DATA, L2_DQ, L2_ERR, L2_VP, L2_VR, L2_CHISQ, L2_DUMO, L2_AMP33,
	L2_LEFT, L2_RIGHT, L2_TOP, L2_BOTTOM, L2_DQ_LEFT, L2_DQ_RIGHT, L2_DQ_TOP,
	L2_DQ_BOTTOM, L2_N
};

struct array {
	const char *name;
	int dtype, ndim;
	long shape[3];
};

struct asdf_writer {
	struct writer w;
	struct engine *g;
	struct asdf_out *out;
	char *path;
	/* the SCA being written */
	int level, sca, nres;
	const struct ramp_pattern *pat;
	const struct ramp_det *det;
	struct ramp_key key;
	struct array arr[L2_N];
	int narr;
	long rows_done;         /* frame rows handed over */
	/* conversion buffers, grown to the largest strip */
	size_t cap;
	void *buf;
	uint16_t *amp;
	int amp_rows;           /* rows amp holds */
	double *scratch;
};

/* ---- what the scene knows, as RAD meta ---- */

/* The date of the exposure's first read: --date, or 2027-01-01T00:00 UTC
 * for a scene without one (wfiscene(1), OUTPUT FORMATS). */
static double start_mjd(const struct engine *g)
{
	return isnan(g->x->date) ? date_mjd(2027, 1, 1, 0, 0, 0) : g->x->date;
}

static void file_date(struct asdf_tree *t, struct fy_node *meta)
{
	const char *epoch = getenv("SOURCE_DATE_EPOCH");
	time_t now = epoch && *epoch ? (time_t)strtoll(epoch, NULL, 10) : time(NULL);

	/* SOURCE_DATE_EPOCH pins it, so that two runs give the same bytes */
	asdf_time(t, meta, "file_date", 40587.0 + (double)now / 86400.0);
}

/* Position angle (degrees east of north) at unit vector s of the
 * direction toward unit vector q. */
static double pa_toward(const double s[3], const double q[3])
{
	double ra = atan2(s[1], s[0]), dec = asin(s[2]);
	double e[3] = { -sin(ra), cos(ra), 0 };
	double n[3] = { -sin(dec) * cos(ra), -sin(dec) * sin(ra), cos(dec) };
	double de = 0, dn = 0;

	for (int k = 0; k < 3; k++) {
		de += e[k] * q[k];
		dn += n[k] * q[k];
	}
	return fmod(atan2(de, dn) * R2D + 360, 360);
}

static void unit_v23(double v2, double v3, double u[3])
{
	double a = v2 / 3600 * D2R, d = v3 / 3600 * D2R;

	u[0] = cos(d) * cos(a);
	u[1] = cos(d) * sin(a);
	u[2] = sin(d);
}

static void att_apply(const double m[3][3], const double v[3], double w[3])
{
	for (int i = 0; i < 3; i++)
		w[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
}

static void radec(const double s[3], double *ra, double *dec)
{
	*ra = fmod(atan2(s[1], s[0]) * R2D + 360, 360);
	*dec = asin(s[2] > 1 ? 1 : s[2] < -1 ? -1 : s[2]) * R2D;
}

/* The sky position and the position angle of +V3 at (v2, v3) arcsec. */
static void v23_sky(const struct engine *g, double v2, double v3, double *ra, double *dec,
		    double *pa_v3)
{
	double u[3], s[3], q[3], t[3];

	unit_v23(v2, v3, u);
	att_apply(g->sky.att, u, s);
	unit_v23(v2, v3 + 1, t);
	att_apply(g->sky.att, t, q);
	radec(s, ra, dec);
	*pa_v3 = pa_toward(s, q);
}

/* The SCA's reference point on the sky and the position angle of +V3
 * there, as wcsinfo gives them: with velocity aberration the attitude
 * turned by the least rotation that takes the unaberrated reference
 * direction u to the aberrated one (geometry's u, ~0.1" away). */
static void sca_ref(const struct engine *g, int sca, double *ra, double *dec, double *pa_v3)
{
	const struct geom_aperture *ap = geom_aperture(sca);
	const double *w = g->sky.sca[sca - 1].geo.u;
	double m[3][3], u[3], a[3], sn, c, k[3][3] = { { 0 } };

	if (g->sky.va == 1) {
		v23_sky(g, ap->v2ref, ap->v3ref, ra, dec, pa_v3);
		return;
	}
	unit_v23(ap->v2ref, ap->v3ref, a);
	att_apply(g->sky.att, a, u);
	/* Rodrigues: R = I + K + K^2 / (1 + c), K the cross-product matrix
	 * of u x w, c = u . w */
	a[0] = u[1] * w[2] - u[2] * w[1];
	a[1] = u[2] * w[0] - u[0] * w[2];
	a[2] = u[0] * w[1] - u[1] * w[0];
	c = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
	k[0][1] = -a[2], k[0][2] = a[1], k[1][0] = a[2];
	k[1][2] = -a[0], k[2][0] = -a[1], k[2][1] = a[0];
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++) {
			double r = (i == j) + k[i][j], k2 = 0;

			for (int q = 0; q < 3; q++)
				k2 += k[i][q] * k[q][j];
			sn = r + k2 / (1 + c);
			m[i][j] = sn;
		}
	{
		double att[3][3], s3[3], q[3], t[3];

		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				att[i][j] = m[i][0] * g->sky.att[0][j] + m[i][1] * g->sky.att[1][j] +
					    m[i][2] * g->sky.att[2][j];
		unit_v23(ap->v2ref, ap->v3ref, a);
		att_apply(att, a, s3);
		unit_v23(ap->v2ref, ap->v3ref + 1, t);
		att_apply(att, t, q);
		radec(s3, ra, dec);
		*pa_v3 = pa_toward(s3, q);
	}
}

static void meta_exposure(struct asdf_writer *aw, struct asdf_tree *t, struct fy_node *meta)
{
	const struct ramp_pattern *p = aw->pat;
	struct fy_node *x = asdf_map(t, meta, "exposure", NULL), *rp;
	double t0 = start_mjd(aw->g);
	char id[16];

	asdf_str(t, x, "type", "WFI_IMAGE");
	asdf_time(t, x, "start_time", t0);
	asdf_time(t, x, "end_time", t0 + p->exptime / 86400);
	asdf_str(t, x, "engineering_quality", "OK");
	asdf_int(t, x, "nresultants", p->nres);
	asdf_null(t, x, "data_problem");
	asdf_num(t, x, "frame_time", p->read_time);
	asdf_num(t, x, "exposure_time", p->exptime);
	/* the time between the first and last resultants' mean reads: what a
	 * ramp fit's slope spans */
	asdf_num(t, x, "effective_exposure_time", p->tbar[p->nres - 1] - p->tbar[0]);
	snprintf(id, sizeof(id), "%d", p->table);
	/* the Project's name of the table where wfiscene's sources give it
	 * (romanisim's parameters: table 4 is C2A_IMG_HLWAS); UNKNOWN, not
	 * a made-up one, for the others */
	asdf_str(t, x, "ma_table_name", p->table == 4 ? "C2A_IMG_HLWAS" : "UNKNOWN");
	asdf_int(t, x, "ma_table_number", p->table);
	asdf_str(t, x, "ma_table_id", id);
	rp = asdf_seq(t, x, "read_pattern");
	for (int i = 0; i < p->nres && rp; i++) {
		struct fy_node *r = asdf_seq_seq(t, rp);

		for (int k = p->first[i]; k <= p->last[i]; k++)
			asdf_seq_int(t, r, k);
	}
	asdf_bool(t, x, "truncated", 0);
	asdf_bool(t, x, "hga_move", 0);
}

/* The observer model of the time-domain positions (motion.h): Roman's
 * heliocentric position at mid-exposure, its velocity by a central
 * difference of an hour either side. */
static void observer(double mjd, double pos_km[3], double vel_kms[3])
{
	double a[3], b[3], c[3];

	motion_observer(mjd, a);
	motion_observer(mjd - 1.0 / 24, b);
	motion_observer(mjd + 1.0 / 24, c);
	for (int k = 0; k < 3; k++) {
		pos_km[k] = a[k] * AU_KM;
		vel_kms[k] = (c[k] - b[k]) * AU_KM / 7200.0;
	}
}

/* guide_star: no guider in a simulation; the schema's fields, none */
static void meta_guide_star(struct asdf_tree *t, struct fy_node *meta)
{
	struct fy_node *n;

	n = asdf_map(t, meta, "guide_star", NULL);
	asdf_str(t, n, "guide_window_id", "none");
	asdf_str(t, n, "guide_mode", "none");
	asdf_int(t, n, "window_xstart", 0);
	asdf_int(t, n, "window_ystart", 0);
	asdf_int(t, n, "window_xstop", 0);
	asdf_int(t, n, "window_ystop", 0);
	asdf_str(t, n, "guide_star_id", "none");
	asdf_str(t, n, "epoch", "none");
}

/* observation: a --pointings name is the observation's id; the numbers
 * default to 1, the exposure to its place in the run */
static void meta_observation(struct asdf_tree *t, struct fy_node *meta,
			     const struct exposure *x)
{
	struct fy_node *n;
	char vid[24];

	n = asdf_map(t, meta, "observation", NULL);
	asdf_str(t, n, "observation_id", x->name[0] ? x->name : "wfiscene");
	snprintf(vid, sizeof(vid), "%05d%02d%03d%03d%03d%03d", 1, 1, 1, 1, 1, 1);
	asdf_str(t, n, "visit_id", vid);
	asdf_int(t, n, "program", 1);
	asdf_int(t, n, "execution_plan", 1);
	asdf_int(t, n, "pass", 1);
	asdf_int(t, n, "segment", 1);
	asdf_int(t, n, "observation", 1);
	asdf_int(t, n, "visit", 1);
	asdf_int(t, n, "visit_file_group", 1);
	asdf_int(t, n, "visit_file_sequence", 1);
	asdf_str(t, n, "visit_file_activity", "01");
	asdf_int(t, n, "exposure", x->index + 1);
	asdf_bool(t, n, "wfi_parallel", 0);
}

/* pointing: V1 (V2 = V3 = 0) and the reference aperture */
static void meta_pointing(struct engine *g, struct asdf_tree *t, struct fy_node *meta)
{
	const struct geom_aperture *ref;
	struct fy_node *n;
	double ra, dec, pa_v3;

	n = asdf_map(t, meta, "pointing", NULL);
	ref = geom_aperture(g->sky.boresight ? 0 : 1);
	asdf_num(t, n, "pa_aperture", g->sky.pa0);
	asdf_str(t, n, "pointing_engineering_source", "CALCULATED");
	v23_sky(g, 0, 0, &ra, &dec, &pa_v3);
	asdf_num(t, n, "ra_v1", ra);
	asdf_num(t, n, "dec_v1", dec);
	asdf_num(t, n, "pa_v3", pa_v3);
	asdf_str(t, n, "target_aperture", ref->sca ? "WFI01_FULL" : "WFI_CEN");
	asdf_num(t, n, "target_ra", g->sky.ra0);
	asdf_num(t, n, "target_dec", g->sky.dec0);
}

/* program, ref_file and rcs: no proposal, no CRDS, no calibration
 * source in a simulation; documented defaults (wfiscene(1)) */
static void meta_bookkeeping(struct asdf_tree *t, struct fy_node *meta)
{
	static const char *const refs[] = {
		"apcorr", "dark", "darkdecaysignal", "distortion", "epsf", "mask", "flat",
		"gain", "readnoise", "linearity", "inverselinearity", "integralnonlinearity",
		"photom", "area", "saturation", "refpix",
	};
	struct fy_node *n, *crds;

	n = asdf_map(t, meta, "program", NULL);
	asdf_str(t, n, "title", "wfiscene simulation");
	asdf_str(t, n, "investigator_name", "none");
	asdf_str(t, n, "category", "none");
	asdf_str(t, n, "subcategory", "none");
	asdf_str(t, n, "science_category", "none");

	n = asdf_map(t, meta, "ref_file", NULL);
	crds = asdf_map(t, n, "crds", NULL);
	asdf_str(t, crds, "version", "none");
	asdf_str(t, crds, "context", "none");
	for (size_t i = 0; i < sizeof(refs) / sizeof(refs[0]); i++)
		asdf_str(t, n, refs[i], "N/A");

	n = asdf_map(t, meta, "rcs", NULL);
	asdf_bool(t, n, "active", 0);
	asdf_null(t, n, "electronics");
	asdf_null(t, n, "bank");
	asdf_null(t, n, "led");
	asdf_int(t, n, "counts", 0);
}

/* velocity aberration of the SCA's reference point, as the scene drew
 * it.  Off (the default): none, scale 1 and the apparent direction the
 * reference point's, so that romancal's assign_wcs (which scales V2/V3
 * about the reference point by scale_factor) puts the sources where they
 * are.  On: the scale factor the geometry applied (sky.h) and the
 * apparent direction of the reference point, u + beta less its part along
 * u, to first order. */
static void meta_aberration(struct engine *g, int sca, const double vel[3],
			    struct asdf_tree *t, struct fy_node *meta)
{
	struct fy_node *n;
	double ra, dec, pa_v3, u[3], beta[3], ub = 0, s[3], nn = 0, ra_a, dec_a;

	sca_ref(g, sca, &ra, &dec, &pa_v3);
	u[0] = cos(dec * D2R) * cos(ra * D2R);
	u[1] = cos(dec * D2R) * sin(ra * D2R);
	u[2] = sin(dec * D2R);
	for (int k = 0; k < 3; k++) {
		beta[k] = g->sky.va == 1 ? 0 : vel[k] / C_KMS;
		ub += u[k] * beta[k];
	}
	for (int k = 0; k < 3; k++) {
		s[k] = u[k] + beta[k] - ub * u[k];
		nn += s[k] * s[k];
	}
	for (int k = 0; k < 3; k++)
		s[k] /= sqrt(nn);
	n = asdf_map(t, meta, "velocity_aberration", NULL);
	radec(s, &ra_a, &dec_a);
	asdf_num(t, n, "ra_reference", g->sky.va == 1 ? ra : ra_a);
	asdf_num(t, n, "dec_reference", g->sky.va == 1 ? dec : dec_a);
	asdf_num(t, n, "scale_factor", g->sky.va);
}

/* visit: one exposure of general astrophysics, no dither named */
static void meta_visit(struct engine *g, struct asdf_tree *t, struct fy_node *meta)
{
	struct fy_node *n, *dither;

	n = asdf_map(t, meta, "visit", NULL);
	dither = asdf_map(t, n, "dither", NULL);
	asdf_null(t, dither, "primary_name");
	asdf_null(t, dither, "subpixel_name");
	asdf_null(t, dither, "executed_pattern");
	asdf_str(t, n, "type", "GENERAL_ASTROPHYSICS");
	asdf_time(t, n, "start_time", start_mjd(g));
	asdf_int(t, n, "nexposures", 1);
	asdf_bool(t, n, "internal_target", 0);
}

/* wcsinfo: the SCA's aperture, its reference point on the sky and the
 * science pixels' corners */
static void meta_wcsinfo(struct asdf_writer *aw, struct asdf_tree *t, struct fy_node *meta)
{
	struct engine *g = aw->g;
	const struct geom_aperture *ap = geom_aperture(aw->sca);
	struct fy_node *n;
	double ra, dec, pa_v3;
	char name[32];

	sca_ref(g, aw->sca, &ra, &dec, &pa_v3);
	n = asdf_map(t, meta, "wcsinfo", NULL);
	snprintf(name, sizeof(name), "WFI%02d_FULL", aw->sca);
	asdf_str(t, n, "aperture_name", name);
	asdf_num(t, n, "v2_ref", ap->v2ref);
	asdf_num(t, n, "v3_ref", ap->v3ref);
	asdf_int(t, n, "vparity", ap->parity < 0 ? -1 : 1);
	asdf_num(t, n, "v3yangle", ap->v3idlyangle);
	asdf_num(t, n, "ra_ref", ra);
	asdf_num(t, n, "dec_ref", dec);
	asdf_num(t, n, "roll_ref", pa_v3);
	{
		/* the corners of the science pixels, counterclockwise */
		static const double cx[4] = { -0.5, WFS_NPIX - 0.5, WFS_NPIX - 0.5, -0.5 };
		static const double cy[4] = { -0.5, -0.5, WFS_NPIX - 0.5, WFS_NPIX - 0.5 };
		struct geom_sca *geo = &g->sky.sca[aw->sca - 1].geo;
		char poly[256];
		int k = snprintf(poly, sizeof(poly), "POLYGON ICRS");

		for (int c = 0; c < 4; c++) {
			double a, d;

			geom_pix_to_sky(geo, cx[c], cy[c], &a, &d);
			k += snprintf(poly + k, sizeof(poly) - (size_t)k, " %.9f %.9f", a, d);
		}
		asdf_str(t, n, "s_region", poly);
	}
}

static void meta_common(struct asdf_writer *aw, struct asdf_tree *t, struct fy_node *meta)
{
	struct engine *g = aw->g;
	const struct exposure *x = g->x;
	struct fy_node *n;
	double mid = start_mjd(g) + aw->pat->exptime / 2 / 86400, pos[3], vel[3];
	char name[32], *base = strrchr(aw->path, '/');

	asdf_str(t, meta, "calibration_software_name", "wfiscene");
	asdf_str(t, meta, "calibration_software_version", WFS_VERSION);
	asdf_str(t, meta, "filename", base ? base + 1 : aw->path);
	file_date(t, meta);
	asdf_str(t, meta, "model_type", aw->level == DETECTOR_L1 ? "ScienceRawModel" :
		 "ImageModel");
	/* the schema's choices are the Roman ground system's; wfiscene's
	 * name is in calibration_software_name and asdf_library */
	asdf_str(t, meta, "origin", "STSCI/SOC");
	asdf_str(t, meta, "prd_version", "none");
	asdf_str(t, meta, "product_type", aw->level == DETECTOR_L1 ? "l1" : "l2");
	asdf_str(t, meta, "sdf_software_version", "none");
	asdf_str(t, meta, "telescope", "ROMAN");

	n = asdf_map(t, meta, "coordinates", NULL);
	asdf_str(t, n, "reference_frame", "ICRS");

	observer(mid, pos, vel);
	n = asdf_map(t, meta, "ephemeris", NULL);
	asdf_str(t, n, "type", "PREDICTED");
	asdf_num(t, n, "time", mid);
	asdf_str(t, n, "ephemeris_reference_frame", "HELIO-ICRS");
	asdf_num(t, n, "spatial_x", pos[0]);
	asdf_num(t, n, "spatial_y", pos[1]);
	asdf_num(t, n, "spatial_z", pos[2]);
	asdf_num(t, n, "velocity_x", vel[0]);
	asdf_num(t, n, "velocity_y", vel[1]);
	asdf_num(t, n, "velocity_z", vel[2]);

	meta_exposure(aw, t, meta);

	meta_guide_star(t, meta);

	n = asdf_map(t, meta, "instrument", NULL);
	snprintf(name, sizeof(name), "WFI%02d", aw->sca);
	asdf_str(t, n, "detector", name);
	asdf_str(t, n, "optical_element", g->filter_name);
	asdf_str(t, n, "name", "WFI");

	meta_observation(t, meta, x);

	meta_pointing(g, t, meta);

	meta_bookkeeping(t, meta);

	meta_aberration(g, aw->sca, vel, t, meta);

	meta_visit(g, t, meta);

	meta_wcsinfo(aw, t, meta);
}

/* Level 2's photometry: the zeropoint (AB mag of 1 counts/s) gives the
 * flux density of 1 DN/s, gain counts/s; over the nominal 0.11" pixel's
 * solid angle, MJy/sr. */
static void meta_photometry(struct asdf_writer *aw, struct asdf_tree *t, struct fy_node *meta)
{
	struct fy_node *n = asdf_map(t, meta, "photometry", NULL);
	double zp = filter_zeropoint(aw->g->o->filter, aw->sca, aw->g->o->zp_stips);
	double area = WFS_PIXSCALE * WFS_PIXSCALE * ARCSEC_SR;

	asdf_num(t, n, "conversion_megajanskys",
		 aw->det->gain * 3631e-6 * pow(10, -0.4 * zp) / area);
	asdf_null(t, n, "conversion_megajanskys_uncertainty");
	asdf_num(t, n, "pixel_area", area);
}

/* ---- the arrays ---- */

static void arrays(struct asdf_writer *aw)
{
	long n = aw->nres;
	struct array *a = aw->arr;

	if (aw->level == DETECTOR_L1) {
		a[L1_DATA] = (struct array){ "data", ASDF_U16, 3, { n, FRAME, FRAME } };
		a[L1_AMP33] = (struct array){ "amp33", ASDF_U16, 3, { n, FRAME, AMP33_COLS } };
		a[L1_REF] = (struct array){ "reference_read", ASDF_U16, 2, { FRAME, FRAME } };
		aw->narr = L1_N;
		return;
	}
	a[L2_DATA] = (struct array){ "data", ASDF_F32, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_DQ] = (struct array){ "dq", ASDF_U32, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_ERR] = (struct array){ "err", ASDF_F16, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_VP] = (struct array){ "var_poisson", ASDF_F16, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_VR] = (struct array){ "var_rnoise", ASDF_F16, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_CHISQ] = (struct array){ "chisq", ASDF_F16, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_DUMO] = (struct array){ "dumo", ASDF_F16, 2, { WFS_NPIX, WFS_NPIX } };
	a[L2_AMP33] = (struct array){ "amp33", ASDF_U16, 3, { n, FRAME, AMP33_COLS } };
	a[L2_LEFT] = (struct array){ "border_ref_pix_left", ASDF_F32, 3, { n, FRAME, BORDER } };
	a[L2_RIGHT] = (struct array){ "border_ref_pix_right", ASDF_F32, 3, { n, FRAME, BORDER } };
	a[L2_TOP] = (struct array){ "border_ref_pix_top", ASDF_F32, 3, { n, BORDER, FRAME } };
	a[L2_BOTTOM] = (struct array){ "border_ref_pix_bottom", ASDF_F32, 3, { n, BORDER, FRAME } };
	a[L2_DQ_LEFT] = (struct array){ "dq_border_ref_pix_left", ASDF_U32, 2, { FRAME, BORDER } };
	a[L2_DQ_RIGHT] = (struct array){ "dq_border_ref_pix_right", ASDF_U32, 2, { FRAME, BORDER } };
	a[L2_DQ_TOP] = (struct array){ "dq_border_ref_pix_top", ASDF_U32, 2, { BORDER, FRAME } };
	a[L2_DQ_BOTTOM] = (struct array){ "dq_border_ref_pix_bottom", ASDF_U32, 2,
					  { BORDER, FRAME } };
	aw->narr = L2_N;
}

static uint64_t array_bytes(const struct array *a)
{
	uint64_t n = asdf_dtype_size(a->dtype);

	for (int i = 0; i < a->ndim; i++)
		n *= (uint64_t)a->shape[i];
	return n;
}

static struct writer *asdf_open(struct engine *g, const char *path, struct err *e)
{
	struct asdf_writer *aw = calloc(1, sizeof(*aw));
	int comp;

	if (!aw || !(aw->path = strdup(path))) {
		free(aw);
		err_sys(e, "output");
		return NULL;
	}
	aw->w.ops = &writer_asdf;
	aw->g = g;
	/* --set asdf-compression: every block stored so (none by default) */
	if (asdf_compression_setting(g->o->settings, &comp, e) < 0 ||
	    !(aw->out = asdf_out_open(path, comp, g->pool, e))) {
		free(aw->path);
		free(aw);
		return NULL;
	}
	return &aw->w;
}

static int asdf_sca_begin(struct writer *w, const struct product *p, struct err *e)
{
	struct asdf_writer *aw = (struct asdf_writer *)w;
	struct asdf_tree t;
	struct fy_node *roman, *meta;
	uint64_t bytes[L2_N];
	size_t itemsize[L2_N];

	if (p->level == DETECTOR_SCENE || p->ylo != 0 || p->yhi != WFS_NPIX)
		return err_set(e, EXIT_INPUT, "%s: an ASDF file holds a whole SCA at level 1 "
			       "or 2", aw->path);
	aw->level = p->level;
	aw->sca = p->sca;
	aw->pat = p->pat;
	aw->det = p->det;
	aw->nres = p->pat->nres;
	aw->key = (struct ramp_key){ .seed = p->g->x->seed, .filter = p->g->o->filter,
				     .sca = p->sca };
	aw->rows_done = 0;
	arrays(aw);
	if (!(aw->scratch = malloc((AMP33_SCRATCH > 2 * FRAME ? AMP33_SCRATCH : 2 * FRAME) *
				   sizeof(double))))
		return err_sys(e, "%s", aw->path);
	ramp_scratch_init(aw->scratch);
	if (asdf_tree_new(&t) < 0)
		return err_sys(e, "%s: the ASDF tree", aw->path);
	roman = asdf_map(&t, asdf_root(&t), "roman",
			 aw->level == DETECTOR_L1 ? TAG_RAW : TAG_IMAGE);
	meta = asdf_map(&t, roman, "meta", NULL);
	meta_common(aw, &t, meta);
	if (aw->level == DETECTOR_L2) {
		meta_photometry(aw, &t, meta);
		struct gwcs_params gp = { .ap = geom_aperture(p->sca) };

		sca_ref(p->g, p->sca, &gp.ra_ref, &gp.dec_ref, &gp.roll_ref);
		gp.va = p->g->sky.va;
		if (asdf_gwcs(&t, meta, &gp) < 0)
			t.bad = 1;
	}
	for (int k = 0; k < aw->narr; k++) {
		asdf_ndarray(&t, roman, aw->arr[k].name, k, aw->arr[k].dtype, aw->arr[k].ndim,
			     aw->arr[k].shape);
		bytes[k] = array_bytes(&aw->arr[k]);
		itemsize[k] = asdf_dtype_size(aw->arr[k].dtype);
	}
	if (t.bad) {
		asdf_tree_free(&t);
		return err_sys(e, "%s: the ASDF tree", aw->path);
	}
	if (asdf_out_begin(aw->out, &t, aw->narr, bytes, itemsize, e) < 0) {
		asdf_tree_free(&t);
		return -1;
	}
	asdf_tree_free(&t);
	return 0;
}

static int grow(struct asdf_writer *aw, size_t bytes, struct err *e)
{
	void *b;

	if (bytes <= aw->cap)
		return 0;
	if (!(b = realloc(aw->buf, bytes)))
		return err_sys(e, "%s", aw->path);
	aw->buf = b;
	aw->cap = bytes;
	return 0;
}

/* Rows of a 3-D array (n, FRAME, cols) of the strip: resultant r's rows
 * are contiguous in the file, so one write a resultant. */
static int put_planes(struct asdf_writer *aw, int k, int fy0, int ny, long cols,
		      const void *src, size_t esize, struct err *e)
{
	for (int r = 0; r < aw->nres; r++) {
		uint64_t off = ((uint64_t)r * FRAME + (uint64_t)fy0) * (uint64_t)cols * esize;

		if (asdf_out_put(aw->out, k, off, (const char *)src +
				 (size_t)r * (size_t)ny * (size_t)cols * esize,
				 (size_t)ny * (size_t)cols * esize, e) < 0)
			return -1;
	}
	return 0;
}

static int put_amp33(struct asdf_writer *aw, int k, const struct level_strip *s,
		     struct err *e)
{
	size_t n = (size_t)aw->nres * (size_t)s->ny * AMP33_COLS;

	if (s->ny > aw->amp_rows) {
		uint16_t *a = realloc(aw->amp, n * sizeof(uint16_t));

		if (!a)
			return err_sys(e, "%s", aw->path);
		aw->amp = a;
		aw->amp_rows = s->ny;
	}
	amp33_rows(aw->pat, aw->det, &aw->key, s->rn, s->fy0, s->ny, aw->amp, aw->scratch);
	return put_planes(aw, k, s->fy0, s->ny, AMP33_COLS, aw->amp, sizeof(uint16_t), e);
}

/* n floats to IEEE halves (asdf_half's rounding), eight at a time by
 * F16C where the machine has it (every AVX2 machine does): the same bits.
 * F16C overflows a finite float past 65504 to infinity; asdf_half
 * saturates it, so such a float is first made +-65504 (|f| in (65504,
 * 65520) rounds there anyway, so nothing else changes).  A NaN fails both
 * comparisons and infinity the second: they pass as they are. */
#ifdef SIMD_X86
__attribute__((target("avx2,f16c"))) static void half8(const float *f, uint16_t *h, size_t n)
{
	const __m256 sign = _mm256_set1_ps(-0.0f), max = _mm256_set1_ps(65504.0f);
	const __m256 inf = _mm256_set1_ps(INFINITY);

	for (size_t i = 0; i + 8 <= n; i += 8) {
		__m256 v = _mm256_loadu_ps(f + i), a = _mm256_andnot_ps(sign, v);
		__m256 over = _mm256_and_ps(_mm256_cmp_ps(a, max, _CMP_GT_OQ),
					    _mm256_cmp_ps(a, inf, _CMP_LT_OQ));

		v = _mm256_blendv_ps(v, _mm256_or_ps(_mm256_and_ps(v, sign), max), over);
		_mm_storeu_si128((__m128i *)(h + i),
				 _mm256_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
	}
}
#endif

static void to_half(const float *f, uint16_t *h, size_t n)
{
	size_t i = 0;

#ifdef SIMD_X86
	if (simd_flags() & SIMD_AVX2) {
		half8(f, h, n);
		i = n / 8 * 8;
	}
#endif
	for (; i < n; i++)
		h[i] = asdf_half(f[i]);
}

static int strip_l2(struct asdf_writer *aw, const struct level_strip *s, struct err *e)
{
	const double gain = aw->det->gain, g2 = gain * gain;
	size_t npx = (size_t)s->nsy * WFS_NPIX, plane = (size_t)s->ny * FRAME;
	uint64_t off = (uint64_t)s->sy0 * WFS_NPIX;
	float *f;
	uint16_t *h;

	/* floats for a strip's planes; halves after the first 2 npx floats */
	if (grow(aw, (size_t)(aw->nres > 3 ? aw->nres : 3) * (size_t)s->ny * FRAME *
		 sizeof(float), e) < 0)
		return -1;
	f = aw->buf;
	h = (uint16_t *)(f + 2 * npx);
	if (s->nsy > 0) {
		const float *src[3] = { s->err, s->var_poisson, s->var_rnoise };
		const double scale[3] = { 1 / gain, 1 / g2, 1 / g2 };

		for (size_t i = 0; i < npx; i++)
			f[i] = (float)(s->rate[i] / gain);
		if (asdf_out_put(aw->out, L2_DATA, off * 4, f, npx * 4, e) < 0 ||
		    asdf_out_put(aw->out, L2_DQ, off * 4, s->dq, npx * 4, e) < 0)
			return -1;
		for (int k = 0; k < 3; k++) {
			for (size_t i = 0; i < npx; i++)
				f[i] = (float)(src[k][i] * scale[k]);
			to_half(f, h, npx);
			if (asdf_out_put(aw->out, L2_ERR + k, off * 2, h, npx * 2, e) < 0)
				return -1;
		}
		to_half(s->chisq, h, npx);
		to_half(s->dumo, h + npx, npx);
		if (asdf_out_put(aw->out, L2_CHISQ, off * 2, h, npx * 2, e) < 0 ||
		    asdf_out_put(aw->out, L2_DUMO, off * 2, h + npx, npx * 2, e) < 0)
			return -1;
	}
	/* the border's resultants as float DN: left and right columns of
	 * every frame row, then the bottom and top rows */
	for (int side = 0; side < 2; side++) {
		int x0 = side ? FRAME - BORDER : 0;

		for (int r = 0; r < aw->nres; r++)
			for (int i = 0; i < s->ny; i++)
				for (int x = 0; x < BORDER; x++)
					f[((size_t)r * (size_t)s->ny + (size_t)i) * BORDER + (size_t)x] =
						s->l1[(size_t)r * plane + (size_t)i * FRAME +
						      (size_t)(x0 + x)];
		if (put_planes(aw, side ? L2_RIGHT : L2_LEFT, s->fy0, s->ny, BORDER, f,
			       sizeof(float), e) < 0)
			return -1;
	}
	for (int side = 0; side < 2; side++) {
		int y0 = side ? FRAME - BORDER : 0;
		int a = y0 > s->fy0 ? y0 : s->fy0;
		int b = y0 + BORDER < s->fy0 + s->ny ? y0 + BORDER : s->fy0 + s->ny;

		for (int r = 0; r < aw->nres && a < b; r++) {
			for (int y = a; y < b; y++)
				for (int x = 0; x < FRAME; x++)
					f[(size_t)(y - a) * FRAME + (size_t)x] =
						s->l1[(size_t)r * plane +
						      (size_t)(y - s->fy0) * FRAME + (size_t)x];
			if (asdf_out_put(aw->out, side ? L2_TOP : L2_BOTTOM,
					 ((uint64_t)r * BORDER + (uint64_t)(a - y0)) * FRAME * 4, f,
					 (size_t)(b - a) * FRAME * 4, e) < 0)
				return -1;
		}
	}
	return put_amp33(aw, L2_AMP33, s, e);
}

static int asdf_strip(struct writer *w, const struct level_strip *s, struct err *e)
{
	struct asdf_writer *aw = (struct asdf_writer *)w;

	if (s->fy0 != aw->rows_done)
		return err_set(e, EXIT_SYSTEM, "%s: strip at frame row %d, expected %ld", aw->path,
			       s->fy0, aw->rows_done);
	aw->rows_done += s->ny;
	if (aw->level == DETECTOR_L1) {
		if (put_planes(aw, L1_DATA, s->fy0, s->ny, FRAME, s->l1, sizeof(uint16_t), e) < 0 ||
		    put_amp33(aw, L1_AMP33, s, e) < 0 || grow(aw, (size_t)s->ny * FRAME * 2, e) < 0)
			return -1;
		/* the reference read: the reset level the resultants start from */
		for (int i = 0; i < s->ny; i++) {
			uint16_t *row = (uint16_t *)aw->buf + (size_t)i * FRAME;
			struct ramp_det dw = *aw->det;

			/* with the correlated read noise, read 0's (readnoise.h) */
			if (s->rn)
				dw.read_noise = s->rn->par.white;
			ramp_reference_row(&dw, &aw->key, (uint32_t)(s->fy0 + i) * FRAME, FRAME, row,
					   aw->scratch);
			if (s->rn)
				rnoise_add_read0_dn(s->rn, aw->det->gain, s->fy0 + i, 0, FRAME, row);
		}
		return asdf_out_put(aw->out, L1_REF, (uint64_t)s->fy0 * FRAME * 2, aw->buf,
				    (size_t)s->ny * FRAME * 2, e);
	}
	return strip_l2(aw, s, e);
}

static int asdf_sca_end(struct writer *w, struct err *e)
{
	struct asdf_writer *aw = (struct asdf_writer *)w;

	if (aw->rows_done != FRAME)
		return err_set(e, EXIT_SYSTEM, "%s: %ld of %d rows written", aw->path,
			       aw->rows_done, FRAME);
	return 0;
}

static void asdf_free(struct asdf_writer *aw)
{
	free(aw->buf);
	free(aw->amp);
	free(aw->scratch);
	free(aw->path);
	free(aw);
}

static int asdf_commit(struct writer *w, struct err *e)
{
	struct asdf_writer *aw = (struct asdf_writer *)w;
	int r = asdf_out_commit(aw->out, e);

	asdf_free(aw);
	return r;
}

static void asdf_abort(struct writer *w)
{
	struct asdf_writer *aw = (struct asdf_writer *)w;

	if (!aw)
		return;
	asdf_out_abort(aw->out);
	asdf_free(aw);
}

const struct writer_ops writer_asdf = {
	.name = "ASDF",
	.one_sca_per_file = 1,
	.l1_at_l2 = 1,
	.ramp_stats = 1,
	.open = asdf_open,
	.sca_begin = asdf_sca_begin,
	.strip = asdf_strip,
	.sca_end = asdf_sca_end,
	.commit = asdf_commit,
	.abort = asdf_abort,
};
