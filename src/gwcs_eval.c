/*
 * gwcs_eval.c - the gwcs of a Roman level-2 ASDF file, evaluated; see
 * gwcs_eval.h.
 *
 * Each transform becomes a node of a tree (compose and concatenate have
 * two children) evaluated one point at a time on a vector of at most
 * MAXD values.  The formulas are astropy's: angles in degrees at the
 * interfaces, rotation matrices as astropy.coordinates.rotation_matrix
 * builds them (R[a1][a2] = sin, R[a2][a1] = -sin about axis i), products
 * of a sequence taken last-first.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <libfyaml.h>

#include "asdf_read.h"
#include "err.h"
#include "gwcs_eval.h"

#define MAXD 8
#define D2R (M_PI / 180)
#define R2D (180 / M_PI)
#define MAXDEG 20

enum op {
	T_COMPOSE, T_CONCAT, T_MAPPING, T_IDENTITY, T_SHIFT, T_SCALE, T_POLY1, T_POLY2,
	T_AFFINE, T_ROT2D, T_ROT_SPH, T_ROT_CART, T_TAN_P2S, T_TAN_S2P, T_S2C, T_C2S,
	T_CONST, T_ARITH
};

struct tnode {
	int op, nin, nout;
	struct tnode *a, *b;    /* compose (a then b), concatenate (a & b) */
	struct tnode *inv;      /* the file's own inverse */
	int map[MAXD];          /* remap_axes */
	double v;               /* offset, factor, value, angle (rad), wrap_lon_at */
	double m[3][3];         /* rotation; affine's 2 x 2 in m[0..1][0..1] */
	double t[2];            /* affine's translation */
	int deg;                /* polynomial */
	double *c;              /* 1D: c[i] of x^i; 2D: c[i * (deg + 1) + j] of x^i y^j */
	double dom[2][2], win[2][2];
	int has_dom[2];
	char arith;             /* + - * / of two transforms' outputs */
	int wrap;               /* rotate3d native2celestial or celestial2native:
				 * longitudes in [0, 360) as astropy's */
};

struct gwcs {
	struct tnode *top;
	int has_inverse;
};

struct ctx {
	struct asdf_in *a;
	char *why;
	size_t nwhy;
	int bad;
};

static void tfree(struct tnode *n)
{
	if (!n)
		return;
	tfree(n->a);
	tfree(n->b);
	tfree(n->inv);
	free(n->c);
	free(n);
}

void gwcs_free(struct gwcs *g)
{
	if (!g)
		return;
	tfree(g->top);
	free(g);
}

__attribute__((format(printf, 2, 3)))
static int fail(struct ctx *c, const char *fmt, ...)
{
	va_list ap;

	if (!c->bad) {
		va_start(ap, fmt);
		vsnprintf(c->why, c->nwhy, fmt, ap);
		va_end(ap);
	}
	c->bad = 1;
	return -1;
}

static struct fy_node *deref(struct fy_node *n)
{
	return n && fy_node_is_alias(n) ? fy_node_resolve_alias(n) : n;
}

static struct fy_node *key(struct fy_node *m, const char *k)
{
	return m && fy_node_is_mapping(m) ? deref(fy_node_mapping_lookup_by_string(m, k, FY_NT))
					   : NULL;
}

/* The transform's name from its tag: "compose" of
 * tag:stsci.edu:asdf/transform/compose-1.2.0. */
static void tag_name(struct fy_node *n, char *name, size_t size)
{
	size_t tl;
	const char *tag = n ? fy_node_get_tag(n, &tl) : NULL;
	const char *s, *dash;

	name[0] = 0;
	if (!tag)
		return;
	s = tag + tl;
	while (s > tag && s[-1] != '/')
		s--;
	for (dash = tag + tl; dash > s && *dash != '-'; dash--)
		;
	if (dash == s)
		dash = tag + tl;
	snprintf(name, size, "%.*s", (int)(dash - s), s);
}

/* A number, or the value of a quantity. */
static int num(struct ctx *c, struct fy_node *n, const char *what, double *v)
{
	const char *s;
	char *end;

	n = deref(n);
	if (n && fy_node_is_mapping(n))
		n = key(n, "value");
	s = n && fy_node_is_scalar(n) ? fy_node_get_scalar0(n) : NULL;
	if (!s)
		return fail(c, "%s is not a number", what);
	*v = strtod(s, &end);
	if (end == s || *end) {
		if (!strcmp(s, ".nan") || !strcmp(s, ".NaN"))
			*v = NAN;
		else if (!strcmp(s, ".inf") || !strcmp(s, "+.inf"))
			*v = INFINITY;
		else if (!strcmp(s, "-.inf"))
			*v = -INFINITY;
		else
			return fail(c, "%s is not a number", what);
	}
	return 0;
}

