/*
 * options.c - command-line parsing and --help from a command's option table
 * (see options.h): the table becomes getopt_long's option array and short
 * option string, each option found is handed to its setter, and --help is
 * laid out from the same entries.
 */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "err.h"
#include "options.h"

#define OPT_MAX 128             /* options in one table */
#define OPT_LONG_VAL 256        /* getopt_long value of entry i: 256 + i */
#define OPT_MAX_WORDS 8          /* words of one option (struct opt nargs) */
#define HELP_COLUMN 24          /* where help text starts in --help */
#define HELP_WIDTH 79

const char *opt_name(const struct opt *o, char *buf, size_t n)
{
	snprintf(buf, n, "--%s", o->name);
	return buf;
}

int opt_parse_double(const struct opt_arg *a, double *out, struct err *e)
{
	const char *s = a->value;
	char *end;
	double v;

	v = strtod(s, &end);
	if (end == s || *end || isnan(v))
		return err_set(e, EXIT_INPUT, "--%s: not a number: '%s'", a->opt->name, s);
	/* past the largest double is out of range; below the smallest (a
	 * value strtod() rounds to a subnormal or 0 with ERANGE) is read as
	 * that, as the catalog's numbers are */
	if (isinf(v) || v < a->opt->lo || v > a->opt->hi)
		return err_set(e, EXIT_INPUT, "--%s: %s is out of range [%g, %g]",
			       a->opt->name, s, a->opt->lo, a->opt->hi);
	*out = v;
	return 0;
}

int opt_parse_ll(const struct opt_arg *a, long long *out, struct err *e)
{
	const char *s = a->value;
	long long v, lo = (long long)a->opt->lo, hi = (long long)a->opt->hi;
	char *end;

	errno = 0;
	v = strtoll(s, &end, 10);
	if (end == s || *end || errno == ERANGE)
		return err_set(e, EXIT_INPUT, "--%s: not an integer: '%s'", a->opt->name, s);
	if (v < lo || v > hi)
		return err_set(e, EXIT_INPUT, "--%s: %s is out of range [%lld, %lld]",
			       a->opt->name, s, lo, hi);
	*out = v;
	return 0;
}

/* The index of a->value among the table's words, case-insensitive. */
int opt_parse_choice(const struct opt_arg *a, struct err *e)
{
	const char *const *w = a->opt->words;
	char list[256] = "";

	for (int i = 0; w[i]; i++)
		if (!strcasecmp(a->value, w[i]))
			return i;
	for (int i = 0; w[i]; i++)
		snprintf(list + strlen(list), sizeof(list) - strlen(list), "%s%s",
			 i ? ", " : "", w[i]);
	return err_set(e, EXIT_INPUT, "--%s: '%s' is not one of %s", a->opt->name,
		       a->value, list);
}

int opt_string(const struct opt_arg *a, struct err *e)
{
	*(const char **)a->field = a->value;
	return 0;
}

int opt_double(const struct opt_arg *a, struct err *e)
{
	return opt_parse_double(a, (double *)a->field, e);
}

int opt_int(const struct opt_arg *a, struct err *e)
{
	long long v;

	if (opt_parse_ll(a, &v, e) < 0)
		return -1;
	*(int *)a->field = (int)v;
	return 0;
}

int opt_size(const struct opt_arg *a, struct err *e)
{
	long long v;

	if (opt_parse_ll(a, &v, e) < 0)
		return -1;
	*(size_t *)a->field = (size_t)v;
	return 0;
}

int opt_choice(const struct opt_arg *a, struct err *e)
{
	int k = opt_parse_choice(a, e);

	if (k < 0)
		return -1;
	*(int *)a->field = k;
	return 0;
}

int opt_choice_word(const struct opt_arg *a, struct err *e)
{
	int k = opt_parse_choice(a, e);

	if (k < 0)
		return -1;
	*(const char **)a->field = a->opt->words[k];
	return 0;
}

int opt_store_lo(const struct opt_arg *a, struct err *e)
{
	*(int *)a->field = (int)a->opt->lo;
	return 0;
}

int opt_count(const struct opt_arg *a, struct err *e)
{
	int *v = a->field;

	*v = *v < 0 ? 1 : *v + 1;
	return 0;
}

