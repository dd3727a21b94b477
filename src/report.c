/*
 * report.c - the side files of an exposure: the --placed list of every
 * placement and the --report JSON of what the run did and what its settings
 * cost.
 *
 * Both are written to a temporary file renamed into place at the end (or
 * in place when the path is a device or FIFO), so a failed run leaves
 * neither behind; their temporaries are in tempfile.h's registry, which the
 * fatal-signal policy empties.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "background.h"
#include "date.h"
#include "engine.h"
#include "err.h"
#include "fftconv.h"
#include "options.h"
#include "tempfile.h"

int side_check(const char *path, struct err *e)
{
	const char *slash = strrchr(path, '/');
	char dir[PATH_MAX], tmp[PATH_MAX];
	struct stat st;
	int fd;

	if (stat(path, &st) == 0 && !S_ISREG(st.st_mode))
		return S_ISDIR(st.st_mode) ?
		       err_set(e, EXIT_INPUT, "%s: is a directory", path) : 0;
	snprintf(dir, sizeof(dir), "%.*s", slash ? (int)(slash - path + 1) : 1,
		 slash ? path : ".");
	if (access(dir, W_OK | X_OK))
		return err_sys(e, "%s: cannot write in '%s'", path, dir);
	/* access() passes some directories that take no file (/proc, a
	 * read-only mount for root): the temporary the file will be written
	 * through, made and removed */
	if ((fd = tempfile_beside(path, tmp, sizeof(tmp), e)) < 0)
		return -1;
	close(fd);
	tempfile_discard(tmp);
	return 0;
}

/* Finish a side file: flush, fsync and rename its temporary (keep) or
 * remove it; a file written in place (tmp "") is only flushed.  Closes f.
 * Returns 0, or -1 with the error in e (only when keep). */
static int side_close(FILE *f, const char *path, char *tmp, int keep, struct err *e)
{
	int bad = fflush(f) != 0 || ferror(f);

	if (!bad && tmp[0] && keep)
		bad = fsync(fileno(f)) != 0;
	bad |= fclose(f) != 0;
	if (bad && keep)
		err_sys(e, "%s", path);
	if (bad || !keep) {
		tempfile_discard(tmp);
		return bad && keep ? -1 : 0;
	}
	return tmp[0] ? tempfile_commit(tmp, path, e) : 0;
}

/* --set placed=romanisim: the --placed list in romanisim's convention
 * (1), wfiscene's (0), or -1 for an unknown one. */
static int placed_convention_roman(const struct engine *g)
{
	const char *hit = setting_last(g->o->settings, "placed");

	if (!hit || !strcasecmp(hit, "wfiscene"))
		return 0;
	if (!strcasecmp(hit, "romanisim"))
		return 1;
	return err_set(g->e, EXIT_INPUT, "--set placed=%s: want wfiscene or romanisim", hit);
}

int placed_open(struct engine *g)
{
	const char *path = g->x->placed;
	int fd;

	if ((fd = tempfile_open_output(path, g->placed_tmp, sizeof(g->placed_tmp), g->e)) < 0)
		return -1;
	if (!(g->placed = fdopen(fd, "w"))) {
		err_sys(g->e, "%s", path);
		close(fd);
		tempfile_discard(g->placed_tmp);
		return -1;
	}
	if ((g->placed_roman = placed_convention_roman(g)) < 0) {
		fclose(g->placed);
		g->placed = NULL;
		tempfile_discard(g->placed_tmp);
		return -1;
	}
	if (g->placed_roman)
		fprintf(g->placed,
			"# %%ECSV 1.0\n# ---\n# delimiter: ','\n# datatype:\n"
			"# - {name: id, datatype: int64}\n# - {name: sca, datatype: int64}\n"
			"# - {name: x, datatype: float64}\n# - {name: y, datatype: float64}\n"
			"# - {name: ra, unit: deg, datatype: float64}\n"
			"# - {name: dec, unit: deg, datatype: float64}\n"
			"# - {name: type, datatype: string}\n# - {name: n, datatype: float64}\n"
			"# - {name: half_light_radius, unit: arcsec, datatype: float64}\n"
			"# - {name: pa, unit: deg, datatype: float64}\n# - {name: ba, datatype: float64}\n"
			"# - {name: %s, datatype: float64}\n"
			"# meta: {convention: romanisim}\n# schema: astropy-2.0\n"
			"id,sca,x,y,ra,dec,type,n,half_light_radius,pa,ba,%s\n",
			g->filter_name, g->filter_name);
	else
		fputs("id,sca,x,y,flux,mag,model\n", g->placed);
	return 0;
}

