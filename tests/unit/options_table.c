/* options_table.c - a command's option table: defaults, parsing in the order
 * given, values checked with messages naming the option, unknown and
 * ambiguous options, options of several words, and --help listing every
 * option with its default. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "err.h"
#include "options.h"
#include "tap.h"

struct demo {
	const char *out;
	double level;
	int count, mode, verbose;
	size_t chunk;
	const char *word;
	const char *files[3];
	int nfiles;
};

#define OFF(f) offsetof(struct demo, f)

static const char *const modes[] = { "fast", "exact", NULL };

static int set_files(const struct opt_arg *a, struct err *e)
{
	struct demo *d = a->base;

	if (a->nvalues < 3)
		return err_set(e, EXIT_INPUT, "--files needs three");
	for (int k = 0; k < 3; k++)
		d->files[k] = a->values[k];
	d->nfiles = 3;
	return 0;
}

static const struct opt demo_options[] = {
	OPT_SECTION("Demo:"),
	{ OPT("output", 'o', "FILE", NULL, "where to write", opt_string, OFF(out)) },
	{ OPT("level", 0, "L", "2.5", "a level", opt_double, OFF(level)), .lo = 0, .hi = 10 },
	{ OPT("count", 'n', "N", "7", "a count", opt_int, OFF(count)), .lo = 1, .hi = 100 },
	{ OPT("chunk", 0, "N", "all rows", "rows per chunk", opt_size, OFF(chunk)),
	  .lo = 1, .hi = 1000, .flags = OPT_SHOW_DEFAULT },
	{ OPT("mode", 0, "M", "fast", "fast or exact", opt_choice, OFF(mode)), .words = modes },
	{ OPT("model", 0, "M", NULL, "a word", opt_choice_word, OFF(word)), .words = modes },
	{ OPT("files", 0, "A B C", NULL, "three files", set_files, 0), .nargs = 3 },
	{ OPT("quiet", 'q', NULL, NULL, "quiet", opt_store_lo, OFF(verbose)), .lo = -1 },
	{ OPT("verbose", 'v', NULL, NULL, "louder", opt_count, OFF(verbose)) },
	{ OPT("help", 'h', NULL, NULL, "this text", opt_show_help, 0) },
	OPT_END
};

static const struct opt_cmd demo_cmd = {
	.prog = "demo", .usage = "usage: demo [options] FILE\n\n", .epilog = "The end.\n",
	.opts = demo_options,
};

/* Parse the words of line (space-separated) into d; returns opt_parse's
 * result, and the first operand in *operand. */
static int parse(const char *line, struct demo *d, struct err *e, const char **operand)
{
	static char buf[512];
	char *argv[32];
	int argc = 0, rc;

	snprintf(buf, sizeof(buf), "demo %s", line);
	for (char *w = strtok(buf, " "); w && argc < 31; w = strtok(NULL, " "))
		argv[argc++] = w;
	argv[argc] = NULL;
	memset(d, 0, sizeof(*d));
	err_clear(e);
	rc = opt_parse(&demo_cmd, argc, argv, d, e);
	*operand = rc >= 0 && rc < argc ? argv[rc] : NULL;
	return rc;
}

int main(void)
{
	struct demo d;
	struct err e = { 0 };
	const char *op;
	char *help = NULL;
	size_t n = 0;
	FILE *f;
	int rc;

	rc = parse("in.txt", &d, &e, &op);
	ok(rc == 1 && op && !strcmp(op, "in.txt"), "an operand alone");
	ok(d.level == 2.5 && d.count == 7 && d.mode == 0 && d.chunk == 0 && !d.out,
	   "defaults are applied through the setters, shown-only ones are not");

	rc = parse("-v in.txt --level 4 -n 9 --mode EXACT -o x --model exact -v", &d, &e, &op);
	ok(rc >= 0 && op && !strcmp(op, "in.txt"), "operands between options");
	ok(d.level == 4 && d.count == 9 && d.mode == 1 && !strcmp(d.out, "x") &&
	   !strcmp(d.word, "exact") && d.verbose == 2, "every value stored");

	rc = parse("-q -v", &d, &e, &op);
	ok(rc >= 0 && d.verbose == 1, "-v after -q is verbose");
	rc = parse("-v -q", &d, &e, &op);
	ok(rc >= 0 && d.verbose == -1, "-q after -v is quiet");

	rc = parse("--level=11", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && e.code == EXIT_INPUT &&
	   !strcmp(e.msg, "--level: 11 is out of range [0, 10]"), "range: %s", e.msg);
	rc = parse("--level abc", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "--level: not a number: 'abc'"), "%s", e.msg);
	rc = parse("-n 1.5", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "--count: not an integer: '1.5'"),
	   "a short option is named by its long name: %s", e.msg);
	rc = parse("--mode slow", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "--mode: 'slow' is not one of fast, exact"),
	   "%s", e.msg);
	rc = parse("--level", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "--level needs a value"), "%s", e.msg);
	rc = parse("-o", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "-o needs a value"), "%s", e.msg);
	rc = parse("--bogus", &d, &e, &op);
	ok(rc == OPT_PARSE_USAGE && !strcmp(e.msg, "unknown option '--bogus'"), "%s", e.msg);
	rc = parse("-x", &d, &e, &op);
	ok(rc == OPT_PARSE_USAGE && !strcmp(e.msg, "unknown option '-x'"), "%s", e.msg);
	rc = parse("--mo fast", &d, &e, &op);
	ok(rc == OPT_PARSE_USAGE && !strcmp(e.msg, "ambiguous option '--mo': --mode, --model"),
	   "%s", e.msg);
	rc = parse("--quiet=1", &d, &e, &op);
	ok(rc == OPT_PARSE_USAGE && strstr(e.msg, "--quiet takes no value"), "%s", e.msg);
	rc = parse("--lev 3", &d, &e, &op);
	ok(rc >= 0 && d.level == 3, "a unique abbreviation");

	rc = parse("--files a b c in.txt", &d, &e, &op);
	ok(rc >= 0 && d.nfiles == 3 && !strcmp(d.files[2], "c") && op && !strcmp(op, "in.txt"),
	   "an option of three words");
	rc = parse("--files a b -v", &d, &e, &op);
	ok(rc == OPT_PARSE_FAIL && !strcmp(e.msg, "--files needs three"),
	   "it stops at an option");
	rc = parse("-- -v", &d, &e, &op);
	ok(rc >= 0 && op && !strcmp(op, "-v") && d.verbose == 0, "-- ends the options");

	f = open_memstream(&help, &n);
	opt_help(&demo_cmd, f);
	fclose(f);
	ok(!strncmp(help, "usage: demo", 11) && strstr(help, "The end.\n"),
	   "help: usage first, epilog last");
	for (const struct opt *o = demo_options; o->name || o->help; o++) {
		char name[64];

		if (o->name)
			ok(strstr(help, opt_name(o, name, sizeof(name))) != NULL,
			   "help lists %s", name);
	}
	ok(strstr(help, "(default 2.5)") && strstr(help, "(default all rows)"),
	   "help shows defaults");
	ok(strstr(help, "  -n, --count N") && strstr(help, "      --level L"),
	   "short and long names in one column");
	free(help);
	return done_testing();
}
