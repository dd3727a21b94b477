/*
 * into_asdf.c - injection into a Roman level-2 ASDF file (--into
 * IMAGE.asdf); see into_asdf.h.
 */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <fitsio.h>

#include "asdf.h"
#include "asdf_read.h"
#include "date.h"
#include "err.h"
#include "geometry.h"
#include "gwcs_eval.h"
#include "instrument.h"
#include "into.h"
#include "into_asdf.h"
#include "ramp.h"
#include "sky.h"
#include "tempfile.h"

#define D2R (M_PI / 180)
#define R2D (180 / M_PI)
#define AS2R (M_PI / 180 / 3600)
#define TAGS "asdf://stsci.edu/datamodels/roman/tags/"

/* The arrays injection changes. */
enum { A_DATA, A_VP, A_ERR, A_N };

struct into_asdf {
	struct asdf_in *in;
	int sca;
	char filter[16];        /* meta.instrument.optical_element, "" none */
	double ra_ref, dec_ref, roll_ref, v2_ref, v3_ref;
	double teff;            /* s: the Poisson variance's time */
	double va;              /* meta.velocity_aberration.scale_factor, 1 without */
	struct gwcs *gw;        /* meta.wcs where it is evaluated, else NULL */
	struct geom_map map;    /* gw as the SCA's mapping */
	char *catalogs;         /* the scene's catalogs, for the history */
	int block[A_N];
	int dtype[A_N];
	int big[A_N];           /* big-endian */
};

int into_is_asdf(const char *path)
{
	char head[6] = "";
	size_t n = strlen(path);
	FILE *f;

	/* by its name too: an empty or foreign file called .asdf is refused
	 * as not ASDF, not opened as FITS */
	if (n >= 5 && !strcmp(path + n - 5, ".asdf"))
		return 1;
	if (!(f = fopen(path, "rb")))
		return 0;
	if (fread(head, 1, 5, f) != 5)
		head[0] = 0;
	fclose(f);
	return !memcmp(head, "#ASDF", 5);
}

static struct fy_node *at(struct fy_node *root, const char *path)
{
	return root ? fy_node_by_path(root, path, FY_NT, FYNWF_DONT_FOLLOW) : NULL;
}

/* A number at path; 0 or -1 with a message. */
static int number(struct asdf_in *a, const char *path, double *v, struct err *e)
{
	struct fy_node *n = at(asdf_in_root(a), path);
	const char *s = n && fy_node_is_scalar(n) ? fy_node_get_scalar0(n) : NULL;
	char *end;

	if (!s)
		return err_set(e, EXIT_INPUT, "%s: no %s in the tree", a->path, path);
	*v = strtod(s, &end);
	if (end == s || *end || !isfinite(*v))
		return err_set(e, EXIT_INPUT, "%s: %s: not a number: '%s'", a->path, path, s);
	return 0;
}

/* The ndarray roman.<name>: its block, datatype, byte order, checked
 * against the shape want. */
static int ndarray(struct into_asdf *ia, const char *name, int k, const long *want, int ndim,
		   struct err *e)
{
	struct asdf_in *a = ia->in;
	char path[64];
	struct fy_node *n, *s, *src, *dt, *bo;
	const char *tag, *v;
	char *end;
	size_t tl;
	long b;

