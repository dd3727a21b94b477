/*
 * asdf.h - ASDF files (the Advanced Scientific Data Format, Standard
 * 1.6.0): a YAML tree, then binary blocks that the tree's arrays
 * (core/ndarray-1.1.0) name by index, then an optional block index.
 *
 *   #ASDF 1.0.0
 *   #ASDF_STANDARD 1.6.0
 *   %YAML 1.1
 *   %TAG ! tag:stsci.edu:asdf/
 *   --- !core/asdf-1.1.0
 *   ...tree...
 *   ...
 *   block 0: "\323BLK", header size (48), flags, compression, allocated,
 *            used and data sizes, MD5 of the data; the data
 *   block 1 ...
 *   #ASDF BLOCK INDEX
 *   %YAML 1.1
 *   --- [offset of block 0, ...]
 *   ...
 *
 * Every integer of a block header is big-endian.  The tree is libfyaml's
 * (Debian's libfyaml-dev): built here as a document, emitted in block
 * style; read back by asdf_read.c for --into.
 *
 * The writer knows every block's size before the first byte of data, so
 * it writes the tree and the block headers first and each block's data
 * at its offset, in any order (pwrite), like fitsout.c's groups; the file
 * is written beside its name and renamed when complete (tempfile.h).
 *
 * Compressed blocks (--set asdf-compression=zlib|lz4, as python3-asdf and
 * roman_datamodels write them): the header's compression field "zlib" or
 * "lz4\0", used_size (= allocated_size) the stored bytes, data_size the
 * array's.  A compressed block's size is known only once compressed, so
 * the writer stages the arrays' bytes uncompressed in the same temporary
 * file, beyond the farthest byte the compressed blocks can reach, and at
 * the end compresses them block after block into their places after the
 * tree and cuts the staging off (ftruncate).  The data are compressed in
 * chunks of 4 MiB on the engine's threads, each chunk on its own, so the
 * bytes do not depend on the thread count:
 *   lz4   asdf's framing (asdf/compression.py, Lz4Compressor): per chunk
 *         its compressed size (4 bytes, big-endian), then what python-lz4's
 *         lz4.block.compress writes: the chunk's size (4 bytes,
 *         little-endian) and the LZ4 block (LZ4_compress_default);
 *   zlib  one zlib stream (RFC 1950, what zlib.decompress reads) of raw
 *         deflate segments, one per chunk, each primed with the 32 KiB of
 *         data before it and ended by a sync flush (the last by the final
 *         block), their Adler-32s combined: how pigz compresses in
 *         parallel.  Level 6, zlib's default and python's.
 * The MD5 is left zero ("not computed", as the Standard allows) by the
 * writer; where one is written (--into, for an image that had them) it is
 * of the data before compression, the checksum python3-asdf checks.
 */
#ifndef WFS_ASDF_H
#define WFS_ASDF_H

#include <stddef.h>
#include <stdint.h>

struct err;
struct fy_document;
struct fy_node;

/* A tree being built: its document and whether a helper failed. */
struct asdf_tree {
	struct fy_document *d;
	int bad;
};

/* The datatypes of core/ndarray that wfiscene writes and reads. */
enum asdf_dtype { ASDF_U8, ASDF_U16, ASDF_U32, ASDF_F16, ASDF_F32, ASDF_F64 };

/* Bytes of one element, and the ndarray datatype name ("float32"). */
size_t asdf_dtype_size(int dtype);
const char *asdf_dtype_name(int dtype);

/* ---- the tree ---- */

/* A new document whose root mapping is tagged core/asdf-1.1.0, with
 * asdf_library naming wfiscene.  0 or -1 out of memory. */
int asdf_tree_new(struct asdf_tree *t);
void asdf_tree_free(struct asdf_tree *t);

/* Children of mapping map (the document's root when map is NULL): a
 * mapping (tag NULL or a full tag), a sequence, scalars.  Strings are
 * written double-quoted, so "1" stays a string; numbers with 17
 * significant digits.  A failure (out of memory) sets t->bad, and the
 * helpers given a NULL map do nothing, so the caller checks t->bad once. */
struct fy_node *asdf_map(struct asdf_tree *t, struct fy_node *map, const char *key,
			 const char *tag);
struct fy_node *asdf_seq(struct asdf_tree *t, struct fy_node *map, const char *key);
void asdf_str(struct asdf_tree *t, struct fy_node *map, const char *key, const char *v);
void asdf_num(struct asdf_tree *t, struct fy_node *map, const char *key, double v);
void asdf_int(struct asdf_tree *t, struct fy_node *map, const char *key, long long v);
void asdf_bool(struct asdf_tree *t, struct fy_node *map, const char *key, int v);
void asdf_null(struct asdf_tree *t, struct fy_node *map, const char *key);
/* The root mapping. */
struct fy_node *asdf_root(struct asdf_tree *t);
/* Append a new sequence to sequence seq. */
struct fy_node *asdf_seq_seq(struct asdf_tree *t, struct fy_node *seq);
/* Append node v (made with map NULL and key NULL, or asdf_node_yaml) to
 * sequence seq. */
