/*
 * preview.h - between the three files of `wfiscene preview`: preview.c (the
 * command: options, detector or sky mode, the run), preview_fits.c (FITS
 * images read, averaged down, and placed on the sky by their WCS) and
 * preview_png.c (levels, colour balance, stretch, PNG).  The overview of
 * the method is at the top of preview.c.
 */
#ifndef WFS_PREVIEW_H
#define WFS_PREVIEW_H

#include <limits.h>
#include <stddef.h>

#include <fitsio.h>

struct err;

#define PREVIEW_WIDTH 1024          /* default output width, pixels */
#define PREVIEW_MAX_SIDE 8192       /* largest PNG side we agree to make */
#define PREVIEW_BLOCK_BYTES (4 << 20) /* FITS rows read per call, bytes */
#define PREVIEW_SAMPLE (1 << 20)    /* pixels sampled for the levels */
#define PREVIEW_Q 8.0               /* asinh softening, Lupton's Q */
#define PREVIEW_NPOINT 9            /* outline points per SCA (see below) */
#define PREVIEW_MAX_HDU 4096

enum preview_stretch { PREVIEW_ASINH, PREVIEW_LINEAR };

struct preview_opts {
	const char *in[3];
	int nin;                    /* 1, or 3 with --rgb */
	const char *out;
	char out_default[PATH_MAX];
	int sca;                    /* 0 unset, -1 all, else EXTNAME WFInn */
	int width;
	int stretch;
	double q;
	double vmin, vmax;
	int have_min, have_max;
	int verbose;
};

/* One picture being built: nx x ny floats, row 0 at the top of the PNG,
 * NaN where there is no data (gaps between SCAs, blank pixels). */
struct preview_plane {
	int nx, ny;
	float *pix;
	long src_nx, src_ny;        /* the detector drawn, in detector mode */
};

/* The sky canvas: a gnomonic (TAN) projection about (ra0, dec0) in
 * standard coordinates xi (east) and eta (north), radians.  Canvas pixel
 * (cx, cy) has its centre at xi = xi_max - (cx + 0.5) step,
 * eta = eta_max - (cy + 0.5) step: east left, north up. */
struct preview_sky {
	double ra0, dec0, sin_d0, cos_d0;
	double xi_max, eta_max, step;
	int nx, ny;
};

/* Levels of one band, in the image's units (counts/s). */
struct preview_levels {
	double sky, sigma, white;
	double lo, hi;              /* what the stretch maps to 0 and 1 */
};

struct preview_png {
	const struct preview_plane *pl; /* 1 or 3 */
	const struct preview_levels *lv;
	int nband;
	int alpha;                  /* write transparency for NaN (sky mode) */
	int balanced;               /* bands scaled by PHOTZPAB to one unit */
	int stretch;
	double q;
	char msg[256];              /* libpng's error, if any */
};

/* FITS input (preview_fits.c).  Functions return 0 (or a count) or -1 with
 * the message, naming the file, in e. */

/* Open a FITS file read-only; a missing file and an unreadable one are told
 * apart.  preview_close(NULL) is a no-op. */
int preview_open(const char *path, fitsfile **f, struct err *e);
void preview_close(fitsfile *f);
/* Image HDUs (2-D, non-empty; tile-compressed ones count) of an open file,
 * as 1-based HDU numbers.  Returns how many, or -1. */
int preview_images(fitsfile *f, const char *path, int *hdu, int max,
		   struct err *e);
/* Move to HDU k and name it for messages: "in.fits[WFI03]" or "in.fits[2]". */
int preview_goto(fitsfile *f, const char *path, int k, char *where,
		 size_t wsize, long *nx, long *ny, struct err *e);
/* The image HDU whose EXTNAME is WFInn (or SCAnn) for detector sca. */
int preview_find_sca(fitsfile *f, const char *path, const int *hdu,
		     int n, int sca, struct err *e);
/* Average the current image HDU (nx x ny) onto ox x oy (box means, NaN
 * left out); output row 0 is FITS row 1. */
int preview_bin(fitsfile *f, const char *where, long nx, long ny,
		int ox, int oy, float *out, struct err *e);
/* Image HDUs a file contributes in sky mode: all of them, or --sca's. */
int preview_sky_hdus(fitsfile *f, const char *path, int *hdu,
		     struct err *e);
/* The sky canvas about the mean SCA centre of all inputs, width pixels
 * wide, spanning every SCA outline. */
int preview_sky_layout(const struct preview_opts *o, int width,
		       struct preview_sky *s, struct err *e);
/* Draw the current HDU onto the canvas through its own WCS. */
int preview_sky_draw(fitsfile *f, const char *where, long nx, long ny,
		     const struct preview_sky *s, struct preview_plane *pl,
		     struct err *e);

/* Levels and PNG (preview_png.c). */

/* Sky, noise and white point of a picture, and what the stretch maps to
 * black and white (--min, --max when given). */
int preview_levels(const struct preview_plane *pl, const char *what,
		   const struct preview_opts *o,
		   struct preview_levels *lv, struct err *e);
/* The factor for each band in scale[3] and 1, if every image HDU of the
 * three inputs has a finite PHOTZPAB; else 0.  -1 with an error if a file
 * cannot be read. */
int preview_balance(const struct preview_opts *o, double *scale,
		    struct err *e);
/* Balanced bands: black at each band's own sky, white one common range
 * above it. */
void preview_common_levels(struct preview_levels *lv,
			   const struct preview_opts *o);
/* Write the PNG to o->out, atomically unless it is "-" or a device. */
int preview_png_save(struct preview_png *p, const struct preview_opts *o,
		     struct err *e);

#endif
