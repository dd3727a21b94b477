/*
 * instrument.h - Roman WFI facts the simulator needs: filters, photometric
 * zeropoints, SCA layout.  Built from the embedded tables in data/.
 */
#ifndef WFS_INSTRUMENT_H
#define WFS_INSTRUMENT_H

struct err;

#define WFS_NSCA 18
#define WFS_NPIX 4088           /* science pixels per side */
#define WFS_PIXSCALE 0.11       /* arcsec per pixel, as STIPS uses */
#define WFS_AREA_CM2 36076.7    /* collecting area STIPS uses, cm^2 */

enum wfs_filter {
	F062, F087, F106, F129, F158, F184, F213, F146, WFS_NFILTER
};

/* The filters --filter takes, in the enum's order: the one spelling of the
 * list in the commands' --help and messages. */
#define FILTER_LIST "F062 F087 F106 F129 F158 F184 F213 F146"

struct filter_info {
	const char *name;       /* "F129" */
	double lam_min, lam_max;/* band edges, micron */
	double pivot;           /* micron */
	double zp_ab[WFS_NSCA]; /* AB mag giving 1 e-/s, per SCA */
	double bkg_avg;         /* counts/s/pixel, STIPS paper Table 1 */
	int wide_pupil;         /* 1 for F184 and F213 (the wide mask) */
};

struct sca_info {
	int sca;                /* 1..18 */
	double x_idl, y_idl;    /* centre in the WFI ideal frame of WFI01, arcsec:
	                           +x along detector +x, +y along detector +y */
	double x_bore, y_bore;  /* the same relative to the WFI centre (boresight) */
};

/* Load the tables once.  Returns 0 or -1 (a broken build). */
int instrument_init(struct err *e);

/* Filter by name, case-insensitive ("f129", "F129"); -1 if unknown. */
int filter_lookup(const char *name);
const struct filter_info *filter_get(int filter);
const struct sca_info *sca_get(int sca);

/* Parse an SCA list: "1", "1-18", "2,5,9", "WFI05", "SCA05", "wfi01-wfi03".
 * Sets mask bit (sca - 1).  Returns 0 or -1 with a message. */
int sca_parse_list(const char *s, unsigned *mask, struct err *e);

/* Counts/s for one unit of `unit` in filter f on SCA sca ('c' counts/s,
 * 'j' Jy, 'p' photons/s/cm^2/Hz... as STIPS's mixed catalogs), see
 * wfiscene-catalog(5). */
double unit_to_counts(int filter, int sca, int unit);

/* STIPS 2.3's fixed AB zeropoint of a filter (for --zeropoints stips). */
double filter_stips_zp(int filter);

/* The AB magnitude giving 1 count/s in filter on SCA sca: the SCA's own
 * zeropoint, or with stips (--zeropoints stips) STIPS's fixed one. */
double filter_zeropoint(int filter, int sca, int stips);

#endif