int placed_close(struct engine *g, int keep)
{
	int r;

	for (int k = 0; k < WFS_NSCA; k++)
		if (g->placed_part[k]) {
			fclose(g->placed_part[k]);
			g->placed_part[k] = NULL;
		}
	if (g->placed_out) {
		g->placed = g->placed_out;
		g->placed_out = NULL;
	}
	if (!g->placed)
		return 0;
	r = side_close(g->placed, g->x->placed, g->placed_tmp, keep, g->e);
	g->placed = NULL;
	return r;
}

/*
 * SCA groups (run.c).  Each pass writes its placements to an unnamed
 * temporary, an empty line after each chunk of rows; in romanisim's
 * convention each line begins with its row in the chunk and a tab
 * (place.c).  One pass lists a chunk's placements slot by slot, and the
 * passes draw consecutive slots, so the list of one pass is, chunk by
 * chunk, the passes' lists one after another; in romanisim's convention a
 * row is listed once, at its first placement, so a row an earlier pass
 * listed in the chunk is left out.
 */
int placed_pass_begin(struct engine *g)
{
	int fd;

	if (g->npass < 2 || (!g->placed && !g->placed_out))
		return 0;
	if (!g->placed_out)
		g->placed_out = g->placed;
	g->placed = NULL;
	if ((fd = tempfile_unnamed("--placed", g->e)) < 0)
		return -1;
	if (!(g->placed_part[g->pass] = fdopen(fd, "w+"))) {
		close(fd);
		return err_sys(g->e, "--placed: temporary list");
	}
	g->placed = g->placed_part[g->pass];
	return 0;
}

int placed_chunk_end(struct engine *g)
{
	if (g->npass > 1 && g->placed && putc('\n', g->placed) == EOF)
		return err_sys(g->e, "--placed: temporary list");
	return 0;
}

/* The next line of part f into *line: 1, or 0 at the end of a chunk or of
 * the file (*end set). */
static int part_line(FILE *f, char **line, size_t *cap, int *end)
{
	ssize_t n = getline(line, cap, f);

	*end = n < 0;
	return n > 0 && (*line)[0] != '\n';
}

int placed_merge(struct engine *g)
{
	FILE *out = g->placed_out;
	uint32_t *stamp = NULL, chunk = 0;
	size_t nstamp = 0, cap = 0;
	char *line = NULL;
	int more = 1, end = 1, rc = 0;

	if (!out)
		return 0;
	for (int k = 0; k < g->npass; k++)
		if (fflush(g->placed_part[k]) || ferror(g->placed_part[k]) ||
		    fseek(g->placed_part[k], 0, SEEK_SET))
			return err_sys(g->e, "--placed: temporary list");
	while (more && rc == 0) {
		more = 0;
		chunk++;
		for (int k = 0; k < g->npass && rc == 0; k++) {
			while (rc == 0 && part_line(g->placed_part[k], &line, &cap, &end)) {
				char *text = line;

				if (g->placed_roman) {
					size_t i = strtoull(line, &text, 10);

					text++;
					if (i >= nstamp) {
						size_t n = 2 * i + 1024;
						uint32_t *more_ = realloc(stamp, n * sizeof(*stamp));

						if (!more_) {
							rc = err_sys(g->e, "--placed");
							break;
						}
						memset(more_ + nstamp, 0, (n - nstamp) * sizeof(*stamp));
						stamp = more_;
						nstamp = n;
					}
					if (stamp[i] == chunk)
						continue;
					stamp[i] = chunk;
				}
				if (fputs(text, out) == EOF)
					rc = err_sys(g->e, "%s", g->x->placed);
			}
			more |= !end;
		}
	}
	for (int k = 0; k < g->npass; k++)
		if (ferror(g->placed_part[k]) && rc == 0)
			rc = err_sys(g->e, "--placed: temporary list");
	free(line);
	free(stamp);
	return rc;
}

