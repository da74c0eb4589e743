/* framelog.c - the FRAMES rows' sidecar of an acquiring run; see
 * framelog.h. */
#define _GNU_SOURCE
#include "framelog.h"

#include <errno.h>
#include <fcntl.h>
#include <glib.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAGIC "SLFRAME1"
#define BLOCK 2880
/* cubefile_frames_table's header is ~30 cards (one block); three blocks
 * leave room for cfitsio's own reserve. */
#define TABLE_HEADER_BYTES (3 * BLOCK)
#define TABLE_ROW_BYTES 44   /* K K K 16A J */

typedef struct header {
    char magic[8];
    uint64_t row_size, nrows, max_rows;
} header;

struct framelog {
    int fd;
    char *path;
    long n, max;
};

char *framelog_path(const char *cube_path)
{
    const char *sfx[] = {".fits.part", ".fits"};
    for (size_t i = 0; i < G_N_ELEMENTS(sfx); i++)
        if (g_str_has_suffix(cube_path, sfx[i])) {
            char *stem = g_strndup(cube_path, strlen(cube_path) - strlen(sfx[i]));
            char *p = g_strconcat(stem, ".frames", NULL);
            g_free(stem);
            return p;
        }
    return g_strconcat(cube_path, ".frames", NULL);
}

/* What the FITS table of n rows takes on disk, and at least the sidecar. */
static off_t room_for(long n)
{
    off_t data = (off_t)n * TABLE_ROW_BYTES;
    off_t table = TABLE_HEADER_BYTES + (data + BLOCK - 1) / BLOCK * BLOCK;
    off_t side = (off_t)sizeof(header) + (off_t)n * (off_t)sizeof(cubefile_row);
    return table > side ? table : side;
}

static int put(int fd, const void *buf, size_t n, off_t at)
{
    const char *p = buf;
    while (n > 0) {
        ssize_t w = pwrite(fd, p, n, at);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        p += w, n -= (size_t)w, at += w;
    }
    return 0;
}

int framelog_create(framelog **out, const char *path, long max_rows, sl_err *err)
{
    *out = NULL;
    off_t size = room_for(max_rows);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
    if (fd < 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    header h = {{0}, sizeof(cubefile_row), 0, (uint64_t)max_rows};
    memcpy(h.magic, MAGIC, sizeof h.magic);
    int e = posix_fallocate(fd, 0, size);
    if (e == 0 && put(fd, &h, sizeof h, 0) != 0)
        e = errno;
    if (e != 0) {
        close(fd);
        unlink(path);
        return sl_seterr(err, SL_EIO, "%s: no room for the FRAMES table of up to %ld frames "
                         "(%lld KiB): %s", path, max_rows, (long long)(size >> 10),
                         g_strerror(e));
    }
    framelog *f = g_new0(framelog, 1);
    f->fd = fd;
    f->path = g_strdup(path);
    f->max = max_rows;
    *out = f;
    return SL_OK;
}

int framelog_append(framelog *f, const cubefile_row *rows, long n, sl_err *err)
{
    if (n <= 0)
        return SL_OK;
    if (f->n + n > f->max)
        return sl_seterr(err, SL_ERANGE, "%s: %ld rows beyond the %ld it has room for",
                         f->path, f->n + n - f->max, f->max);
    off_t at = (off_t)sizeof(header) + (off_t)f->n * (off_t)sizeof(cubefile_row);
    uint64_t count = (uint64_t)(f->n + n);
    /* Rows first, then the count that covers them. */
    if (put(f->fd, rows, (size_t)n * sizeof(cubefile_row), at) != 0 ||
        put(f->fd, &count, sizeof count, offsetof(header, nrows)) != 0)
        return sl_seterr(err, SL_EIO, "%s: %s", f->path, g_strerror(errno));
    f->n += n;
    return SL_OK;
}

void framelog_close(framelog *f)
{
    if (!f)
        return;
    close(f->fd);
    g_free(f->path);
    g_free(f);
}

int framelog_read(const char *path, cubefile_row **rows, long *n, sl_err *err)
{
    header h;
    struct stat st;
    *rows = NULL;
    *n = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    int rc = SL_OK;
    if (fstat(fd, &st) != 0 || pread(fd, &h, sizeof h, 0) != (ssize_t)sizeof h) {
        rc = sl_seterr(err, SL_EIO, "%s: %s", path, errno ? g_strerror(errno) : "short header");
        goto close_fd;
    }
    off_t need = (off_t)sizeof h + (off_t)h.nrows * (off_t)sizeof(cubefile_row);
    if (memcmp(h.magic, MAGIC, sizeof h.magic) != 0 || h.row_size != sizeof(cubefile_row) ||
        h.nrows > h.max_rows || need > st.st_size) {
        rc = sl_seterr(err, SL_EFORMAT, "%s: not a FRAMES sidecar of this daemon (or cut "
                       "short)", path);
        goto close_fd;
    }
    cubefile_row *v = g_new(cubefile_row, h.nrows ? h.nrows : 1);
    size_t bytes = (size_t)h.nrows * sizeof *v;
    if (bytes && pread(fd, v, bytes, sizeof h) != (ssize_t)bytes) {
        g_free(v);
        rc = sl_seterr(err, SL_EIO, "%s: reading %llu rows: %s", path,
                       (unsigned long long)h.nrows, g_strerror(errno));
        goto close_fd;
    }
    *rows = v;
    *n = (long)h.nrows;
close_fd:
    close(fd);
    return rc;
}

int framelog_table(const char *cube, const char *log_path, cubefile_row *rows, long n,
                   int on_disk, const camera_stats *st, sl_err *err)
{
    for (long i = 0; i < n; i++)
        if (rows[i].cube_idx >= on_disk)
            rows[i].cube_idx = -1;
    int rc = cubefile_frames_table(cube, rows, n, st, err);
    /* Disk full: the sidecar's room was held for this table. */
    if (rc != SL_OK && log_path && unlink(log_path) == 0) {
        g_message("%s: no room for the FRAMES table; its sidecar's room used", cube);
        sl_clearerr(err);
        rc = cubefile_frames_table(cube, rows, n, st, err);
    }
    if (log_path && unlink(log_path) != 0 && errno != ENOENT)
        g_warning("%s: %s", log_path, g_strerror(errno));
    return rc;
}

int framelog_recover(const char *cube, int on_disk, sl_err *err)
{
    char *path = framelog_path(cube);
    cubefile_row *rows = NULL;
    long n = 0;
    int rc = SL_OK;
    if (access(path, F_OK) != 0)
        goto free_path;
    if (cubefile_has_table(cube)) {
        unlink(path);
        goto free_path;
    }
    rc = framelog_read(path, &rows, &n, err);
    if (rc == SL_OK)
        rc = framelog_table(cube, path, rows, n, on_disk, NULL, err);
    else
        unlink(path);
    g_free(rows);
free_path:
    g_free(path);
    return rc;
}
