/*
 * asdf_read.h - reading an ASDF file (asdf.h describes the layout): its
 * Standard's version, its tree (a libfyaml document), its blocks.
 */
#ifndef WFS_ASDF_READ_H
#define WFS_ASDF_READ_H

#include <stddef.h>
#include <stdint.h>

struct err;
struct fy_document;
struct fy_node;

struct asdf_block {
	uint64_t off;           /* the header's first byte */
	uint64_t data_off;      /* the data's */
	uint32_t flags;
	char comp[4];           /* "\0\0\0\0", "zlib", "lz4\0", ... */
	uint64_t allocated, used, data;
	unsigned char md5[16];  /* zeros: not computed */
};

struct asdf_in {
	char *path;
	int fd;
	uint64_t size;          /* of the file */
	int standard;           /* #ASDF_STANDARD x.y.z as x * 10000 + y * 100 + z */
	char *text;             /* the file's start, the tree within it */
	uint64_t tree_off, tree_end;    /* the tree's bytes, "%YAML" to "...\n" */
	struct fy_document *d;
	struct asdf_block *b;
	int nblock;
	uint64_t blocks_end;    /* where the blocks end (an index may follow) */
};

/*
 * Open path: the header lines, the tree parsed, every block's header
 * checked against the file (sizes that do not add up, a file that ends
 * early).  NULL with a message naming the file (exit 1 for a file that is
 * not a sound ASDF file, 2 for one that cannot be read).
 */
struct asdf_in *asdf_in_open(const char *path, struct err *e);

struct fy_node *asdf_in_root(const struct asdf_in *a);

/* Block k's data, n bytes (its data size), into out: inflated when zlib,
 * its MD5 checked when it has one.  0 or -1 with a message. */
int asdf_in_block(struct asdf_in *a, int k, void *out, size_t n, struct err *e);

void asdf_in_free(struct asdf_in *a);

#endif