static int decode(const unsigned char *p, const char *dt, int big, double *v)
{
	unsigned char b[8];
	size_t k = !strcmp(dt, "float64") || !strcmp(dt, "int64") || !strcmp(dt, "uint64") ? 8
		 : !strcmp(dt, "float32") || !strcmp(dt, "int32") || !strcmp(dt, "uint32") ? 4 : 0;
	const uint16_t one = 1;
	int little = *(const unsigned char *)&one == 1;

	if (!k)
		return -1;
	for (size_t i = 0; i < k; i++)
		b[i] = p[big == little ? k - 1 - i : i];
	if (!strcmp(dt, "float64")) {
		double d;

		memcpy(&d, b, 8);
		*v = d;
	} else if (!strcmp(dt, "float32")) {
		float f;

		memcpy(&f, b, 4);
		*v = f;
	} else if (!strcmp(dt, "int64")) {
		int64_t i;

		memcpy(&i, b, 8);
		*v = (double)i;
	} else if (!strcmp(dt, "uint64")) {
		uint64_t i;

		memcpy(&i, b, 8);
		*v = (double)i;
	} else if (!strcmp(dt, "int32")) {
		int32_t i;

		memcpy(&i, b, 4);
		*v = i;
	} else {
		uint32_t i;

		memcpy(&i, b, 4);
		*v = i;
	}
	return 0;
}

/* Nested sequences of numbers into v (at most cap), row-major; their
 * shape into shape[] (ndim at most 2). */
static int flat(struct ctx *c, struct fy_node *s, double *v, int cap, int *n, int *shape,
		int depth, const char *what)
{
	int k = fy_node_sequence_item_count(s);

	if (depth > 1)
		return fail(c, "%s: an array of more than 2 dimensions", what);
	shape[depth] = k;
	for (int i = 0; i < k; i++) {
		struct fy_node *e = deref(fy_node_sequence_get_by_index(s, i));

		if (e && fy_node_is_sequence(e)) {
			if (flat(c, e, v, cap, n, shape, depth + 1, what) < 0)
				return -1;
			continue;
		}
		if (*n >= cap)
			return fail(c, "%s: too many numbers", what);
		if (num(c, e, what, &v[*n]) < 0)
			return -1;
		(*n)++;
	}
	return 0;
}

/* An ndarray (inline, or in a block) or a plain sequence, as at most cap
 * doubles; its dimensions (1 or 2) and shape. */
static int array(struct ctx *c, struct fy_node *n, const char *what, double *v, int cap,
		 int *ndim, int *shape)
{
	struct fy_node *src, *dt, *bo, *sh, *off;
	long nb, count = 1, o = 0;
	unsigned char *raw;
	size_t es;

	n = deref(n);
	shape[0] = shape[1] = 1;
	if (n && fy_node_is_mapping(n) && (src = key(n, "data")))
		n = src;
	if (n && fy_node_is_sequence(n)) {
		int k = 0, sp[2] = { 0, 1 };

		if (flat(c, n, v, cap, &k, sp, 0, what) < 0)
			return -1;
		*ndim = sp[1] > 1 || (k && k != sp[0]) ? 2 : 1;
		shape[0] = sp[0];
		shape[1] = *ndim == 2 ? k / (sp[0] ? sp[0] : 1) : 1;
		if ((long)shape[0] * shape[1] != k)
			return fail(c, "%s: a ragged array", what);
		return 0;
	}
	if (!n || !fy_node_is_mapping(n) || !(src = key(n, "source")) || !fy_node_is_scalar(src))
		return fail(c, "%s is not an array", what);
	dt = key(n, "datatype");
	bo = key(n, "byteorder");
	sh = key(n, "shape");
	off = key(n, "offset");
	if (!dt || !fy_node_is_scalar(dt) || !sh || !fy_node_is_sequence(sh) ||
	    fy_node_sequence_item_count(sh) > 2)
		return fail(c, "%s: an array without a datatype or shape of 1 or 2 dimensions",
			    what);
	*ndim = fy_node_sequence_item_count(sh);
	for (int i = 0; i < *ndim; i++) {
		struct fy_node *d = deref(fy_node_sequence_get_by_index(sh, i));

		shape[i] = d && fy_node_is_scalar(d) ? atoi(fy_node_get_scalar0(d)) : -1;
		if (shape[i] < 0)
			return fail(c, "%s: a bad shape", what);
		count *= shape[i];
	}
	if (count > cap)
		return fail(c, "%s: too many numbers", what);
	nb = atol(fy_node_get_scalar0(src));
	if (nb < 0 || nb >= c->a->nblock)
		return fail(c, "%s: its source is not one of the file's blocks", what);
	if (off && fy_node_is_scalar(off))
		o = atol(fy_node_get_scalar0(off));
	{
		const char *d = fy_node_get_scalar0(dt);

		es = strstr(d, "64") ? 8 : strstr(d, "32") ? 4 : 0;
		if (!es || strstr(d, "complex") || o < 0 ||
		    (uint64_t)(o + (long)es * count) > c->a->b[nb].data)
			return fail(c, "%s: an array of a datatype or size not read here", what);
		if (!(raw = malloc(c->a->b[nb].data ? c->a->b[nb].data : 1)))
			return fail(c, "%s: out of memory", what);
		{
			struct err e = { 0 };

			if (asdf_in_block(c->a, (int)nb, raw, c->a->b[nb].data, &e) < 0) {
				free(raw);
				if (!c->bad)
					snprintf(c->why, c->nwhy, "%s", e.msg);
				c->bad = 2;
				return -1;
			}
		}
		for (long i = 0; i < count; i++)
			if (decode(raw + o + i * (long)es, d,
				   bo && fy_node_is_scalar(bo) && !strcmp(fy_node_get_scalar0(bo), "big"),
				   &v[i]) < 0) {
				free(raw);
				return fail(c, "%s: an array of a datatype not read here", what);
			}
		free(raw);
	}
	return 0;
}

