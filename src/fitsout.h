/*
 * fitsout.h - writing the output FITS file.
 *
 * A file is written under a temporary name in the same directory
 * (".NAME.XXXXXX") and renamed to its name by fitsout_commit(), so a failed
 * or interrupted run never leaves a half-written file under the requested
 * name.  "-" streams to stdout with bounded memory (a FITS file is written
 * strictly in order: header, then data, HDU after HDU), which cfitsio's own
 * "-" cannot do (it keeps the whole file in memory).
 *
 * Header cards are passed as one string of ncards 80-character FITS cards
 * (the format wcslib's wcshdo() produces); the writer adds the structural
 * keywords (SIMPLE/XTENSION, BITPIX, NAXISn, PCOUNT, GCOUNT, EXTEND, END).
 */
#ifndef WFS_FITSOUT_H
#define WFS_FITSOUT_H

struct err;
struct fitsout;

/* compress: NULL or "none", "rice", "gzip" (cfitsio tile compression of the
 * image HDUs; refused for stdout, which cannot be compressed in order). */
struct fitsout *fitsout_open(const char *path, const char *compress,
			     struct err *e);

/* The primary HDU: no data, the scene's settings as keywords. */
int fitsout_primary(struct fitsout *f, const char *cards, int ncards,
		    struct err *e);

/* Start an nx x ny float32 image extension with the given cards (EXTNAME,
 * WCS, BUNIT, ...).  Then write its rows in order, FITS row 1 (y = 0) first,
 * any number of rows per call, and end it. */
int fitsout_image_begin(struct fitsout *f, int nx, int ny, const char *cards,
			int ncards, struct err *e);
int fitsout_image_rows(struct fitsout *f, const float *rows, int nrows,
		       struct err *e);
int fitsout_image_end(struct fitsout *f, struct err *e);

/*
 * A group of image HDUs whose data are written side by side, by file
 * offset, in any order (the planes of a level-1 cube, the five images of
 * level 2, one strip of rows at a time): fitsout_group_begin() writes every
 * header and reserves the data; fitsout_group_rows() writes nrows rows of
 * plane `plane` of HDU k from row y0, native values: uint16_t for bitpix
 * 16 (stored with BZERO 32768), uint32_t for 32 (BZERO 2^31), float for
 * -32; fitsout_group_end() checks every row was written.  Needs a file
 * that can seek and no compression (a clear error otherwise).
 */
struct fitsout_hdu {
	const char *name;       /* for messages; EXTNAME goes in cards */
	const char *cards;
	int ncards;
	int bitpix;             /* 16, 32 or -32 */
	long nx, ny, nz;        /* nz > 1: a cube (NAXIS3) */
};

int fitsout_group_begin(struct fitsout *f, int nhdu, const struct fitsout_hdu *h,
			struct err *e);
int fitsout_group_rows(struct fitsout *f, int k, int plane, long y0, int nrows,
		       const void *data, struct err *e);
int fitsout_group_end(struct fitsout *f, struct err *e);

/* Finish: flush, fsync, close, rename to the requested name.  After a
 * failure the temporary file is removed.  Frees f either way. */
int fitsout_commit(struct fitsout *f, struct err *e);

/* Give up: close and remove the temporary file.  Frees f.  NULL is a no-op. */
void fitsout_abort(struct fitsout *f);

/* Format one card "KEY     = value / comment" padded to 80 characters into
 * buf (81 bytes).  Helpers for building card strings. */
void fits_card_str(char *buf, const char *key, const char *value,
		   const char *comment);
void fits_card_dbl(char *buf, const char *key, double value,
		   const char *comment);
void fits_card_int(char *buf, const char *key, long long value,
		   const char *comment);
void fits_card_bool(char *buf, const char *key, int value,
		    const char *comment);

#endif
