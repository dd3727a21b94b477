/*
 * catalog.h - reading source catalogs in chunks of rows.
 *
 * Two layers.  The table layer reads any supported format (CSV, whitespace
 * separated, IPAC with \key=value metadata, ECSV, FITS binary tables through
 * cfitsio), plain or compressed (input.h), into a chunk of at most
 * chunk_rows rows: every column as text, with the file line of each row.
 * The catalog layer gives the columns their meaning (wfiscene-catalog(5)):
 * positions, fluxes and units, model type, id, and STIPS's catalog types
 * (internal, mixed, multifilter, generic), and reports a bad value with its
 * place: "stars.csv:12: column 'flux': not a number: 'abc'".
 *
 * Memory is bounded by chunk_rows and the longest line, not by catalog
 * length.  Column names are case-insensitive; they are stored lower-case.
 */
#ifndef WFS_CATALOG_H
#define WFS_CATALOG_H

#include <stddef.h>

struct err;
struct table_chunk;
struct tree_counts;
struct tree_disc;

/* Units a flux value can carry (per file or per row). */
enum flux_unit {
	UNIT_COUNTS = 'c',      /* counts/s (e-/s), the default */
	UNIT_ABMAG = 'm',       /* AB magnitude */
	UNIT_JY = 'j',          /* Jansky */
	UNIT_PHOT = 'p',        /* STIPS mixed 'p' */
	UNIT_ERG = 'e',         /* STIPS mixed 'e' */
	/* Read, never passed on: turned into UNIT_ABMAG as rows are read. */
	UNIT_MAGGIES = 'g',     /* maggies: AB mag = -2.5 log10(value) */
	UNIT_NMGY = 'n',        /* nanomaggies: AB mag = 22.5 - 2.5 log10 */
};

struct catalog_opts {
	int filter;             /* enum wfs_filter of the scene */
	int flux_unit;          /* default unit of a flux column, or 0 for the
	                           file's metadata, else counts/s */
	size_t chunk_rows;      /* rows per chunk; 0 for the default 65536 */
	/* For a catalog tree (a directory, tree.h): the region where rows
	 * matter, and the settings that describe the tree. */
	const struct tree_disc *disc;
	int ndisc;              /* 0: every file of a tree is read */
	const char *const *settings;    /* "key=value", NULL-ended, or NULL */
	double epoch;           /* Julian epoch of positions without an 'epoch'
	                           cell; 0 for MOTION_EPOCH_DEFAULT */
	struct pool *pool;      /* threads that parse a chunk's cells, or NULL */
};

/*
 * One chunk of interpreted rows.  Arrays have n entries and belong to the
 * catalog; they are valid until the next catalog_read() or catalog_close().
 */
struct rows {
	size_t n;
	const char *file;       /* name for messages: path or "<stdin>" */
	long *line;             /* 1-based line (text) or row (FITS) of each row */
	double *ra, *dec;       /* degrees; NaN in both when the row gives x, y */
	double *x, *y;          /* 0-based pixels (the catalog's 1-based minus 1);
	                           NaN when the row gives ra, dec */
	int *sca;               /* SCA of x, y; 0 = the scene's first SCA */
	double *flux;           /* value in unit[i] (NaN never passes: an error) */
	unsigned char *unit;    /* enum flux_unit of each row */
	/* Where the flux came from, for messages (rows_flux_text): its
	 * column, the 'units' column that may give a row its unit (-1 for
	 * none), and the column's own unit, maggies and nanomaggies as such
	 * (unit[] holds them as UNIT_ABMAG). */
	int flux_col;
	int units_col;
	int flux_unit;
	const char **type;      /* model name, lower-case; "point" by default */
	long long *id;          /* the id column, else the 1-based row number */
	/* Proper motion (mas/yr; pmra includes cos dec), parallax (mas) and
	 * the Julian epoch of ra, dec (motion.h): all NULL when the catalog
	 * has none of the pmra, pmdec, parallax columns, else all set (empty
	 * cells 0, the epoch catalog_opts.epoch). */
	double *pmra, *pmdec, *parallax, *epoch;
	/* The spectrum (spectrum.h): both NULL when the catalog has none of
	 * the teff, beta and color_F1_F2 columns, else enum spec_kind and
	 * teff or beta of each row (SPEC_DEFAULT for an empty row). */
	unsigned char *spec_kind;
	double *spec_value;
	int sersic_ie;          /* 1 when this catalog's Sersic fluxes are the
	                           surface brightness at re (STIPS internal) */
	int sky_angle_col;      /* column whose angles are position angles on
	                           the sky (degrees east of north, romanisim's
	                           pa read as "phi"), turned into detector
	                           angles by the engine; -1 for none */
	int roman;              /* 1: the catalog follows romanisim's
	                           convention (ROMANISIM CATALOGS) */

