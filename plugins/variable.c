/*
 * variable.c - the "variable" model: a periodic variable star, drawn as a
 * point source (drawn_by "point") whose flux at the exposure's date follows
 * its light curve.
 *
 * The light curve is in magnitudes about the catalog's, m(t) = mag + dm(phi),
 * at the phase phi = frac((t - t0) / period + phase):
 *
 *   shape 0  sinusoid: dm = -amplitude/2 cos(2 pi phi), brightest at phi 0;
 *            the catalog's magnitude is the mean magnitude.
 *   shape 1  RR Lyrae (RRab) like: the brightness falls over 85 % of the
 *            cycle, quickly at first (dm = A (1 - (1 - phi/0.85)^2) - A/2)
 *            and rises in the last 15 % (a half cosine back to maximum);
 *            the catalog's magnitude is the middle of the range.
 *   shape 2  detached eclipsing binary: out of eclipse the catalog's
 *            magnitude; eclipses of half-width `width` (phase) centred on
 *            phi 0 (primary, amplitude mag deep) and 0.5 (depth2 times as
 *            deep), dm = depth sqrt(1 - (d/width)^2) at phase distance d.
 *   shape 3  a light curve from the file of --set variable-curve=FILE: two
 *            columns, phase (0 to 1) and dm, linearly interpolated and
 *            wrapped; with period 0, the first column is an MJD instead and
 *            the curve holds its end values outside its range.
 *
 * Without a date the star has the catalog's magnitude.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "wfiscene/model.h"

enum { C_PERIOD, C_AMPLITUDE, C_PHASE, C_T0, C_SHAPE, C_DEPTH2, C_WIDTH, NCOL };

static const struct wfs_column columns[NCOL] = {
	{ "period", 0, 1, "period, days (shape 3: 0 for a curve in MJD)" },
	{ "amplitude", 0, 0, "peak-to-peak amplitude, mag (shape 2: primary depth)" },
	{ "phase", 0, 0, "phase at t0, cycles (0: maximum light, or primary eclipse)" },
	{ "t0", 0, 0, "MJD of the phase given (default 0)" },
	{ "shape", 0, 0, "0 sinusoid, 1 RR Lyrae, 2 eclipsing binary, 3 curve file" },
	{ "depth2", 0.5, 0, "shape 2: secondary eclipse depth over the primary's" },
	{ "width", 0.05, 0, "shape 2: eclipse half-width, phase (0 to 0.25)" },
};

static const struct wfs_setting settings[] = {
	{ "variable-curve", "(none)", "file", "light curve of shape-3 rows: phase (or MJD) and "
	  "dm per line" },
};

struct variable {
	const struct wfs_host *host;
	double mjd;             /* the exposure's date, NaN for none */
	double *cx, *cy;        /* the curve file: phase or MJD, dm */
	int ncurve;
	char curve_name[256];
};

/* Read the curve file: "x dm" a line, blanks or commas, '#' comments, x
 * increasing.  Returns 0 or -1 with the error recorded. */
