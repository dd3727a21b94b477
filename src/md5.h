/*
 * md5.h - the MD5 digest (RFC 1321), which ASDF blocks carry as their
 * checksum.  Not for security: only to find a block whose data changed.
 */
#ifndef WFS_MD5_H
#define WFS_MD5_H

#include <stddef.h>

void md5(const void *data, size_t n, unsigned char out[16]);

#endif