	snprintf(path, sizeof(path), "/roman/%s", name);
	if (!(n = at(asdf_in_root(a), path)) || !fy_node_is_mapping(n))
		return err_set(e, EXIT_INPUT, "%s: no array roman.%s", a->path, name);
	tag = fy_node_get_tag(n, &tl);
	if (!tag || tl < 35 || strncmp(tag, "tag:stsci.edu:asdf/core/ndarray-1.", 34))
		return err_set(e, EXIT_INPUT, "%s: roman.%s is not an ndarray", a->path, name);
	src = fy_node_mapping_lookup_by_string(n, "source", FY_NT);
	dt = fy_node_mapping_lookup_by_string(n, "datatype", FY_NT);
	bo = fy_node_mapping_lookup_by_string(n, "byteorder", FY_NT);
	s = fy_node_mapping_lookup_by_string(n, "shape", FY_NT);
	if (!src || !fy_node_is_scalar(src) || !dt || !fy_node_is_scalar(dt) || !s ||
	    !fy_node_is_sequence(s))
		return err_set(e, EXIT_INPUT, "%s: roman.%s: an ndarray without a block source, "
			       "datatype or shape (an inline or external array is not read here)",
			       a->path, name);
	/* a block's number; a string is an external file, not read here */
	v = fy_node_get_scalar0(src);
	errno = 0;
	b = strtol(v, &end, 10);
	if (end == v || *end || errno || b < 0 || b >= a->nblock)
		return err_set(e, EXIT_INPUT, "%s: roman.%s: source '%s' is not one of the "
			       "file's %d blocks (truncated, or an external array?)", a->path,
			       name, v, a->nblock);
	for (int j = 0; j < k; j++)
		if (ia->block[j] == (int)b)
			return err_set(e, EXIT_INPUT, "%s: roman.%s: block %ld is another "
				       "array's too", a->path, name, b);
	ia->block[k] = (int)b;
	v = fy_node_get_scalar0(dt);
	if (!strcmp(v, "float32"))
		ia->dtype[k] = ASDF_F32;
	else if (!strcmp(v, "float16"))
		ia->dtype[k] = ASDF_F16;
	else
		return err_set(e, EXIT_INPUT, "%s: roman.%s is %s, not float32 or float16",
			       a->path, name, v);
	ia->big[k] = bo && fy_node_is_scalar(bo) && !strcmp(fy_node_get_scalar0(bo), "big");
	if (fy_node_sequence_item_count(s) != ndim)
		return err_set(e, EXIT_INPUT, "%s: roman.%s has %d dimensions, not %d", a->path,
			       name, fy_node_sequence_item_count(s), ndim);
	for (int i = 0; i < ndim; i++) {
		struct fy_node *d = fy_node_sequence_get_by_index(s, i);

		if (!d || !fy_node_is_scalar(d) || atol(fy_node_get_scalar0(d)) != want[i])
			return err_set(e, EXIT_INPUT, "%s: roman.%s is not %ld x %ld pixels",
				       a->path, name, want[0], want[1]);
	}
	return 0;
}

/* The model of the tree's roman node, checked: a level-2 image. */
static int check_model(struct asdf_in *a, struct err *e)
{
	struct fy_node *r = at(asdf_in_root(a), "/roman");
	const char *tag;
	size_t tl;
	char name[128];

	if (!r)
		return err_set(e, EXIT_INPUT, "%s: the tree has no 'roman' node: not a Roman "
			       "datamodel file", a->path);
	tag = fy_node_get_tag(r, &tl);
	if (!tag || tl <= strlen(TAGS) || strncmp(tag, TAGS, strlen(TAGS)))
		return err_set(e, EXIT_INPUT, "%s: the tree's 'roman' node has no Roman "
			       "datamodel tag", a->path);
	snprintf(name, sizeof(name), "%.*s", (int)(tl - strlen(TAGS)), tag + strlen(TAGS));
	if (!strncmp(name, "wfi_science_raw-", 16))
		return err_set(e, EXIT_INPUT, "%s: a level 1 file (%s): --into adds sources to a "
			       "level 2 image (wfi_image)", a->path, name);
	if (strncmp(name, "wfi_image-", 10))
		return err_set(e, EXIT_INPUT, "%s: 'roman' is %s, not a level 2 image "
			       "(wfi_image)", a->path, name);
	return 0;
}

static void map_sky(const void *ctx, double x, double y, double *ra, double *dec)
{
	gwcs_pix_to_sky(ctx, x, y, ra, dec);
}

static void map_pix(const void *ctx, double ra, double dec, double x0, double y0, double *x,
		    double *y)
{
	gwcs_sky_to_pix(ctx, ra, dec, x0, y0, x, y);
}

/* meta.wcs, where it can be evaluated; a warning naming what cannot be
 * otherwise (the sources are then placed by meta.wcsinfo).  -1 for a
 * gwcs whose own arrays cannot be read (a broken file). */
static int load_gwcs(struct into_asdf *ia, struct err *e)
{
	struct fy_node *w = at(asdf_in_root(ia->in), "/roman/meta/wcs");
	char why[512];
	int fatal;

	if (!w || fy_node_is_scalar(w)) {
		fprintf(stderr, "wfiscene: warning: %s: no meta.wcs (a gwcs): the sources are "
			"placed by meta.wcsinfo and wfiscene's SIAF distortion\n", ia->in->path);
		return 0;
	}
	if (!(ia->gw = gwcs_load(ia->in, w, why, sizeof(why), &fatal))) {
		if (fatal)
			return err_set(e, EXIT_INPUT, "%s: meta.wcs: %s", ia->in->path, why);
		fprintf(stderr, "wfiscene: warning: %s: %s: the sources are placed by "
			"meta.wcsinfo and wfiscene's SIAF distortion instead of meta.wcs\n",
			ia->in->path, why);
		return 0;
	}
	ia->map = (struct geom_map){ ia->gw, map_sky, map_pix };
	return 0;
}

