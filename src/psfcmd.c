/*
 * psfcmd.c - `wfiscene psf`: write built-in PSF grids in the STPSF/WebbPSF
 * gridded format, so that photutils' GriddedPSFModel, STIPS or a later
 * `wfiscene --psf FILE` can read them.
 */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "commands.h"
#include "err.h"
#include "instrument.h"
#include "optics.h"
#include "psf.h"

static const char usage[] =
"usage: wfiscene psf --filter F --sca LIST [options] -o FILE\n"
"\n"
"Write the built-in PSF grid of each SCA in LIST (\"1\", \"1-18\", \"2,5\",\n"
"\"WFI05\") for filter F as an STPSF-style gridded PSF FITS file.\n"
"\n"
"  -f, --filter F        F062 F087 F106 F129 F158 F184 F213 F146\n"
"  -s, --sca LIST        SCAs; with more than one, FILE gets _wfiNN\n"
"                        before its .fits suffix, one file per SCA\n"
"  -k, --kind K          epsf (default: pixel and IPC kernels applied)\n"
"                        or psf (the optical PSF)\n"
"      --size N          samples per side: 177 (default), 353 or 705\n"
"      --halo R          the halo instead: 2 samples per pixel over +-R\n"
"                        pixels (32 to 1024), one node unless --grid\n"
"      --grid N          nodes per axis (default 3)\n"
"      --nwave N         wavelengths (default: measured per filter)\n"
"      --pupil-n N       pupil samples across (default 256)\n"
"      --jitter SIGMA    Gaussian jitter per axis, arcsec (default 0.012;\n"
"                        another value bypasses the cache)\n"
"  -j, --threads N       threads for building (default: all cores)\n"
"      --cache-dir DIR   PSF cache (default $WFISCENE_CACHE,\n"
"                        $XDG_CACHE_HOME/wfiscene, ~/.cache/wfiscene)\n"
"      --no-cache        neither read nor write the cache\n"
"  -o, --output FILE     output file\n"
"  -v, --verbose         say what is built or loaded, and how long it took\n"
"  -h, --help            this text\n";

/* FILE with "_wfiNN" before a trailing .fits (or appended). */
static void sca_name(char *buf, size_t n, const char *file, int sca)
{
	size_t len = strlen(file);

	if (len > 5 && !strcasecmp(file + len - 5, ".fits"))
		snprintf(buf, n, "%.*s_wfi%02d.fits", (int)(len - 5), file, sca);
	else
		snprintf(buf, n, "%s_wfi%02d", file, sca);
}

