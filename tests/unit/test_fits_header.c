/* test_fits_header.c - the standard header of every image the writer
 * makes (io/cube.h): CHECKSUM and DATASUM right on disk after each flush,
 * at close and after a crash that follows a flush, for every BITPIX and
 * frame sizes that leave words half filled; HISTORY wrapped over cards,
 * read back and bounded; DATE and CREATOR; the WCS derived from the plate
 * scale; keywords the writer derives never travel as extras.  Sums are
 * checked by cfitsio's own verifier on a copy of the file as it is on
 * disk (cfitsio would otherwise share the writer's buffers). */
#include "base/version.h"
#include "io/cube.h"
#include "tcheck.h"
#include "tmpdir_fx.h"

#include <fitsio.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static int copy_file(const char *src, const char *dst)
{
    FILE *in = fopen(src, "rb"), *out = fopen(dst, "wb");
    char buf[65536];
    size_t n;
    int ok = in && out;
    while (ok && (n = fread(buf, 1, sizeof buf, in)) > 0)
        ok = fwrite(buf, 1, n, out) == n;
    if (in)
        fclose(in);
    if (out && fclose(out) != 0)
        ok = 0;
    return ok;
}

/* Every HDU of path verified by cfitsio: the number of HDUs whose DATASUM
 * and CHECKSUM both verify, -1 when the file does not open.  *first_bad:
 * the first HDU (1-based) that failed, 0 when none. */
static int verified_hdus(const char *path, int *nhdu, int *first_bad)
{
    fitsfile *fp;
    int st = 0, good = 0, type;
    *nhdu = 0, *first_bad = 0;
    if (fits_open_diskfile(&fp, path, READONLY, &st))
        return -1;
    fits_get_num_hdus(fp, nhdu, &st);
    for (int i = 1; i <= *nhdu && !st; i++) {
        int data = 0, hdu = 0;
        fits_movabs_hdu(fp, i, &type, &st);
        fits_verify_chksum(fp, &data, &hdu, &st);
        if (data == 1 && hdu == 1)
            good++;
        else if (!*first_bad)
            *first_bad = i;
    }
    fits_close_file(fp, &st);
    return st ? -1 : good;
}

/* The on-disk state of path, through a copy: every HDU verifies. */
static int disk_verifies(tmpdir *d, const char *path, int want_hdus)
{
    const char *copy = tmp_path(d, 3, "copy.fits");
    int n = 0, bad = 0;
    if (!copy_file(path, copy))
        return 0;
    int good = verified_hdus(copy, &n, &bad);
    return good == want_hdus && n == want_hdus;
}

/* Where the primary HDU's data start, -1 when unknown. */
static long data_start(const char *path)
{
    fitsfile *fp;
    int st = 0;
    LONGLONG head = 0, data = -1, end = 0;
    fits_open_diskfile(&fp, path, READONLY, &st);
    fits_get_hduaddrll(fp, &head, &data, &end, &st);
    if (!st)
        fits_close_file(fp, &st);
    return st ? -1 : (long)data;
}

/* Values the type holds: integers within range, floats with NaN/Inf. */
static void fill_frame(float *f, int npx, int bitpix, int k)
{
    for (int i = 0; i < npx; i++) {
        float v = (float)(i * 37 + k * 101);
        switch (bitpix) {
        case 8: f[i] = (float)((int)v % 256); break;
        case 16: f[i] = (float)((int)v % 60000 - 30000); break;
        case CUBE_BITPIX_U16: f[i] = (float)((int)v * 97 % 65536); break;
        case 32: f[i] = (float)((int)v * 7919 - 1000000); break;
        case CUBE_BITPIX_U32: f[i] = (float)((int)v * 65537 % 16777216) * 255.0f; break;
        default: f[i] = i == 3 ? NAN : i == 4 ? -INFINITY : v * 0.37f - 11.0f;
        }
    }
}

/* 5 x 3 frames: 15 pixels, so 8- and 16-bit frames end mid-word and the
 * next frame's words start at another byte. */
