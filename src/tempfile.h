/*
 * tempfile.h - the temporary file beside an output, and what a fatal signal
 * does with it.
 *
 * Every file wfiscene writes (FITS images, merged files, --placed and
 * --report, PNG previews, PSF grids and the PSF cache) is written under a
 * hidden name beside it, ".NAME.XXXXXX", and renamed over NAME when
 * complete, so a failed run never leaves a half-written file under the
 * requested name.
 *
 * One registry holds the temporaries that exist, and one signal policy,
 * set by main() before any subcommand runs (tempfile_signals), removes them
 * all on SIGINT, SIGTERM or SIGHUP and exits 4 (EXIT_SIGNAL), wherever the
 * program is: reading, drawing, writing or merging.  A temporary is
 * registered by tempfile_beside() as it is created and leaves the registry
 * through tempfile_commit() (renamed) or tempfile_discard() (removed).
 * Creating and registering is one step for the signal: the handler waits
 * for creations under way, and a thread that starts one after the signal
 * waits for the exit, so no thread leaves a file the handler did not see.
 */
#ifndef WFS_TEMPFILE_H
#define WFS_TEMPFILE_H

#include <stddef.h>
#include <string.h>

#include "err.h"

/* Bytes a temporary name for path needs, with its NUL. */
#define TEMPFILE_SIZE(path) (strlen(path) + 9)

/* The most temporaries that can exist at once (an exposure's images are
 * written one after another; --pointings allows 64 exposures, each with a
 * --placed file open through the run). */
#define TEMPFILE_MAX 256

/*
 * Create ".BASE.XXXXXX" in path's directory with O_EXCL and mode 0666 less
 * the umask, as any new file gets (mkstemp would make it 0600), put its
 * name in tmp (cap bytes) and register it.  Returns the descriptor, or -1
 * with tmp "" and "path: cannot create temporary file 'NAME': reason"
 * recorded (exit 2; a path ending in '/' is exit 1).
 */
int tempfile_beside(const char *path, char *tmp, size_t cap, struct err *e);

/*
 * Rename the temporary tmp over path and leave the registry (after the
 * rename: a signal in between removes a name that no longer exists, which
 * is harmless, where the other order could leave the temporary behind).
 * The file must be complete and closed.  On failure the temporary is
 * removed, "path: renaming 'tmp': reason" recorded (exit 2) and -1
 * returned.  tmp is "" afterwards either way.  On Linux, a regular file
 * of at least TEMPFILE_RELEASE_MIN bytes (allocated) on a local file
 * system, with no other link, that the rename replaces is freed on a
 * thread of its own (the process still waits for it at its exit), so
 * that the caller goes on while the file system gives back its blocks.
 */
#define TEMPFILE_RELEASE_MIN (1u << 20)
int tempfile_commit(char *tmp, const char *path, struct err *e);

/* Remove the temporary tmp and leave the registry; tmp becomes "".  A tmp
 * of "" (an output written in place) is left alone.  Keeps errno. */
void tempfile_discard(char *tmp);

/*
 * The signal policy of every subcommand: SIGINT, SIGTERM and SIGHUP remove
 * every registered temporary, print "PROG: interrupted; partial output
 * removed" and exit 4; SIGPIPE is ignored (a closed pipe is a write error,
 * EPIPE, that the writer reports).  prog is copied (up to 63 bytes).
 */
void tempfile_signals(const char *prog);

/* Remove every registered temporary.  Async-signal-safe (atomic loads and
 * unlink(2) only): for the handler above, and for a caller that is about to
 * _exit. */
void tempfile_remove_all(void);

/*
 * Open an output for writing.  A new name or an existing regular file gets
 * its temporary beside it (tempfile_beside; its name in tmp), to be renamed
 * over path when complete.  An existing device, FIFO or socket (/dev/stdout,
 * /dev/null, a named pipe, also through a symbolic link) is opened in place,
 * since renaming over it would replace the node itself; tmp is then "".  A
 * directory is refused (exit 1).  Returns the descriptor or -1.
 */
int tempfile_open_output(const char *path, char *tmp, size_t cap, struct err *e);

/*
 * An unnamed temporary file for the program's own use (a catalog read from
 * stdin kept for several passes over it, the --placed lists of SCA groups):
 * created in $TMPDIR (or /tmp) and unlinked at once, so nothing is left
 * behind however the program ends.  Returns a descriptor open for reading
 * and writing, or -1 with "what: cannot create a temporary file in DIR:
 * reason" recorded (exit 2).
 */
int tempfile_unnamed(const char *what, struct err *e);

/*
 * A scratch file that must keep its name for a while (a library opens it
 * by name): "$TMPDIR/STEM-XXXXXX" (or /tmp), its name in name (cap bytes),
 * registered as a temporary, so that a fatal signal removes it; the caller
 * removes it with tempfile_discard(name) as soon as the name is no longer
 * needed.  Returns a descriptor open for reading and writing, or -1 with
 * name "" and tempfile_unnamed()'s message recorded (exit 2).
 */
int tempfile_scratch(const char *what, const char *stem, char *name, size_t cap,
		     struct err *e);

/*
 * Copy the rest of stdin (as it comes: compressed bytes stay compressed)
 * to an unnamed temporary that then takes stdin's place (descriptor 0),
 * at its start, so that it can be read again after lseek(0, 0, SEEK_SET).
 * Returns the bytes copied, or -1 with the error recorded (exit 2).
 */
long long tempfile_spool_stdin(struct err *e);

/*
 * Ask the kernel to start writing back the pages of fd from the one that
 * holds byte lo up to, but not including, the one that holds byte hi
 * (the next write may still change that page, and on a file system that
 * keeps pages stable under writeback would wait for it): an output's
 * temporary, written in order, so that the fsync() that ends it waits for
 * its last pages only.  Linux's sync_file_range(SYNC_FILE_RANGE_WRITE):
 * advice, its failure ignored, nothing where it is absent.  Returns the
 * offset up to which writing back was asked (the start of hi's page), or
 * lo when nothing was.
 */
long long tempfile_writeback(int fd, long long lo, long long hi);

#endif