/* A JSON string: quotes, backslashes and control bytes escaped (--set
 * values reach the report as the user typed them). */
static void report_string(FILE *f, const char *s)
{
	fputc('"', f);
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;

		if (c == '"' || c == '\\')
			fprintf(f, "\\%c", c);
		else if (c < 0x20)
			fprintf(f, "\\u%04x", c);
		else
			fputc(c, f);
	}
	fputc('"', f);
}

/*
 * "model_settings": each model the run loaded, with the settings it declares
 * (wfs_model.settings) and the value each had: the --set value, or the
 * model's own default.  The host knows no model's settings itself.
 */
static void report_model_settings(FILE *f, struct engine *g)
{
	int first = 1;

	fputs("  \"model_settings\": {", f);
	for (int m = 0; m < g->plugins.n; m++) {
		const struct plugin *pl = &g->plugins.p[m];

		if (!pl->ready)
			continue;
		fprintf(f, "%s\n    \"%s\": {", first ? "" : ",", pl->name);
		first = 0;
		for (int k = 0; k < pl->nsettings; k++) {
			const struct wfs_setting *st = plugin_setting(pl, k);
			const char *v = host_setting(g, st->key);

			fprintf(f, "%s", k ? ", " : "");
			report_string(f, st->key);
			fputs(": ", f);
			report_string(f, v && *v ? v : st->fallback ? st->fallback : "");
		}
		fputc('}', f);
	}
	fputs(first ? "}\n" : "\n  }\n", f);
}

/* "name": number, or null for NaN (JSON has no NaN); then sep. */
static void report_number(FILE *f, const char *name, double v, const char *sep)
{
	if (isfinite(v))
		fprintf(f, "\"%s\": %.10g%s", name, v, sep);
	else
		fprintf(f, "\"%s\": null%s", name, sep);
}

/* The background used on each SCA written, and its parts. */
static void report_background(FILE *f, struct engine *g)
{
	static const char *const model[] = { "none", "number", "avg", "sky" };
	const struct bkg_exposure *b = &g->x->bkg;
	char when[32];

	fprintf(f, "  \"background\": {\"model\": \"%s\", ", model[b->model]);
	if (b->model == BKG_SKY)
		fprintf(f, "\"zodi_norm\": \"%s\", ", background_norm_name(b->norm));
	if (isnan(b->mjd)) {
		fputs("\"date\": null, ", f);
	} else {
		date_format(b->mjd, when, sizeof(when));
		fprintf(f, "\"date\": \"%s\", ", when);
	}
	report_number(f, "mjd", b->mjd, ", ");
	report_number(f, "sun_angle", b->sun_angle, ", ");
	fputs("\"sca\": [", f);
	for (int s = 0; s < g->nslot; s++) {
		const struct bkg_part *p = &b->sca[g->slot[s].sca - 1];

		fprintf(f, "%s\n    {\"sca\": %d, ", s ? "," : "", g->slot[s].sca);
		report_number(f, "total", p->total, ", ");
		report_number(f, "zodi", p->zodi, ", ");
		report_number(f, "thermal", p->thermal, ", ");
		report_number(f, "r_sca", p->r_sca, ", ");
		report_number(f, "table", p->table, ", ");
		report_number(f, "scale", p->scale, ", ");
		report_number(f, "ecl_lon", p->ecl_lon, ", ");
		report_number(f, "ecl_lat", p->ecl_lat, ", ");
		report_number(f, "dlon_sun", p->dlon, ", ");
		report_number(f, "sun_angle", p->sun_angle, "}");
	}
	fputs("\n  ]},\n", f);
}