TEST(checksums_right_after_every_flush_and_close)
{
    static const int bitpix[] = {8, 16, 32, -32, -64, CUBE_BITPIX_U16, CUBE_BITPIX_U32};
    enum { W = 5, H = 3 };
    float f[W * H];
    tmpdir d;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "c.fits");
    cube_meta m;
    cube_meta_init(&m);
    m.plate_scale_arcsec = 0.05;
    cube_meta_add_history(&m, "made by test_fits_header");
    for (size_t b = 0; b < sizeof bitpix / sizeof bitpix[0]; b++) {
        cube_writer *w = NULL;
        sl_err e = {0};
        int rc = cube_writer_open(&w, p, W, H, bitpix[b], &m, &e), ok[4] = {0};
        ok[0] = rc == SL_OK && cube_writer_flush(w) == SL_OK && disk_verifies(&d, p, 1);
        for (int k = 0; rc == SL_OK && k < 5; k++) {
            fill_frame(f, W * H, bitpix[b], k);
            rc = cube_writer_append(w, f);
            if (rc == SL_OK && (k == 0 || k == 2))
                ok[k == 0 ? 1 : 2] = cube_writer_flush(w) == SL_OK && disk_verifies(&d, p, 1);
        }
        fill_frame(f, W * H, -32, 9);
        rc = rc ? rc : cube_writer_add_image(w, "TRUTH", f, W, H, &m);
        rc = rc ? rc : cube_writer_close(w);
        const char *msg = w ? cube_writer_errmsg(w) : e.msg;
        ok[3] = rc == SL_OK && disk_verifies(&d, p, 2);
        CHECK(rc == SL_OK, "bitpix %d: %s", bitpix[b], msg);
        cube_writer_free(w);
        CHECK(ok[0] && ok[1] && ok[2] && ok[3], "bitpix %d: sums right when empty %d, after "
              "1 frame %d, 3 frames %d, at close with an extension %d", bitpix[b], ok[0],
              ok[1], ok[2], ok[3]);
    }
    /* the check can fail: one byte of the cube's data changed is caught */
    int n = 0, bad = 0;
    long at = data_start(p) + 7;
    FILE *fh = fopen(p, "r+b");
    CHECK(at > 7 && fh && fseek(fh, at, SEEK_SET) == 0 && fputc(0x5A, fh) != EOF &&
          fclose(fh) == 0, "corrupting %s at %ld", p, at);
    int good = verified_hdus(p, &n, &bad);
    tmp_remove(&d);
    CHECK(good == 1 && bad == 1, "a changed byte: %d of %d HDUs verify, first bad %d", good,
          n, bad);
}

TEST(one_frame_image_has_sums)
{
    tmpdir d;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "img.fits");
    seq *s = seq_new(7, 5, 1);
    fill_frame(s->data, 35, -32, 1);
    int rc = cube_write(p, s, NULL, &e), n = 0, bad = 0;
    int good = rc == SL_OK ? verified_hdus(p, &n, &bad) : -1;
    seq_free(s);
    tmp_remove(&d);
    CHECK(rc == SL_OK && good == 1 && n == 1, "rc %d (%s), %d of %d HDUs verify", rc, e.msg,
          good, n);
}

/* A crash right after a flush leaves a file whose sums hold. */
TEST(sums_hold_after_a_crash_that_follows_a_flush)
{
    tmpdir d;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "crash.fits");
    fflush(stdout);
    pid_t pid = fork();
    CHECK(pid >= 0, "fork");
    if (pid == 0) {
        float f[33 * 17];
        cube_writer *w = NULL;
        int rc = cube_writer_open(&w, p, 33, 17, CUBE_BITPIX_U16, NULL, NULL);
        for (int k = 0; rc == SL_OK && k < 3; k++) {
            fill_frame(f, 33 * 17, CUBE_BITPIX_U16, k);
            rc = cube_writer_append(w, f);
        }
        if (rc != SL_OK || cube_writer_flush(w) != SL_OK)
            _exit(1);
        raise(SIGKILL);
    }
    int status = 0, n = 0, bad = 0;
    waitpid(pid, &status, 0);
    int good = verified_hdus(p, &n, &bad);
    tmp_remove(&d);
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL, "child status %#x", status);
    CHECK(good == 1 && n == 1, "%d of %d HDUs verify", good, n);
}

