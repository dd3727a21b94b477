/* main.c - the wfiscene command line: options, exit statuses, signals. */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "catalog.h"
#include "commands.h"
#include "err.h"
#include "fitsout.h"
#include "geometry.h"
#include "instrument.h"
#include "noise.h"
#include "pool.h"
#include "scene.h"

static const char usage_text[] =
"usage: wfiscene [options] [catalog ...]      simulate a Roman WFI exposure\n"
"       wfiscene psf --filter F --sca LIST -o FILE   write a PSF grid\n"
"       wfiscene preview IN.fits -o OUT.png          make a PNG preview\n"
"       wfiscene merge -o OUT.fits IN.fits ...        join runs split by SCA\n"
"\n"
"Reads source catalogs (CSV, whitespace, IPAC, ECSV or FITS tables, plain,\n"
"gzip or zstd; '-' or none for stdin) and writes one FITS image per SCA.\n"
"\n"
"Scene:\n"
"  -o FILE               output FITS ('-' stdout; '%d' in FILE: one per SCA)\n"
"  --filter F            F062 F087 F106 F129 F158 F184 F213 F146 (required)\n"
"  --sca LIST            SCAs: 1, 1-18, 2,5,9, WFI05 (default 1)\n"
"  --ra DEG --dec DEG    pointing (default 0 0)\n"
"  --pa DEG              position angle of the detectors' +y axis (default 0)\n"
"  --pointing-ref REF    wfi01 (default: ra/dec is WFI01's centre) or boresight\n"
"  --exptime S           exposure time in seconds (default 1)\n"
"  --bunit UNIT          counts/s (default) or counts\n"
"  --placed FILE         write the sources placed on each SCA (CSV)\n"
"  --report FILE         write a JSON report: timings, counts, flux, errors\n"
"  --pointings FILE      several exposures (ra dec pa [name [seed]] a line);\n"
"                        -o, --placed and --report then need a %s for the name\n"
"  --compress C          none (default), rice or gzip tile compression\n"
"  --rows A-B            draw and write only rows A to B of each SCA (a part\n"
"                        for wfiscene merge)\n"
"Sources:\n"
"  --flux-unit U         counts (default), abmag or jy: unit of 'flux' columns\n"
"  --zeropoints Z        rti (per-SCA, 2024-03-01; default) or stips\n"
"  --psf P               builtin (default) or an STPSF gridded PSF file\n"
"  --psf-cache DIR       where built PSF grids are kept\n"
"  --bright-limit M      AB mag at or below which the 88-pixel box is used (14)\n"
"  --xbright-limit M     AB mag at or below which the 176-pixel box is used (3)\n"
"  --sersic METHOD       quick (default) or precise for type 'sersic'\n"
"  --sersic-flux MEANING total (default) or ie: what a Sersic row's flux is\n"
"  --sersic-trunc F      light allowed beyond a galaxy's cut (1e-3 quick, 1e-4 precise)\n"
"  --sersic-tol T        precise: relative tolerance per pixel (default 1e-5)\n"
"  --sersic-core K       half-width of the finely drawn galaxy core (default 1)\n"
"  --sersic-convolve Y   yes (default) or no: convolve galaxies with the PSF\n"
"  --plugin-path DIRS    where to look for source-model plugins first\n"
"  --set KEY=VALUE       a setting for the source models (repeatable)\n"
"Noise:\n"
"  --background B        none (default), avg (STIPS paper Table 1) or counts/s/px\n"
"  --noise LIST          none (default), all, or poisson,readnoise,dark,flat,cosmic\n"
"  --readnoise E         read noise in e- (default 12)\n"
"  --dark-current R      dark current in e-/s/pixel (default 0.028)\n"
"  --cosmic-rate R       hits/cm^2/s per population (default 5)\n"
"  --cosmic-residual F   fraction of each hit kept (default 0.01)\n"
"  --seed N              random seed (default 1234)\n"
"Running:\n"
"  --threads N           worker threads (default: all cores)\n"
"  --tile N              tile side in pixels (default 256)\n"
"  --chunk N             catalog rows per chunk (default 65536)\n"
"  -q, --quiet           no messages but errors\n"
"  -v, --verbose         explain what happens (repeat for more)\n"
"  -h, --help            this text\n"
"  --version             print the version\n"
"\n"
"Exit status: 0 ok, 1 usage or bad input, 2 system or I/O error, 3 model plugin\n"
"error, 4 interrupted.  See wfiscene(1), wfiscene-catalog(5), wfiscene-model(7).\n";