int opt_show_help(const struct opt_arg *a, struct err *e)
{
	opt_help(a->cmd, stdout);
	return OPT_EXIT;
}

/* Help text: words of s wrapped to HELP_WIDTH, every line but the first
 * indented to HELP_COLUMN; col is where the first line starts. */
static void help_wrap(FILE *f, const char *s, int col)
{
	while (*s) {
		size_t len = strcspn(s, " \n");

		if (col > HELP_COLUMN && col + 1 + (int)len > HELP_WIDTH) {
			fprintf(f, "\n%*s", HELP_COLUMN, "");
			col = HELP_COLUMN;
		} else if (col > HELP_COLUMN) {
			fputc(' ', f);
			col++;
		}
		fwrite(s, 1, len, f);
		col += (int)len;
		s += len;
		if (*s == '\n') {
			fprintf(f, "\n%*s", HELP_COLUMN, "");
			col = HELP_COLUMN;
		}
		while (*s == ' ' || *s == '\n')
			s++;
	}
	fputc('\n', f);
}

void opt_help(const struct opt_cmd *c, FILE *f)
{
	fputs(c->usage, f);
	for (const struct opt *o = c->opts; o->name || o->help; o++) {
		char head[128], text[1024];
		int n;

		if (!o->name) {
			fprintf(f, "%s\n", o->help);
			continue;
		}
		if (o->letter)
			n = snprintf(head, sizeof(head), "  -%c, --%s", o->letter, o->name);
		else
			n = snprintf(head, sizeof(head), "      --%s", o->name);
		if (o->arg)
			n += snprintf(head + n, sizeof(head) - (size_t)n, " %s", o->arg);
		snprintf(text, sizeof(text), "%s%s%s%s", o->help, o->def ? " (default " : "",
			 o->def ? o->def : "", o->def ? ")" : "");
		if (n + 2 > HELP_COLUMN)
			fprintf(f, "%s\n%*s", head, HELP_COLUMN, "");
		else
			fprintf(f, "%-*s", HELP_COLUMN, head);
		help_wrap(f, text, HELP_COLUMN);
	}
	if (c->epilog)
		fputs(c->epilog, f);
}

int opt_fail(const struct opt_cmd *c, int rc, const struct err *e)
{
	fprintf(stderr, "%s: %s\n", c->prog, e->msg);
	if (rc == OPT_PARSE_USAGE)
		opt_help(c, stderr);
	return e->code ? e->code : EXIT_SYSTEM;
}

static int call(const struct opt_cmd *c, const struct opt *o, const char *value,
		const char *given, void *base, struct err *e)
{
	struct opt_arg a = {
		.cmd = c, .opt = o, .value = value, .values = &value, .nvalues = !!value,
		.given = given, .field = (char *)base + o->off, .base = base,
	};

	return o->set(&a, e);
}

static int is_option(const char *w)
{
	return w[0] == '-' && w[1];
}

/* An option of several words: optarg and those after it, up to o->nargs,
 * while they are not options; getopt goes on after the last one taken. */
static int call_words(const struct opt_cmd *c, const struct opt *o, int argc,
		      char **argv, const char *given, void *base, struct err *e)
{
	const char *words[OPT_MAX_WORDS];
	struct opt_arg a = {
		.cmd = c, .opt = o, .value = optarg, .values = words, .given = given,
		.field = (char *)base + o->off, .base = base,
	};

	if (!is_option(optarg)) {
		words[a.nvalues++] = optarg;
		while (a.nvalues < o->nargs && a.nvalues < OPT_MAX_WORDS && optind < argc &&
		       !is_option(argv[optind]))
			words[a.nvalues++] = argv[optind++];
	}
	return o->set(&a, e);
}

/* An unknown option, an ambiguous abbreviation, or a value where none is
 * taken; arg is the word of argv getopt stopped at. */