/* The HISTORY cards of path's primary HDU, each line one card. */
static int history_cards(const char *path, char *out, size_t n, int *ncards, int *longest)
{
    fitsfile *fp;
    int st = 0, nkeys = 0;
    char card[FLEN_CARD];
    size_t used = 0;
    *ncards = 0, *longest = 0, out[0] = '\0';
    fits_open_diskfile(&fp, path, READONLY, &st);
    fits_get_hdrspace(fp, &nkeys, NULL, &st);
    for (int i = 1; i <= nkeys && !st; i++) {
        fits_read_record(fp, i, card, &st);
        if (strncmp(card, "HISTORY ", 8) != 0)
            continue;
        size_t len = strlen(card + 8);
        while (len > 0 && card[8 + len - 1] == ' ')
            len--;
        (*ncards)++;
        *longest = (int)len > *longest ? (int)len : *longest;
        if (used + len + 2 < n) {
            memcpy(out + used, card + 8, len);
            used += len;
            out[used++] = '\n';
            out[used] = '\0';
        }
    }
    fits_close_file(fp, &st);
    return st;
}

TEST(history_wraps_at_blanks_and_reads_back)
{
    tmpdir d;
    cube_meta m, got;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "h.fits"), *q = tmp_path(&d, 1, "h2.fits");
    char words[400] = "", solid[151];
    for (int i = 0; i < 40; i++)
        snprintf(words + strlen(words), sizeof words - strlen(words), "word%02d ", i);
    words[strlen(words) - 1] = '\0';      /* 279 characters, blanks every 7 */
    memset(solid, 'x', 150);
    solid[150] = '\0';
    cube_meta_init(&m);
    CHECK(cube_meta_add_history(&m, "input: %s", "a.fits") == SL_OK &&
          cube_meta_add_history(&m, "%s", words) == SL_OK &&
          cube_meta_add_history(&m, "%s", solid) == SL_OK &&
          cube_meta_add_history(&m, "two\nlines\twith caf\xc3\xa9") == SL_OK, "add");
    seq *s = seq_new(4, 4, 1), *back = NULL;
    memset(s->data, 0, 16 * sizeof(float));
    int rc = cube_write(p, s, &m, &e);
    rc = rc ? rc : cube_read(&back, &got, &p, 1, 0, &e);
    seq_free(back);
    rc = rc ? rc : cube_write(q, s, &got, &e);
    seq_free(s);
    static char c1[8192], c2[8192];
    int n1 = 0, n2 = 0, long1 = 0, long2 = 0;
    int r1 = rc ? -1 : history_cards(p, c1, sizeof c1, &n1, &long1);
    int r2 = rc ? -1 : history_cards(q, c2, sizeof c2, &n2, &long2);
    tmp_remove(&d);
    CHECK(rc == SL_OK && r1 == 0 && r2 == 0, "%s", e.msg);
    /* words: 4 cards cut at blanks; solid: 72 + 72 + 6; two lines */
    CHECK(n1 == 1 + 4 + 3 + 2 && long1 <= CUBE_HISTORY_CARD, "%d cards, longest %d:\n%s", n1,
          long1, c1);
    char joined[400] = "";
    const char *line = strchr(c1, '\n') + 1;
    for (int i = 0; i < 4; i++) {
        const char *nl = strchr(line, '\n');
        snprintf(joined + strlen(joined), sizeof joined - strlen(joined), "%s%.*s",
                 i ? " " : "", (int)(nl - line), line);
        line = nl + 1;
    }
    CHECK(!strcmp(joined, words), "the wrapped entry reads '%s'", joined);
    CHECK(strstr(c1, "two\nlines?with caf??\n") != NULL, "control and non-ASCII: %s", c1);
    CHECK(!strcmp(c1, c2) && n1 == n2, "a read and write changed the cards:\n%s---\n%s", c1,
          c2);
    CHECK(!strncmp(got.history, "input: a.fits\n", 14), "read back: %.40s", got.history);
}