/* astropy.coordinates.rotation_matrix of angle (radians) about axis. */
static void axis_matrix(double ang, char axis, double r[3][3])
{
	int i = axis - 'x', a1 = (i + 1) % 3, a2 = (i + 2) % 3;
	double s = sin(ang), co = cos(ang);

	memset(r, 0, 9 * sizeof(double));
	r[i][i] = 1;
	r[a1][a1] = co;
	r[a1][a2] = s;
	r[a2][a1] = -s;
	r[a2][a2] = co;
}

/* m = R_n ... R_1 of the angles (radians) about axes[0 .. n). */
static void sequence(const double *ang, const char *axes, int n, double m[3][3])
{
	double r[3][3], p[3][3];

	memset(m, 0, 9 * sizeof(double));
	m[0][0] = m[1][1] = m[2][2] = 1;
	for (int k = 0; k < n; k++) {
		axis_matrix(ang[k], axes[k], r);
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				p[i][j] = r[i][0] * m[0][j] + r[i][1] * m[1][j] + r[i][2] * m[2][j];
		memcpy(m, p, sizeof(p));
	}
}

static struct tnode *parse(struct ctx *c, struct fy_node *n, const char *where);

static struct tnode *pair(struct ctx *c, struct fy_node *n, struct tnode *t, const char *where)
{
	struct fy_node *f = key(n, "forward");

	if (!f || !fy_node_is_sequence(f) || fy_node_sequence_item_count(f) != 2) {
		fail(c, "%s: a compound transform without two parts", where);
		return NULL;
	}
	if (!(t->a = parse(c, deref(fy_node_sequence_get_by_index(f, 0)), where)) ||
	    !(t->b = parse(c, deref(fy_node_sequence_get_by_index(f, 1)), where)))
		return NULL;
	if (t->op == T_ARITH) {
		if (t->a->nin != t->b->nin || t->a->nout != t->b->nout) {
			fail(c, "%s: arithmetic of transforms of other dimensions", where);
			return NULL;
		}
		t->nin = t->a->nin;
		t->nout = t->a->nout;
	} else if (t->op == T_COMPOSE) {
		if (t->a->nout != t->b->nin) {
			fail(c, "%s: a composition of parts whose outputs and inputs differ in "
			     "number", where);
			return NULL;
		}
		t->nin = t->a->nin;
		t->nout = t->b->nout;
	} else {
		t->nin = t->a->nin + t->b->nin;
		t->nout = t->a->nout + t->b->nout;
		if (t->nin > MAXD || t->nout > MAXD) {
			fail(c, "%s: a concatenation of too many axes", where);
			return NULL;
		}
	}
	return t;
}

static int poly(struct ctx *c, struct fy_node *n, struct tnode *t, const char *where)
{
	double v[(MAXDEG + 1) * (MAXDEG + 1)];
	int nd, sh[2];
	struct fy_node *dom = key(n, "domain"), *win = key(n, "window");

	if (array(c, key(n, "coefficients"), where, v, (int)(sizeof(v) / sizeof(v[0])), &nd,
		  sh) < 0)
		return -1;
	if (nd == 2 && sh[0] != sh[1])
		return fail(c, "%s: a 2D polynomial's coefficients are not square", where);
	t->op = nd == 1 ? T_POLY1 : T_POLY2;
	t->nin = nd;
	t->nout = 1;
	t->deg = sh[0] - 1;
	if (t->deg < 0 || !(t->c = malloc((size_t)sh[0] * sh[1] * sizeof(double))))
		return fail(c, "%s: a polynomial without coefficients", where);
	memcpy(t->c, v, (size_t)sh[0] * sh[1] * sizeof(double));
	/* domain and window: per axis a pair, or (1D) one pair */
	for (int ax = 0; ax < nd; ax++) {
		struct fy_node *d = dom, *w = win;

		if (!d || !fy_node_is_sequence(d))
			continue;
		if (nd == 2) {
			d = deref(fy_node_sequence_get_by_index(dom, ax));
			w = win && fy_node_is_sequence(win) ?
			    deref(fy_node_sequence_get_by_index(win, ax)) : NULL;
		}
		if (!d || !fy_node_is_sequence(d) || fy_node_sequence_item_count(d) != 2)
			continue;       /* null: no mapping */
		if (num(c, fy_node_sequence_get_by_index(d, 0), where, &t->dom[ax][0]) < 0 ||
		    num(c, fy_node_sequence_get_by_index(d, 1), where, &t->dom[ax][1]) < 0)
			return -1;
		t->win[ax][0] = -1;
		t->win[ax][1] = 1;
		if (w && fy_node_is_sequence(w) && fy_node_sequence_item_count(w) == 2 &&
		    (num(c, fy_node_sequence_get_by_index(w, 0), where, &t->win[ax][0]) < 0 ||
		     num(c, fy_node_sequence_get_by_index(w, 1), where, &t->win[ax][1]) < 0))
			return -1;
		if (t->dom[ax][1] == t->dom[ax][0])
			return fail(c, "%s: a polynomial's domain is empty", where);
		t->has_dom[ax] = 1;
	}
	return 0;
}

