/*
 * write_fits.c - the FITS writer of an exposure's products (product.h).
 *
 * The primary HDU holds the scene's settings; each SCA is an image
 * extension WFInn (the scene level, written strip by strip as it comes),
 * a cube of resultants WFInn (level 1) or the five planes of the ramp fit,
 * WFInn, WFInn_ERR, WFInn_DQ, WFInn_VAR_POISSON, WFInn_VAR_RNOISE (level
 * 2), whose data fitsout.c writes side by side at their offsets (groups),
 * a strip at a time.  The layout: wfiscene(1), OUTPUT FORMATS.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "background.h"
#include "date.h"
#include "detector.h"
#include "engine.h"
#include "err.h"
#include "fitsout.h"
#include "levels.h"
#include "product.h"

#define FRAME 4096              /* the array with its reference border */
#define BORDER 4

static int add_card(char **cards, int *n, int *cap, const char *card)
{
	if (*n == *cap) {
		char *more = realloc(*cards, (size_t)(*cap ? 2 * *cap : 64) * 80 + 1);

		if (!more)
			return -1;
		*cards = more;
		*cap = *cap ? 2 * *cap : 64;
	}
	memcpy(*cards + (size_t)*n * 80, card, 80);
	(*n)++;
	return 0;
}

static int primary_cards(struct engine *g, char **cards, int *n)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	char c[81], buf[64];
	int cap = 0, bad = 0;
	const char *epoch = getenv("SOURCE_DATE_EPOCH");
	time_t now = epoch && *epoch ? (time_t)strtoll(epoch, NULL, 10) : time(NULL);
	struct tm tm;

	*cards = NULL;
	*n = 0;
#define CARD(fn, k, v, com) (fn(c, k, v, com), bad |= add_card(cards, n, &cap, c))
	CARD(fits_card_str, "ORIGIN", "wfiscene", "Roman WFI scene simulator");
	CARD(fits_card_str, "WFSVERS", WFS_VERSION, "wfiscene version");
	gmtime_r(&now, &tm);
	strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%S", &tm);
	/* SOURCE_DATE_EPOCH pins the date, so two runs can give the same bytes */
	CARD(fits_card_str, "DATE", buf, "file creation date (UTC)");
	CARD(fits_card_str, "TELESCOP", "ROMAN", NULL);
	CARD(fits_card_str, "INSTRUME", "WFI", NULL);
	CARD(fits_card_str, "FILTER", g->filter_name, "optical element");
	CARD(fits_card_dbl, "EXPTIME", o->exptime, "exposure time (s)");
	CARD(fits_card_dbl, "RA_TARG", g->sky.ra0, "pointing RA (deg)");
	CARD(fits_card_dbl, "DEC_TARG", g->sky.dec0, "pointing Dec (deg)");
	CARD(fits_card_dbl, "PA_APER", g->sky.pa0, "position angle of reference +y (deg E of N)");
	CARD(fits_card_str, "POINTREF", x->boresight ? "BORESIGHT" : "WFI01",
	     "what RA_TARG/DEC_TARG point at");
	CARD(fits_card_str, "GEOMETRY", geom_name(o->geometry),
	     o->geometry == GEOM_STIPS ? "0.11\" square aligned SCAs, TAN" : "Roman SIAF, TAN-SIP");
	CARD(fits_card_int, "SEED", (long long)x->seed, "random seed");
	CARD(fits_card_str, "PSFSRC", o->psf, "PSF source");
	CARD(fits_card_str, "BUNIT", o->level == DETECTOR_L1 ? "DN" : o->bunit_counts ?
	     "counts" : "counts/s", NULL);
	if (o->level) {
		CARD(fits_card_str, "LEVEL", o->level == DETECTOR_L1 ? "1" : "2",
		     "detector level (--level)");
		CARD(fits_card_int, "MATABLE", o->ma_table, "MultiAccum table (--ma-table)");
	}
	CARD(fits_card_str, "BKGRND", o->background_arg ? o->background_arg : "none",
	     "background setting");
	/* Only what every SCA shares: a run split by SCA has the same primary. */
	if (o->bkg_model == BKG_AVG)
		CARD(fits_card_dbl, "BKGRATE", x->background,
		     "STIPS Table 1 (counts/s/px); per SCA in HDUs");
	else if (o->bkg_model != BKG_SKY)
		CARD(fits_card_dbl, "BKGRATE", x->background, "background (counts/s/pixel)");
	if (o->bkg_model == BKG_SKY)
		CARD(fits_card_str, "ZODINORM", background_norm_name(o->zodi_norm),
		     "zodiacal light scale (--zodi)");
	if (!isnan(x->date)) {
		char when[32];

		date_format(x->date, when, sizeof(when));
		CARD(fits_card_str, "DATE-OBS", when, "exposure date (UTC)");
		CARD(fits_card_dbl, "MJD-OBS", x->date, "exposure date (MJD, UTC)");
		CARD(fits_card_dbl, "SUNANGLE", x->bkg.sun_angle, "boresight to Sun (deg)");
	}
	snprintf(buf, sizeof(buf), "%s%s%s%s%s", o->noise & NOISE_POISSON ? "P" : "",
		 o->noise & NOISE_READ ? "R" : "", o->noise & NOISE_DARK ? "D" : "",
		 o->noise & NOISE_FLAT ? "F" : "", o->noise & NOISE_COSMIC ? "C" : "");
	CARD(fits_card_str, "NOISE", buf[0] ? buf : "NONE",
	     "P poisson R read D dark F flat C cosmic");
	if (o->noise & NOISE_READ)
		CARD(fits_card_dbl, "RDNOISE", o->readnoise, "read noise (e-)");
	CARD(fits_card_str, "ZPTABLE", o->zp_stips ? "STIPS" : "RTI-20240301",
	     "AB zeropoints used");
	CARD(fits_card_dbl, "BRIGHTLM", o->bright_limit, "bright ePSF box limit (AB)");
	CARD(fits_card_dbl, "XBRITELM", o->xbright_limit, "extra-bright box limit (AB)");
