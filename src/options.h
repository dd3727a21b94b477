/*
 * options.h - command-line options written once: each command describes its
 * options in one table (name, short letter, argument, default, help, and the
 * function that stores the value), and both getopt_long parsing and --help
 * come from that table.
 *
 * Adding an option is one table entry and, when none fits, a field in the
 * command's struct:
 *
 *     { OPT("exptime", 0, "S", "1", "exposure time in seconds",
 *           opt_double, OFF(o.exptime)), .lo = 1e-9, .hi = 1e12 },
 *
 * A table is an array of struct opt ended by OPT_END; OPT_SECTION("Noise:")
 * entries start a group of options in --help.  Defaults are applied by the
 * option's own setter before argv is read, so a default is exactly what the
 * user would get by typing it, and --help shows it as "(default DEF)".
 */
#ifndef WFS_OPTIONS_H
#define WFS_OPTIONS_H

#include <stddef.h>
#include <stdio.h>

struct err;
struct opt;
struct opt_cmd;

/* What a setter is handed for one occurrence of an option. */
struct opt_arg {
	const struct opt_cmd *cmd;
	const struct opt *opt;
	const char *value;      /* the argument; NULL for an option taking none */
	const char *const *values; /* for an option of nargs words: the words */
	int nvalues;            /* found, up to nargs (fewer when argv ends or
	                           the next word is an option) */
	const char *given;      /* as spelt: "--name" or "-c" ("--name" for defaults) */
	void *field;            /* the command's struct plus opt->off */
	void *base;             /* the command's struct */
};

/* Stores a->value in a->field.  Returns 0, -1 with a message (naming the
 * option) and exit status in e, or OPT_EXIT when the command is done and
 * exits 0 (--help, --version). */
typedef int opt_set_fn(const struct opt_arg *a, struct err *e);

enum {
	OPT_EXIT = 1,
	/* flags */
	OPT_SHOW_DEFAULT = 1,   /* def is shown in --help but not applied
	                           (the program works it out, e.g. "all cores") */
};

struct opt {
	const char *name;       /* long name without "--"; NULL: a section title */
	int letter;             /* short option letter, or 0 */
	const char *arg;        /* argument name for --help; NULL: takes none */
	const char *def;        /* default value, or NULL */
	const char *help;       /* what it does, one line or more (wrapped) */
	opt_set_fn *set;
	size_t off;             /* offset of the field in the command's struct */
	double lo, hi;          /* range, for number setters */
	const char *const *words; /* NULL-ended choices, for opt_choice* */
	unsigned flags;         /* OPT_SHOW_DEFAULT */
	int nargs;              /* words taken when more than one ("--rgb R G B") */
};

/* The fields every option has, for a table entry: { OPT(...), .lo = ... }. */
#define OPT(n_, letter_, arg_, def_, help_, set_, off_) \
	.name = (n_), .letter = (letter_), .arg = (arg_), .def = (def_), \
	.help = (help_), .set = (set_), .off = (off_)
#define OPT_SECTION(title) { .help = (title) }
#define OPT_END { 0 }

/* One command: its name in messages, usage text before the options and
 * text after them in --help, and its table. */
struct opt_cmd {
	const char *prog;       /* "wfiscene", "wfiscene psf": message prefix */
	const char *usage;      /* printed first by --help, and after usage errors */
	const char *epilog;     /* printed after the options, or NULL */
	const struct opt *opts;
};

enum {
	OPT_PARSE_FAIL = -1,    /* a bad or missing value: the message is in e */
	OPT_PARSE_DONE = -2,    /* --help or --version was answered: exit 0 */
	OPT_PARSE_USAGE = -3,   /* an unknown option: message in e, then usage */
};

/* Apply the defaults of c's table to base, then parse argv (argv[0] is the
 * command) with getopt_long, calling each option's setter in the order
 * given.  Operands may come between options (getopt's permutation) and
 * after "--".  Returns the index of the first operand (argc when none) or
 * one of OPT_PARSE_FAIL, OPT_PARSE_DONE, OPT_PARSE_USAGE, the first and last
 * with the message and exit status (EXIT_INPUT) in e. */
int opt_parse(const struct opt_cmd *c, int argc, char **argv, void *base,
	      struct err *e);

/* Print "prog: message" for e on stderr and, when rc is OPT_PARSE_USAGE,
 * c's help after it (an unknown option).  Returns the exit status. */
int opt_fail(const struct opt_cmd *c, int rc, const struct err *e);

/* Print c's --help to f: usage, the options by section, the epilog. */
void opt_help(const struct opt_cmd *c, FILE *f);

/* The long name of an option as written in messages: "--name". */
const char *opt_name(const struct opt *o, char *buf, size_t n);

/*
 * Setters.  Messages name the option by its long name, as the scene command
 * always has ("--exptime: not a number: 'abc'").
 */
opt_set_fn opt_string;      /* const char *: the argument as given */
opt_set_fn opt_double;      /* double, finite, in [lo, hi] */
opt_set_fn opt_int;         /* int in [lo, hi] */
opt_set_fn opt_size;        /* size_t in [lo, hi] */
opt_set_fn opt_choice;      /* int: the index of the word (case-insensitive) */
opt_set_fn opt_choice_word; /* const char *: the table's spelling of the word */
opt_set_fn opt_store_lo;    /* int: lo, for an option without argument */
opt_set_fn opt_count;       /* int: +1 per occurrence (-v -v), 1 after -1 (-q) */
opt_set_fn opt_show_help;   /* print --help on stdout, done */

/* Parse helpers for setters of a command's own: the same checks and
 * messages as opt_double, opt_int and opt_choice, for an option named by
 * a->opt. */
int opt_parse_double(const struct opt_arg *a, double *out, struct err *e);

/* The value of the last "key=value" of settings (the --set list, NULL
 * ended; NULL itself for none) whose key is key, or NULL. */
const char *setting_last(const char *const *settings, const char *key);
/* Follow which entries of settings (at most SETTINGS_WATCH_MAX) any
 * setting_last() on it asks for, from now on: setting_was_read(i) says
 * whether entry i's key has been asked for. */
#define SETTINGS_WATCH_MAX 256
void setting_watch(const char *const *settings);
int setting_was_read(int i);
/* A key the run knows, kept for setting_nearest(): one a model of the run
 * declares (wfs_model.settings), or any setting_last() asks the watched
 * list for (once per thread and key); any thread. */
void setting_declare(const char *key);
/* The declared key nearest key (len bytes), for a warning's "did you
 * mean": one to two edits away (an insertion, deletion, change, or swap of
 * neighbours) and fewer than a third of its length, the first in strcmp
 * order of those nearest; NULL when none is. */
const char *setting_nearest(const char *key, size_t len);
int opt_parse_ll(const struct opt_arg *a, long long *out, struct err *e);
int opt_parse_choice(const struct opt_arg *a, struct err *e);

#endif