/* remap_axes: the axes a mapping passes on, in its order */
static int parse_mapping(struct ctx *c, struct fy_node *n, struct tnode *t, const char *what)
{
	struct fy_node *m = key(n, "mapping"), *ni = key(n, "n_inputs");
	int k = m && fy_node_is_sequence(m) ? fy_node_sequence_item_count(m) : 0, hi = 0;

	if (k < 1 || k > MAXD) {
		fail(c, "%s: a mapping of 1 to 8 axes is read here", what);
		return -1;
	}
	for (int i = 0; i < k; i++) {
		struct fy_node *e = deref(fy_node_sequence_get_by_index(m, i));
		double d;

		/* a constant in the mapping (a fixed value) is not read */
		if (num(c, e, what, &d) < 0 || d < 0 || d >= MAXD || d != floor(d)) {
			c->bad = 0;
			fail(c, "%s: a mapping of axis numbers is read here", what);
			return -1;
		}
		t->map[i] = (int)d;
		hi = t->map[i] + 1 > hi ? t->map[i] + 1 : hi;
	}
	t->op = T_MAPPING;
	t->nout = k;
	t->nin = ni && fy_node_is_scalar(ni) ? atoi(fy_node_get_scalar0(ni)) : hi;
	if (t->nin < hi || t->nin > MAXD) {
		fail(c, "%s: n_inputs below the mapping's axes", what);
		return -1;
	}
	return 0;
}

/* affine: a 2 x 2 matrix and a translation */
static int parse_affine(struct ctx *c, struct fy_node *n, struct tnode *t, const char *what)
{
	double v[9];
	int nd, sh[2];

	t->op = T_AFFINE;
	t->nin = t->nout = 2;
	if (array(c, key(n, "matrix"), what, v, 9, &nd, sh) < 0)
		return -1;
	if (nd != 2 || sh[0] != 2 || sh[1] != 2) {
		fail(c, "%s: a 2 x 2 matrix is read here", what);
		return -1;
	}
	t->m[0][0] = v[0], t->m[0][1] = v[1], t->m[1][0] = v[2], t->m[1][1] = v[3];
	if (key(n, "translation")) {
		if (array(c, key(n, "translation"), what, v, 9, &nd, sh) < 0)
			return -1;
		if (sh[0] * sh[1] != 2) {
			fail(c, "%s: a translation of 2 is read here", what);
			return -1;
		}
		t->t[0] = v[0];
		t->t[1] = v[1];
	}
	return 0;
}

/* rotate3d: Euler angles, or the native/celestial rotations of a projection */
static int parse_rotate3d(struct ctx *c, struct fy_node *n, struct tnode *t, const char *what)
{
	struct fy_node *d = key(n, "direction");
	const char *dir = d && fy_node_is_scalar(d) ? fy_node_get_scalar0(d) : "zxz";
	double phi, theta, psi, a[3];

	t->op = T_ROT_SPH;
	t->nin = t->nout = 2;
	if (num(c, key(n, "phi"), what, &phi) < 0 ||
	    num(c, key(n, "theta"), what, &theta) < 0 ||
	    num(c, key(n, "psi"), what, &psi) < 0)
		return -1;
	phi *= D2R, theta *= D2R, psi *= D2R;
	if (!strcmp(dir, "native2celestial")) {
		/* astropy's RotateNative2Celestial(lon, lat, lon_pole) */
		a[0] = psi - M_PI / 2;
		a[1] = -(M_PI / 2 - theta);
		a[2] = -(M_PI / 2 + phi);
		sequence(a, "zxz", 3, t->m);
		t->wrap = 1;
	} else if (!strcmp(dir, "celestial2native")) {
		a[0] = M_PI / 2 + phi;
		a[1] = M_PI / 2 - theta;
		a[2] = -(psi - M_PI / 2);
		sequence(a, "zxz", 3, t->m);
		t->wrap = 1;
	} else if (strlen(dir) == 3 && strspn(dir, "xyz") == 3) {
		a[0] = phi, a[1] = theta, a[2] = psi;
		sequence(a, dir, 3, t->m);
	} else {
		fail(c, "%s: direction not read here", what);
		return -1;
	}
	return 0;
}