#undef CARD
	return bad ? -1 : 0;
}

static int image_cards(struct engine *g, int s, char **cards, int *n)
{
	const struct scene_opts *o = g->o;
	char c[81], name[16], *wcs = NULL;
	int nwcs = 0, cap = 0, bad = 0, sca = g->slot[s].sca;
	const struct bkg_part *bp = &g->x->bkg.sca[sca - 1];

	*cards = NULL;
	*n = 0;
	if (sky_header(&g->sky, sca, g->ylo, &wcs, &nwcs, g->e) < 0)
		return -1;
	snprintf(name, sizeof(name), "WFI%02d", sca);
#define CARD(fn, k, v, com) (fn(c, k, v, com), bad |= add_card(cards, n, &cap, c))
	CARD(fits_card_str, "EXTNAME", name, "detector");
	CARD(fits_card_str, "DETECTOR", name, NULL);
	CARD(fits_card_str, "FILTER", g->filter_name, NULL);
	CARD(fits_card_dbl, "EXPTIME", o->exptime, "exposure time (s)");
	CARD(fits_card_str, "BUNIT", o->bunit_counts ? "counts" : "counts/s", NULL);
	CARD(fits_card_dbl, "PHOTZPAB", filter_zeropoint(o->filter, sca, o->zp_stips),
	     "AB mag of 1 count/s");
	CARD(fits_card_dbl, "PA_APER", g->sky.sca[sca - 1].pa, "position angle of +y (deg)");
	CARD(fits_card_dbl, "RA_APER", g->sky.sca[sca - 1].ra, "detector centre RA");
	CARD(fits_card_dbl, "DEC_APER", g->sky.sca[sca - 1].dec, "detector centre Dec");
	CARD(fits_card_dbl, "BKGRATE", bp->total, "background (counts/s/pixel)");
	if (o->bkg_model == BKG_AVG || o->bkg_model == BKG_SKY) {
		CARD(fits_card_dbl, "BKGZODI", bp->zodi, "of which zodiacal light");
		CARD(fits_card_dbl, "BKGTHERM", bp->thermal, "of which internal thermal");
	}
	CARD(fits_card_int, "NSOURCES", (long long)g->placed_on[sca - 1], "sources drawn on this SCA");
	if (o->row_first) {
		char rows[32];

		snprintf(rows, sizeof(rows), "%d-%d", o->row_first, o->row_last);
		CARD(fits_card_str, "ROWS", rows, "rows of the SCA in this part (--rows)");
	}
#undef CARD
	for (int k = 0; k < nwcs; k++)
		if (strncmp(wcs + 80 * k, "WCSAXES ", 8) && strncmp(wcs + 80 * k, "COMMENT", 7))
			bad |= add_card(cards, n, &cap, wcs + 80 * k);
	free(wcs);
	return bad ? err_sys(g->e, "header") : 0;
}

