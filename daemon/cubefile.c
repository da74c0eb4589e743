/* cubefile.c - salvage, FRAMES table, checksum, fsync; see cubefile.h. */
#define _GNU_SOURCE
#include "cubefile.h"

#include <errno.h>
#include <fcntl.h>
#include <fitsio.h>
#include <glib.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define BLOCK 2880
#define CARD 80
#define MAX_HEADER_BLOCKS 64   /* 2304 cards: far beyond any cube header */

typedef struct header {
    long bitpix, naxis, n1, n2, n3;
    off_t n3_card;    /* offset of the NAXIS3 card */
    off_t datastart;
    int simple;
} header;

/* The integer value of a fixed-format card ("KEY     = value / c"). */
static int card_int(const char *card, const char *key, long *out)
{
    char k[9];
    snprintf(k, sizeof k, "%-8s", key);
    if (memcmp(card, k, 8) != 0 || memcmp(card + 8, "= ", 2) != 0)
        return 0;
    char val[71];
    memcpy(val, card + 10, 70);
    val[70] = '\0';
    char *slash = strchr(val, '/');
    if (slash)
        *slash = '\0';
    char *end = NULL;
    long v = strtol(val, &end, 10);
    while (end && *end == ' ')
        end++;
    if (!end || end == val || *end)
        return 0;
    *out = v;
    return 1;
}

static int read_header(int fd, const char *path, header *h, sl_err *err)
{
    char block[BLOCK];
    memset(h, 0, sizeof *h);
    h->n3_card = -1;
    for (int b = 0; b < MAX_HEADER_BLOCKS; b++) {
        ssize_t n = pread(fd, block, BLOCK, (off_t)b * BLOCK);
        if (n != BLOCK)
            return sl_seterr(err, n < 0 ? SL_EIO : SL_EFORMAT, "%s: primary header %s", path,
                             n < 0 ? g_strerror(errno) : "incomplete (no END card)");
        for (int c = 0; c < BLOCK / CARD; c++) {
            const char *card = block + c * CARD;
            if (b == 0 && c == 0)
                h->simple = !memcmp(card, "SIMPLE  = ", 10) && strchr(card + 10, 'T') &&
                            strchr(card + 10, 'T') < card + 30;
            card_int(card, "BITPIX", &h->bitpix);
            card_int(card, "NAXIS", &h->naxis);
            card_int(card, "NAXIS1", &h->n1);
            card_int(card, "NAXIS2", &h->n2);
            if (card_int(card, "NAXIS3", &h->n3))
                h->n3_card = (off_t)b * BLOCK + c * CARD;
            if (!memcmp(card, "END     ", 8)) {
                h->datastart = (off_t)(b + 1) * BLOCK;
                if (!h->simple || h->naxis != 3 || h->n3_card < 0 || h->n1 < 1 ||
                    h->n2 < 1 || h->n3 < 0 ||
                    (h->bitpix != 8 && h->bitpix != 16 && h->bitpix != 32 &&
                     h->bitpix != -32 && h->bitpix != -64))
                    return sl_seterr(err, SL_EFORMAT, "%s: not a 3-D FITS cube", path);
                return SL_OK;
            }
        }
    }
    return sl_seterr(err, SL_EFORMAT, "%s: no END card in %d header blocks", path,
                     MAX_HEADER_BLOCKS);
}

static off_t padded(off_t bytes)
{
    return (bytes + BLOCK - 1) / BLOCK * BLOCK;
}

/* Make the primary HDU's CHECKSUM and DATASUM right again when the cube
 * has them and they fail (a crash between the writer's flushes, or the
 * repair above).  The cards are rewritten in place: the file never grows. */
static int fix_checksum(const char *path, sl_err *err)
{
    fitsfile *f = NULL;
    int s = 0, data_ok = 0, hdu_ok = 0;
    char card[FLEN_CARD];
    fits_open_diskfile(&f, path, READWRITE, &s);
    if (!s && fits_read_card(f, "CHECKSUM", card, &s) == KEY_NO_EXIST) {
        s = 0;   /* a cube from before checksums: nothing to keep right */
        data_ok = hdu_ok = 1;
    }
    if (!s && !(data_ok && hdu_ok))
        fits_verify_chksum(f, &data_ok, &hdu_ok, &s);
    if (!s && (data_ok != 1 || hdu_ok != 1))
        fits_write_chksum(f, &s);
    if (f) {
        int s2 = 0;
        fits_close_file(f, s ? &s2 : &s);
    }
    if (!s)
        return SL_OK;
    char text[FLEN_STATUS];
    fits_get_errstatus(s, text);
    fits_clear_errmsg();
    return sl_seterr(err, SL_EIO, "%s: making its CHECKSUM right: %s", path, text);
}