struct into_asdf *into_asdf_open(const char *path, unsigned mask, struct err *e)
{
	struct into_asdf *ia = calloc(1, sizeof(*ia));
	static const long shape[2] = { WFS_NPIX, WFS_NPIX };
	struct fy_node *det;
	const char *dn;

	if (!ia) {
		err_sys(e, "%s", path);
		return NULL;
	}
	if (geom_init(e) < 0 || !(ia->in = asdf_in_open(path, e)))
		goto fail;
	if (ia->in->standard < 10600) {
		err_set(e, EXIT_INPUT, "%s: ASDF Standard %d.%d.%d: Roman's datamodels need "
			"1.6.0 or later", path, ia->in->standard / 10000, ia->in->standard / 100 % 100,
			ia->in->standard % 100);
		goto fail;
	}
	if (check_model(ia->in, e) < 0)
		goto fail;
	det = at(asdf_in_root(ia->in), "/roman/meta/instrument/detector");
	dn = det && fy_node_is_scalar(det) ? fy_node_get_scalar0(det) : NULL;
	if (!dn || strncmp(dn, "WFI", 3) || (ia->sca = atoi(dn + 3)) < 1 || ia->sca > WFS_NSCA) {
		err_set(e, EXIT_INPUT, "%s: meta.instrument.detector is not WFI01 to WFI18", path);
		goto fail;
	}
	if (mask != 1u << (ia->sca - 1)) {
		err_set(e, EXIT_INPUT, "%s holds %s: give --sca %d (and that SCA only)", path, dn,
			ia->sca);
		goto fail;
	}
	/* checked against --filter by into_apply (into.h) */
	det = at(asdf_in_root(ia->in), "/roman/meta/instrument/optical_element");
	dn = det && fy_node_is_scalar(det) ? fy_node_get_scalar0(det) : NULL;
	if (dn)
		snprintf(ia->filter, sizeof(ia->filter), "%s", dn);
	if (number(ia->in, "/roman/meta/wcsinfo/ra_ref", &ia->ra_ref, e) < 0 ||
	    number(ia->in, "/roman/meta/wcsinfo/dec_ref", &ia->dec_ref, e) < 0 ||
	    number(ia->in, "/roman/meta/wcsinfo/roll_ref", &ia->roll_ref, e) < 0 ||
	    number(ia->in, "/roman/meta/wcsinfo/v2_ref", &ia->v2_ref, e) < 0 ||
	    number(ia->in, "/roman/meta/wcsinfo/v3_ref", &ia->v3_ref, e) < 0 ||
	    number(ia->in, "/roman/meta/exposure/effective_exposure_time", &ia->teff, e) < 0)
		goto fail;
	if (!(ia->teff > 0)) {
		err_set(e, EXIT_INPUT, "%s: meta.exposure.effective_exposure_time %g: not a "
			"time", path, ia->teff);
		goto fail;
	}
	if (ndarray(ia, "data", A_DATA, shape, 2, e) < 0 ||
	    ndarray(ia, "var_poisson", A_VP, shape, 2, e) < 0 ||
	    ndarray(ia, "err", A_ERR, shape, 2, e) < 0)
		goto fail;
	ia->va = 1;
	if (at(asdf_in_root(ia->in), "/roman/meta/velocity_aberration/scale_factor") &&
	    (number(ia->in, "/roman/meta/velocity_aberration/scale_factor", &ia->va, e) < 0 ||
	     !(ia->va > 0.99 && ia->va < 1.01))) {
		if (!e->code)
			err_set(e, EXIT_INPUT, "%s: meta.velocity_aberration.scale_factor %g: not "
				"near 1", path, ia->va);
		goto fail;
	}
	if (load_gwcs(ia, e) < 0)
		goto fail;
	return ia;
fail:
	into_asdf_free(ia);
	return NULL;
}

/* East and north unit vectors at (lon, lat) radians. */
static void en(double lon, double lat, double e[3], double n[3])
{
	e[0] = -sin(lon);
	e[1] = cos(lon);
	e[2] = 0;
	n[0] = -sin(lat) * cos(lon);
	n[1] = -sin(lat) * sin(lon);
	n[2] = cos(lat);
}