/* rotate_sequence_3d: rotations about the axes in axes_order */
static int parse_rotseq(struct ctx *c, struct fy_node *n, struct tnode *t, const char *what)
{
	struct fy_node *ax = key(n, "axes_order"), *rt = key(n, "rotation_type");
	const char *axes = ax && fy_node_is_scalar(ax) ? fy_node_get_scalar0(ax) : "";
	double a[MAXD];
	int nd, sh[2], k = (int)strlen(axes);

	if (k < 1 || k > MAXD || strspn(axes, "xyz") != (size_t)k) {
		fail(c, "%s: axes_order not read here", what);
		return -1;
	}
	if (array(c, key(n, "angles"), what, a, MAXD, &nd, sh) < 0)
		return -1;
	if (sh[0] * sh[1] != k) {
		fail(c, "%s: as many angles as axes are read here", what);
		return -1;
	}
	for (int i = 0; i < k; i++)
		a[i] *= D2R;
	sequence(a, axes, k, t->m);
	t->op = rt && fy_node_is_scalar(rt) && !strcmp(fy_node_get_scalar0(rt), "spherical")
		? T_ROT_SPH : T_ROT_CART;
	t->nin = t->nout = t->op == T_ROT_SPH ? 2 : 3;
	return 0;
}

/* spherical_cartesian: unit vectors and back */
static int parse_sphcart(struct ctx *c, struct fy_node *n, struct tnode *t, const char *what)
{
	struct fy_node *ty = key(n, "transform_type"), *w = key(n, "wrap_lon_at");
	const char *s = ty && fy_node_is_scalar(ty) ? fy_node_get_scalar0(ty) : "";

	if (!strcmp(s, "spherical_to_cartesian")) {
		t->op = T_S2C;
		t->nin = 2, t->nout = 3;
	} else if (!strcmp(s, "cartesian_to_spherical")) {
		t->op = T_C2S;
		t->nin = 3, t->nout = 2;
	} else {
		fail(c, "%s: transform_type not read here", what);
		return -1;
	}
	t->v = 360;
	if (w && num(c, w, what, &t->v) < 0)
		return -1;
	return 0;
}

static struct tnode *parse(struct ctx *c, struct fy_node *n, const char *where)
{
	struct tnode *t = calloc(1, sizeof(*t));
	struct fy_node *inv;
	char name[64], what[160];

	if (!t) {
		fail(c, "%s: out of memory", where);
		return NULL;
	}
	tag_name(n, name, sizeof(name));
	snprintf(what, sizeof(what), "%s: %s", where, name[0] ? name : "(untagged)");
	if (!n || !fy_node_is_mapping(n)) {
		fail(c, "%s is not a transform", what);
		goto bad;
	}
	t->nin = t->nout = 1;
	if (!strcmp(name, "compose") || !strcmp(name, "concatenate")) {
		t->op = name[1] == 'o' && name[2] == 'm' ? T_COMPOSE : T_CONCAT;
		if (!pair(c, n, t, where))
			goto bad;
	} else if (!strcmp(name, "add") || !strcmp(name, "subtract") || !strcmp(name, "multiply") ||
		   !strcmp(name, "divide")) {
		/* the compound arithmetic of two transforms (a + b ...) */
		t->op = T_ARITH;
		t->arith = name[0] == 'a' ? '+' : name[0] == 's' ? '-' : name[0] == 'm' ? '*' : '/';
		if (!pair(c, n, t, where))
			goto bad;
	} else if (!strcmp(name, "remap_axes")) {
		if (parse_mapping(c, n, t, what) < 0)
			goto bad;
	} else if (!strcmp(name, "identity")) {
		struct fy_node *nd = key(n, "n_dims");

		t->op = T_IDENTITY;
		t->nin = t->nout = nd && fy_node_is_scalar(nd) ? atoi(fy_node_get_scalar0(nd)) : 1;
		if (t->nin < 1 || t->nin > MAXD) {
			fail(c, "%s: n_dims out of range", what);
			goto bad;
		}
	} else if (!strcmp(name, "shift")) {
		t->op = T_SHIFT;
		if (num(c, key(n, "offset"), what, &t->v) < 0)
			goto bad;
	} else if (!strcmp(name, "scale") || !strcmp(name, "multiplyscale")) {
		t->op = T_SCALE;
		if (num(c, key(n, "factor"), what, &t->v) < 0)
			goto bad;
	} else if (!strcmp(name, "constant")) {
		struct fy_node *d = key(n, "dimensions");

		t->op = T_CONST;
		t->nin = d && fy_node_is_scalar(d) ? atoi(fy_node_get_scalar0(d)) : 1;
		if (t->nin < 1 || t->nin > 2 || num(c, key(n, "value"), what, &t->v) < 0) {
			fail(c, "%s: a constant of 1 or 2 inputs is read here", what);
			goto bad;
		}
	} else if (!strcmp(name, "polynomial")) {
		struct fy_node *pt = key(n, "polynomial_type");

		if (pt && fy_node_is_scalar(pt) && strcmp(fy_node_get_scalar0(pt), "Polynomial")) {
			fail(c, "%s: only the power series (Polynomial) is read here", what);
			goto bad;
		}
		if (poly(c, n, t, what) < 0)
			goto bad;
	} else if (!strcmp(name, "affine")) {
		if (parse_affine(c, n, t, what) < 0)
			goto bad;
	} else if (!strcmp(name, "rotate2d")) {
		t->op = T_ROT2D;
		t->nin = t->nout = 2;
		if (num(c, key(n, "angle"), what, &t->v) < 0)
			goto bad;
		t->v *= D2R;
	} else if (!strcmp(name, "rotate3d")) {
		if (parse_rotate3d(c, n, t, what) < 0)
			goto bad;
	} else if (!strcmp(name, "rotate_sequence_3d")) {
		if (parse_rotseq(c, n, t, what) < 0)
			goto bad;
	} else if (!strcmp(name, "gnomonic")) {
		struct fy_node *d = key(n, "direction");
		const char *dir = d && fy_node_is_scalar(d) ? fy_node_get_scalar0(d) : "pix2sky";

		t->op = !strcmp(dir, "sky2pix") ? T_TAN_S2P : T_TAN_P2S;
		t->nin = t->nout = 2;
	} else if (!strcmp(name, "spherical_cartesian")) {
		if (parse_sphcart(c, n, t, what) < 0)
			goto bad;
	} else {
		fail(c, "%s: this transform is not evaluated by wfiscene", what);
		goto bad;
	}
	if ((inv = key(n, "inverse")) && !fy_node_is_scalar(inv)) {
		if (!(t->inv = parse(c, inv, where)))
			goto bad;
		if (t->inv->nin != t->nout || t->inv->nout != t->nin) {
			fail(c, "%s: an inverse of other dimensions", what);
			goto bad;
		}
	}
	return t;
bad:
	tfree(t);
	return NULL;
}