/* "work": what the scene needed and so did. */
static void report_work(FILE *f, struct engine *g)
{
	const struct scene_opts *o = g->o;
	int first;

	/* What the scene needed and so did: the models loaded, the FFT plans
	 * made (Sersic convolution), the tiles drawn on before noise (the
	 * rest were never allocated), the noise stages that drew random
	 * numbers (none: the random number code never ran). */
	fprintf(f, "  \"work\": {\"models\": [");
	first = 1;
	for (int m = 0; m < g->plugins.n; m++)
		if (g->plugins.p[m].ready) {
			fprintf(f, "%s\"%s\"", first ? "" : ", ", g->plugins.p[m].name);
			first = 0;
		}
	fprintf(f, "], \"fft_plans\": %d, \"tiles_drawn\": %llu, \"tiles\": %llu, "
		"\"noise_stages\": [", fftconv_nplans(g->fft), g->tiles_drawn, g->tiles);
	first = 1;
	for (int k = 0; k < 5; k++)
		if (o->noise & (1u << k)) {
			static const char *const stage[] = { "poisson", "readnoise", "dark", "flat",
							     "cosmic" };

			fprintf(f, "%s\"%s\"", first ? "" : ", ", stage[k]);
			first = 0;
		}
	fputs("]},\n", f);
}

/*
 * The PSF grids the report lists: per SCA and size class, the grid's
 * samples and least enclosed light (a class that shares the class
 * before's grid is not listed again), and which spectral classes' grids
 * were drawn with.  From the grids themselves, or for an SCA whose grids
 * a pass freed (SCA groups, run.c) from the note taken just before.
 */
struct grid_note {
	unsigned char noted[WFS_NSCA];
	int n[WFS_NSCA][3];             /* samples; 0: not listed */
	double lo[WFS_NSCA][3];
	unsigned char *cls;             /* [sca][class][k]: ncls a class */
	int ncls;
};

/* The box of SCA sca, size class c, from its grids: 1 with *n and *lo,
 * or 0 when not listed. */
static int grid_box_live(struct engine *g, int sca, int c, int *n, double *lo)
{
	const struct psf_grid *gr = psfgrids_get(g, sca, c);

	if (!gr || (c > 0 && gr == psfgrids_get(g, sca, c - 1)))
		return 0;
	*lo = 1;
	for (int k = 0; k < gr->nx * gr->ny; k++)
		for (int p = 0; p < gr->over * gr->over; p++)
			*lo = fmin(*lo, psf_enclosed(gr, k, p % gr->over, p / gr->over));
	*n = gr->n;
	return 1;
}

static int grid_box(struct engine *g, int sca, int c, int *n, double *lo)
{
	const struct grid_note *gn = g->grid_note;

	if (!gn || !gn->noted[sca - 1])
		return grid_box_live(g, sca, c, n, lo);
	*n = gn->n[sca - 1][c];
	*lo = gn->lo[sca - 1][c];
	return *n > 0;
}

static int grid_class(struct engine *g, int sca, int c, int k)
{
	const struct grid_note *gn = g->grid_note;

	if (!gn || !gn->noted[sca - 1])
		return psfgrids_colour_get(g, sca, c, k) != NULL;
	return k < gn->ncls && gn->cls[((size_t)(sca - 1) * 4 + c) * gn->ncls + k];
}

int report_grids_note(struct engine *g, int sca)
{
	struct grid_note *gn = g->grid_note;
	int ncls = g->classes ? 2 * g->classes->n : 0;

	if (!gn && !(gn = g->grid_note = calloc(1, sizeof(*gn))))
		return err_sys(g->e, "report");
	if (ncls && !gn->cls) {
		if (!(gn->cls = calloc((size_t)WFS_NSCA * 4 * ncls, 1)))
			return err_sys(g->e, "report");
		gn->ncls = ncls;
	}
	for (int c = 0; c < 3; c++)
		if (!grid_box_live(g, sca, c, &gn->n[sca - 1][c], &gn->lo[sca - 1][c]))
			gn->n[sca - 1][c] = 0;
	/* the spectral classes' grids, their halos (class 3) too */
	for (int c = 0; c < 4; c++)
		for (int k = 0; k < gn->ncls; k++)
			gn->cls[((size_t)(sca - 1) * 4 + c) * gn->ncls + k] =
				psfgrids_colour_get(g, sca, c, k) != NULL;
	gn->noted[sca - 1] = 1;
	return 0;
}

