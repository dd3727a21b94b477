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
#include <sys/stat.h>
#include <unistd.h>

#include "engine.h"
#include "err.h"
#include "fftconv.h"
#include "tempfile.h"

int side_check(const char *path, struct err *e)
{
	const char *slash = strrchr(path, '/');
	char dir[PATH_MAX];
	struct stat st;

	if (stat(path, &st) == 0 && !S_ISREG(st.st_mode))
		return S_ISDIR(st.st_mode) ?
		       err_set(e, EXIT_INPUT, "%s: is a directory", path) : 0;
	snprintf(dir, sizeof(dir), "%.*s", slash ? (int)(slash - path + 1) : 1,
		 slash ? path : ".");
	if (access(dir, W_OK | X_OK))
		return err_sys(e, "%s: cannot write in '%s'", path, dir);
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
	fputs("id,sca,x,y,flux,mag,model\n", g->placed);
	return 0;
}

int placed_close(struct engine *g, int keep)
{
	int r;

	if (!g->placed)
		return 0;
	r = side_close(g->placed, g->x->placed, g->placed_tmp, keep, g->e);
	g->placed = NULL;
	return r;
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

/* "name": "value of --set key, or fallback", */
static void report_setting(FILE *f, struct engine *g, const char *name, const char *key,
			   const char *fallback)
{
	const char *v = host_setting(g, key);

	fprintf(f, "\"%s\": ", name);
	report_string(f, v && *v ? v : fallback);
	fputs(", ", f);
}

/* The per-run report: what was done, how long each stage took, what the
 * chosen settings cost in accuracy.  JSON, written atomically. */
int report_write(struct engine *g)
{
	const struct scene_opts *o = g->o;
	const struct exposure *x = g->x;
	char tmp[PATH_MAX];
	double render = 0, worst_loss = 0;
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
	for (int i = 0; i < g->nworker; i++)
		render += g->t_render[i];
	fprintf(f, "{\n  \"wfiscene\": \"%s\",\n", WFS_VERSION);
	fprintf(f, "  \"settings\": {\"filter\": \"%s\", \"scas\": [", g->filter_name);
	for (int s = 0; s < g->nslot; s++)
		fprintf(f, "%s%d", s ? ", " : "", g->slot[s].sca);
	fprintf(f, "], \"ra\": %.10g, \"dec\": %.10g, \"pa\": %.10g, \"exptime\": %.10g, "
		"\"psf\": \"%s\", \"threads\": %d, \"tile\": %d, \"chunk\": %zu, "
		"\"seed\": %llu, \"noise\": %u, \"background\": %.10g},\n",
		g->sky.ra0, g->sky.dec0, g->sky.pa0, o->exptime, o->psf, g->nworker, g->tile,
		o->chunk, (unsigned long long)x->seed, o->noise, x->background);
	fprintf(f, "  \"seconds\": {\"total\": %.6f, \"read_parse\": %.6f, "
		"\"project_place\": %.6f, \"render_busy\": %.6f, \"render_wait\": %.6f, "
		"\"noise\": %.6f, \"write\": %.6f},\n", g->t_total, g->t_read, g->t_place,
		render, g->t_wait, g->t_noise, g->t_write);
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
	fprintf(f, "}},\n  \"flux\": [");
	for (int s = 0; s < g->nslot; s++) {
		int sca = g->slot[s].sca;

		fprintf(f, "%s\n    {\"sca\": %d, \"requested\": %.10g, \"placed\": %.10g}",
			s ? "," : "", sca, g->flux_requested[sca - 1], g->image_sum[sca - 1]);
	}
	/* What the scene needed and so did: the models loaded, the FFT sizes
	 * planned (Sersic convolution), the tiles drawn on before noise (the
	 * rest were never allocated), the noise stages that drew random
	 * numbers (none: the random number code never ran). */
	fprintf(f, "\n  ],\n  \"work\": {\"models\": [");
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
	fprintf(f, "]},\n  \"psf_grids\": {\"built\": %d, \"loaded\": %d, \"boxes\": [",
		g->pbo.built, g->pbo.loaded);
	/* The light a point source's box leaves out, at the grid's worst node
	 * and phase: the largest truncation loss of the settings. */
	first = 1;
	for (int s = 0; s < WFS_NSCA; s++)
		for (int c = 0; c < 3; c++) {
			const struct psf_grid *gr = psfgrids_get(g, s + 1, c);
			double lo = 1;

			if (!gr || (c > 0 && gr == psfgrids_get(g, s + 1, c - 1)))
				continue;
			for (int k = 0; k < gr->nx * gr->ny; k++)
				for (int p = 0; p < gr->over * gr->over; p++)
					lo = fmin(lo, psf_enclosed(gr, k, p % gr->over, p / gr->over));
			worst_loss = fmax(worst_loss, 1 - lo);
			fprintf(f, "%s\n    {\"sca\": %d, \"class\": %d, \"samples\": %d, "
				"\"min_enclosed\": %.8f}", first ? "" : ",", s + 1, c, gr->n, lo);
			first = 0;
		}
	fprintf(f, "\n  ]},\n  \"error_budget\": {\"largest_truncation_loss\": %.8f, "
		"\"psf_grid\": \"%dx%d nodes, bilinear in position\", ",
		worst_loss, g->user_grid ? g->user_grid->nx : 3, g->user_grid ? g->user_grid->ny : 3);
	/* The point model's approximations as --set chose them (its defaults
	 * otherwise), so that a report says which evaluation made the image. */
	report_setting(f, g, "interpolation", "psf-interp", "core");
	report_setting(f, g, "core_halfwidth_px", "psf-core", "4");
	report_setting(f, g, "wing_halfwidth_px", "psf-wing", "8");
	report_setting(f, g, "box", "psf-box", "fixed");
	report_setting(f, g, "box_noise_fraction", "psf-box-noise", "0.1");
	report_setting(f, g, "blend", "psf-blend", "core");
	fprintf(f, "\"blend_cell_px\": ");
	report_string(f, host_setting(g, "psf-cell") ? host_setting(g, "psf-cell") : "512");
	fprintf(f, "}\n}\n");
	return side_close(f, x->report, tmp, 1, g->e);
}

