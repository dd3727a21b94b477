/* main.c - the wfiscene command line: options, exit statuses, signals. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <strings.h>
#include <unistd.h>

#include "background.h"
#include "catalog.h"
#include "commands.h"
#include "date.h"
#include "detector.h"
#include "err.h"
#include "instrument.h"
#include "levels.h"
#include "names.h"
#include "noise.h"
#include "geometry.h"
#include "options.h"
#include "pool.h"
#include "product.h"
#include "into_asdf.h"
#include "scene.h"
#include "tempfile.h"

#define STR_(x) #x
#define STR(x) STR_(x)
#define MAX_SETTINGS 64

/* What the scene command's options fill in. */
struct scene_cmd {
	struct scene_opts o;
	/* "key=value" for the models, from --set and its shortcuts, in the
	 * order given; NULL-ended.  The strings the shortcuts allocate live as
	 * long as the program (the struct is static, so LeakSanitizer sees
	 * them reachable). */
	const char *settings[MAX_SETTINGS + 1];
	int nset;
	unsigned char given[MAX_SETTINGS];     /* from --set itself */
};

#define OFF(f) offsetof(struct scene_cmd, f)

static opt_set_fn set_stage_knob, set_filter, set_sca, set_rows, set_setting, set_model_number,
	set_model_int, set_model_word, set_flux_unit, set_psf, set_background, set_noise,
	set_seed, set_version, set_date, set_exptime, set_level, set_ma_table, set_detector,
	set_format;

static const char *const refs[] = { "wfi01", "boresight", NULL };
/* in the order of enum wfs_geometry */
static const char *const geometries[] = { "siaf", "stips", NULL };
static const char *const bunits[] = { "counts/s", "counts", NULL };
static const char *const units[] = { "counts", "abmag", "jy", NULL };
static const char *const zps[] = { "rti", "stips", NULL };
static const char *const methods[] = { "quick", "precise", NULL };
static const char *const meanings[] = { "total", "ie", NULL };
static const char *const yesno[] = { "yes", "no", NULL };
static const char *const compressions[] = { "none", "rice", "gzip", NULL };
static const char *const formats[] = { "fits", "asdf", NULL };     /* enum product_format */
static const char *const norms[] = { "project", "etc", NULL };    /* enum bkg_norm */