void report_notes_free(struct engine *g)
{
	if (g->grid_note)
		free(g->grid_note->cls);
	free(g->grid_note);
	g->grid_note = NULL;
}

/* The spectral classes (psf.h) and the grids of them drawn with, inside
 * "psf_grids"; nothing when the scene had no source with a spectrum. */
static void report_spectral_classes(FILE *f, struct engine *g)
{
	const struct psf_classes *pc = g->classes;
	int first;

	if (!pc)
		return;
	fprintf(f, ", \"spectral_classes\": [");
	for (int k = 0; k < 2 * pc->n; k++) {
		int kind;
		double v;

		psf_classes_spectrum(pc, k, &kind, &v);
		fprintf(f, "%s\n    {\"class\": %d, \"%s\": %.6g, \"lam_eff_sca1\": %.6f, "
			"\"grids\": [", k ? "," : "", k, k < pc->n ? "beta" : "teff", v,
			pc->lam[0][k >= pc->n][k % pc->n]);
		first = 1;
		for (int s = 0; s < WFS_NSCA; s++)
			for (int c = 0; c < 4; c++)
				if (grid_class(g, s + 1, c, k)) {
					if (c < 3)
						fprintf(f, "%s{\"sca\": %d, \"samples\": %d}",
							first ? "" : ", ", s + 1, psf_class_n[c]);
					else
						fprintf(f, "%s{\"sca\": %d, \"halo\": true}",
							first ? "" : ", ", s + 1);
					first = 0;
				}
		fprintf(f, "]}");
	}
	fprintf(f, "\n  ]");
}

/* "psf_grids": the grids built and loaded and each one's least enclosed
 * light; returns the largest truncation loss among them. */
static double report_psf_grids(FILE *f, struct engine *g)
{
	double worst_loss = 0;
	int first;

	fprintf(f, "  \"psf_grids\": {\"built\": %d, \"loaded\": %d, \"boxes\": [",
		g->pbo.built, g->pbo.loaded);
	/* The light a point source's box leaves out, at the grid's worst node
	 * and phase: the largest truncation loss of the settings. */
	first = 1;
	for (int s = 0; s < WFS_NSCA; s++)
		for (int c = 0; c < 3; c++) {
			double lo;
			int n;

			if (!grid_box(g, s + 1, c, &n, &lo))
				continue;
			worst_loss = fmax(worst_loss, 1 - lo);
			fprintf(f, "%s\n    {\"sca\": %d, \"class\": %d, \"samples\": %d, "
				"\"min_enclosed\": %.8f}", first ? "" : ",", s + 1, c, n, lo);
			first = 0;
		}
	fputs("\n  ]", f);
	report_spectral_classes(f, g);
	fputs("},\n", f);
	return worst_loss;
}

/* The per-run report: what was done, how long each stage took, what the
 * chosen settings cost in accuracy.  JSON, written atomically. */
