/* fuzz_util.h - what every libFuzzer target here shares: the input as a
 * file, and contract checks that abort (a finding) when a module breaks
 * its promises.  Define FUZZ_NAME (the target's name, for messages) before
 * including it.  Header-only so that each target stays one link unit;
 * inline so that a target need not use every helper.
 */
#ifndef SL_FUZZ_UTIL_H
#define SL_FUZZ_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "status.h"

/* A memfd holding the bytes, path "/proc/self/fd/N"; -1 on failure. */
static inline int mem_file(const uint8_t *data, size_t size, char *path, size_t n)
{
    int fd = memfd_create(FUZZ_NAME, MFD_CLOEXEC);
    if (fd < 0)
        return -1;
    for (size_t off = 0; off < size;) {
        ssize_t w = write(fd, data + off, size - off);
        if (w <= 0) {
            close(fd);
            return -1;
        }
        off += (size_t)w;
    }
    snprintf(path, n, "/proc/self/fd/%d", fd);
    return fd;
}

static inline void require(int cond, const char *what, const char *msg)
{
    if (!cond) {
        fprintf(stderr, "%s: contract broken: %s (%s)\n", FUZZ_NAME, what,
                msg);
        abort();
    }
}

static inline void check_failure(int rc, const sl_err *e, const char *what)
{
    require(rc < 0 && rc >= SL_EEND, what, "status outside SL_E*");
    require(e->code == rc, what, "sl_err code differs from the status");
    require(memchr(e->msg, '\0', sizeof e->msg) && e->msg[0], what,
            "empty or unterminated message");
}

#endif
