/*
 * scene.h - one simulated exposure, from catalogs to FITS.
 *
 * The engine streams: each catalog chunk is projected onto the requested
 * SCAs, its rows become placements (a source on one SCA), placements are
 * binned by the tiles their footprints touch, and worker threads render whole
 * tiles, each tile by one worker in catalog order, while the main thread
 * reads the next chunk.  After the last chunk, each strip of tiles gets its
 * background and noise in parallel and is written out.
 */
#ifndef WFS_SCENE_H
#define WFS_SCENE_H

#include <stddef.h>
#include <stdint.h>

struct err;

/* --exptime's upper bound, s (persist.c bounds a state's times by it) */
#define SCENE_EXPTIME_MAX 1e12

struct scene_opts {
	int filter;                     /* enum wfs_filter */
	unsigned sca_mask;              /* bit s-1 for SCA s */
	double ra, dec, pa;             /* pointing, degrees */
	int boresight;                  /* ra/dec is the boresight, not WFI01 */
	int geometry;                   /* GEOM_SIAF (0, the default) or GEOM_STIPS */
	double exptime;                 /* seconds */
	int bunit_counts;               /* output counts instead of counts/s */
	const char *psf;                /* "builtin" or a gridded PSF file */
	const char *psf_cache;          /* NULL: default cache directory */
	int threads;                    /* 0: all cores */
	uint64_t seed;
	int verbose;                    /* -1 quiet, 0 normal, 1.. -v */
	double background;              /* counts/s/pixel: BKG_NUMBER's, or
	                                   BKG_AVG's filter-wide number */
	const char *background_arg;     /* as given, for the header */
	int bkg_model;                  /* enum bkg_model */
	int zodi_norm;                  /* enum bkg_norm */
	int allow_sun;                  /* --allow-sun-angle */
	double date;                    /* MJD (UTC) of --date; NaN for none */
	double memory_mb;               /* --memory: the budget for exposures
	                                   (or an exposure's SCAs) drawn at
	                                   once (run.c); 0: half the memory */
	double epoch;                   /* --epoch: Julian year of catalog
	                                   positions without an epoch column */
	unsigned noise;                 /* enum noise_stage bits */
	double readnoise, dark_current, cosmic_rate, cosmic_residual;
	const char *output;             /* "-", a path, or a path with %d */
	int format;                     /* enum product_format: --format, or
	                                   -o's extension */
	int format_given;
	const char *placed;             /* --placed file or NULL */
	const char *into;               /* --into IMAGE[.fits[HDU]] or NULL: add
	                                   the sources to that image (into.h) */
	const char *report;             /* --report JSON file or NULL */
	const char *pointings;          /* --pointings file: one exposure a line */
	const char *compress;           /* NULL, "none", "rice", "gzip" */
	const char *plugin_path;
	const char *sersic;             /* default method: "quick"/"precise" */
	const char *sersic_flux;        /* NULL (per catalog), "total", "ie" */
	double bright_limit, xbright_limit;
	int tile;                       /* tile side in pixels */
	int row_first, row_last;        /* --rows: FITS rows (1-based) of each
	                                   SCA to draw and write; 0 0 for all */
	size_t chunk;                   /* rows per chunk */
	int flux_unit;                  /* enum flux_unit default */
	int zp_stips;                   /* STIPS's fixed zeropoints */
	const char *const *settings;    /* "key=value" for models (--set), NULL-ended */
	int level;                      /* enum detector_level: --level */
	int ma_table;                   /* --ma-table: read pattern of levels 1, 2 */
	int exptime_given;              /* --exptime was on the command line */
	int ma_table_given;             /* --ma-table was on the command line */
	const char *stage_knob;         /* the first of --readnoise, --dark-current,
	                                   --cosmic-rate, --cosmic-residual given */
	unsigned detector;              /* --detector: enum detector_part bits */
	int detector_given;             /* --detector was on the command line */
	const char *persistence_state;  /* --persistence-state FILE or NULL */
};

/* Simulate the scene from the catalogs (NULL-terminated; "-" is stdin).
 * Returns 0, or -1 with the message and exit status in e. */
int scene_run(const struct scene_opts *o, char *const *catalogs, struct err *e);
/* --chunk's default for o (run.c), its SCAs and --pointings set. */
size_t scene_default_chunk(const struct scene_opts *o);

#endif