enum {
	OPT_FILTER = 256, OPT_SCA, OPT_RA, OPT_DEC, OPT_PA, OPT_POINTREF, OPT_EXPTIME,
	OPT_BUNIT, OPT_PLACED, OPT_COMPRESS, OPT_FLUXUNIT, OPT_ZP, OPT_PSF, OPT_PSFCACHE,
	OPT_BRIGHT, OPT_XBRIGHT, OPT_SERSIC, OPT_SERSICFLUX, OPT_PLUGINPATH, OPT_BKG,
	OPT_NOISE, OPT_READNOISE, OPT_DARK, OPT_CRRATE, OPT_CRRES, OPT_SEED, OPT_THREADS,
	OPT_TILE, OPT_CHUNK, OPT_VERSION, OPT_REPORT, OPT_SET, OPT_POINTINGS,
	OPT_SERSICTRUNC, OPT_SERSICTOL, OPT_SERSICCORE, OPT_SERSICCONV, OPT_ROWS,
	OPT_GEOMETRY,
};

static const struct option long_options[] = {
	{ "output", required_argument, NULL, 'o' },
	{ "filter", required_argument, NULL, OPT_FILTER },
	{ "sca", required_argument, NULL, OPT_SCA },
	{ "ra", required_argument, NULL, OPT_RA },
	{ "dec", required_argument, NULL, OPT_DEC },
	{ "pa", required_argument, NULL, OPT_PA },
	{ "pointing-ref", required_argument, NULL, OPT_POINTREF },
	{ "geometry", required_argument, NULL, OPT_GEOMETRY },
	{ "exptime", required_argument, NULL, OPT_EXPTIME },
	{ "bunit", required_argument, NULL, OPT_BUNIT },
	{ "placed", required_argument, NULL, OPT_PLACED },
	{ "report", required_argument, NULL, OPT_REPORT },
	{ "set", required_argument, NULL, OPT_SET },
	{ "pointings", required_argument, NULL, OPT_POINTINGS },
	{ "compress", required_argument, NULL, OPT_COMPRESS },
	{ "rows", required_argument, NULL, OPT_ROWS },
	{ "flux-unit", required_argument, NULL, OPT_FLUXUNIT },
	{ "zeropoints", required_argument, NULL, OPT_ZP },
	{ "psf", required_argument, NULL, OPT_PSF },
	{ "psf-cache", required_argument, NULL, OPT_PSFCACHE },
	{ "bright-limit", required_argument, NULL, OPT_BRIGHT },
	{ "xbright-limit", required_argument, NULL, OPT_XBRIGHT },
	{ "sersic", required_argument, NULL, OPT_SERSIC },
	{ "sersic-flux", required_argument, NULL, OPT_SERSICFLUX },
	{ "sersic-trunc", required_argument, NULL, OPT_SERSICTRUNC },
	{ "sersic-tol", required_argument, NULL, OPT_SERSICTOL },
	{ "sersic-core", required_argument, NULL, OPT_SERSICCORE },
	{ "sersic-convolve", required_argument, NULL, OPT_SERSICCONV },
	{ "plugin-path", required_argument, NULL, OPT_PLUGINPATH },
	{ "background", required_argument, NULL, OPT_BKG },
	{ "noise", required_argument, NULL, OPT_NOISE },
	{ "readnoise", required_argument, NULL, OPT_READNOISE },
	{ "dark-current", required_argument, NULL, OPT_DARK },
	{ "cosmic-rate", required_argument, NULL, OPT_CRRATE },
	{ "cosmic-residual", required_argument, NULL, OPT_CRRES },
	{ "seed", required_argument, NULL, OPT_SEED },
	{ "threads", required_argument, NULL, OPT_THREADS },
	{ "tile", required_argument, NULL, OPT_TILE },
	{ "chunk", required_argument, NULL, OPT_CHUNK },
	{ "quiet", no_argument, NULL, 'q' },
	{ "verbose", no_argument, NULL, 'v' },
	{ "help", no_argument, NULL, 'h' },
	{ "version", no_argument, NULL, OPT_VERSION },
	{ NULL, 0, NULL, 0 },
};