static const struct opt scene_options[] = {
	OPT_SECTION("Scene:"),
	{ OPT("output", 'o', "FILE", NULL, "output FITS or ASDF ('-' stdout; '%d' in FILE: one "
	  "per SCA)", opt_string, OFF(o.output)) },
	{ OPT("format", 0, "F", "asdf for -o *.asdf, else fits", "fits or asdf (Roman's "
	  "levels 1 and 2)", set_format, OFF(o.format)), .words = formats,
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("filter", 0, "F", NULL, FILTER_LIST " (required)",
	  set_filter, OFF(o.filter)) },
	{ OPT("sca", 0, "LIST", "1", "SCAs: 1, 1-18, 2,5,9, WFI05", set_sca, OFF(o.sca_mask)) },
	{ OPT("ra", 0, "DEG", "0", "right ascension of the pointing", opt_double, OFF(o.ra)),
	  .lo = -360, .hi = 720 },
	{ OPT("dec", 0, "DEG", "0", "declination of the pointing", opt_double, OFF(o.dec)),
	  .lo = -90, .hi = 90 },
	{ OPT("pa", 0, "DEG", "0", "position angle of the reference's +y axis", opt_double,
	  OFF(o.pa)), .lo = -720, .hi = 720 },
	{ OPT("pointing-ref", 0, "REF", "wfi01", "wfi01 (ra/dec is WFI01's centre) or boresight",
	  opt_choice, OFF(o.boresight)), .words = refs },
	{ OPT("geometry", 0, "G", "siaf", "siaf (Roman's SIAF distortion) or stips (0.11\" "
	  "square aligned pixels)", opt_choice, OFF(o.geometry)), .words = geometries },
	{ OPT("exptime", 0, "S", "1", "exposure time in seconds", set_exptime, OFF(o.exptime)),
	  .lo = 1e-9, .hi = SCENE_EXPTIME_MAX },
	{ OPT("bunit", 0, "UNIT", "counts/s", "counts/s or counts", opt_choice,
	  OFF(o.bunit_counts)), .words = bunits },
	{ OPT("placed", 0, "FILE", NULL, "write the sources placed on each SCA (CSV)",
	  opt_string, OFF(o.placed)) },
	{ OPT("into", 0, "IMAGE[[N]]", NULL, "add the sources to an existing image, placed by "
	  "its WCS", opt_string, OFF(o.into)) },
	{ OPT("report", 0, "FILE", NULL, "write a JSON report: timings, counts, flux, errors",
	  opt_string, OFF(o.report)) },
	{ OPT("pointings", 0, "FILE", NULL, "several exposures (ra dec pa [name [seed [date]]] a "
	  "line); "
	  "-o, --placed and --report then need a %s for the name", opt_string,
	  OFF(o.pointings)) },
	{ OPT("memory", 0, "MB", "half the RAM, at most 2000 at levels 1 and 2", "memory for the exposures (or an exposure's "
	  "SCAs) drawn at once; the rest in later passes over the catalogs", opt_double,
	  OFF(o.memory_mb)),
	  .lo = 1, .hi = 1e9, .flags = OPT_SHOW_DEFAULT },
	{ OPT("compress", 0, "C", "none", "none, rice or gzip tile compression",
	  opt_choice_word, OFF(o.compress)), .words = compressions },
	{ OPT("rows", 0, "A-B", NULL, "draw and write only rows A to B of each SCA (a part "
	  "for wfiscene merge)", set_rows, OFF(o.row_first)) },
	OPT_SECTION("Sources:"),
	{ OPT("flux-unit", 0, "U", "counts", "counts, abmag or jy: unit of 'flux' columns",
	  set_flux_unit, OFF(o.flux_unit)), .words = units },
	{ OPT("zeropoints", 0, "Z", "rti", "rti (per-SCA, 2024-03-01) or stips", opt_choice,
	  OFF(o.zp_stips)), .words = zps },
	{ OPT("psf", 0, "P", "builtin", "builtin or an STPSF gridded PSF file", set_psf,
	  OFF(o.psf)) },
	{ OPT("psf-cache", 0, "DIR", NULL, "where built PSF grids are kept", opt_string,
	  OFF(o.psf_cache)) },
	{ OPT("bright-limit", 0, "M", "14", "AB mag at or below which the 88-pixel box is used",
	  opt_double, OFF(o.bright_limit)), .lo = -50, .hi = 100 },
	{ OPT("xbright-limit", 0, "M", "3", "AB mag at or below which the 176-pixel box is used",
	  opt_double, OFF(o.xbright_limit)), .lo = -50, .hi = 100 },
	{ OPT("sersic", 0, "METHOD", "quick", "quick or precise for type 'sersic'",
	  opt_choice_word, OFF(o.sersic)), .words = methods },
	{ OPT("sersic-flux", 0, "MEANING", "total, or the catalog's",
	  "total or ie: what a Sersic row's flux is",
	  opt_choice_word, OFF(o.sersic_flux)), .words = meanings, .flags = OPT_SHOW_DEFAULT },
	{ OPT("sersic-trunc", 0, "F", "1e-3 quick, 1e-4 precise",
	  "light allowed beyond a galaxy's cut", set_model_number, 0), .lo = 1e-12, .hi = 0.5,
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("sersic-tol", 0, "T", "1e-5", "precise: relative tolerance per pixel",
	  set_model_number, 0), .lo = 1e-12, .hi = 0.1, .flags = OPT_SHOW_DEFAULT },
	{ OPT("sersic-core", 0, "K", "1", "half-width of the finely drawn galaxy core",
	  set_model_int, 0), .lo = 0, .hi = 16, .flags = OPT_SHOW_DEFAULT },
	{ OPT("sersic-convolve", 0, "Y", "yes", "yes or no: convolve galaxies with the PSF",
	  set_model_word, 0), .words = yesno, .flags = OPT_SHOW_DEFAULT },
	{ OPT("plugin-path", 0, "DIRS", NULL, "where to look for source-model plugins first",
	  opt_string, OFF(o.plugin_path)) },
	{ OPT("set", 0, "KEY=VALUE", NULL, "a setting for the source models (repeatable)",
	  set_setting, 0) },
	OPT_SECTION("Noise:"),
	{ OPT("background", 0, "B", "none", "none, avg (STIPS paper Table 1), sky (zodiacal "
	  "light by position and --date, and thermal) or counts/s/px",
	  set_background, OFF(o.background)), .lo = 0, .hi = 1e12 },
	{ OPT("date", 0, "D", NULL, "UTC date of the exposure: 2027-05-15[T06:30[:12.5]] or an "
	  "MJD", set_date, OFF(o.date)) },
	{ OPT("epoch", 0, "YEAR", "2016.0", "Julian year of the catalogs' positions, for "
	  "pmra, pmdec and parallax", opt_double, OFF(o.epoch)), .lo = 1000, .hi = 3000 },
	{ OPT("zodi", 0, "N", "project", "project or etc: the zodiacal light scale of "
	  "--background sky", opt_choice, OFF(o.zodi_norm)), .words = norms },
	{ OPT("allow-sun-angle", 0, NULL, NULL, "simulate pointings Roman cannot take (the Sun "
	  "outside 54-126 deg)", opt_store_lo, OFF(o.allow_sun)), .lo = 1 },
	{ OPT("noise", 0, "LIST", "none", "none, all, or poisson,readnoise,dark,flat,cosmic",
	  set_noise, OFF(o.noise)) },
	{ OPT("readnoise", 0, "E", STR(NOISE_READNOISE), "read noise in e-", set_stage_knob,
	  OFF(o.readnoise)), .lo = 0, .hi = 1e6 },
	{ OPT("dark-current", 0, "R", STR(NOISE_DARK_CURRENT), "dark current in e-/s/pixel",
	  set_stage_knob, OFF(o.dark_current)), .lo = 0, .hi = 1e6 },
	{ OPT("cosmic-rate", 0, "R", STR(NOISE_COSMIC_RATE), "hits/cm^2/s per population",
	  set_stage_knob, OFF(o.cosmic_rate)), .lo = 0, .hi = 1e6 },
	{ OPT("cosmic-residual", 0, "F", STR(NOISE_COSMIC_RESIDUAL), "fraction of each hit kept",
	  set_stage_knob, OFF(o.cosmic_residual)), .lo = 0, .hi = 1 },
	{ OPT("seed", 0, "N", "1234", "random seed", set_seed, OFF(o.seed)) },
	OPT_SECTION("Detector levels:"),
	{ OPT("level", 0, "L", "scene", "scene (rates), 1 (resultants in DN) or 2 (ramp fits)",
	  set_level, OFF(o.level)) },
	{ OPT("ma-table", 0, "N", "4", "MultiAccum table of levels 1 and 2 (3-17, 109, 110)",
	  set_ma_table, OFF(o.ma_table)), .lo = 1, .hi = 999 },
	{ OPT("detector", 0, "LIST", "persistence at levels 1, 2", "parts of the detector model: all, "
	  "none, or persistence,correlated", set_detector, OFF(o.detector)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("persistence-state", 0, "FILE", NULL, "carry persistence across runs: read "
	  "FILE if it exists, write it at the end", opt_string, OFF(o.persistence_state)) },
	OPT_SECTION("Running:"),
	{ OPT("threads", 0, "N", "all cores", "worker threads", opt_int, OFF(o.threads)),
	  .lo = 0, .hi = 1024, .flags = OPT_SHOW_DEFAULT },
	{ OPT("tile", 0, "N", "256", "tile side in pixels", opt_int, OFF(o.tile)),
	  .lo = 16, .hi = WFS_NPIX },
	{ OPT("chunk", 0, "N", NULL, "catalog rows per chunk (default 262144; with --pointings "
	       "16384 an SCA, 65536 to 262144)", opt_size, OFF(o.chunk)),
	  .lo = 1, .hi = 1 << 24 },
	{ OPT("quiet", 'q', NULL, NULL, "no messages but errors", opt_store_lo, OFF(o.verbose)),
	  .lo = -1 },
	{ OPT("verbose", 'v', NULL, NULL, "explain what happens (repeat for more)", opt_count,
	  OFF(o.verbose)) },
	{ OPT("help", 'h', NULL, NULL, "this text", opt_show_help, 0) },
	{ OPT("version", 0, NULL, NULL, "print the version", set_version, 0) },
	OPT_END
};

static const struct opt_cmd scene_cmd_line = {
	.prog = "wfiscene",
	.usage =
"usage: wfiscene [options] [catalog ...]      simulate a Roman WFI exposure\n"
"       wfiscene psf --filter F --sca LIST -o FILE   write a PSF grid\n"
"       wfiscene preview IN.fits -o OUT.png          make a PNG preview\n"
"       wfiscene merge -o OUT.fits IN.fits ...        join runs split by SCA\n"
"\n"
"Reads source catalogs (CSV, whitespace, IPAC, ECSV or FITS tables, plain,\n"
"gzip or zstd; '-' or none for stdin) and writes one FITS image per SCA.\n"
"\n",
	.epilog =
"\n"
"Exit status: 0 ok, 1 usage or bad input, 2 system or I/O error, 3 model plugin\n"
"error, 4 interrupted.  See wfiscene(1), wfiscene-catalog(5), wfiscene-model(7).\n",
	.opts = scene_options,
};

static int set_filter(const struct opt_arg *a, struct err *e)
{
	if ((*(int *)a->field = filter_lookup(a->value)) < 0)
		return err_set(e, EXIT_INPUT, "--filter: unknown filter '%s': use one of "
			       FILTER_LIST, a->value);
	return 0;
}

static int set_sca(const struct opt_arg *a, struct err *e)
{
	return sca_parse_list(a->value, a->field, e);
}

/* --rows A-B: FITS rows A to B (1-based, inclusive) of an SCA. */
static int set_rows(const struct opt_arg *a, struct err *e)
{
	struct scene_opts *o = &((struct scene_cmd *)a->base)->o;
	const char *s = a->value, *p;
	char *end;
	long lo, hi;

	errno = 0;
	lo = strtol(s, &end, 10);
	if (end == s || *end != '-' || errno)
		goto bad;
	p = end + 1;
	hi = strtol(p, &end, 10);
	if (end == p || *end || errno)
		goto bad;
	if (lo < 1 || hi > WFS_NPIX || lo > hi)
		return err_set(e, EXIT_INPUT, "--rows: %ld-%ld: want 1 <= A <= B <= %d",
			       lo, hi, WFS_NPIX);
	o->row_first = (int)lo;
	o->row_last = (int)hi;
	return 0;
bad:
	return err_set(e, EXIT_INPUT, "--rows: want A-B, two row numbers from 1 to %d, "
		       "got '%s'", WFS_NPIX, s);
}

static int set_setting(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;
	const char *eq = strchr(a->value, '=');

	if (!eq || eq == a->value || c->nset == MAX_SETTINGS)
		return err_set(e, EXIT_INPUT, "--set: expected KEY=VALUE (at most %d), "
			       "got '%s'", MAX_SETTINGS, a->value);
	c->given[c->nset] = 1;
	c->settings[c->nset++] = a->value;
	return 0;
}

/* Each --set whose key nothing in the run asked for (no model the run
 * used declares it, and wfiscene does not read it there): most likely a
 * misspelt key, which would otherwise change nothing without a word. */
static void warn_unread(const struct scene_cmd *c)
{
	for (int i = 0; i < c->nset; i++)
		if (c->given[i] && !setting_was_read(i)) {
			size_t n = (size_t)(strchr(c->settings[i], '=') - c->settings[i]);
			const char *near = setting_nearest(c->settings[i], n);

			fprintf(stderr, "wfiscene: warning: --set %.*s: nothing in this run "
				"reads it (a model the run did not use, or a misspelt key%s%s%s)\n",
				(int)n, c->settings[i], near ? "; did you mean " : "",
				near ? near : "", near ? "?" : "");
		}
}

/* Options that are shortcuts for --set NAME=VALUE: once the value is
 * checked, it is stored as a setting under the option's name. */
static int add_setting(const struct opt_arg *a, const char *value, struct err *e)
{
	struct scene_cmd *c = a->base;
	size_t len = strlen(a->opt->name) + strlen(value) + 2;
	char *kv;

	if (c->nset == MAX_SETTINGS)
		return err_set(e, EXIT_INPUT, "--%s: too many settings (at most %d)",
			       a->opt->name, MAX_SETTINGS);
	if (!(kv = malloc(len)))
		return err_sys(e, "--%s", a->opt->name);
	snprintf(kv, len, "%s=%s", a->opt->name, value);
	c->settings[c->nset++] = kv;
	return 0;
}

static int set_model_number(const struct opt_arg *a, struct err *e)
{
	double v;

	if (opt_parse_double(a, &v, e) < 0)
		return -1;
	return add_setting(a, a->value, e);
}

static int set_model_int(const struct opt_arg *a, struct err *e)
{
	long long v;

	if (opt_parse_ll(a, &v, e) < 0)
		return -1;
	return add_setting(a, a->value, e);
}

/* The table's spelling of the word is stored ("YES" as "yes"). */
static int set_model_word(const struct opt_arg *a, struct err *e)
{
	int k = opt_parse_choice(a, e);

	if (k < 0)
		return -1;
	return add_setting(a, a->opt->words[k], e);
}

static int set_flux_unit(const struct opt_arg *a, struct err *e)
{
	static const int unit[] = { UNIT_COUNTS, UNIT_ABMAG, UNIT_JY };
	int k = opt_parse_choice(a, e);

	if (k < 0)
		return -1;
	*(int *)a->field = unit[k];
	return 0;
}

static int set_psf(const struct opt_arg *a, struct err *e)
{
	*(const char **)a->field = strcasecmp(a->value, "builtin") ? a->value : "builtin";
	return 0;
}

static int set_background(const struct opt_arg *a, struct err *e)
{
	struct scene_opts *o = &((struct scene_cmd *)a->base)->o;

	o->background_arg = a->value;
	o->background = 0;
	if (!strcasecmp(a->value, "none"))
		o->bkg_model = BKG_NONE;
	else if (!strcasecmp(a->value, "avg"))
		o->bkg_model = BKG_AVG;         /* the filter's number, once known */
	else if (!strcasecmp(a->value, "sky"))
		o->bkg_model = BKG_SKY;
	else if (opt_parse_double(a, &o->background, e) < 0)
		return -1;
	else
		o->bkg_model = BKG_NUMBER;
	return 0;
}

static int set_date(const struct opt_arg *a, struct err *e)
{
	return date_parse(a->value, "--date", a->field, e);
}

/* As opt_double, remembering whether the value came from the command line
 * (the defaults are applied with the table's own string). */
static int set_exptime(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;

	c->o.exptime_given = a->value != a->opt->def;
	return opt_double(a, e);
}

/* As opt_double, remembering the first of the scene's noise stages'
 * settings given on the command line (levels 1 and 2 take the
 * detector's own). */
static int set_stage_knob(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;

	if (a->value != a->opt->def && !c->o.stage_knob)
		c->o.stage_knob = a->opt->name;
	return opt_double(a, e);
}

static int set_ma_table(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;

	c->o.ma_table_given = a->value != a->opt->def;
	return opt_int(a, e);
}

static int set_format(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;

	c->o.format_given = 1;
	return opt_choice(a, e);
}

static int set_level(const struct opt_arg *a, struct err *e)
{
	return level_parse(a->value, a->field, e);
}

static int set_detector(const struct opt_arg *a, struct err *e)
{
	struct scene_cmd *c = a->base;

	c->o.detector_given = 1;
	return detector_parse(a->value, a->field, e);
}

static int set_noise(const struct opt_arg *a, struct err *e)
{
	return noise_parse(a->value, a->field, e);
}

static int set_seed(const struct opt_arg *a, struct err *e)
{
	char *end;

	errno = 0;
	*(uint64_t *)a->field = strtoull(a->value, &end, 10);
	if (end == a->value || *end || errno || a->value[0] == '-')
		return err_set(e, EXIT_INPUT, "--seed: not an integer from 0 to "
			       "18446744073709551615: '%s'", a->value);
	return 0;
}

static int set_version(const struct opt_arg *a, struct err *e)
{
	printf("wfiscene %s\n", WFS_VERSION);
	return OPT_EXIT;
}

/* The names the options give (names.h): -o may hold %d, one file per SCA;
 * with --pointings -o, --placed and --report must hold %s, the exposure's
 * name; --psf may hold %d, one grid per SCA.  No other escape is read. */
static int check_names(const struct scene_opts *o, struct err *e)
{
	unsigned expo = o->pointings ? NAME_EXPOSURE : NAME_NEEDS_POINTINGS;
	unsigned need = o->pointings ? NAME_EXPOSURE : 0;

	if (o->pointings && !strcmp(o->output, "-"))
		return err_set(e, EXIT_INPUT, "-o: stdout holds one exposure, not several");
	if (name_check("-o", o->output, NAME_SCA | expo, need, e) < 0 ||
	    (o->placed && name_check("--placed", o->placed, expo, need, e) < 0) ||
	    (o->report && name_check("--report", o->report, expo, need, e) < 0) ||
	    (strcmp(o->psf, "builtin") && name_check("--psf", o->psf, NAME_SCA, 0, e) < 0))
		return -1;
	return 0;
}

static int fail(const struct err *e)
{
	return opt_fail(&scene_cmd_line, OPT_PARSE_FAIL, e);
}

/* What an ASDF output allows: the Roman pipeline's products of a whole SCA
 * in Roman's own geometry, one file per SCA, written at offsets. */
static int check_asdf(const struct scene_opts *o, struct err *e)
{
	if (strcmp(o->compress, "none"))
		return err_set(e, EXIT_INPUT, "--compress %s with ASDF: FITS tile compression; "
			       "an ASDF file's blocks take --set asdf-compression=zlib or lz4",
			       o->compress);
	if (o->level == LEVEL_SCENE)
		return err_set(e, EXIT_INPUT, "-o %s: ASDF holds Roman's level 1 or 2 products; "
			       "add --level 1 or --level 2 (or write FITS)", o->output);
	if (!strcmp(o->output, "-"))
		return err_set(e, EXIT_INPUT, "-o - with ASDF: the blocks are written at "
			       "offsets and need a file, not stdout");
	if (o->row_first)
		return err_set(e, EXIT_INPUT, "--rows with ASDF: a Roman product holds the "
			       "whole SCA (write FITS parts and merge them)");
	if (o->geometry != GEOM_SIAF)
		return err_set(e, EXIT_INPUT, "--geometry stips with ASDF: a Roman product's "
			       "WCS is the SIAF's (use --geometry siaf)");
	if (o->into)
		return err_set(e, EXIT_INPUT, "--into with ASDF output: injection writes the "
			       "image it reads");
	if ((o->sca_mask & (o->sca_mask - 1)) && !(name_fields(o->output) & NAME_SCA))
		return err_set(e, EXIT_INPUT, "-o %s: an ASDF file holds one SCA; put %%d in "
			       "the name for one file per SCA (-o NAME_WFI%%02d.asdf)", o->output);
	/* every file's name is checked once the exposures are read, before
	 * anything is drawn (run.c, asdf_names) */
	return 0;
}

/* --into a Roman level-2 ASDF file: the engine draws a scene in counts/s
 * (written as FITS under the output's name), which into_asdf.c turns into
 * the image with the light added, an ASDF file whatever -o's name. */
static int check_into_asdf(struct scene_opts *o, struct err *e)
{
	if (o->level != LEVEL_SCENE)
		return err_set(e, EXIT_INPUT, "--into %s with --level: the sources are added to "
			       "the level-2 image as a rate (leave --level out)", o->into);
	if (o->bunit_counts)
		return err_set(e, EXIT_INPUT, "--into %s with --bunit counts: the image is in "
			       "DN/s", o->into);
	if (o->geometry != GEOM_SIAF)
		return err_set(e, EXIT_INPUT, "--into %s with --geometry stips: a Roman image is "
			       "placed through the SIAF", o->into);
	o->format = FORMAT_FITS;
	return 0;
}

/* What the options allow only together. */
static int check_options(struct scene_opts *o, struct err *e)
{
	if (o->filter < 0)
		return err_set(e, EXIT_INPUT, "--filter is required (" FILTER_LIST ")");
	if (!o->chunk)
		o->chunk = scene_default_chunk(o);
	if (o->bkg_model == BKG_AVG)
		o->background = filter_get(o->filter)->bkg_avg;
	if (o->bkg_model == BKG_SKY && isnan(o->date) && !o->pointings)
		return err_set(e, EXIT_INPUT, "--background sky needs --date (the Sun's place "
			       "sets the zodiacal light)");
	if (!o->output) {
		if (isatty(1))
			return err_set(e, EXIT_INPUT, "no output: give -o FILE (or -o - for "
				       "stdout)");
		o->output = "-";
	}
	if (check_names(o, e) < 0)
		return -1;
	if (!o->format_given)
		o->format = product_format_of(o->output);
	if (o->into && into_is_asdf(o->into) && check_into_asdf(o, e) < 0)
		return -1;
	if (o->format == FORMAT_ASDF && check_asdf(o, e) < 0)
		return -1;
	if (strcmp(o->compress, "none") && !strcmp(o->output, "-"))
		return err_set(e, EXIT_INPUT, "--compress %s: stdout cannot be tile-compressed "
			       "(it is written in one pass); write a file instead", o->compress);
	if (o->row_first && strcmp(o->compress, "none"))
		return err_set(e, EXIT_INPUT, "--rows with --compress %s: the parts of an image "
			       "are joined uncompressed (compress the merged file, e.g. with "
			       "fpack(1))", o->compress);
	if (o->level == LEVEL_SCENE && o->ma_table_given)
		return err_set(e, EXIT_INPUT, "--ma-table %d without --level 1 or 2: a read "
			       "pattern is for the detector levels (the scene level takes "
			       "--exptime)", o->ma_table);
	if (o->level != LEVEL_SCENE) {
		struct ramp_pattern p;
		struct stat st;
		const char *lv = o->level == LEVEL_1 ? "1" : "2";

		if (ramp_pattern_get(o->ma_table, &p, e) < 0)
			return -1;
		if (o->exptime_given && fabs(o->exptime - p.exptime) > 1e-3)
			return err_set(e, EXIT_INPUT, "--exptime %g with --level %s: MA table %d "
				       "lasts %.3f s (its last read); leave --exptime out or "
				       "choose another --ma-table", o->exptime, lv, o->ma_table,
				       p.exptime);
		o->exptime = p.exptime;
		if (o->noise)
			return err_set(e, EXIT_INPUT, "--noise with --level %s: levels 1 and 2 "
				       "simulate the detector's noise themselves (see wfiscene(1), "
				       "DETECTOR LEVELS)", lv);
		if (o->stage_knob)
			return err_set(e, EXIT_INPUT, "--%s with --level %s: it sets the scene "
				       "level's noise stages; levels 1 and 2 take the detector's "
				       "own read noise, dark current and cosmic rays (see "
				       "wfiscene(1), DETECTOR LEVELS)", o->stage_knob, lv);
		if (o->bunit_counts)
			return err_set(e, EXIT_INPUT, "--bunit counts with --level %s: level 1 "
				       "is in DN and level 2 in counts/s", lv);
		if (strcmp(o->compress, "none"))
			return err_set(e, EXIT_INPUT, "--compress %s with --level %s: the planes "
				       "are written side by side, uncompressed (compress the file "
				       "afterwards, e.g. with fpack(1))", o->compress, lv);
		if (!strcmp(o->output, "-"))
			return err_set(e, EXIT_INPUT, "-o - with --level %s: the planes are "
				       "written side by side and need a file, not stdout", lv);
		if (o->format != FORMAT_ASDF && !name_fields(o->output) &&
		    stat(o->output, &st) == 0 &&
		    (S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode)))
			return err_set(e, EXIT_INPUT, "-o %s with --level %s: the planes are "
				       "written side by side and need a file that can seek, not "
				       "a pipe", o->output, lv);
	}
	/* the parts of the detector model: all the data supports at levels
	 * 1 and 2, none at the scene level, unless --detector says */
	if (!o->detector_given)
		o->detector = o->level != LEVEL_SCENE ? DETECTOR_DEFAULT : 0;
	if (o->persistence_state && !(o->detector & DETECTOR_PERSISTENCE))
		return err_set(e, EXIT_INPUT, "--persistence-state without persistence: it is "
			       "on by default at --level 1 and 2; at the scene level give "
			       "--detector persistence");
	if (o->xbright_limit > o->bright_limit)
		return err_set(e, EXIT_INPUT, "--xbright-limit %g is fainter than "
			       "--bright-limit %g", o->xbright_limit, o->bright_limit);
	return 0;
}