void into_asdf_pointing(const struct into_asdf *ia, double *ra, double *dec, double *pa)
{
	/* the attitude m of wcsinfo: (V2Ref, V3Ref) to (ra_ref, dec_ref),
	 * +V3 at roll_ref there (and +V2 90 degrees east of it: the
	 * attitude is a rotation) */
	double u[3], e2[3], e3[3], s[3], ee[3], nn[3], N[3], E[3], m[3][3];
	double r = ia->roll_ref * D2R;
	const struct geom_aperture *ap = geom_aperture(1);
	double a1[3], e21[3], e31[3], y1[3], s1[3], y1s[3], th = ap->v3idlyangle * D2R;

	geom_unit(ia->v2_ref * AS2R, ia->v3_ref * AS2R, u);
	en(ia->v2_ref * AS2R, ia->v3_ref * AS2R, e2, e3);
	geom_unit(ia->ra_ref * D2R, ia->dec_ref * D2R, s);
	en(ia->ra_ref * D2R, ia->dec_ref * D2R, ee, nn);
	for (int k = 0; k < 3; k++) {
		N[k] = cos(r) * nn[k] + sin(r) * ee[k];
		E[k] = -sin(r) * nn[k] + cos(r) * ee[k];
	}
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			m[i][j] = s[i] * u[j] + E[i] * e2[j] + N[i] * e3[j];
	/* WFI01's reference point and its +y_idl on the sky: the pointing
	 * that sky.c turns back into the same attitude */
	geom_unit(ap->v2ref * AS2R, ap->v3ref * AS2R, a1);
	en(ap->v2ref * AS2R, ap->v3ref * AS2R, e21, e31);
	for (int k = 0; k < 3; k++)
		y1[k] = sin(th) * e21[k] + cos(th) * e31[k];
	for (int i = 0; i < 3; i++) {
		s1[i] = m[i][0] * a1[0] + m[i][1] * a1[1] + m[i][2] * a1[2];
		y1s[i] = m[i][0] * y1[0] + m[i][1] * y1[1] + m[i][2] * y1[2];
	}
	*ra = fmod(atan2(s1[1], s1[0]) * R2D + 360, 360);
	*dec = asin(s1[2]) * R2D;
	en(*ra * D2R, *dec * D2R, ee, nn);
	{
		double de = 0, dn = 0;

		for (int k = 0; k < 3; k++) {
			de += y1s[k] * ee[k];
			dn += y1s[k] * nn[k];
		}
		*pa = atan2(de, dn) * R2D;
	}
}

int into_asdf_sca(const struct into_asdf *ia)
{
	return ia->sca;
}

const char *into_asdf_filter(const struct into_asdf *ia)
{
	return ia->filter[0] ? ia->filter : NULL;
}

static void swap_bytes(void *p, size_t n, size_t size)
{
	unsigned char *c = p;

	for (size_t i = 0; i < n; i++, c += size)
		for (size_t k = 0; k < size / 2; k++) {
			unsigned char t = c[k];

			c[k] = c[size - 1 - k];
			c[size - 1 - k] = t;
		}
}

static int little_endian(void)
{
	const uint16_t one = 1;

	return *(const unsigned char *)&one == 1;
}

/* Array k of the image as floats (npx of them). */
static int read_array(struct into_asdf *ia, int k, float *out, size_t npx, struct err *e)
{
	size_t es = ia->dtype[k] == ASDF_F32 ? 4 : 2;
	void *raw = es == 4 ? (void *)out : malloc(npx * 2);

	if (!raw)
		return err_sys(e, "%s", ia->in->path);
	if (asdf_in_block(ia->in, ia->block[k], raw, npx * es, e) < 0) {
		if (raw != out)
			free(raw);
		return -1;
	}
	if (ia->big[k] == little_endian())
		swap_bytes(raw, npx, es);
	if (es == 2) {
		const uint16_t *h = raw;

		for (size_t i = 0; i < npx; i++)
			out[i] = asdf_half_to_float(h[i]);
		free(raw);
	}
	return 0;
}

/* Array k's bytes as the file stores them (its datatype and order). */
static void *store(const struct into_asdf *ia, int k, const float *v, size_t npx)
{
	size_t es = ia->dtype[k] == ASDF_F32 ? 4 : 2;
	void *p = malloc(npx * es);

	if (!p)
		return NULL;
	if (es == 4) {
		memcpy(p, v, npx * 4);
	} else {
		uint16_t *h = p;

		for (size_t i = 0; i < npx; i++)
			h[i] = asdf_half(v[i]);
	}
	if (ia->big[k] == little_endian())
		swap_bytes(p, npx, es);
	return p;
}

