/*
 * psfcmd.c - `wfiscene psf`: write built-in PSF grids in the STPSF/WebbPSF
 * gridded format, so that photutils' GriddedPSFModel, STIPS or a later
 * `wfiscene --psf FILE` can read them.
 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "commands.h"
#include "err.h"
#include "geometry.h"
#include "instrument.h"
#include "names.h"
#include "optics.h"
#include "options.h"
#include "psf.h"
#include "spectrum.h"

#define STR_(x) #x
#define STR(x) STR_(x)

/* What the psf command's options fill in. */
struct psf_cmd {
	struct psf_build_opts bo;
	const char *filter, *sca, *out;
	int kind;               /* enum psf_kind */
	int cls;                /* index into psf_class_n */
	double jitter;          /* arcsec; -1: the default, through the cache */
	int halo;               /* --halo R: the halo of +-R pixels, 0 for none */
	int geometry;           /* enum wfs_geometry */
	double teff, beta;      /* NaN: not given */
	int report;             /* --report: list the spectral classes */
	int classes;            /* --classes N for --report; 0: the default */
};

#define OFF(f) offsetof(struct psf_cmd, f)

/* in the order of enum wfs_geometry */
static const char *const geometries[] = { "siaf", "stips", NULL };

static opt_set_fn set_count, set_kind, set_size, set_jitter, set_no_cache, set_teff,
	set_beta;