static int unknown(const struct opt_cmd *c, const char *arg, int letter, struct err *e)
{
	char list[256] = "";
	size_t len;
	int n = 0;

	if (letter && arg[0] == '-' && arg[1] != '-')
		return err_set(e, EXIT_INPUT, "unknown option '-%c'", letter);
	if (strncmp(arg, "--", 2))
		return err_set(e, EXIT_INPUT, "unknown option '%s'", arg);
	len = strcspn(arg + 2, "=");
	for (const struct opt *o = c->opts; o->name || o->help; o++) {
		if (!o->name || strncmp(o->name, arg + 2, len))
			continue;
		if (strlen(o->name) == len && arg[2 + len] == '=' && !o->arg)
			return err_set(e, EXIT_INPUT, "--%s takes no value: '%s'", o->name, arg);
		snprintf(list + strlen(list), sizeof(list) - strlen(list), "%s--%s",
			 n++ ? ", " : "", o->name);
	}
	if (n > 1)
		return err_set(e, EXIT_INPUT, "ambiguous option '%.*s': %s", (int)len + 2,
			       arg, list);
	return err_set(e, EXIT_INPUT, "unknown option '%s'", arg);
}

static const struct opt *by_value(const struct opt_cmd *c, int v)
{
	if (v >= OPT_LONG_VAL)
		return &c->opts[v - OPT_LONG_VAL];
	for (const struct opt *o = c->opts; o->name || o->help; o++)
		if (o->name && o->letter == v)
			return o;
	return NULL;
}

static int apply_defaults(const struct opt_cmd *c, void *base, struct err *e)
{
	for (const struct opt *o = c->opts; o->name || o->help; o++) {
		char given[64];

		if (!o->name || !o->def || (o->flags & OPT_SHOW_DEFAULT))
			continue;
		if (call(c, o, o->def, opt_name(o, given, sizeof(given)), base, e) < 0) {
			err_prefix(e, "default");
			return -1;
		}
	}
	return 0;
}

int opt_parse(const struct opt_cmd *c, int argc, char **argv, void *base, struct err *e)
{
	struct option longs[OPT_MAX + 1];
	char shorts[2 * OPT_MAX + 2] = ":", given[80];
	size_t nl = 0, ns = 1;
	int ch, li;

	for (const struct opt *o = c->opts; o->name || o->help; o++) {
		if (!o->name)
			continue;
		if (nl == OPT_MAX)
			return err_set(e, EXIT_SYSTEM, "%s: more than %d options", c->prog,
				       OPT_MAX);
		longs[nl++] = (struct option){
			o->name, o->arg ? required_argument : no_argument, NULL,
			o->letter ? o->letter : OPT_LONG_VAL + (int)(o - c->opts),
		};
		if (o->letter) {
			shorts[ns++] = (char)o->letter;
			if (o->arg)
				shorts[ns++] = ':';
		}
	}
	longs[nl] = (struct option){ 0 };
	shorts[ns] = 0;
	if (apply_defaults(c, base, e) < 0)
		return OPT_PARSE_FAIL;

	optind = 0;             /* glibc: start afresh (another command may have run) */
	opterr = 0;             /* our messages name the command and the option */
	while (li = -1, (ch = getopt_long(argc, argv, shorts, longs, &li)) != -1) {
		const char *word = argv[optind - 1];
		const struct opt *o;
		int rc;

		if (ch == '?') {
			unknown(c, word, optopt, e);
			return OPT_PARSE_USAGE;
		}
		if (ch == ':') {
			o = by_value(c, optopt);
			if (o && !strncmp(word, "--", 2))
				err_set(e, EXIT_INPUT, "--%s needs a value", o->name);
			else
				err_set(e, EXIT_INPUT, "-%c needs a value", optopt);
			return OPT_PARSE_FAIL;
		}
		if (!(o = by_value(c, ch)))
			return err_set(e, EXIT_SYSTEM, "%s: option %d not in the table",
				       c->prog, ch);
		if (li >= 0 || !o->letter)
			opt_name(o, given, sizeof(given));
		else
			snprintf(given, sizeof(given), "-%c", o->letter);
		if (o->nargs > 1)
			rc = call_words(c, o, argc, argv, given, base, e);
		else
			rc = call(c, o, o->arg ? optarg : NULL, given, base, e);
		if (rc < 0)
			return OPT_PARSE_FAIL;
		if (rc == OPT_EXIT)
			return OPT_PARSE_DONE;
	}
	return optind;
}

/* The list setting_watch() follows, and which of its entries a
 * setting_last() has asked for (any thread: the host and the models read
 * settings from several). */
static const char *const *watched;
static atomic_uchar watched_read[SETTINGS_WATCH_MAX];