static int put(int fd, const void *p, size_t n, uint64_t *off, const char *path, struct err *e)
{
	if (asdf_fd_write(fd, p, n, *off, path, e) < 0)
		return -1;
	*off += n;
	return 0;
}

/* Copy n bytes of the image from offset from to the output. */
static int copy(struct into_asdf *ia, int fd, uint64_t from, uint64_t n, uint64_t *off,
		const char *path, struct err *e)
{
	static const size_t chunk = 1 << 20;
	char *b = malloc(chunk);

	if (!b)
		return err_sys(e, "%s", path);
	while (n > 0) {
		size_t k = n < chunk ? (size_t)n : chunk;
		ssize_t r = pread(ia->in->fd, b, k, (off_t)from);

		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0 || put(fd, b, (size_t)r, off, path, e) < 0) {
			if (r <= 0)
				err_sys(e, "%s: reading", ia->in->path);
			free(b);
			return -1;
		}
		from += (uint64_t)r;
		n -= (uint64_t)r;
	}
	free(b);
	return 0;
}

void into_asdf_catalogs(struct into_asdf *ia, char *const *catalogs)
{
	size_t n = 1;
	char *p;

	for (char *const *c = catalogs; c && *c; c++)
		n += strlen(*c) + 2;
	free(ia->catalogs);
	if (!(ia->catalogs = p = malloc(n)))
		return;
	*p = 0;
	for (char *const *c = catalogs; c && *c; c++)
		p += sprintf(p, "%s%s", c == catalogs ? "" : ", ", *c);
}

/* s as a YAML double-quoted scalar into out (n bytes). */
static void quoted(const char *s, char *out, size_t n)
{
	size_t k = 0;

	if (n < 3)
		return;
	out[k++] = '"';
	for (; *s && k + 3 < n; s++) {
		if (*s == '"' || *s == '\\')
			out[k++] = '\\';
		out[k++] = (unsigned char)*s < ' ' ? ' ' : *s;
	}
	out[k++] = '"';
	out[k] = 0;
}

/* A node of YAML text yaml (libfyaml keeps the text: a copy it frees). */
static struct fy_node *node_yaml(struct fy_document *d, const char *yaml)
{
	char *c = strdup(yaml);
	/* (on a failure libfyaml may still hold it: not freed here) */
	return c ? fy_node_build_from_malloc_string(d, c, FY_NT) : NULL;
}

/* map[key] = the node of YAML text yaml (replaced, or appended). */
static int set_yaml(struct fy_document *d, struct fy_node *map, const char *key, const char *yaml)
{
	struct fy_node *v = node_yaml(d, yaml), *k;
	struct fy_node_pair *p = fy_node_mapping_lookup_pair_by_string(map, key, FY_NT);

	if (!v)
		return -1;
	if (p)
		return fy_node_pair_set_value(p, v);
	if (!(k = fy_node_create_scalar_copy(d, key, FY_NT)))
		return -1;
	return fy_node_mapping_append(map, k, v);
}

/*
 * The tree of the injected file: meta.filename its name, meta.file_date
 * now (SOURCE_DATE_EPOCH pins it), and an entry in the ASDF history
 * (history-1.1.0's entries, or an old file's list of entries) saying
 * what wfiscene added.
 */
static int update_tree(struct into_asdf *ia, const char *path, long nsrc, const char *filter,
		       struct err *e)
{
	struct fy_document *d = ia->in->d;
	struct fy_node *root = fy_document_root(d), *meta = at(root, "/roman/meta"), *h, *ent;
	const char *base = strrchr(path, '/'), *epoch = getenv("SOURCE_DATE_EPOCH");
	time_t now = epoch && *epoch ? (time_t)strtoll(epoch, NULL, 10) : time(NULL);
	char q[1024], when[40], yaml[2600], desc[1800], iso[40];
	struct tm tm;