static const struct opt psf_options[] = {
	{ OPT("filter", 'f', "F", NULL, FILTER_LIST,
	  opt_string, OFF(filter)) },
	{ OPT("sca", 's', "LIST", NULL, "SCAs; with more than one, FILE gets _wfiNN before "
	  "its .fits suffix, one file per SCA", opt_string, OFF(sca)) },
	{ OPT("kind", 'k', "K", "epsf", "epsf (pixel and IPC kernels applied), epsf-noipc "
	  "(the pixel kernel only, as levels 1 and 2 draw) or psf (the optical PSF)",
	  set_kind, OFF(kind)) },
	{ OPT("size", 0, "N", "177", "samples per side: 177, 353 or 705", set_size,
	  OFF(cls)) },
	{ OPT("halo", 0, "R", NULL, "the halo instead (the far wing of bright stars): "
	  "2 samples per pixel over +-R pixels (32 to " STR(PSF_HALO_MAX) "), one node "
	  "unless --grid", opt_int, OFF(halo)), .lo = 32, .hi = PSF_HALO_MAX },
	{ OPT("geometry", 'G', "G", "siaf", "the pixels the PSF is sampled on: siaf (each "
	  "SCA's own, through the SIAF's local Jacobian at each node) or stips (0.11\" "
	  "square)", opt_choice, OFF(geometry)), .words = geometries },
	{ OPT("teff", 0, "T", NULL, "the PSF of a blackbody of T K (1000 to 100000) instead "
	  "of the default 5700 K", set_teff, OFF(teff)) },
	{ OPT("beta", 0, "B", NULL, "the PSF of a power law f_nu ~ nu^B (-20 to 20)", set_beta,
	  OFF(beta)) },
	{ OPT("report", 0, NULL, NULL, "list the spectral classes of the filter on each SCA "
	  "(their slopes and effective wavelengths) on standard output", opt_count,
	  OFF(report)) },
	{ OPT("classes", 0, "N", "measured per filter", "spectral classes for --report, as "
	  "--set psf-colour-classes", opt_int, OFF(classes)), .lo = 2, .hi = PSF_COLOUR_MAX,
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("grid", 0, "N", "3", "nodes per axis", set_count, OFF(bo.grid)),
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("nwave", 0, "N", "measured per filter", "wavelengths", set_count,
	  OFF(bo.nwave)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("pupil-n", 0, "N", "256", "pupil samples across", set_count, OFF(bo.pupil_n)),
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("jitter", 0, "SIGMA", STR(OPTICS_JITTER), "Gaussian jitter per axis, arcsec; "
	  "another value than the default bypasses the cache", set_jitter, OFF(jitter)),
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("threads", 'j', "N", "all cores", "threads for building", set_count,
	  OFF(bo.threads)), .flags = OPT_SHOW_DEFAULT },
	{ OPT("cache-dir", 0, "DIR", "$WFISCENE_CACHE, $XDG_CACHE_HOME/wfiscene, "
	  "~/.cache/wfiscene", "PSF cache", opt_string, OFF(bo.cache_dir)),
	  .flags = OPT_SHOW_DEFAULT },
	{ OPT("no-cache", 0, NULL, NULL, "neither read nor write the cache", set_no_cache,
	  OFF(bo.cache_dir)) },
	{ OPT("output", 'o', "FILE", NULL, "output file", opt_string, OFF(out)) },
	{ OPT("verbose", 'v', NULL, NULL, "say what is built or loaded, and how long it "
	  "took", opt_count, OFF(bo.verbose)) },
	{ OPT("help", 'h', NULL, NULL, "this text", opt_show_help, 0) },
	OPT_END
};

static const struct opt_cmd psf_cmd_line = {
	.prog = "wfiscene psf",
	.usage =
"usage: wfiscene psf --filter F --sca LIST [options] -o FILE\n"
"\n"
"Write the built-in PSF grid of each SCA in LIST (\"1\", \"1-18\", \"2,5\",\n"
"\"WFI05\") for filter F as an STPSF-style gridded PSF FITS file.\n"
"\n",
	.opts = psf_options,
};

/* A count: an integer from 1 to 100000. */
static int set_count(const struct opt_arg *a, struct err *e)
{
	char *end;
	long v = strtol(a->value, &end, 10);

	if (*end || end == a->value || v < 1 || v > 100000)
		return err_set(e, EXIT_INPUT, "%s: not an integer from 1 to 100000: '%s'",
			       a->given, a->value);
	*(int *)a->field = (int)v;
	return 0;
}

static int set_size(const struct opt_arg *a, struct err *e)
{
	int n, cls;

	if (set_count(&(struct opt_arg){ .given = a->given, .value = a->value,
					 .field = &n }, e) < 0)
		return -1;
	for (cls = 0; cls < 3 && psf_class_n[cls] != n; cls++)
		;
	if (cls == 3)
		return err_set(e, EXIT_INPUT, "--size: want 177, 353 or 705, not '%s'",
			       a->value);
	*(int *)a->field = cls;
	return 0;
}

static int set_kind(const struct opt_arg *a, struct err *e)
{
	if (!strcasecmp(a->value, "epsf"))
		*(int *)a->field = PSF_EPSF;
	else if (!strcasecmp(a->value, "epsf-noipc"))
		*(int *)a->field = PSF_EPSF_NOIPC;
	else if (!strcasecmp(a->value, "psf"))
		*(int *)a->field = PSF_OPTICAL;
	else
		return err_set(e, EXIT_INPUT, "--kind: want epsf, epsf-noipc or psf, not '%s'",
			       a->value);
	return 0;
}

static int set_jitter(const struct opt_arg *a, struct err *e)
{
	char *end;
	double v = strtod(a->value, &end);

	if (*end || end == a->value || !(v >= 0 && v < 1))
		return err_set(e, EXIT_INPUT, "--jitter: want arcsec in [0, 1), not '%s'",
			       a->value);
	*(double *)a->field = v;
	return 0;
}

static int set_teff(const struct opt_arg *a, struct err *e)
{
	char *end;
	double v = strtod(a->value, &end);

	if (*end || end == a->value || !(v >= SPEC_TEFF_MIN && v <= SPEC_TEFF_MAX))
		return err_set(e, EXIT_INPUT, "--teff: want a temperature from %g to %g K, "
			       "not '%s'", SPEC_TEFF_MIN, SPEC_TEFF_MAX, a->value);
	*(double *)a->field = v;
	return 0;
}

static int set_beta(const struct opt_arg *a, struct err *e)
{
	char *end;
	double v = strtod(a->value, &end);

	if (*end || end == a->value || !(fabs(v) <= SPEC_BETA_MAX))
		return err_set(e, EXIT_INPUT, "--beta: want a slope from %g to %g, not '%s'",
			       -SPEC_BETA_MAX, SPEC_BETA_MAX, a->value);
	*(double *)a->field = v;
	return 0;
}

static int set_no_cache(const struct opt_arg *a, struct err *e)
{
	*(const char **)a->field = "";
	return 0;
}

/* FILE with "_wfiNN" before a trailing .fits (or appended); -1 when that
 * does not fit in n bytes. */
static int sca_name(char *buf, size_t n, const char *file, int sca)
{
	size_t len = strlen(file);
	int r;

	if (len > 5 && !strcasecmp(file + len - 5, ".fits"))
		r = snprintf(buf, n, "%.*s_wfi%02d.fits", (int)(len - 5), file, sca);
	else
		r = snprintf(buf, n, "%s_wfi%02d", file, sca);
	return r < 0 || (size_t)r >= n ? -1 : 0;
}

/* --report: the filter's spectral classes (psf.h) on each SCA of the list,
 * as a table on standard output: SCA, class, spectrum, effective
 * wavelength, and with --teff or --beta that spectrum's own (fractional)
 * class and effective wavelength. */
static int report_classes(const struct psf_cmd *c)
{
	struct err e = { 0 };
	struct psf_classes pc;
	struct colour *col = NULL;
	unsigned mask;
	int filter;

	if (instrument_init(&e) || (filter = filter_lookup(c->filter)) < 0 ||
	    sca_parse_list(c->sca, &mask, &e) || !(col = colour_new(filter, &e)) ||
	    psf_classes_make(&pc, col, filter, c->classes > 0 ? c->classes :
			     psf_default_classes(filter), &e)) {
		fprintf(stderr, "wfiscene psf: --report: %s\n", e.msg[0] ? e.msg : "unknown filter");
		colour_free(col);
		return EXIT_INPUT;
	}
	printf("# spectral classes of %s (psf-colour-classes %d)\n", c->filter, pc.n);
	printf("sca\tclass\tspectrum\tlam_eff\n");
	for (int s = 1; s <= WFS_NSCA; s++) {
		if (!((mask >> (s - 1)) & 1))
			continue;
		for (int k = 0; k < 2 * pc.n; k++) {
			int kind;
			double v;

			psf_classes_spectrum(&pc, k, &kind, &v);
			printf("%d\t%d\t%s %.6g\t%.6f\n", s, k, kind == SPEC_POWER ? "beta" : "teff",
			       v, pc.lam[s - 1][k >= pc.n][k % pc.n]);
		}
		if (!isnan(c->teff) || !isnan(c->beta)) {
			struct spectrum sp = { isnan(c->teff) ? SPEC_POWER : SPEC_BLACKBODY,
					       isnan(c->teff) ? c->beta : c->teff };

			printf("%d\t%.4f\t%s %.6g\t%.6f\n", s, psf_classes_of(&pc, col, s, &sp),
			       isnan(c->teff) ? "beta" : "teff", sp.value,
			       colour_lam_eff(col, s, &sp));
		}
	}
	colour_free(col);
	return EXIT_OK;
}

/* Build SCA s's grid as the command line asks (halo, optical PSF with its
 * own jitter, or the built-in ePSF) and write it to path with the cards
 * that say how it was made.  0, or -1 with e set. */
static int write_grid(struct psf_cmd *c, int filter, int s, const char *path,
		      struct err *e)
{
	struct psf_build_opts *bo = &c->bo;
	struct psf_grid *g;

	if (c->halo && (c->kind == PSF_OPTICAL || (c->jitter >= 0 && c->jitter != OPTICS_JITTER))) {
		err_set(e, EXIT_INPUT, "--halo is the built-in ePSF: no --kind psf or "
			"--jitter with it");
		return -1;
	}
	if (c->halo)
		g = psf_builtin_halo(filter, s, c->halo, bo->grid, c->kind, bo, e);
	else if (c->jitter >= 0 && c->jitter != OPTICS_JITTER)
		g = psf_build_uncached(filter, s, c->cls, c->kind, bo, c->jitter, e);
	else
		g = psf_builtin(filter, s, c->cls, c->kind, bo, e);
	if (!g)
		return -1;
	char c1[81], c2[81], c3[81], c4[81];
	snprintf(c1, sizeof(c1), "NWAVES  = %d / Number of wavelengths used "
		 "in calculation", bo->nwave > 0 ? bo->nwave :
		 psf_default_nwave(filter));
	snprintf(c2, sizeof(c2), "JITRSIGM= %g / Gaussian sigma for jitter, "
		 "per axis [arcsec]", c->jitter >= 0 ? c->jitter : OPTICS_JITTER);
	if (bo->spec_kind == SPEC_POWER)
		snprintf(c3, sizeof(c3), "SRCBETA = %.10g / Source f_nu ~ nu^beta for "
			 "the wavelength weights", bo->spec_value);
	else
		snprintf(c3, sizeof(c3), "SRCTEMP = %.10g / [K] Blackbody source for "
			 "the wavelength weights", bo->spec_kind ? bo->spec_value :
			 OPTICS_BB_TEMP);
	snprintf(c4, sizeof(c4), "GEOMETRY= '%s' / %s", geom_name(c->geometry),
		 c->geometry == GEOM_SIAF ? "sampled on the SCA's own pixels (SIAF)" :
		 "sampled on 0.11\" square pixels (STIPS)");
	const char *cards[] = {
		c1, c2, c3, c4,
		"COMMENT Built-in Roman WFI PSF of wfiscene: Cycle-9 pupil and",
		"COMMENT Zernikes; planes in STPSF order, positions in DET_YX*",
		"COMMENT (4096-pixel frame); see wfiscene(1), wfiscene psf.",
		NULL
	};
	int rc = psf_grid_write(path, g, cards, e);

	psf_grid_free(g);
	return rc ? -1 : 0;
}

int psf_main(int argc, char **argv)
{
	struct psf_cmd c = { .jitter = -1, .teff = NAN, .beta = NAN };
	struct psf_build_opts *bo = &c.bo;
	struct err e = { 0 };
	const char *out;
	unsigned mask = 0;
	int first;

	first = opt_parse(&psf_cmd_line, argc, argv, &c, &e);
	if (first == OPT_PARSE_DONE)
		return EXIT_OK;
	if (first < 0)
		return opt_fail(&psf_cmd_line, first, &e);
	if (first < argc) {
		fprintf(stderr, "wfiscene psf: unexpected argument '%s'\n", argv[first]);
		return EXIT_INPUT;
	}
	if (c.report && c.filter && c.sca && !c.out)
		return report_classes(&c);
	if (!c.filter || !c.sca || !c.out) {
		fprintf(stderr, "wfiscene psf: --filter, --sca and -o are required\n");
		opt_help(&psf_cmd_line, stderr);
		return EXIT_INPUT;
	}
	out = c.out;
	if (!strcmp(out, "-")) {
		fprintf(stderr, "wfiscene psf: -o: a PSF grid is written to a "
			"file (atomically), not to standard output\n");
		return EXIT_INPUT;
	}
	/* '%d' (the SCA) and '%%' are the escapes of -o (names.h) */
	if (name_check("-o", out, NAME_SCA, 0, &e) < 0)
		goto fail;
	if (instrument_init(&e))
		goto fail;
	int filter = filter_lookup(c.filter);
	if (filter < 0) {
		fprintf(stderr, "wfiscene psf: --filter: unknown filter '%s' "
			"(" FILTER_LIST ")\n", c.filter);
		return EXIT_INPUT;
	}
	if (sca_parse_list(c.sca, &mask, &e)) {
		err_prefix(&e, "--sca");
		goto fail;
	}
	bo->pixgrid = c.geometry == GEOM_SIAF ? PSF_PIX_SIAF : PSF_PIX_SQUARE;
	if (!isnan(c.teff) && !isnan(c.beta)) {
		err_set(&e, EXIT_INPUT, "--teff and --beta: give one spectrum");
		goto fail;
	}
	if (!isnan(c.teff) || !isnan(c.beta)) {
		bo->spec_kind = isnan(c.teff) ? SPEC_POWER : SPEC_BLACKBODY;
		bo->spec_value = isnan(c.teff) ? c.beta : c.teff;
	}
	if (c.report && report_classes(&c) != EXIT_OK)
		return EXIT_INPUT;
	int nsca = 0;
	for (int s = 0; s < WFS_NSCA; s++)
		nsca += (mask >> s) & 1;
	for (int s = 1; s <= WFS_NSCA; s++) {
		char path[4200];

		if (!((mask >> (s - 1)) & 1))
			continue;
		if (name_expand(path, sizeof(path), "-o", out, s, NULL, &e) < 0)
			goto fail;
		if (nsca > 1 && !(name_fields(out) & NAME_SCA)) {
			char base[sizeof(path)];

			memcpy(base, path, sizeof(base));
			if (sca_name(path, sizeof(path), base, s) < 0) {
				err_set(&e, EXIT_INPUT, "-o: '%s': the name is too long", out);
				goto fail;
			}
		}
		if (write_grid(&c, filter, s, path, &e) < 0)
			goto fail;
	}
	return EXIT_OK;
fail:
	fprintf(stderr, "wfiscene psf: %s\n", e.msg);
	return e.code ? e.code : EXIT_SYSTEM;
}