static const char *option_name(int c)
{
	for (const struct option *o = long_options; o->name; o++)
		if (o->val == c)
			return o->name;
	return "?";
}

/* A finite number in [lo, hi] for option c. */
static int number(int c, const char *s, double lo, double hi, double *out, struct err *e)
{
	char *end;
	double v;

	errno = 0;
	v = strtod(s, &end);
	if (end == s || *end || errno == ERANGE || !isfinite(v))
		return err_set(e, EXIT_INPUT, "--%s: not a number: '%s'", option_name(c), s);
	if (v < lo || v > hi)
		return err_set(e, EXIT_INPUT, "--%s: %s is out of range [%g, %g]",
			       option_name(c), s, lo, hi);
	*out = v;
	return 0;
}

static int integer(int c, const char *s, long long lo, long long hi, long long *out,
		   struct err *e)
{
	char *end;
	long long v;

	errno = 0;
	v = strtoll(s, &end, 10);
	if (end == s || *end || errno == ERANGE)
		return err_set(e, EXIT_INPUT, "--%s: not an integer: '%s'", option_name(c), s);
	if (v < lo || v > hi)
		return err_set(e, EXIT_INPUT, "--%s: %s is out of range [%lld, %lld]",
			       option_name(c), s, lo, hi);
	*out = v;
	return 0;
}

/* One of the words in choices (NULL-terminated), case-insensitive. */
static int choice(int c, const char *s, const char *const *choices, struct err *e)
{
	char list[256] = "";

	for (int i = 0; choices[i]; i++)
		if (!strcasecmp(s, choices[i]))
			return i;
	for (int i = 0; choices[i]; i++)
		snprintf(list + strlen(list), sizeof(list) - strlen(list), "%s%s",
			 i ? ", " : "", choices[i]);
	return err_set(e, EXIT_INPUT, "--%s: '%s' is not one of %s", option_name(c), s, list);
}

/* An output name may hold one %d (any width flags), for one file per SCA,
 * and with --pointings must hold one %s, for the exposure's name.  what
 * names the option for messages. */
static int check_name(const char *what, const char *s, int pointings, int per_sca,
		      struct err *e)
{
	int nd = 0, ns = 0;

	for (const char *p = s; *p; p++) {
		if (*p != '%')
			continue;
		if (p[1] == '%') {
			p++;
			continue;
		}
		p++;
		if (*p == 's') {
			ns++;
			continue;
		}
		while (*p == '0' || (*p >= '1' && *p <= '9'))
			p++;
		if (*p != 'd')
			return err_set(e, EXIT_INPUT, "%s: '%s': only '%%d' (the SCA) and, with "
				       "--pointings, '%%s' (the exposure) may appear", what, s);
		nd++;
	}
	if (nd && !per_sca)
		return err_set(e, EXIT_INPUT, "%s: '%s': one file covers every SCA; no '%%d'",
			       what, s);
	if (nd > 1 || ns > 1)
		return err_set(e, EXIT_INPUT, "%s: '%s': only one '%%d' and one '%%s' may "
			       "appear in a name", what, s);
	if (ns && !pointings)
		return err_set(e, EXIT_INPUT, "%s: '%s': '%%s' stands for the exposure's name "
			       "and needs --pointings", what, s);
	if (!ns && pointings)
		return err_set(e, EXIT_INPUT, "%s: '%s' needs a '%%s' for the exposure's name "
			       "with --pointings", what, s);
	if (!strcmp(s, "-") && pointings)
		return err_set(e, EXIT_INPUT, "%s: stdout holds one exposure, not several", what);
	return 0;
}

/* --rows A-B: FITS rows A to B (1-based, inclusive) of an SCA. */
static int rows_parse(const char *s, int *first, int *last, struct err *e)
{
	const char *p;
	char *end;
	long a, b;

	errno = 0;
	a = strtol(s, &end, 10);
	if (end == s || *end != '-' || errno)
		goto bad;
	p = end + 1;
	b = strtol(p, &end, 10);
	if (end == p || *end || errno)
		goto bad;
	if (a < 1 || b > WFS_NPIX || a > b)
		return err_set(e, EXIT_INPUT, "--rows: %ld-%ld: want 1 <= A <= B <= %d",
			       a, b, WFS_NPIX);
	*first = (int)a;
	*last = (int)b;
	return 0;
bad:
	return err_set(e, EXIT_INPUT, "--rows: want A-B, two row numbers from 1 to %d, "
		       "got '%s'", WFS_NPIX, s);
}