	/* Every column, as text, for models that read columns by name. */
	int ncol;
	char **colname;         /* lower-case names */
	const char ***text;     /* text[col][row]; "" for an empty cell; NULL
	                           for a FITS double not needed as text yet:
	                           rows_text() gives every cell */
	const double **num;     /* num[col][row] of FITS numeric columns, else
	                           NULL or num[col] == NULL */
	const struct table_chunk *chunk;
};

/* The text of cell (col, i); see text above. */
const char *rows_text(const struct rows *r, int col, size_t i);

/* The enum flux_unit a unit's name gives (a column's unit, a fluxunit
 * keyword, a units cell; case and blanks aside), 0 for none known. */
int catalog_unit_code(const char *s);

/* Row i's flux as the catalog gave it, for a message about it: its column,
 * the cell's text and the unit it was read in, as "column 'mag': 20 (AB
 * mag)" or "column 'f158': 1e-9 (maggies)".  Writes at most size bytes
 * to buf (as snprintf) and returns buf.  Reads only, so it may run on any
 * thread; it is not for the per-row path. */
const char *rows_flux_text(const struct rows *r, size_t i, char *buf, size_t size);

struct catalog;

/* Open a catalog file, or stdin for "-", or a catalog tree (a directory of
 * files split by HEALPix pixel, tree.h: its files that reach o's region are
 * read in turn as one catalog).  The format is recognised from the
 * content.  Reads the header (and metadata) so that column errors such as a
 * missing position or flux column are reported here, with the file name. */
struct catalog *catalog_open(const char *path, const struct catalog_opts *o,
			     struct err *e);

/* Read the next chunk.  Returns the number of rows (> 0), 0 at the end of
 * the catalog, or -1 with a message naming file, line, column and value. */
long catalog_read(struct catalog *c, struct rows *r, struct err *e);

/* The index of column name (case-insensitive) in r, or -1. */
int rows_column(const struct rows *r, const char *name);

/* Parse text cell (col, i) as a finite double.  An empty cell gives
 * fallback; a bad one is an error naming the place.  Returns 0 or -1. */
int rows_number(const struct rows *r, int col, size_t i, double fallback,
		double *out, struct err *e);

/* The type a romanisim catalog's type t (case ignored) is read as: "point"
 * for PSF, "sersic" for SER, NULL for any other (read as itself). */
const char *catalog_roman_type(const char *t);

/* Parse s (blanks around it allowed) as a decimal number, correctly
 * rounded.  Returns 0 with *out, 1 when s is not a number, 2 when it is
 * NaN or infinite.  (Used by rows_number; public for plugins' hosts and
 * tests.) */
int catalog_parse_double(const char *s, double *out);

/* Whether the catalog (its first file, for a tree) has a spectrum column,
 * known once it is open, before any row: 0, or the families its columns
 * name, SPECTRAL_BLACKBODY (teff) or'd with SPECTRAL_POWER (beta or
 * color_F1_F2), and SPECTRAL_TYPED when its rows may also name their
 * model (a type column: galaxies, say). */
#define SPECTRAL_BLACKBODY 1
#define SPECTRAL_POWER 2
#define SPECTRAL_TYPED 4
int catalog_spectral(const struct catalog *c);

/* Rows read and raw bytes consumed so far, for reports. */
unsigned long long catalog_rows(const struct catalog *c);
unsigned long long catalog_bytes(const struct catalog *c);

/* For a catalog tree: its counts of files and rows skipped unread (1);
 * 0 for a single file. */
int catalog_tree_counts(const struct catalog *c, struct tree_counts *out);

void catalog_close(struct catalog *c);

#endif