void asdf_seq_add(struct asdf_tree *t, struct fy_node *seq, struct fy_node *v);
/* Put detached node v under key of map. */
void asdf_put(struct asdf_tree *t, struct fy_node *map, const char *key, struct fy_node *v);
/* A detached node of YAML text. */
struct fy_node *asdf_node_yaml(struct asdf_tree *t, const char *yaml);
/* Append a number to a sequence. */
void asdf_seq_num(struct asdf_tree *t, struct fy_node *seq, double v);
void asdf_seq_int(struct asdf_tree *t, struct fy_node *seq, long long v);
/* A node of YAML text (a flow sequence, a tagged scalar), under key. */
void asdf_yaml(struct asdf_tree *t, struct fy_node *map, const char *key, const char *yaml);
/* An ndarray under key, its data in block `block`: datatype, the
 * machine's byte order, shape[0 .. ndim). */
void asdf_ndarray(struct asdf_tree *t, struct fy_node *map, const char *key, int block,
		  int dtype, int ndim, const long *shape);
/* A detached inline ndarray of n doubles, shape rows x cols (rows 0: a
 * vector of cols). */
struct fy_node *asdf_inline(struct asdf_tree *t, const double *v, int rows, int cols);
/* A time (time-1.2.0) of an MJD in UTC, as an ISO string. */
void asdf_time(struct asdf_tree *t, struct fy_node *map, const char *key, double mjd);

/* ---- compressed blocks ---- */

struct pool;

/* How blocks are stored: ASDF_KEEP (no setting: --into keeps each block's
 * own, a new file writes none), uncompressed, zlib, lz4. */
enum asdf_compression { ASDF_KEEP = -1, ASDF_NONE, ASDF_ZLIB, ASDF_LZ4 };

/* The setting asdf-compression among settings ("key=value", NULL-ended or
 * NULL; the last one given wins) into *c: none, zlib or lz4, ASDF_KEEP
 * where absent.  0, or -1 (exit 1) naming the key and the value. */
int asdf_compression_setting(const char *const *settings, int *c, struct err *e);

/* The 4-byte compression field of a block header for c (NONE: zeros). */
const char *asdf_compression_field(int c);

/* n bytes of p written at offset off of fd, whatever pwrite() takes at a
 * time; 0, or -1 with e naming path. */
int asdf_fd_write(int fd, const void *p, size_t n, uint64_t off, const char *path,
		  struct err *e);

/* Fill buf with n bytes of a block's data from byte off of the data. */
typedef int asdf_get_fn(void *arg, uint64_t off, void *buf, size_t n, struct err *e);

/* One block to write: its data (n bytes, read through get in order), the
 * element size (lz4's chunks are whole elements, as asdf's), how stored,
 * and whether to compute its MD5. */
struct asdf_block_src {
	int compression;        /* ASDF_NONE, ASDF_ZLIB or ASDF_LZ4 */
	uint64_t n;
	size_t itemsize;
	int md5;
	asdf_get_fn *get;
	void *arg;
};

/* The most bytes block src can take in a file, header included. */
uint64_t asdf_block_bound(const struct asdf_block_src *src);

/* Write block src (header and data) to fd at offset at, compressing on
 * pool's threads (NULL: this thread); *end the offset after it.  0 or -1
 * with a message naming path. */
int asdf_block_write(int fd, uint64_t at, const struct asdf_block_src *src, struct pool *pool,
		     const char *path, uint64_t *end, struct err *e);

/* ---- writing a file ---- */

struct asdf_out;

/* Open path for writing: the file is made beside it (tempfile.h), its
 * blocks stored as compression says (ASDF_NONE, ZLIB or LZ4), compressed
 * on pool's threads (may be NULL).  NULL with a message; "-" (stdout) is
 * refused, an ASDF file being written at offsets. */
struct asdf_out *asdf_out_open(const char *path, int compression, struct pool *pool,
			       struct err *e);

/* Whether path may take an ASDF file: absent or a regular file (a file
 * made beside it is renamed over it, which would replace a device or a
 * named pipe).  0, or -1 with a message (exit 1). */
int asdf_out_target(const char *path, struct err *e);

/* Write tree t and the headers of nblock blocks of bytes[k] bytes each
 * (elements of itemsize[k] bytes), and reserve their data.  0 or -1 with a
 * message. */
int asdf_out_begin(struct asdf_out *a, struct asdf_tree *t, int nblock,
		   const uint64_t *bytes, const size_t *itemsize, struct err *e);

/* n bytes of block k's data from byte off of that block. */
int asdf_out_put(struct asdf_out *a, int k, uint64_t off, const void *p, size_t n,
		 struct err *e);

/* The blocks compressed into their places (when compressed), the block
 * index, then fsync, close and rename over the name.  Frees a either way. */
int asdf_out_commit(struct asdf_out *a, struct err *e);

/* Remove the temporary and free a.  NULL is a no-op. */
void asdf_out_abort(struct asdf_out *a);

/* float to IEEE half (round to nearest even; a finite float beyond 65504
 * saturates to +-65504, infinity and NaN stay so). */
uint16_t asdf_half(float f);
float asdf_half_to_float(uint16_t h);

#endif