/* ---- evaluation ---- */

static void cart(double lon, double lat, double v[3])
{
	v[0] = cos(lat * D2R) * cos(lon * D2R);
	v[1] = cos(lat * D2R) * sin(lon * D2R);
	v[2] = sin(lat * D2R);
}

static void sph(const double v[3], double *lon, double *lat)
{
	*lon = atan2(v[1], v[0]) * R2D;
	*lat = atan2(v[2], hypot(v[0], v[1])) * R2D;
}

static void mul(const double m[3][3], int transpose, const double *in, double *out)
{
	for (int i = 0; i < 3; i++)
		out[i] = transpose ? m[0][i] * in[0] + m[1][i] * in[1] + m[2][i] * in[2]
				   : m[i][0] * in[0] + m[i][1] * in[1] + m[i][2] * in[2];
}

static double mapdom(const struct tnode *t, int ax, double x)
{
	const double *d = t->dom[ax], *w = t->win[ax];

	if (!t->has_dom[ax])
		return x;
	return (w[0] * d[1] - w[1] * d[0]) / (d[1] - d[0]) + x * (w[1] - w[0]) / (d[1] - d[0]);
}

static int eval(const struct tnode *t, const double *in, double *out);
static int eval_inv(const struct tnode *t, const double *in, double *out);

static int eval(const struct tnode *t, const double *in, double *out)
{
	double mid[MAXD], v[3], w[3];

	switch (t->op) {
	case T_COMPOSE:
		return eval(t->a, in, mid) < 0 ? -1 : eval(t->b, mid, out);
	case T_CONCAT:
		if (eval(t->a, in, out) < 0)
			return -1;
		return eval(t->b, in + t->a->nin, out + t->a->nout);
	case T_ARITH:
		if (eval(t->a, in, out) < 0 || eval(t->b, in, mid) < 0)
			return -1;
		for (int i = 0; i < t->nout; i++)
			out[i] = t->arith == '+' ? out[i] + mid[i] : t->arith == '-' ? out[i] - mid[i] :
				 t->arith == '*' ? out[i] * mid[i] : out[i] / mid[i];
		return 0;
	case T_MAPPING:
		for (int i = 0; i < t->nout; i++)
			out[i] = in[t->map[i]];
		return 0;
	case T_IDENTITY:
		memcpy(out, in, (size_t)t->nin * sizeof(double));
		return 0;
	case T_SHIFT:
		out[0] = in[0] + t->v;
		return 0;
	case T_SCALE:
		out[0] = in[0] * t->v;
		return 0;
	case T_CONST:
		out[0] = t->v;
		return 0;
	case T_POLY1: {
		double x = mapdom(t, 0, in[0]), s = 0;

		for (int i = t->deg; i >= 0; i--)
			s = s * x + t->c[i];
		out[0] = s;
		return 0;
	}
	case T_POLY2: {
		double x = mapdom(t, 0, in[0]), y = mapdom(t, 1, in[1]), s = 0, yp = 1;
		int n = t->deg + 1;

		/* sum over i + j <= deg of c[i][j] x^i y^j */
		for (int j = 0; j <= t->deg; j++, yp *= y) {
			double r = 0;

			for (int i = t->deg - j; i >= 0; i--)
				r = r * x + t->c[i * n + j];
			s += r * yp;
		}
		out[0] = s;
		return 0;
	}
	case T_AFFINE:
		out[0] = t->m[0][0] * in[0] + t->m[0][1] * in[1] + t->t[0];
		out[1] = t->m[1][0] * in[0] + t->m[1][1] * in[1] + t->t[1];
		return 0;
	case T_ROT2D:
		out[0] = cos(t->v) * in[0] - sin(t->v) * in[1];
		out[1] = sin(t->v) * in[0] + cos(t->v) * in[1];
		return 0;
	case T_ROT_SPH:
		cart(in[0], in[1], v);
		mul(t->m, 0, v, w);
		sph(w, &out[0], &out[1]);
		if (t->wrap && out[0] < 0)
			out[0] += 360;
		return 0;
	case T_ROT_CART:
		mul(t->m, 0, in, out);
		return 0;
	case T_TAN_P2S: {
		double r = hypot(in[0], in[1]);

		out[0] = atan2(in[0], -in[1]) * R2D;
		out[1] = atan2(R2D, r) * R2D;
		return 0;
	}
	case T_TAN_S2P: {
		double th = in[1] * D2R, r;

		if (!(sin(th) > 0))
			return -1;
		r = R2D * cos(th) / sin(th);
		out[0] = r * sin(in[0] * D2R);
		out[1] = -r * cos(in[0] * D2R);
		return 0;
	}
	case T_S2C:
		cart(in[0], in[1], out);
		return 0;
	case T_C2S: {
		double lon, lat;

		sph(in, &lon, &lat);
		/* wrap_lon_at 180: (-180, 180]; 360: [0, 360) */
		if (t->v == 360 && lon < 0)
			lon += 360;
		out[0] = lon;
		out[1] = lat;
		return 0;
	}
	}
	return -1;
}