int main(int argc, char **argv)
{
	static struct scene_cmd cmd = { .o = { .filter = -1, .date = NAN } };
	static char *stdin_only[] = { "-", NULL };
	struct err e = { 0 };
	int first;

	/* One signal policy for every subcommand, before any of them can make
	 * a file: a fatal signal removes the temporaries and exits 4. */
	if (argc > 1 && (!strcmp(argv[1], "psf") || !strcmp(argv[1], "preview") ||
			 !strcmp(argv[1], "merge"))) {
		char prog[32];

		snprintf(prog, sizeof(prog), "wfiscene %s", argv[1]);
		tempfile_signals(prog);
	} else {
		tempfile_signals("wfiscene");
	}
	if (argc > 1 && !strcmp(argv[1], "psf"))
		return psf_main(argc - 1, argv + 1);
	if (argc > 1 && !strcmp(argv[1], "preview"))
		return preview_main(argc - 1, argv + 1);
	if (argc > 1 && !strcmp(argv[1], "merge"))
		return merge_main(argc - 1, argv + 1);
	if (instrument_init(&e) < 0 || background_init(&e) < 0)
		return fail(&e);
	first = opt_parse(&scene_cmd_line, argc, argv, &cmd, &e);
	if (first == OPT_PARSE_DONE)
		return EXIT_OK;
	if (first < 0)
		return opt_fail(&scene_cmd_line, first, &e);
	if (check_options(&cmd.o, &e) < 0)
		return fail(&e);
	cmd.o.settings = cmd.settings;
	setting_watch(cmd.settings);
	if (scene_run(&cmd.o, first < argc ? argv + first : stdin_only, &e) < 0)
		return fail(&e);
	warn_unread(&cmd);
	if (!strcmp(cmd.o.output, "-") && (fflush(stdout) != 0 || ferror(stdout))) {
		err_sys(&e, "writing stdout");
		return fail(&e);
	}
	return EXIT_OK;
}