int psf_main(int argc, char **argv)
{
	enum { O_SIZE = 256, O_GRID, O_NWAVE, O_PUPIL, O_CACHE, O_NOCACHE,
	       O_JITTER, O_HALO };
	static const struct option opts[] = {
		{ "filter", required_argument, NULL, 'f' },
		{ "sca", required_argument, NULL, 's' },
		{ "kind", required_argument, NULL, 'k' },
		{ "size", required_argument, NULL, O_SIZE },
		{ "grid", required_argument, NULL, O_GRID },
		{ "nwave", required_argument, NULL, O_NWAVE },
		{ "pupil-n", required_argument, NULL, O_PUPIL },
		{ "threads", required_argument, NULL, 'j' },
		{ "cache-dir", required_argument, NULL, O_CACHE },
		{ "no-cache", no_argument, NULL, O_NOCACHE },
		{ "jitter", required_argument, NULL, O_JITTER },
		{ "halo", required_argument, NULL, O_HALO },
		{ "output", required_argument, NULL, 'o' },
		{ "verbose", no_argument, NULL, 'v' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	struct psf_build_opts bo = { 0 };
	struct err e = { 0 };
	const char *filter_s = NULL, *sca_s = NULL, *out = NULL;
	int kind = PSF_EPSF, cls = 0, c, halo = 0;
	double jit = -1;
	unsigned mask = 0;
	char *end;

	optind = 1;
	opterr = 0;
	while ((c = getopt_long(argc, argv, ":f:s:k:j:o:vh", opts, NULL)) != -1) {
		long v = 0;

		if (optarg && (c == 'j' || c == O_SIZE || c == O_GRID ||
			       c == O_NWAVE || c == O_PUPIL || c == O_HALO)) {
			v = strtol(optarg, &end, 10);
			if (*end || end == optarg || v < 1 || v > 100000) {
				fprintf(stderr, "wfiscene psf: %s: not a positive "
					"integer: '%s'\n", argv[optind - 1], optarg);
				return EXIT_INPUT;
			}
		}
		switch (c) {
		case 'f': filter_s = optarg; break;
		case 's': sca_s = optarg; break;
		case 'o': out = optarg; break;
		case 'v': bo.verbose = 1; break;
		case 'j': bo.threads = (int)v; break;
		case O_GRID: bo.grid = (int)v; break;
		case O_HALO:
			if (v < 32 || v > PSF_HALO_MAX) {
				fprintf(stderr, "wfiscene psf: --halo: want 32 to %d pixels, "
					"not '%s'\n", PSF_HALO_MAX, optarg);
				return EXIT_INPUT;
			}
			halo = (int)v;
			break;
		case O_NWAVE: bo.nwave = (int)v; break;
		case O_PUPIL: bo.pupil_n = (int)v; break;
		case O_CACHE: bo.cache_dir = optarg; break;
		case O_NOCACHE: bo.cache_dir = ""; break;
		case O_JITTER:
			jit = strtod(optarg, &end);
			if (*end || end == optarg || !(jit >= 0 && jit < 1)) {
				fprintf(stderr, "wfiscene psf: --jitter: want "
					"arcsec in [0, 1), not '%s'\n", optarg);
				return EXIT_INPUT;
			}
			break;
		case 'k':
			if (!strcasecmp(optarg, "epsf"))
				kind = PSF_EPSF;
			else if (!strcasecmp(optarg, "psf"))
				kind = PSF_OPTICAL;
			else {
				fprintf(stderr, "wfiscene psf: --kind: want epsf "
					"or psf, not '%s'\n", optarg);
				return EXIT_INPUT;
			}
			break;
		case O_SIZE:
			for (cls = 0; cls < 3 && psf_class_n[cls] != v; cls++)
				;
			if (cls == 3) {
				fprintf(stderr, "wfiscene psf: --size: want 177, "
					"353 or 705, not '%s'\n", optarg);
				return EXIT_INPUT;
			}
			break;
		case 'h':
			fputs(usage, stdout);
			return EXIT_OK;
		case ':':
			fprintf(stderr, "wfiscene psf: %s needs a value\n",
				argv[optind - 1]);
			return EXIT_INPUT;
		default:
			fprintf(stderr, "wfiscene psf: unknown option '%s'\n%s",
				argv[optind - 1], usage);
			return EXIT_INPUT;
		}
	}
	if (optind < argc) {
		fprintf(stderr, "wfiscene psf: unexpected argument '%s'\n",
			argv[optind]);
		return EXIT_INPUT;
	}
	if (!filter_s || !sca_s || !out) {
		fprintf(stderr, "wfiscene psf: --filter, --sca and -o are "
			"required\n%s", usage);
		return EXIT_INPUT;
	}
	if (!strcmp(out, "-")) {
		fprintf(stderr, "wfiscene psf: -o: a PSF grid is written to a "
			"file (atomically), not to standard output\n");
		return EXIT_INPUT;
	}
	if (instrument_init(&e))
		goto fail;
	int filter = filter_lookup(filter_s);
	if (filter < 0) {
		fprintf(stderr, "wfiscene psf: --filter: unknown filter '%s' "
			"(F062 F087 F106 F129 F158 F184 F213 F146)\n", filter_s);
		return EXIT_INPUT;
	}
	if (sca_parse_list(sca_s, &mask, &e)) {
		err_prefix(&e, "--sca");
		goto fail;
	}
	int nsca = 0;
	for (int s = 0; s < WFS_NSCA; s++)
		nsca += (mask >> s) & 1;
	for (int s = 1; s <= WFS_NSCA; s++) {
		char path[4200];
		struct psf_grid *g;

		if (!((mask >> (s - 1)) & 1))
			continue;
		if (nsca > 1)
			sca_name(path, sizeof(path), out, s);
		else
			snprintf(path, sizeof(path), "%s", out);
		if (halo && (kind != PSF_EPSF || (jit >= 0 && jit != OPTICS_JITTER))) {
			fprintf(stderr, "wfiscene psf: --halo is the built-in ePSF: no "
				"--kind psf or --jitter with it\n");
			return EXIT_INPUT;
		}
		if (halo)
			g = psf_builtin_halo(filter, s, halo, bo.grid, &bo, &e);
		else if (jit >= 0 && jit != OPTICS_JITTER)
			g = psf_build_uncached(filter, s, cls, kind, &bo, jit, &e);
		else
			g = psf_builtin(filter, s, cls, kind, &bo, &e);
		if (!g)
			goto fail;
		char c1[81], c2[81], c3[81];
		snprintf(c1, sizeof(c1), "NWAVES  = %d / Number of wavelengths used "
			 "in calculation", bo.nwave > 0 ? bo.nwave :
			 psf_default_nwave(filter));
		snprintf(c2, sizeof(c2), "JITRSIGM= %g / Gaussian sigma for jitter, "
			 "per axis [arcsec]", jit >= 0 ? jit : OPTICS_JITTER);
		snprintf(c3, sizeof(c3), "SRCTEMP = %g / [K] Blackbody source for "
			 "the wavelength weights", OPTICS_BB_TEMP);
		const char *cards[] = {
			c1, c2, c3,
			"COMMENT Built-in Roman WFI PSF of wfiscene: Cycle-9 pupil and",
			"COMMENT Zernikes; planes in STPSF order, positions in DET_YX*",
			"COMMENT (4096-pixel frame); see wfiscene(1), wfiscene psf.",
			NULL
		};
		int rc = psf_grid_write(path, g, cards, &e);
		psf_grid_free(g);
		if (rc)
			goto fail;
	}
	return EXIT_OK;
fail:
	fprintf(stderr, "wfiscene psf: %s\n", e.msg);
	return e.code ? e.code : EXIT_SYSTEM;
}