	if (!meta || !fy_node_is_mapping(meta))
		return err_set(e, EXIT_INPUT, "%s: no meta mapping", ia->in->path);
	quoted(base ? base + 1 : path, q, sizeof(q));
	date_format(40587.0 + (double)now / 86400.0, when, sizeof(when));
	snprintf(yaml, sizeof(yaml), "!time/time-1.2.0 \"%s\"", when);
	if (set_yaml(d, meta, "filename", q) < 0 || set_yaml(d, meta, "file_date", yaml) < 0)
		goto nomem;
	snprintf(desc, sizeof(desc), "wfiscene --into: %ld source%s of %s drawn in %s on %s "
		 "and added to data (DN/s), their Poisson variance to var_poisson and err",
		 nsrc, nsrc == 1 ? "" : "s", ia->catalogs && *ia->catalogs ? ia->catalogs :
		 "the catalog", filter, fy_node_get_scalar0(at(root,
		 "/roman/meta/instrument/detector")));
	quoted(desc, q, sizeof(q));
	gmtime_r(&now, &tm);
	strftime(iso, sizeof(iso), "%Y-%m-%dT%H:%M:%SZ", &tm);
	snprintf(yaml, sizeof(yaml), "!core/history_entry-1.0.0 {description: %s, software: "
		 "!core/software-1.0.0 {name: wfiscene, version: \"%s\"}, "
		 "time: \"%s\"}", q, WFS_VERSION, iso);
	if (!(ent = node_yaml(d, yaml)))
		goto nomem;
	h = at(root, "/history");
	if (h && fy_node_is_sequence(h))
		return fy_node_sequence_append(h, ent) < 0 ? err_sys(e, "%s", path) : 0;
	if (!h || !fy_node_is_mapping(h)) {
		if (set_yaml(d, root, "history", "{entries: []}") < 0)
			goto nomem;
		h = at(root, "/history");
	}
	if (!fy_node_mapping_lookup_by_string(h, "entries", FY_NT) &&
	    set_yaml(d, h, "entries", "[]") < 0)
		goto nomem;
	h = fy_node_mapping_lookup_by_string(h, "entries", FY_NT);
	if (!h || !fy_node_is_sequence(h))
		return err_set(e, EXIT_INPUT, "%s: history.entries is not a list", ia->in->path);
	if (fy_node_sequence_append(h, ent) < 0)
		goto nomem;
	return 0;
nomem:
	return err_sys(e, "%s: the ASDF tree", path);
}

/* Block data from memory, for asdf_block_write. */
static int mem_get(void *arg, uint64_t off, void *buf, size_t n, struct err *e)
{
	(void)e;
	memcpy(buf, (const unsigned char *)arg + off, n);
	return 0;
}

/* The compression a block is stored with, as asdf.h's enum; -1 for one
 * not written here (bzp2, an extension's). */
static int stored_as(const struct asdf_block *b)
{
	for (int c = ASDF_NONE; c <= ASDF_LZ4; c++)
		if (!memcmp(b->comp, asdf_compression_field(c), 4))
			return c;
	return -1;
}

/* The image with the changed arrays, to fd: the header and tree as they
 * were, then the blocks.  Each stored as compression says (ASDF_KEEP:
 * as it was); a block unchanged and stored so already is copied byte for
 * byte, the others written anew (an unchanged one read back, its MD5
 * checked), with an MD5 of their data where the image had one. */
static int write_image(struct into_asdf *ia, int fd, void *const *data, int compression,
		       struct pool *pool, const char *path, struct err *e)
{
	struct asdf_in *a = ia->in;
	uint64_t off = 0, *where = calloc((size_t)a->nblock + 1, sizeof(*where));
	FILE *m = NULL;
	char *idx = NULL;
	size_t ni = 0;
	int r = -1;