TEST(history_read_is_bounded)
{
    tmpdir d;
    fitsfile *fp;
    int st = 0;
    long nx[2] = {2, 2};
    float px[4] = {0};
    char text[71];
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "many.fits");
    memset(text, 'h', 70);
    text[70] = '\0';
    fits_create_diskfile(&fp, p, &st);
    fits_create_img(fp, FLOAT_IMG, 2, nx, &st);
    for (int i = 0; i < 300; i++)   /* 21000 bytes of HISTORY */
        fits_write_history(fp, text, &st);
    fits_write_img(fp, TFLOAT, 1, 4, px, &st);
    fits_close_file(fp, &st);
    CHECK(st == 0, "cfitsio %d", st);
    seq *s = NULL;
    cube_meta m;
    sl_err e = {0};
    int rc = cube_read(&s, &m, &p, 1, 0, &e);
    seq_free(s);
    tmp_remove(&d);
    CHECK(rc == SL_OK, "%s", e.msg);
    size_t kept = strlen(m.history);
    CHECK(kept <= CUBE_HISTORY_MAX / 2 && kept > CUBE_HISTORY_MAX / 2 - 80 && m.ndropped > 0,
          "kept %zu bytes, %d dropped", kept, m.ndropped);
    char big[3000];
    memset(big, 'y', sizeof big - 1);
    big[sizeof big - 1] = '\0';
    CHECK(cube_meta_add_history(&m, "%s", big) == SL_OK, "no room left for the caller");
    memset(m.history, 'z', CUBE_HISTORY_MAX - 10);
    m.history[CUBE_HISTORY_MAX - 10] = '\0';
    CHECK(cube_meta_add_history(&m, "%s", "0123456789") == SL_ERANGE, "overflow accepted");
    CHECK(strlen(m.history) == CUBE_HISTORY_MAX - 10, "a refused entry changed the text");
}

/* Keyword cards of path's primary HDU: 1 when key is present, its value
 * text (unquoted for strings) in val. */
static int key_text(const char *path, const char *key, char *val, size_t n)
{
    fitsfile *fp;
    int st = 0;
    char v[FLEN_VALUE];
    fits_open_diskfile(&fp, path, READONLY, &st);
    fits_read_keyword(fp, key, v, NULL, &st);
    int found = st == 0;
    if (found && v[0] == '\'') {
        char *end = strrchr(v + 1, '\'');
        *end = '\0';
        while (end > v + 1 && end[-1] == ' ')
            *--end = '\0';
        snprintf(val, n, "%s", v + 1);
    } else if (found) {
        snprintf(val, n, "%s", v);
    }
    st = 0;
    fits_close_file(fp, &st);
    return found;
}

static double key_num(const char *path, const char *key)
{
    char v[FLEN_VALUE];
    return key_text(path, key, v, sizeof v) ? strtod(v, NULL) : NAN;
}

static int write_meta(const char *path, int w, int h, const cube_meta *m)
{
    sl_err e;
    seq *s = seq_new(w, h, 1);
    memset(s->data, 0, sizeof(float) * (size_t)w * (size_t)h);
    int rc = cube_write(path, s, m, &e);
    seq_free(s);
    return rc;
}