int cubefile_salvage(const char *path, int *nframes, sl_err *err)
{
    header h;
    struct stat st;
    int rc = SL_OK;
    *nframes = 0;
    int fd = open(path, O_RDWR | O_CLOEXEC);
    if (fd < 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    if (fstat(fd, &st) != 0) {
        rc = sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
        goto close_fd;
    }
    if ((rc = read_header(fd, path, &h, err)) != SL_OK)
        goto close_fd;
    off_t fb = (off_t)h.n1 * h.n2 * (labs(h.bitpix) / 8);
    off_t avail = st.st_size > h.datastart ? st.st_size - h.datastart : 0;
    long k = (long)(avail / fb) < h.n3 ? (long)(avail / fb) : h.n3;
    /* Fill to the block boundary must fit in the bytes already there. */
    while (k > 0 && h.datastart + padded((off_t)k * fb) > st.st_size)
        k--;
    *nframes = (int)k;
    if (k == h.n3 && h.datastart + padded((off_t)k * fb) <= st.st_size)
        goto check_sum;   /* already a valid cube (maybe with extensions) */
    char val[21];
    snprintf(val, sizeof val, "%20ld", k);
    off_t data_end = h.datastart + (off_t)k * fb, end = h.datastart + padded((off_t)k * fb);
    char zero[BLOCK] = {0};
    if (pwrite(fd, val, 20, h.n3_card + 10) != 20 ||
        (end > data_end && pwrite(fd, zero, (size_t)(end - data_end), data_end) !=
                               (ssize_t)(end - data_end)) ||
        ftruncate(fd, end) != 0 || fsync(fd) != 0)
        rc = sl_seterr(err, SL_EIO, "%s: repairing the cube to %ld frames: %s", path, k,
                       g_strerror(errno));
check_sum:
    close(fd);
    return rc == SL_OK ? fix_checksum(path, err) : rc;
close_fd:
    close(fd);
    return rc;
}

int cubefile_frames_table(const char *path, const cubefile_row *rows, long n,
                          const camera_stats *st, sl_err *err)
{
    char *ttype[] = {"FRAME_ID", "CAM_TS_NS", "SYS_TS_NS", "STATUS", "CUBE_IDX"};
    char *tform[] = {"1K", "1K", "1K", "16A", "1J"};
    char *tunit[] = {"", "ns", "ns", "", ""};
    struct stat sb;
    fitsfile *f = NULL;
    int s = 0;
    if (stat(path, &sb) != 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    long m = n > 0 ? n : 1;
    LONGLONG *col = g_new(LONGLONG, m);
    char **names = g_new(char *, m);
    int *idx = g_new(int, m);
    fits_open_diskfile(&f, path, READWRITE, &s);
    fits_create_tbl(f, BINARY_TBL, 0, 5, ttype, tform, tunit, "FRAMES", &s);
    for (int c = 0; c < 3 && !s && n > 0; c++) {
        for (long i = 0; i < n; i++)
            col[i] = (LONGLONG)(c == 0 ? rows[i].frame_id
                                       : c == 1 ? rows[i].cam_ts_ns : rows[i].sys_ts_ns);
        fits_write_col(f, TLONGLONG, c + 1, 1, 1, n, col, &s);
    }
    for (long i = 0; i < n; i++) {
        names[i] = (char *)camera_frame_status_name(rows[i].status);
        idx[i] = rows[i].cube_idx;
    }
    if (n > 0) {
        fits_write_col(f, TSTRING, 4, 1, 1, n, names, &s);
        fits_write_col(f, TINT, 5, 1, 1, n, idx, &s);
    }
    if (st) {
        fits_update_key_lng(f, "NSTORED", (LONGLONG)st->completed, "SUCCESS frames returned", &s);
        fits_update_key_lng(f, "NFAILED", (LONGLONG)st->failed, "damaged buffers, not stored", &s);
        fits_update_key_lng(f, "NMISSPKT", (LONGLONG)st->missing_packets, "GigE packets missing",
                            &s);
        fits_update_key_lng(f, "NUNDERRN", (LONGLONG)st->underruns, "frames dropped: no buffer",
                            &s);
        fits_update_key_lng(f, "NIDGAPS", (LONGLONG)st->id_gaps, "frame ids never delivered", &s);
    }
    fits_write_chksum(f, &s);   /* last: after every row and keyword */
    /* cfitsio does not always report a write its close could not finish
     * (seen on a full tmpfs: the table's last bytes were dropped and the
     * close returned 0), so the file's size is checked against the end
     * of the table. */
    LONGLONG head = 0, data = 0, end = 0, width = 0;
    fits_get_hduaddrll(f, &head, &data, &end, &s);
    fits_read_key_lnglng(f, "NAXIS1", &width, NULL, &s);
    end = data + (width * (n > 0 ? n : 0) + BLOCK - 1) / BLOCK * BLOCK;
    int os_errno = errno;
    if (f) {
        int s2 = 0;
        fits_close_file(f, s ? &s2 : &s);
    }
    struct stat after;
    int short_write = !s && (stat(path, &after) != 0 || after.st_size < (off_t)end);
    if (short_write) {
        s = WRITE_ERROR;
        os_errno = ENOSPC;
    }
    int rc = SL_OK;
    if (s) {
        char text[FLEN_STATUS];
        fits_get_errstatus(s, text);
        fits_clear_errmsg();
        rc = sl_seterr(err, SL_EIO, "%s: writing the FRAMES table: %s (%s)", path, text,
                       g_strerror(os_errno));
        if (truncate(path, sb.st_size) != 0)
            g_warning("%s: cannot cut back a partial FRAMES table: %s", path,
                      g_strerror(errno));
    }
    g_free(col);
    g_free(names);
    g_free(idx);
    return rc;
}

int cubefile_has_table(const char *path)
{
    fitsfile *f = NULL;
    int s = 0;
    fits_open_diskfile(&f, path, READONLY, &s);
    fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &s);
    int has = s == 0;
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    fits_clear_errmsg();
    return has;
}

int cubefile_sha256(const char *path, char hex[65], sl_err *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    GChecksum *ck = g_checksum_new(G_CHECKSUM_SHA256);
    guchar *buf = g_malloc(1 << 16);
    ssize_t n;
    while ((n = read(fd, buf, 1 << 16)) > 0 || (n < 0 && errno == EINTR))
        if (n > 0)
            g_checksum_update(ck, buf, n);
    int rc = SL_OK;
    if (n < 0)
        rc = sl_seterr(err, SL_EIO, "%s: reading for the checksum: %s", path,
                       g_strerror(errno));
    else
        snprintf(hex, 65, "%s", g_checksum_get_string(ck));
    g_free(buf);
    g_checksum_free(ck);
    close(fd);
    return rc;
}

static int sync_path(const char *path, int flags, sl_err *err)
{
    int fd = open(path, flags | O_CLOEXEC);
    if (fd < 0)
        return sl_seterr(err, SL_EIO, "%s: %s", path, g_strerror(errno));
    int rc = fsync(fd) == 0 ? SL_OK
                            : sl_seterr(err, SL_EIO, "%s: fsync: %s", path, g_strerror(errno));
    close(fd);
    return rc;
}

int cubefile_fsync(const char *path, sl_err *err)
{
    return sync_path(path, O_RDONLY, err);
}

int cubefile_fsync_dir(const char *path_in_dir, sl_err *err)
{
    char *dir = g_path_get_dirname(path_in_dir);
    int rc = sync_path(dir, O_RDONLY | O_DIRECTORY, err);
    g_free(dir);
    return rc;
}

int cubefile_under(const char *dir, const char *path)
{
    char *d = realpath(dir, NULL), *p = realpath(path, NULL);
    size_t n = d ? strlen(d) : 0;
    int ok = d && p && strncmp(d, p, n) == 0 && p[n] == '/';
    free(d);
    free(p);
    return ok;
}