static void on_fatal_signal(int sig)
{
	static const char msg[] = "wfiscene: interrupted; partial output removed\n";

	fitsout_abort_all_signal();
	scene_remove_temporaries();
	if (write(2, msg, sizeof(msg) - 1) < 0)
		_exit(EXIT_SIGNAL);
	_exit(EXIT_SIGNAL);
}

static void set_signals(void)
{
	struct sigaction sa;

	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = on_fatal_signal;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGHUP, &sa, NULL);
	/* A closed pipe is an I/O error that a write reports, not a death. */
	sa.sa_handler = SIG_IGN;
	sigaction(SIGPIPE, &sa, NULL);
}

/* Options that are shortcuts for --set: store "key=value" in settings,
 * after the caller has checked the value. */
static int add_setting(const char **settings, int *nset, int max, const char *key,
		       const char *value, struct err *e)
{
	size_t len = strlen(key) + strlen(value) + 2;
	char *kv;

	if (*nset == max)
		return err_set(e, EXIT_INPUT, "--%s: too many settings (at most %d)", key, max);
	if (!(kv = malloc(len)))
		return err_sys(e, "--%s", key);
	snprintf(kv, len, "%s=%s", key, value);
	settings[(*nset)++] = kv;
	return 0;
}

static int fail(const struct err *e)
{
	fprintf(stderr, "wfiscene: %s\n", e->msg);
	return e->code ? e->code : EXIT_SYSTEM;
}