/* What the cards of a level's HDUs are made from. */
struct level_cards {
	int level, sca, ylo, yhi;
	const struct ramp_pattern *pat;
	const struct ramp_det *det;
	const char *cards;      /* the SCA's image cards */
	int ncards;
	int correlated;
};

/* Append card c (80 characters) to the list. */
static int push(char **cards, int *n, const char *c)
{
	char *more = realloc(*cards, (size_t)(*n + 1) * 80 + 1);

	if (!more)
		return -1;
	*cards = more;
	memcpy(more + (size_t)*n * 80, c, 80);
	(*n)++;
	return 0;
}

/* The cards of one HDU: the SCA's without EXTNAME, BUNIT and EXPTIME,
 * CRPIXn moved by (dx, dy), then ours. */
static int hdu_cards(const struct level_cards *L, const char *extname, const char *bunit,
		     double dx, double dy, char **cards, int *n)
{
	const struct ramp_pattern *p = L->pat;
	char c[81], key[16], val[32];
	int bad = 0;

	*cards = NULL;
	*n = 0;
	fits_card_str(c, "EXTNAME", extname, NULL);
	bad |= push(cards, n, c);
	if (bunit) {
		fits_card_str(c, "BUNIT", bunit, NULL);
		bad |= push(cards, n, c);
	}
	fits_card_dbl(c, "EXPTIME", p->exptime, "exposure time: last read (s)");
	bad |= push(cards, n, c);
	for (int i = 0; i < L->ncards; i++) {
		const char *in = L->cards + (size_t)i * 80;

		if (!strncmp(in, "EXTNAME ", 8) || !strncmp(in, "BUNIT   ", 8) ||
		    !strncmp(in, "EXPTIME ", 8))
			continue;
		if ((!strncmp(in, "CRPIX1  =", 9) && dx) || (!strncmp(in, "CRPIX2  =", 9) && dy)) {
			char k[9];

			memcpy(k, in, 8);
			k[8] = 0;
			for (int j = 7; j >= 0 && k[j] == ' '; j--)
				k[j] = 0;
			fits_card_dbl(c, k, strtod(in + 10, NULL) + (in[5] == '1' ? dx : dy),
				      "reference pixel (moved by the reference border)");
			bad |= push(cards, n, c);
			continue;
		}
		bad |= push(cards, n, in);
	}
	fits_card_str(c, "LEVEL", L->level == DETECTOR_L1 ? "1" : "2",
		      "1: resultants, 2: ramp fit (wfiscene --level)");
	bad |= push(cards, n, c);
	fits_card_int(c, "MATABLE", p->table, "MultiAccum table");
	bad |= push(cards, n, c);
	fits_card_int(c, "NRESULT", p->nres, "resultants");
	bad |= push(cards, n, c);
	fits_card_dbl(c, "READTIME", p->read_time, "time between reads (s)");
	bad |= push(cards, n, c);
	fits_card_dbl(c, "GAIN", L->det->gain, "e-/DN");
	bad |= push(cards, n, c);
	for (int i = 0; i < p->nres; i++) {
		snprintf(key, sizeof(key), "MAREAD%d", i + 1);
		snprintf(val, sizeof(val), "%d-%d", p->first[i], p->last[i]);
		fits_card_str(c, key, val, "reads averaged into this resultant");
		bad |= push(cards, n, c);
	}
	fits_card_dbl(c, "RDNOISE", L->det->read_noise, "read noise per read (e-)");
	bad |= push(cards, n, c);
	if (L->correlated) {
		/* RDNOISE stays the read noise of a (reference-corrected) read */
		fits_card_bool(c, "RNCORR", 1, "read noise correlated (channels, slow part)");
		bad |= push(cards, n, c);
	}
	fits_card_dbl(c, "DARKCURR", L->det->dark, "dark current (e-/s)");
	bad |= push(cards, n, c);
	fits_card_dbl(c, "SATURATE", L->det->saturation, "saturation (DN, pedestal included)");
	bad |= push(cards, n, c);
	fits_card_dbl(c, "NLBETA", L->det->beta, "measured = true + NLBETA true^2 (e-)");
	bad |= push(cards, n, c);
	fits_card_dbl(c, "PEDESTAL", L->det->pedestal, "reset level (e-)");
	bad |= push(cards, n, c);
	if (L->level == DETECTOR_L2) {
		fits_card_str(c, "RAMPFIT", "OPTIMAL",
			      "Casertano et al. 2022 weights, jumps split");
		bad |= push(cards, n, c);
		fits_card_dbl(c, "JUMPTHR", L->det->jump_threshold, "jump threshold (sigma)");
		bad |= push(cards, n, c);
	}
	if (bad) {
		free(*cards);
		*cards = NULL;
		return -1;
	}
	return 0;
}