int report_write(struct engine *g)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	char tmp[PATH_MAX];
	double render = 0, render_cpu = 0, worst_loss = 0;
	struct rusage ru;
	FILE *f;
	int fd, first;

	if ((fd = tempfile_open_output(x->report, tmp, sizeof(tmp), g->e)) < 0)
		return -1;
	if (!(f = fdopen(fd, "w"))) {
		err_sys(g->e, "%s", x->report);
		close(fd);
		tempfile_discard(tmp);
		return -1;
	}
	for (int i = 0; i < g->nworker; i++) {
		render += g->t_render[i];
		render_cpu += g->t_render_cpu[i];
	}
	getrusage(RUSAGE_SELF, &ru);
	fprintf(f, "{\n  \"wfiscene\": \"%s\",\n", WFS_VERSION);
	fprintf(f, "  \"settings\": {\"filter\": \"%s\", \"scas\": [", g->filter_name);
	for (int s = 0; s < g->nslot; s++)
		fprintf(f, "%s%d", s ? ", " : "", g->slot[s].sca);
	fprintf(f, "], \"ra\": %.10g, \"dec\": %.10g, \"pa\": %.10g, \"geometry\": \"%s\", "
		"\"exptime\": %.10g, \"psf\": ",
		g->sky.ra0, g->sky.dec0, g->sky.pa0, geom_name(o->geometry), o->exptime);
	/* --psf is a user's file name: escaped like the --set values */
	report_string(f, o->psf);
	fprintf(f, ", \"threads\": %d, \"tile\": %d, \"chunk\": %zu, "
		"\"seed\": %llu, \"noise\": %u, \"background\": ",
		g->nworker, g->tile, o->chunk, (unsigned long long)x->seed, o->noise);
	if (o->bkg_model == BKG_SKY)
		fputs("\"sky\"},\n", f);
	else
		fprintf(f, "%.10g},\n", x->background);
	report_background(f, g);
	fprintf(f, "  \"seconds\": {\"total\": %.6f, \"read_parse\": %.6f, "
		"\"project_place\": %.6f, \"render_busy\": %.6f, \"render_wait\": %.6f, "
		"\"noise\": %.6f, \"write\": %.6f, \"render_cpu\": %.6f, \"cpu_user\": %.6f, "
		"\"cpu_system\": %.6f},\n", g->t_total, g->t_read, g->t_place,
		render, g->t_wait, g->t_noise, g->t_write, render_cpu,
		ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec,
		ru.ru_stime.tv_sec + 1e-6 * ru.ru_stime.tv_usec);
	fprintf(f, "  \"rows\": {\"read\": %llu, \"culled_far\": %llu, "
		"\"off_detector\": %llu, \"placements\": %llu, \"by_model\": {",
		g->rows_read, g->culled, g->offdet, g->placements);
	first = 1;
	for (int m = 0; m < g->plugins.n; m++)
		if (g->plugins.p[m].ready) {
			fprintf(f, "%s\"%s\": %llu", first ? "" : ", ", g->plugins.p[m].name,
				g->per_model[m]);
			first = 0;
		}
	fprintf(f, "}},\n");
	if (g->trees)
		fprintf(f, "  \"catalog_trees\": {\"trees\": %llu, \"files\": %llu, "
			"\"files_read\": %llu, \"files_skipped\": %llu, \"bytes_skipped\": %llu, "
			"\"rows_skipped\": %llu, \"files_skipped_rows_unknown\": %llu},\n",
			g->trees, g->tree_files, g->tree_files - g->tree_skipped, g->tree_skipped,
			g->tree_bytes_skipped, g->tree_rows_skipped, g->tree_rows_uncounted);
	fprintf(f, "  \"flux\": [");
	for (int s = 0; s < g->nslot; s++) {
		int sca = g->slot[s].sca;

		fprintf(f, "%s\n    {\"sca\": %d, \"requested\": %.10g, \"placed\": %.10g}",
			s ? "," : "", sca, g->flux_requested[sca - 1], g->image_sum[sca - 1]);
	}
	fputs("\n  ],\n", f);
	report_work(f, g);
	worst_loss = report_psf_grids(f, g);
	fprintf(f, "  \"error_budget\": {\"largest_truncation_loss\": %.8f, "
		"\"psf_grid\": \"%dx%d nodes, bilinear in position\", ",
		worst_loss, g->user_grid ? g->user_grid->nx : 3, g->user_grid ? g->user_grid->ny : 3);
	/* the noise per pixel that models drawing down to a fraction of it
	 * follow (point's psf-extent; the light left beyond is "requested"
	 * less "placed" above), and the radius of the halo grids */
	fputs("\"pixel_sigma\": ", f);
	report_string(f, g->sigma_str);
	fputs(", \"halo_radius_px\": ", f);
	report_string(f, host_setting(g, "psf-halo-radius") ? host_setting(g, "psf-halo-radius")
		      : "256");
	fputs("},\n", f);
	/* The models' approximations as --set chose them (their defaults
	 * otherwise), so that a report says which evaluation made the image. */
	report_model_settings(f, g);
	fputs("}\n", f);
	return side_close(f, x->report, tmp, 1, g->e);
}