	if (!where)
		return err_sys(e, "%s", path);
	{
		/* the header lines and the YAML directives as they were, then
		 * the tree emitted again (its tags in the same shorthand) */
		const char *dash = strstr(a->text + a->tree_off, "\n---");
		size_t nd = dash ? (size_t)(dash - a->text) + 1 : 0, nt;
		char *tree;

		if (!dash || nd > a->tree_end) {
			err_set(e, EXIT_INPUT, "%s: no '---' before the tree", a->path);
			goto done;
		}
		tree = fy_emit_document_to_string(a->d, FYECF_MODE_ORIGINAL | FYECF_WIDTH_INF |
						  FYECF_INDENT_2 | FYECF_DOC_START_MARK_ON |
						  FYECF_DOC_END_MARK_OFF | FYECF_VERSION_DIR_OFF |
						  FYECF_TAG_DIR_OFF);
		if (!tree) {
			err_sys(e, "%s: the ASDF tree", path);
			goto done;
		}
		nt = strlen(tree);
		if (copy(ia, fd, 0, nd, &off, path, e) < 0 || put(fd, tree, nt, &off, path, e) < 0 ||
		    put(fd, nt && tree[nt - 1] == '\n' ? "...\n" : "\n...\n",
			nt && tree[nt - 1] == '\n' ? 4 : 5, &off, path, e) < 0) {
			free(tree);
			goto done;
		}
		free(tree);
	}
	for (int k = 0; k < a->nblock; k++) {
		const struct asdf_block *b = &a->b[k];
		int changed = -1, was = stored_as(b), to = compression == ASDF_KEEP ? was : compression;
		struct asdf_block_src src = { .n = b->data, .itemsize = 1, .get = mem_get,
					      .md5 = memcmp(b->md5, (const unsigned char[16]){ 0 }, 16) };
		void *back = NULL;

		for (int j = 0; j < A_N; j++)
			if (ia->block[j] == k) {
				changed = j;
				src.itemsize = ia->dtype[j] == ASDF_F32 ? 4 : 2;
			}
		where[k] = off;
		if (changed < 0 && to == was) {
			if (copy(ia, fd, b->off, b->data_off - b->off + b->allocated, &off, path,
				 e) < 0)
				goto done;
			continue;
		}
		if (changed < 0) {
			/* recompressed: the data read back (and checked) first */
			if (!(back = malloc(b->data ? b->data : 1))) {
				err_sys(e, "%s", path);
				goto done;
			}
			if (asdf_in_block(a, k, back, b->data, e) < 0) {
				free(back);
				goto done;
			}
		}
		/* a changed block of a compression not written here: none */
		src.compression = to < 0 ? ASDF_NONE : to;
		src.arg = changed < 0 ? back : data[changed];
		r = asdf_block_write(fd, off, &src, pool, path, &off, e);
		free(back);
		if (r < 0)
			goto done;
		r = -1;
	}
	if (!(m = open_memstream(&idx, &ni))) {
		err_sys(e, "%s", path);
		goto done;
	}
	fputs("#ASDF BLOCK INDEX\n%YAML 1.1\n---\n", m);
	for (int k = 0; k < a->nblock; k++)
		fprintf(m, "- %llu\n", (unsigned long long)where[k]);
	fputs("...\n", m);
	if (fclose(m)) {
		m = NULL;
		err_sys(e, "%s", path);
		goto done;
	}
	m = NULL;
	if (a->nblock && put(fd, idx, ni, &off, path, e) < 0)
		goto done;
	if (ftruncate(fd, (off_t)off) || fsync(fd)) {
		err_sys(e, "%s: write error", path);
		goto done;
	}
	r = 0;
done:
	free(idx);
	free(where);
	return r;
}

int into_asdf_compose(struct into_asdf *ia, const char *path, int compression,
		      struct pool *pool, struct err *e)
{
	size_t npx = (size_t)WFS_NPIX * WFS_NPIX;
	float *v[A_N] = { 0 };
	double *add = NULL;
	void *data[A_N] = { 0 };
	char tmp[4200] = "", filter[FLEN_VALUE] = "";
	struct ramp_det det;
	long nsrc = 0;
	int fd = -1, rc = -1;

	/* the engine's light, counts/s (e-/s), from its scene */
	if (!(add = malloc(npx * sizeof(double)))) {
		err_sys(e, "%s", path);
		goto out;
	}
	if (into_scene(path, ia->sca, WFS_NPIX, WFS_NPIX, add, &nsrc, filter, sizeof(filter),
		       e) < 0)
		goto out;
	if (update_tree(ia, path, nsrc, filter, e) < 0)
		goto out;
	if (ramp_det_get(ia->sca, &det, e) < 0)
		goto out;
	for (int k = 0; k < A_N; k++)
		if (!(v[k] = malloc(npx * sizeof(float))) ||
		    read_array(ia, k, v[k], npx, e) < 0) {
			if (!v[k])
				err_sys(e, "%s", ia->in->path);
			goto out;
		}
	/* DN/s = counts/s over the gain; the Poisson variance of a rate of
	 * R DN/s measured over the effective time T is R / (gain T) */
	for (size_t i = 0; i < npx; i++) {
		double r = add[i] / det.gain, var = (r > 0 ? r : 0) / (det.gain * ia->teff);
		double er = v[A_ERR][i];

		v[A_DATA][i] = (float)(v[A_DATA][i] + r);
		v[A_VP][i] = (float)(v[A_VP][i] + var);
		v[A_ERR][i] = (float)sqrt((isfinite(er) ? er * er : 0) + var);
	}
	for (int k = 0; k < A_N; k++)
		if (!(data[k] = store(ia, k, v[k], npx))) {
			err_sys(e, "%s", path);
			goto out;
		}
	if ((fd = tempfile_beside(path, tmp, sizeof(tmp), e)) < 0 ||
	    write_image(ia, fd, data, compression, pool, path, e) < 0)
		goto out;
	if (close(fd)) {
		fd = -1;
		err_sys(e, "%s: write error", path);
		goto out;
	}
	fd = -1;
	if (tempfile_commit(tmp, path, e) < 0)
		goto out;
	rc = 0;
out:
	if (fd >= 0)
		close(fd);
	if (tmp[0])
		tempfile_discard(tmp);
	free(add);
	for (int k = 0; k < A_N; k++) {
		free(v[k]);
		free(data[k]);
	}
	return rc;
}