/* 1 when t has an inverse (its own or astropy's analytic one). */
static int invertible(const struct tnode *t)
{
	if (t->inv)
		return 1;
	switch (t->op) {
	case T_COMPOSE:
	case T_CONCAT:
		return invertible(t->a) && invertible(t->b);
	case T_MAPPING:
		/* astropy inverts a mapping that keeps every input */
		for (int i = 0; i < t->nin; i++) {
			int hit = 0;

			for (int k = 0; k < t->nout; k++)
				hit |= t->map[k] == i;
			if (!hit)
				return 0;
		}
		return 1;
	case T_SCALE:
		return t->v != 0;
	case T_AFFINE:
		return t->m[0][0] * t->m[1][1] - t->m[0][1] * t->m[1][0] != 0;
	case T_POLY1:
	case T_POLY2:
	case T_CONST:
	case T_ARITH:
		return 0;
	}
	return 1;
}

static int eval_inv(const struct tnode *t, const double *in, double *out)
{
	double mid[MAXD], v[3], w[3];

	if (t->inv)
		return eval(t->inv, in, out);
	switch (t->op) {
	case T_COMPOSE:
		return eval_inv(t->b, in, mid) < 0 ? -1 : eval_inv(t->a, mid, out);
	case T_CONCAT:
		if (eval_inv(t->a, in, out) < 0)
			return -1;
		return eval_inv(t->b, in + t->a->nout, out + t->a->nin);
	case T_MAPPING:
		/* input i is the first output that carries it */
		for (int i = 0; i < t->nin; i++)
			for (int k = t->nout - 1; k >= 0; k--)
				if (t->map[k] == i)
					out[i] = in[k];
		return 0;
	case T_IDENTITY:
		memcpy(out, in, (size_t)t->nin * sizeof(double));
		return 0;
	case T_SHIFT:
		out[0] = in[0] - t->v;
		return 0;
	case T_SCALE:
		out[0] = in[0] / t->v;
		return 0;
	case T_AFFINE: {
		double det = t->m[0][0] * t->m[1][1] - t->m[0][1] * t->m[1][0];
		double a = in[0] - t->t[0], b = in[1] - t->t[1];

		out[0] = (t->m[1][1] * a - t->m[0][1] * b) / det;
		out[1] = (-t->m[1][0] * a + t->m[0][0] * b) / det;
		return 0;
	}
	case T_ROT2D:
		out[0] = cos(t->v) * in[0] + sin(t->v) * in[1];
		out[1] = -sin(t->v) * in[0] + cos(t->v) * in[1];
		return 0;
	case T_ROT_SPH:
		cart(in[0], in[1], v);
		mul(t->m, 1, v, w);
		sph(w, &out[0], &out[1]);
		if (t->wrap && out[0] < 0)
			out[0] += 360;
		return 0;
	case T_ROT_CART:
		mul(t->m, 1, in, out);
		return 0;
	case T_TAN_P2S: {
		struct tnode s = *t;

		s.op = T_TAN_S2P;
		return eval(&s, in, out);
	}
	case T_TAN_S2P: {
		struct tnode s = *t;

		s.op = T_TAN_P2S;
		return eval(&s, in, out);
	}
	case T_S2C: {
		struct tnode s = *t;

		s.op = T_C2S;
		return eval(&s, in, out);
	}
	case T_C2S:
		cart(in[0], in[1], out);
		return 0;
	}
	return -1;
}

