/*
 * tempfile.h - the temporary file beside an output.
 *
 * Every output wfiscene writes (FITS images, merged files, --placed and
 * --report) is written under a hidden name beside it, ".NAME.XXXXXX", and
 * renamed over NAME when complete, so a failed run never leaves a
 * half-written file under the requested name.
 */
#ifndef WFS_TEMPFILE_H
#define WFS_TEMPFILE_H

#include <stddef.h>
#include <string.h>

#include "err.h"

/* Bytes a temporary name for path needs, with its NUL. */
#define TEMPFILE_SIZE(path) (strlen(path) + 9)

/*
 * Create ".BASE.XXXXXX" in path's directory with O_EXCL and mode 0666 less
 * the umask, as any new file gets (mkstemp would make it 0600), and put its
 * name in tmp (cap bytes).  Returns the descriptor, or -1 with tmp "" and
 * "path: cannot create temporary file 'NAME': reason" recorded (exit 2; a
 * path ending in '/' is exit 1).
 */
int tempfile_beside(const char *path, char *tmp, size_t cap, struct err *e);

/*
 * Open an output for writing.  A new name or an existing regular file gets
 * its temporary beside it (tempfile_beside; its name in tmp), to be renamed
 * over path when complete.  An existing device, FIFO or socket (/dev/stdout,
 * /dev/null, a named pipe, also through a symbolic link) is opened in place,
 * since renaming over it would replace the node itself; tmp is then "".  A
 * directory is refused (exit 1).  Returns the descriptor or -1.
 */
int tempfile_open_output(const char *path, char *tmp, size_t cap, struct err *e);

#endif