int into_asdf_apply(const struct into_asdf *ia, struct sky *sky, struct err *e)
{
	struct sky_sca *ss = &sky->sca[ia->sca - 1];
	const struct geom_aperture *ap = geom_aperture(ia->sca);
	double x0 = ap->xref - 1, y0 = ap->yref - 1, ra2, dec2, cx, cy, far = 0;

	/* the SIAF chain of wcsinfo's attitude, whatever --set said */
	geom_sca_free(&ss->geo);
	if (geom_sca_init(&ss->geo, GEOM_SIAF, ia->sca, (const double (*)[3])sky->att, 0, 0, 0,
			  e) < 0)
		return -1;
	if (ia->gw)
		ss->geo.map = &ia->map;
	else if (ia->va != 1)
		/* romancal's WCS of wcsinfo: V2/V3 scaled about the reference */
		geom_sca_aberrate(&ss->geo, ia->va, ss->geo.u);
	geom_pix_to_sky(&ss->geo, x0, y0, &ss->ra, &ss->dec);
	geom_pix_to_sky(&ss->geo, x0, y0 + 1, &ra2, &dec2);
	if (!isfinite(ss->ra) || !isfinite(ss->dec) || !isfinite(ra2) || !isfinite(dec2))
		return err_set(e, EXIT_INPUT, "%s: meta.wcs gives no sky position for the "
			       "reference pixel", ia->in->path);
	{
		double a = ss->ra * D2R, d = ss->dec * D2R, s2[3], ee[3], nn[3], de = 0, dn = 0;

		geom_unit(ra2 * D2R, dec2 * D2R, s2);
		en(a, d, ee, nn);
		for (int k = 0; k < 3; k++) {
			de += s2[k] * ee[k];
			dn += s2[k] * nn[k];
		}
		ss->pa = atan2(de, dn) * R2D;
	}
	/* the engine culls rows outside a square about the SCA in the focal
	 * plane: the square of the image's own corners */
	sky_to_focal(sky, 1, &ss->ra, &ss->dec, INFINITY, &cx, &cy);
	if (!isfinite(cx) || !isfinite(cy))
		return err_set(e, EXIT_INPUT, "%s: meta.wcs puts the image far from its "
			       "meta.wcsinfo pointing", ia->in->path);
	ss->fx = cx;
	ss->fy = cy;
	for (int c = 0; c < 8; c++) {
		static const double px[8] = { -0.5, 4087.5, -0.5, 4087.5, -0.5, 4087.5, 2043.5,
					      2043.5 };
		static const double py[8] = { -0.5, -0.5, 4087.5, 4087.5, 2043.5, 2043.5, -0.5,
					      4087.5 };
		double r, d, fx, fy;

		geom_pix_to_sky(&ss->geo, px[c], py[c], &r, &d);
		sky_to_focal(sky, 1, &r, &d, INFINITY, &fx, &fy);
		far = fmax(far, fmax(fabs(fx - cx), fabs(fy - cy)));
	}
	if (!(far <= SKY_SCA_HALF * 1.1))
		return err_set(e, EXIT_INPUT, "%s: meta.wcs: the image reaches %.1f arcsec from "
			       "its centre along the detector axes, more than an SCA's %.1f",
			       ia->in->path, far, SKY_SCA_HALF * 1.1);
	ss->half = fmax(SKY_SCA_HALF, far + 1.0);
	return 0;
}

void into_asdf_free(struct into_asdf *ia)
{
	if (!ia)
		return;
	gwcs_free(ia->gw);
	free(ia->catalogs);
	asdf_in_free(ia->in);
	free(ia);
}