/* The HDUs of the SCA, their cards in cards[] (the caller frees them) and
 * their names in name[]: at level 1 one cube of resultants in DN, the
 * reference border included, rows [flo, fhi) of the frame; at level 2 the
 * five planes of the ramp fit, science pixels only, as the Roman pipeline
 * names them.  The number of HDUs, or -1 out of memory. */
static int sca_hdus(const struct level_cards *L, int flo, int fhi, struct fitsout_hdu h[5],
		    char *cards[5], char name[5][24])
{
	static const char *const suffix[5] = { "", "_ERR", "_DQ", "_VAR_POISSON",
					       "_VAR_RNOISE" };
	static const char *const unit[5] = { "counts/s", "counts/s", NULL,
					     "(counts/s)^2", "(counts/s)^2" };
	const struct ramp_pattern *p = L->pat;
	int sca = L->sca, ncards;

	if (L->level == DETECTOR_L1) {
		snprintf(name[0], sizeof(name[0]), "WFI%02d", sca);
		if (hdu_cards(L, name[0], "DN", BORDER, L->ylo == 0 ? BORDER : 0,
			      &cards[0], &ncards) < 0)
			return -1;
		h[0] = (struct fitsout_hdu){ name[0], cards[0], ncards, 16, FRAME,
					     fhi - flo, p->nres };
		return 1;
	}
	for (int k = 0; k < 5; k++) {
		snprintf(name[k], sizeof(name[k]), "WFI%02d%s", sca, suffix[k]);
		if (hdu_cards(L, name[k], unit[k], 0, 0, &cards[k], &ncards) < 0)
			return -1;
		h[k] = (struct fitsout_hdu){ name[k], cards[k], ncards, k == 2 ? 32 : -32,
					     WFS_NPIX, L->yhi - L->ylo, 1 };
	}
	return 5;
}

struct fits_writer {
	struct writer w;
	struct engine *g;
	struct fitsout *f;
	int level, ylo, flo;    /* the SCA being written */
	int nres;
};

static struct writer *fits_open(struct engine *g, const char *path, struct err *e)
{
	struct fits_writer *fw = calloc(1, sizeof(*fw));
	char *cards = NULL;
	int ncards;