int main(int argc, char **argv)
{
	static const char *const refs[] = { "wfi01", "boresight", NULL };
	static const char *const geometries[] = { "siaf", "stips", NULL };
	static const char *const bunits[] = { "counts/s", "counts", NULL };
	static const char *const units[] = { "counts", "abmag", "jy", NULL };
	static const char *const zps[] = { "rti", "stips", NULL };
	static const char *const methods[] = { "quick", "precise", NULL };
	static const char *const meanings[] = { "total", "ie", NULL };
	static const char *const yesno[] = { "yes", "no", NULL };
	static const char *const compressions[] = { "none", "rice", "gzip", NULL };
	struct scene_opts o = {
		.filter = -1, .sca_mask = 1, .exptime = 1, .psf = "builtin", .seed = 1234,
		.readnoise = NOISE_READNOISE, .dark_current = NOISE_DARK_CURRENT,
		.cosmic_rate = NOISE_COSMIC_RATE, .cosmic_residual = NOISE_COSMIC_RESIDUAL,
		.sersic = "quick", .bright_limit = 14, .xbright_limit = 3, .tile = 256,
		.chunk = 65536, .flux_unit = UNIT_COUNTS,
	};
	struct err e = { 0 };
	static char *stdin_only[] = { "-", NULL };
	enum { MAX_SETTINGS = 64 };
	/* Static: the strings add_setting allocates live as long as the
	 * program and stay reachable (LeakSanitizer, make check SANITIZE=1,
	 * reported them as leaks when this array was on the stack). */
	static const char *settings[MAX_SETTINGS + 1];
	int nset = 0;
	long long n;
	int c, k;

	if (argc > 1 && !strcmp(argv[1], "psf"))
		return psf_main(argc - 1, argv + 1);
	if (argc > 1 && !strcmp(argv[1], "preview"))
		return preview_main(argc - 1, argv + 1);
	if (argc > 1 && !strcmp(argv[1], "merge"))
		return merge_main(argc - 1, argv + 1);
	if (instrument_init(&e) < 0)
		return fail(&e);

	while ((c = getopt_long(argc, argv, "o:qvh", long_options, NULL)) != -1) {
		switch (c) {
		case 'o':
			o.output = optarg;
			break;
		case OPT_FILTER:
			if ((o.filter = filter_lookup(optarg)) < 0) {
				err_set(&e, EXIT_INPUT, "--filter: unknown filter '%s': use F062, "
					"F087, F106, F129, F158, F184, F213 or F146", optarg);
				return fail(&e);
			}
			break;
		case OPT_SCA:
			if (sca_parse_list(optarg, &o.sca_mask, &e) < 0)
				return fail(&e);
			break;
		case OPT_RA:
			if (number(c, optarg, -360, 720, &o.ra, &e) < 0)
				return fail(&e);
			break;
		case OPT_DEC:
			if (number(c, optarg, -90, 90, &o.dec, &e) < 0)
				return fail(&e);
			break;
		case OPT_PA:
			if (number(c, optarg, -720, 720, &o.pa, &e) < 0)
				return fail(&e);
			break;
		case OPT_POINTREF:
			if ((k = choice(c, optarg, refs, &e)) < 0)
				return fail(&e);
			o.boresight = k == 1;
			break;
		case OPT_GEOMETRY:
			if ((k = choice(c, optarg, geometries, &e)) < 0)
				return fail(&e);
			o.geometry = k == 1 ? GEOM_STIPS : GEOM_SIAF;
			break;
		case OPT_EXPTIME:
			if (number(c, optarg, 1e-9, 1e12, &o.exptime, &e) < 0)
				return fail(&e);
			break;
		case OPT_BUNIT:
			if ((k = choice(c, optarg, bunits, &e)) < 0)
				return fail(&e);
			o.bunit_counts = k == 1;
			break;
		case OPT_PLACED:
			o.placed = optarg;
			break;
		case OPT_REPORT:
			o.report = optarg;
			break;
		case OPT_POINTINGS:
			o.pointings = optarg;
			break;
		case OPT_SET: {
			const char *eq = strchr(optarg, '=');

			if (!eq || eq == optarg || nset == MAX_SETTINGS) {
				err_set(&e, EXIT_INPUT, "--set: expected KEY=VALUE (at most %d), "
					"got '%s'", MAX_SETTINGS, optarg);
				return fail(&e);
			}
			settings[nset++] = optarg;
			break;
		}
		case OPT_COMPRESS:
			if ((k = choice(c, optarg, compressions, &e)) < 0)
				return fail(&e);
			o.compress = compressions[k];
			break;
		case OPT_ROWS:
			if (rows_parse(optarg, &o.row_first, &o.row_last, &e) < 0)
				return fail(&e);
			break;
		case OPT_FLUXUNIT:
			if ((k = choice(c, optarg, units, &e)) < 0)
				return fail(&e);
			o.flux_unit = k == 0 ? UNIT_COUNTS : k == 1 ? UNIT_ABMAG : UNIT_JY;
			break;
		case OPT_ZP:
			if ((k = choice(c, optarg, zps, &e)) < 0)
				return fail(&e);
			o.zp_stips = k == 1;
			break;
		case OPT_PSF:
			o.psf = strcasecmp(optarg, "builtin") ? optarg : "builtin";
			break;
		case OPT_PSFCACHE:
			o.psf_cache = optarg;
			break;
		case OPT_BRIGHT:
			if (number(c, optarg, -50, 100, &o.bright_limit, &e) < 0)
				return fail(&e);
			break;
		case OPT_XBRIGHT:
			if (number(c, optarg, -50, 100, &o.xbright_limit, &e) < 0)
				return fail(&e);
			break;
		case OPT_SERSIC:
			if ((k = choice(c, optarg, methods, &e)) < 0)
				return fail(&e);
			o.sersic = methods[k];
			break;
		case OPT_SERSICFLUX:
			if ((k = choice(c, optarg, meanings, &e)) < 0)
				return fail(&e);
			o.sersic_flux = meanings[k];
			break;
		case OPT_SERSICTRUNC:
		case OPT_SERSICTOL:
		case OPT_SERSICCORE:
		case OPT_SERSICCONV: {
			double v;
			long long n;

			if ((c == OPT_SERSICTRUNC && number(c, optarg, 1e-12, 0.5, &v, &e) < 0) ||
			    (c == OPT_SERSICTOL && number(c, optarg, 1e-12, 0.1, &v, &e) < 0) ||
			    (c == OPT_SERSICCORE && integer(c, optarg, 0, 16, &n, &e) < 0) ||
			    (c == OPT_SERSICCONV && (k = choice(c, optarg, yesno, &e)) < 0) ||
			    add_setting(settings, &nset, MAX_SETTINGS, option_name(c),
					c == OPT_SERSICCONV ? yesno[k] : optarg, &e) < 0)
				return fail(&e);
			break;
		}
		case OPT_PLUGINPATH:
			o.plugin_path = optarg;
			break;
		case OPT_BKG:
			o.background_arg = optarg;
			if (!strcasecmp(optarg, "none"))
				o.background = 0;
			else if (!strcasecmp(optarg, "avg"))
				o.background = NAN;     /* the filter's, once known */
			else if (number(c, optarg, 0, 1e12, &o.background, &e) < 0)
				return fail(&e);
			break;
		case OPT_NOISE:
			if (noise_parse(optarg, &o.noise, &e) < 0)
				return fail(&e);
			break;
		case OPT_READNOISE:
			if (number(c, optarg, 0, 1e6, &o.readnoise, &e) < 0)
				return fail(&e);
			break;
		case OPT_DARK:
			if (number(c, optarg, 0, 1e6, &o.dark_current, &e) < 0)
				return fail(&e);
			break;
		case OPT_CRRATE:
			if (number(c, optarg, 0, 1e6, &o.cosmic_rate, &e) < 0)
				return fail(&e);
			break;
		case OPT_CRRES:
			if (number(c, optarg, 0, 1, &o.cosmic_residual, &e) < 0)
				return fail(&e);
			break;
		case OPT_SEED: {
			char *end;

			errno = 0;
			o.seed = strtoull(optarg, &end, 10);
			if (end == optarg || *end || errno || optarg[0] == '-') {
				err_set(&e, EXIT_INPUT, "--seed: not an integer from 0 to "
					"18446744073709551615: '%s'", optarg);
				return fail(&e);
			}
			break;
		}
		case OPT_THREADS:
			if (integer(c, optarg, 0, 1024, &n, &e) < 0)
				return fail(&e);
			o.threads = (int)n;
			break;
		case OPT_TILE:
			if (integer(c, optarg, 16, WFS_NPIX, &n, &e) < 0)
				return fail(&e);
			o.tile = (int)n;
			break;
		case OPT_CHUNK:
			if (integer(c, optarg, 1, 1 << 24, &n, &e) < 0)
				return fail(&e);
			o.chunk = (size_t)n;
			break;
		case 'q':
			o.verbose = -1;
			break;
		case 'v':
			o.verbose = o.verbose < 0 ? 1 : o.verbose + 1;
			break;
		case 'h':
			fputs(usage_text, stdout);
			return EXIT_OK;
		case OPT_VERSION:
			printf("wfiscene %s\n", WFS_VERSION);
			return EXIT_OK;
		default:
			fputs(usage_text, stderr);
			return EXIT_INPUT;
		}
	}
	if (o.filter < 0) {
		err_set(&e, EXIT_INPUT, "--filter is required (F062, F087, F106, F129, "
			"F158, F184, F213 or F146)");
		return fail(&e);
	}
	if (isnan(o.background))
		o.background = filter_get(o.filter)->bkg_avg;
	if (!o.output) {
		if (isatty(1)) {
			err_set(&e, EXIT_INPUT, "no output: give -o FILE (or -o - for stdout)");
			return fail(&e);
		}
		o.output = "-";
	}
	if (check_name("-o", o.output, o.pointings != NULL, 1, &e) < 0 ||
	    (o.placed && check_name("--placed", o.placed, o.pointings != NULL, 0, &e) < 0) ||
	    (o.report && check_name("--report", o.report, o.pointings != NULL, 0, &e) < 0))
		return fail(&e);
	if (o.compress && strcmp(o.compress, "none") && !strcmp(o.output, "-")) {
		err_set(&e, EXIT_INPUT, "--compress %s: stdout cannot be tile-compressed "
			"(it is written in one pass); write a file instead", o.compress);
		return fail(&e);
	}
	if (o.row_first && o.compress && strcmp(o.compress, "none")) {
		err_set(&e, EXIT_INPUT, "--rows with --compress %s: the parts of an image "
			"are joined uncompressed (compress the merged file, e.g. with "
			"fpack(1))", o.compress);
		return fail(&e);
	}
	if (o.xbright_limit > o.bright_limit) {
		err_set(&e, EXIT_INPUT, "--xbright-limit %g is fainter than --bright-limit %g",
			o.xbright_limit, o.bright_limit);
		return fail(&e);
	}
	o.settings = settings;
	set_signals();
	if (scene_run(&o, optind < argc ? argv + optind : stdin_only, &e) < 0)
		return fail(&e);
	if (!strcmp(o.output, "-") && (fflush(stdout) != 0 || ferror(stdout))) {
		err_sys(&e, "writing stdout");
		return fail(&e);
	}
	return EXIT_OK;
}