static int read_curve(struct variable *v, const char *path)
{
	const struct wfs_host *h = v->host;
	FILE *f = fopen(path, "r");
	char line[512];
	int cap = 0, lineno = 0;
	struct stat st;

	if (!f)
		return h->error(h->ctx, "variable-curve %s: %s", path, strerror(errno));
	/* a directory opens, and then reads as empty */
	if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
		fclose(f);
		return h->error(h->ctx, "variable-curve %s: is a directory, not a light curve",
				path);
	}
	snprintf(v->curve_name, sizeof(v->curve_name), "%s", path);
	while (fgets(line, sizeof(line), f)) {
		char *p = strchr(line, '#'), *end;
		double x, y;

		lineno++;
		if (p)
			*p = 0;
		for (p = line; *p; p++)
			if (*p == ',')
				*p = ' ';
		p = line + strspn(line, " \t\r\n");
		if (!*p)
			continue;
		x = strtod(p, &end);
		if (end == p || (y = strtod(end, &p), p == end) || !isfinite(x) || !isfinite(y) ||
		    p[strspn(p, " \t\r\n")]) {
			fclose(f);
			return h->error(h->ctx, "variable-curve %s:%d: want two numbers, "
					"phase (or MJD) and dm", path, lineno);
		}
		if (v->ncurve && x <= v->cx[v->ncurve - 1]) {
			fclose(f);
			return h->error(h->ctx, "variable-curve %s:%d: %g does not follow %g: "
					"the first column must increase", path, lineno, x,
					v->cx[v->ncurve - 1]);
		}
		if (v->ncurve == cap) {
			double *a, *b;

			cap = cap ? 2 * cap : 64;
			a = realloc(v->cx, cap * sizeof(double));
			if (a)
				v->cx = a;
			b = realloc(v->cy, cap * sizeof(double));
			if (b)
				v->cy = b;
			if (!a || !b) {
				fclose(f);
				return h->error(h->ctx, "variable-curve %s: out of memory", path);
			}
		}
		v->cx[v->ncurve] = x;
		v->cy[v->ncurve++] = y;
	}
	fclose(f);
	if (v->ncurve < 2)
		return h->error(h->ctx, "variable-curve %s: fewer than two points", path);
	return 0;
}

static void variable_fini(void *state)
{
	struct variable *v = state;

	if (!v)
		return;
	free(v->cx);
	free(v->cy);
	free(v);
}

static int variable_init(const struct wfs_host *host, void **state)
{
	struct variable *v = calloc(1, sizeof(*v));
	const char *curve = host->setting(host->ctx, "variable-curve");
	const char *mjd = host->setting(host->ctx, "mjd");

	if (!v)
		return host->error(host->ctx, "out of memory");
	v->host = host;
	v->mjd = mjd ? strtod(mjd, NULL) : NAN;
	*state = v;
	if (curve && read_curve(v, curve) < 0) {
		variable_fini(v);
		*state = NULL;
		return -1;
	}
	return 0;
}

/* The curve at x: linear between its points; periodic (x a phase in
 * [0, 1), the curve wrapped from its last point to its first plus one) or
 * held at its ends. */
static double curve_at(const struct variable *v, double x, int periodic)
{
	const double *cx = v->cx, *cy = v->cy;
	int n = v->ncurve, lo = 0, hi = n - 1;

	if (x < cx[0] || x >= cx[n - 1]) {
		double x0, x1, y0, y1;

		if (!periodic)
			return x < cx[0] ? cy[0] : cy[n - 1];
		/* between the last point and the first, one cycle later */
		x0 = cx[n - 1];
		y0 = cy[n - 1];
		x1 = cx[0] + 1;
		y1 = cy[0];
		if (x < cx[0])
			x += 1;
		return x1 > x0 ? y0 + (y1 - y0) * (x - x0) / (x1 - x0) : y0;
	}
	while (hi - lo > 1) {
		int mid = (lo + hi) / 2;

		if (cx[mid] <= x)
			lo = mid;
		else
			hi = mid;
	}
	return cy[lo] + (cy[hi] - cy[lo]) * (x - cx[lo]) / (cx[hi] - cx[lo]);
}

/* dm of shape at phase phi in [0, 1). */
static double shape_dm(const double *p, double phi)
{
	double a = p[C_AMPLITUDE], d, w = p[C_WIDTH];

	switch ((int)p[C_SHAPE]) {
	case 0:
		return -0.5 * a * cos(2 * M_PI * phi);
	case 1:
		if (phi < 0.85) {
			double q = 1 - phi / 0.85;

			return a * (1 - q * q) - 0.5 * a;
		}
		return a * (0.5 + 0.5 * cos(M_PI * (phi - 0.85) / 0.15)) - 0.5 * a;
	default:
		d = fmin(phi, 1 - phi);         /* from the primary eclipse */
		if (d < w)
			return a * sqrt(1 - (d / w) * (d / w));
		d = fabs(phi - 0.5);
		if (d < w)
			return a * p[C_DEPTH2] * sqrt(1 - (d / w) * (d / w));
		return 0;
	}
}