	if (!fw) {
		err_sys(e, "output");
		return NULL;
	}
	fw->w.ops = &writer_fits;
	fw->g = g;
	if (primary_cards(g, &cards, &ncards) < 0) {
		err_sys(e, "header");
		goto fail;
	}
	if (!(fw->f = fitsout_open(path, g->o->compress, e)) ||
	    fitsout_primary(fw->f, cards, ncards, e) < 0)
		goto fail;
	free(cards);
	return &fw->w;
fail:
	free(cards);
	fitsout_abort(fw->f);
	free(fw);
	return NULL;
}

static int fits_sca_begin(struct writer *w, const struct product *p, struct err *e)
{
	struct fits_writer *fw = (struct fits_writer *)w;
	struct engine *g = p->g;
	char *cards, *hc[5] = { 0 }, name[5][24];
	struct fitsout_hdu h[5];
	int ncards, nh, r = -1;

	fw->level = p->level;
	fw->ylo = p->ylo;
	fw->nres = p->pat ? p->pat->nres : 0;
	fw->flo = p->ylo == 0 ? 0 : p->ylo + BORDER;
	if (image_cards(g, p->slot, &cards, &ncards) < 0)
		return -1;
	if (p->level == DETECTOR_SCENE) {
		r = fitsout_image_begin(fw->f, WFS_NPIX, p->yhi - p->ylo, cards, ncards, e);
		free(cards);
		return r;
	} else {
		struct level_cards L = { p->level, p->sca, p->ylo, p->yhi, p->pat, p->det, cards, ncards,
					 p->correlated };
		int fhi = p->yhi == WFS_NPIX ? FRAME : p->yhi + BORDER;

		if ((nh = sca_hdus(&L, fw->flo, fhi, h, hc, name)) < 0)
			err_sys(e, "detector level %d: memory", p->level);
		else
			r = fitsout_group_begin(fw->f, nh, h, e);
	}
	free(cards);
	for (int k = 0; k < 5; k++)
		free(hc[k]);
	return r;
}

static int fits_rows(struct writer *w, const float *rows, int nrows, struct err *e)
{
	return fitsout_image_rows(((struct fits_writer *)w)->f, rows, nrows, e);
}

/* The planes of a strip at their places in the file. */
static int fits_strip(struct writer *w, const struct level_strip *s, struct err *e)
{
	struct fits_writer *fw = (struct fits_writer *)w;

	if (fw->level == DETECTOR_L1) {
		for (int g = 0; g < fw->nres; g++)
			if (fitsout_group_rows(fw->f, 0, g, s->fy0 - fw->flo, s->ny,
					       s->l1 + (size_t)g * s->ny * FRAME, e) < 0)
				return -1;
	} else {
		const void *plane[5] = { s->rate, s->err, s->dq, s->var_poisson, s->var_rnoise };

		for (int k = 0; k < 5 && s->nsy > 0; k++)
			if (fitsout_group_rows(fw->f, k, 0, s->sy0 - fw->ylo, s->nsy, plane[k],
					       e) < 0)
				return -1;
	}
	return 0;
}

static int fits_sca_end(struct writer *w, struct err *e)
{
	struct fits_writer *fw = (struct fits_writer *)w;

	return fw->level == DETECTOR_SCENE ? fitsout_image_end(fw->f, e) :
		fitsout_group_end(fw->f, e);
}

static int fits_commit(struct writer *w, struct err *e)
{
	struct fits_writer *fw = (struct fits_writer *)w;
	int r = fitsout_commit(fw->f, e);

	free(fw);
	return r;
}

static void fits_abort(struct writer *w)
{
	struct fits_writer *fw = (struct fits_writer *)w;

	if (!fw)
		return;
	fitsout_abort(fw->f);
	free(fw);
}

const struct writer_ops writer_fits = {
	.name = "FITS",
	.open = fits_open,
	.sca_begin = fits_sca_begin,
	.rows = fits_rows,
	.strip = fits_strip,
	.sca_end = fits_sca_end,
	.commit = fits_commit,
	.abort = fits_abort,
};