struct gwcs *gwcs_load(struct asdf_in *a, struct fy_node *w, char *why, size_t nwhy,
		       int *fatal)
{
	struct ctx c = { a, why, nwhy, 0 };
	struct gwcs *g = calloc(1, sizeof(*g));
	struct fy_node *steps = key(deref(w), "steps");
	int n = steps && fy_node_is_sequence(steps) ? fy_node_sequence_item_count(steps) : 0;
	char name[64];

	why[0] = 0;
	*fatal = 0;
	tag_name(deref(w), name, sizeof(name));
	if (!g) {
		snprintf(why, nwhy, "out of memory");
		return NULL;
	}
	if (strcmp(name, "wcs") || n < 2) {
		snprintf(why, nwhy, "meta.wcs is not a gwcs of two or more steps");
		goto bad;
	}
	for (int i = 0; i < n - 1; i++) {
		struct fy_node *s = deref(fy_node_sequence_get_by_index(steps, i));
		struct fy_node *tr = key(s, "transform");
		char where[64];
		struct tnode *t;

		snprintf(where, sizeof(where), "meta.wcs step %d", i + 1);
		if (!tr || fy_node_is_scalar(tr)) {
			snprintf(why, nwhy, "%s has no transform", where);
			goto bad;
		}
		if (!(t = parse(&c, tr, where)))
			goto bad;
		if (!g->top) {
			g->top = t;
			continue;
		}
		{
			struct tnode *comp = calloc(1, sizeof(*comp));

			if (!comp || g->top->nout != t->nin) {
				tfree(t);
				free(comp);
				snprintf(why, nwhy, "%s: its inputs are not the last step's outputs",
					 where);
				goto bad;
			}
			comp->op = T_COMPOSE;
			comp->a = g->top;
			comp->b = t;
			comp->nin = g->top->nin;
			comp->nout = t->nout;
			g->top = comp;
		}
	}
	if (g->top->nin != 2 || g->top->nout != 2) {
		snprintf(why, nwhy, "meta.wcs maps %d axes to %d, not pixels to the sky",
			 g->top->nin, g->top->nout);
		goto bad;
	}
	g->has_inverse = invertible(g->top);
	return g;
bad:
	*fatal = c.bad == 2;
	gwcs_free(g);
	return NULL;
}

int gwcs_has_inverse(const struct gwcs *g)
{
	return g->has_inverse;
}

int gwcs_pix_to_sky(const struct gwcs *g, double x, double y, double *ra, double *dec)
{
	double in[MAXD] = { x, y }, out[MAXD];

	if (eval(g->top, in, out) < 0 || !isfinite(out[0]) || !isfinite(out[1])) {
		*ra = *dec = NAN;
		return -1;
	}
	*ra = fmod(fmod(out[0], 360) + 360, 360);
	*dec = out[1];
	return 0;
}

/* Offsets east and north (degrees) of (ra, dec) from (ra0, dec0) in the
 * plane tangent there. */
static void offsets(double ra0, double dec0, double ra, double dec, double *e, double *n)
{
	double u[3], s[3], east[3] = { -sin(ra0 * D2R), cos(ra0 * D2R), 0 };
	double north[3] = { -sin(dec0 * D2R) * cos(ra0 * D2R), -sin(dec0 * D2R) * sin(ra0 * D2R),
			    cos(dec0 * D2R) };
	double w;

	cart(ra0, dec0, u);
	cart(ra, dec, s);
	w = s[0] * u[0] + s[1] * u[1] + s[2] * u[2];
	*e = (s[0] * east[0] + s[1] * east[1] + s[2] * east[2]) / w * R2D;
	*n = (s[0] * north[0] + s[1] * north[1] + s[2] * north[2]) / w * R2D;
}

int gwcs_sky_to_pix(const struct gwcs *g, double ra, double dec, double x0, double y0,
		    double *x, double *y)
{
	double in[MAXD] = { ra, dec }, out[MAXD];

	*x = *y = NAN;
	if (g->has_inverse) {
		if (eval_inv(g->top, in, out) < 0 || !isfinite(out[0]) || !isfinite(out[1]))
			return -1;
		*x = out[0];
		*y = out[1];
		return 0;
	}
	/* Newton on the forward transform, the Jacobian by central
	 * differences of half a pixel, in the plane tangent at the target */
	if (!isfinite(x0) || !isfinite(y0))
		x0 = y0 = 2043.5;
	for (int it = 0; it < 30; it++) {
		double r, d, e, n, j[4], det, dx, dy;

		if (gwcs_pix_to_sky(g, x0, y0, &r, &d) < 0)
			return -1;
		offsets(ra, dec, r, d, &e, &n);
		for (int k = 0; k < 2; k++) {
			double r1, d1, r2, d2, e1, n1, e2, n2;

			if (gwcs_pix_to_sky(g, x0 + (k == 0) * 0.5, y0 + (k == 1) * 0.5, &r1, &d1) < 0 ||
			    gwcs_pix_to_sky(g, x0 - (k == 0) * 0.5, y0 - (k == 1) * 0.5, &r2, &d2) < 0)
				return -1;
			offsets(ra, dec, r1, d1, &e1, &n1);
			offsets(ra, dec, r2, d2, &e2, &n2);
			j[k] = e1 - e2;
			j[2 + k] = n1 - n2;
		}
		det = j[0] * j[3] - j[1] * j[2];
		if (!(fabs(det) > 0))
			return -1;
		dx = -(j[3] * e - j[1] * n) / det;
		dy = -(-j[2] * e + j[0] * n) / det;
		x0 += dx;
		y0 += dy;
		if (!isfinite(x0) || !isfinite(y0) || fabs(x0) > 1e6 || fabs(y0) > 1e6)
			return -1;
		if (fabs(dx) < 1e-10 && fabs(dy) < 1e-10)
			break;
	}
	*x = x0;
	*y = y0;
	return 0;
}