static int variable_prepare(void *state, struct wfs_source *src)
{
	struct variable *v = state;
	const struct wfs_host *h = v->host;
	double mjd = v->mjd;
	const double *p = src->param;
	double shape = p[C_SHAPE], period = p[C_PERIOD], dm, phi;

	if (!(shape == 0 || shape == 1 || shape == 2 || shape == 3))
		return h->error(h->ctx, "column 'shape': want 0, 1, 2 or 3, not %g", shape);
	if (shape == 3 && !v->ncurve)
		return h->error(h->ctx, "shape 3 needs a light curve: --set variable-curve=FILE");
	if (!(period > 0 && period <= 1e7) && !(shape == 3 && period == 0))
		return h->error(h->ctx, "column 'period': want days from 0 to 1e7 "
				"(0 only with shape 3), not %g", period);
	/* a periodic row reads the curve as phases, which wrap at 1 */
	if (shape == 3 && period > 0 && (v->cx[0] < 0 || v->cx[v->ncurve - 1] > 1))
		return h->error(h->ctx, "column 'period': %g days reads variable-curve %s as "
				"phases from 0 to 1, but its first column runs from %.9g to %.9g "
				"(MJDs want period 0)", period, v->curve_name, v->cx[0],
				v->cx[v->ncurve - 1]);
	if (!(fabs(p[C_AMPLITUDE]) <= 20))
		return h->error(h->ctx, "column 'amplitude': want at most 20 mag, not %g",
				p[C_AMPLITUDE]);
	if (shape == 2 && !(p[C_WIDTH] > 0 && p[C_WIDTH] <= 0.25 && p[C_DEPTH2] >= 0 &&
			    p[C_DEPTH2] <= 10))
		return h->error(h->ctx, "columns 'width' (0 to 0.25) and 'depth2' (0 to 10): "
				"not %g and %g", p[C_WIDTH], p[C_DEPTH2]);
	/* the exposure's date: the source's when the host gives it */
	if (WFS_HAS(h->size, struct wfs_host, source_size) &&
	    WFS_HAS(h->source_size, struct wfs_source, mjd))
		mjd = src->mjd;
	if (isnan(mjd))
		return 0;
	if (shape == 3 && period == 0) {
		dm = curve_at(v, mjd, 0);
	} else {
		/* the phase, reduced before it is scaled so that long spans
		 * keep their precision */
		phi = fmod((mjd - p[C_T0]) / period + p[C_PHASE], 1.0);
		if (phi < 0)
			phi += 1;
		if (!(phi < 1))
			phi = 0;
		dm = shape == 3 ? curve_at(v, phi, 1) : shape_dm(p, phi);
	}
	src->flux *= pow(10.0, -0.4 * dm);
	return 0;
}

static const struct wfs_model variable_model = {
	.abi = WFS_ABI_VERSION,
	.size = sizeof(struct wfs_model),
	.name = "variable",
	.summary = "periodic variable star (sinusoid, RR Lyrae, eclipsing binary, curve file), "
		   "drawn as a point source",
	.columns = columns,
	.ncolumns = NCOL,
	.init = variable_init,
	.fini = variable_fini,
	.prepare = variable_prepare,
	.column_size = sizeof(struct wfs_column),
	.setting_size = sizeof(struct wfs_setting),
	.settings = settings,
	.nsettings = 1,
	.drawn_by = "point",
};

WFS_EXPORT const struct wfs_model *wfs_model_entry(uint32_t host_abi)
{
	return host_abi == WFS_ABI_VERSION ? &variable_model : NULL;
}