void setting_watch(const char *const *settings)
{
	watched = settings;
	for (int i = 0; i < SETTINGS_WATCH_MAX; i++)
		atomic_store_explicit(&watched_read[i], 0, memory_order_relaxed);
}

int setting_was_read(int i)
{
	return i >= 0 && i < SETTINGS_WATCH_MAX &&
	       atomic_load_explicit(&watched_read[i], memory_order_relaxed);
}

const char *setting_last(const char *const *settings, const char *key)
{
	const char *hit = NULL;
	size_t n = strlen(key);

	/* a key the run asks for is a real one, for a misspelt one's warning:
	 * declared once per thread and key, by the key's address (a model
	 * may ask in prepare(), row after row, on several threads; a key
	 * whose address changes is only declared again) */
	if (settings && settings == watched) {
		static _Thread_local const char *seen[32];
		static _Thread_local unsigned nseen;
		unsigned k = 0;

		while (k < nseen && k < 32 && seen[k] != key)
			k++;
		if (k == nseen || k == 32) {
			setting_declare(key);
			seen[nseen++ % 32] = key;
		}
	}
	for (const char *const *kv = settings; kv && *kv; kv++)
		if (!strncmp(*kv, key, n) && (*kv)[n] == '=') {
			hit = *kv + n + 1;
			if (settings == watched && kv - settings < SETTINGS_WATCH_MAX)
				atomic_store_explicit(&watched_read[kv - settings], 1,
						      memory_order_relaxed);
		}
	return hit;
}

/* The keys the run knows (setting_declare), for setting_nearest(). */
static pthread_mutex_t declared_mu = PTHREAD_MUTEX_INITIALIZER;
static char **declared;
static int ndeclared, capdeclared;

void setting_declare(const char *key)
{
	pthread_mutex_lock(&declared_mu);
	for (int i = 0; i < ndeclared; i++)
		if (!strcmp(declared[i], key))
			goto out;
	if (ndeclared == capdeclared) {
		int cap = capdeclared ? 2 * capdeclared : 32;
		char **d = realloc(declared, (size_t)cap * sizeof(*d));

		if (!d)
			goto out;       /* only a suggestion is lost */
		declared = d;
		capdeclared = cap;
	}
	if ((declared[ndeclared] = strdup(key)))
		ndeclared++;
out:
	pthread_mutex_unlock(&declared_mu);
}

/* The optimal string alignment distance of a (n bytes) and b (keys are
 * short: longer ones count as far). */
#define NEAREST_MAX 64

static int edit_distance(const char *a, size_t n, const char *b)
{
	size_t m = strlen(b);
	int d[NEAREST_MAX + 1][NEAREST_MAX + 1];

	if (n > NEAREST_MAX || m > NEAREST_MAX)
		return NEAREST_MAX + 1;
	for (size_t i = 0; i <= n; i++)
		d[i][0] = (int)i;
	for (size_t j = 0; j <= m; j++)
		d[0][j] = (int)j;
	for (size_t i = 1; i <= n; i++)
		for (size_t j = 1; j <= m; j++) {
			int c = d[i - 1][j - 1] + (a[i - 1] != b[j - 1]);

			c = d[i - 1][j] + 1 < c ? d[i - 1][j] + 1 : c;
			c = d[i][j - 1] + 1 < c ? d[i][j - 1] + 1 : c;
			if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] &&
			    d[i - 2][j - 2] + 1 < c)
				c = d[i - 2][j - 2] + 1;
			d[i][j] = c;
		}
	return d[n][m];
}

const char *setting_nearest(const char *key, size_t len)
{
	const char *best = NULL;
	int bd = 3;

	pthread_mutex_lock(&declared_mu);
	/* not the key itself (a model may declare a key it did not read in
	 * this run); of equal distances the first in strcmp order, so that
	 * the order the keys were met in does not matter */
	for (int i = 0; i < ndeclared; i++) {
		int dist = edit_distance(key, len, declared[i]);

		if (dist > 0 && 3 * (size_t)dist < len &&
		    (dist < bd || (dist == bd && strcmp(declared[i], best) < 0))) {
			bd = dist;
			best = declared[i];
		}
	}
	pthread_mutex_unlock(&declared_mu);
	return best;
}