TEST(wcs_from_the_plate_scale)
{
    tmpdir d;
    char v[80];
    cube_meta m;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "w.fits");
    cube_meta_init(&m);
    CHECK(write_meta(p, 64, 48, &m) == SL_OK, "write");
    int none = !key_text(p, "CTYPE1", v, sizeof v) && !key_text(p, "CDELT1", v, sizeof v) &&
               !key_text(p, "CRPIX1", v, sizeof v);
    m.plate_scale_arcsec = 0.05;
    CHECK(write_meta(p, 64, 48, &m) == SL_OK, "write");
    int off = key_text(p, "CTYPE1", v, sizeof v) && !strcmp(v, "EOFFSET") &&
              key_text(p, "CTYPE2", v, sizeof v) && !strcmp(v, "NOFFSET") &&
              key_text(p, "CUNIT1", v, sizeof v) && !strcmp(v, "arcsec") &&
              key_num(p, "CRPIX1") == 33 && key_num(p, "CRPIX2") == 25 &&
              key_num(p, "CRVAL1") == 0 && key_num(p, "CDELT1") == -0.05 &&
              key_num(p, "CDELT2") == 0.05 && !key_text(p, "CTYPE1A", v, sizeof v);
    m.pixel_aspect = 1.25;
    CHECK(write_meta(p, 65, 47, &m) == SL_OK, "write");
    int odd = key_num(p, "CRPIX1") == 33 && key_num(p, "CRPIX2") == 24 &&
              key_num(p, "CDELT2") == 0.0625 && key_num(p, "PIXASPCT") == 1.25;
    m.pixel_aspect = NAN;
    m.ra_deg = 201.5, m.dec_deg = -43.25;
    CHECK(write_meta(p, 64, 48, &m) == SL_OK, "write");
    int sky = key_text(p, "CTYPE1", v, sizeof v) && !strcmp(v, "RA---TAN") &&
              key_text(p, "CTYPE2", v, sizeof v) && !strcmp(v, "DEC--TAN") &&
              key_text(p, "CUNIT1", v, sizeof v) && !strcmp(v, "deg") &&
              key_text(p, "RADESYS", v, sizeof v) && !strcmp(v, "ICRS") &&
              key_num(p, "CRVAL1") == 201.5 && key_num(p, "CRVAL2") == -43.25 &&
              fabs(key_num(p, "CDELT1") + 0.05 / 3600) < 1e-15 &&
              key_text(p, "CTYPE1A", v, sizeof v) && !strcmp(v, "EOFFSET") &&
              key_num(p, "CDELT1A") == -0.05 && key_num(p, "CRPIX1A") == 33;
    seq *s = NULL;
    cube_meta got;
    sl_err e = {0};
    int rc = cube_read(&s, &got, &p, 1, 0, &e);
    seq_free(s);
    tmp_remove(&d);
    CHECK(none, "a WCS without a plate scale");
    CHECK(off, "the offset WCS");
    CHECK(odd, "odd sizes and tall pixels");
    CHECK(sky, "the celestial WCS with the offsets as WCS A");
    CHECK(rc == SL_OK && got.ra_deg == 201.5 && got.dec_deg == -43.25 &&
          got.plate_scale_arcsec == 0.05 && got.nextra == 0, "read back: RA %g DEC %g, "
          "%d extras (first %s)", got.ra_deg, got.dec_deg, got.nextra,
          got.nextra ? got.extra[0].key : "");
}

TEST(date_and_creator)
{
    tmpdir d;
    char v[80], want[80];
    cube_meta m;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "dc.fits");
    cube_meta_init(&m);
    time_t t0 = time(NULL);
    CHECK(write_meta(p, 8, 8, &m) == SL_OK, "write");
    struct tm tm = {0};
    int date = key_text(p, "DATE", v, sizeof v) && strlen(v) == 19 &&
               sscanf(v, "%d-%d-%dT%d:%d:%d", &tm.tm_year, &tm.tm_mon, &tm.tm_mday,
                      &tm.tm_hour, &tm.tm_min, &tm.tm_sec) == 6;
    tm.tm_year -= 1900, tm.tm_mon -= 1;
    time_t when = date ? timegm(&tm) : 0;
    snprintf(want, sizeof want, "specklab %s", SPECKLAB_VERSION);
    int creator = key_text(p, "CREATOR", v, sizeof v) && !strcmp(v, want);
    snprintf(m.creator, sizeof m.creator, "specklabd %s", SPECKLAB_VERSION);
    CHECK(write_meta(p, 8, 8, &m) == SL_OK, "write");
    snprintf(want, sizeof want, "specklabd %s", SPECKLAB_VERSION);
    int theirs = key_text(p, "CREATOR", v, sizeof v) && !strcmp(v, want);
    tmp_remove(&d);
    CHECK(date && when >= t0 - 1 && when <= t0 + 60, "DATE '%s' vs now %lld", v, (long long)t0);
    CHECK(creator && theirs, "CREATOR '%s'", v);
}

/* A file from elsewhere with its own WCS, DATE and CREATOR: none of them
 * travels (the WCS would describe another grid, the others another file). */
TEST(derived_keywords_never_travel)
{
    static const char *derived[] = {"DATE", "CREATOR", "CTYPE1", "CRPIX2", "CDELT1A",
                                    "CUNIT3", "PC1_2", "CD2_1", "PV2_1", "WCSNAME",
                                    "RADESYS", "EQUINOXA", "LONPOLE", "CROTA2"};
    static const char *fine[] = {"CRPIXEL", "DATEOBS", "CDX", "PCB", "CREATORS"};
    cube_meta m;
    cube_meta_init(&m);
    for (size_t i = 0; i < sizeof derived / sizeof derived[0]; i++)
        CHECK(cube_meta_set_num(&m, derived[i], 1, NULL) == SL_EINVAL, "%s accepted",
              derived[i]);
    for (size_t i = 0; i < sizeof fine / sizeof fine[0]; i++)
        CHECK(cube_meta_set_num(&m, fine[i], 1, NULL) == SL_OK, "%s refused", fine[i]);
    tmpdir d;
    fitsfile *fp;
    int st = 0;
    long nx[2] = {4, 4};
    float px[16] = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "foreign.fits"), *q = tmp_path(&d, 1, "again.fits");
    fits_create_diskfile(&fp, p, &st);
    fits_create_img(fp, FLOAT_IMG, 2, nx, &st);
    fits_update_key_str(fp, "CTYPE1", "RA---TAN", NULL, &st);
    fits_update_key_dbl(fp, "CDELT1", -1e-4, 6, NULL, &st);
    fits_update_key_str(fp, "CREATOR", "another program", NULL, &st);
    fits_write_date(fp, &st);
    fits_write_img(fp, TFLOAT, 1, 16, px, &st);
    fits_close_file(fp, &st);
    CHECK(st == 0, "cfitsio %d", st);
    seq *s = NULL;
    sl_err e = {0};
    int rc = cube_read(&s, &m, &p, 1, 0, &e);
    rc = rc ? rc : cube_write(q, s, &m, &e);
    seq_free(s);
    char v[80], want[80];
    snprintf(want, sizeof want, "specklab %s", SPECKLAB_VERSION);
    int creator = key_text(q, "CREATOR", v, sizeof v) && !strcmp(v, want);
    int no_wcs = !key_text(q, "CTYPE1", v, sizeof v) && !key_text(q, "CDELT1", v, sizeof v);
    tmp_remove(&d);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(m.nextra == 0 && m.ndropped == 0 && m.creator[0] == 0, "%d extras (first %s), "
          "%d dropped, creator '%s'", m.nextra, m.nextra ? m.extra[0].key : "", m.ndropped,
          m.creator);
    CHECK(creator && no_wcs, "written again: CREATOR '%s', WCS %s", want,
          no_wcs ? "absent" : "copied");
}

TC_MAIN(TC_CASE(checksums_right_after_every_flush_and_close), TC_CASE(one_frame_image_has_sums),
        TC_CASE(sums_hold_after_a_crash_that_follows_a_flush),
        TC_CASE(history_wraps_at_blanks_and_reads_back), TC_CASE(history_read_is_bounded),
        TC_CASE(wcs_from_the_plate_scale), TC_CASE(date_and_creator),
        TC_CASE(derived_keywords_never_travel))
